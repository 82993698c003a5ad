//! The per-frame pipeline on the committed episode with the shipped model.

use moe_arap::ShapeOptions;
use moe_contact::ContactEstimator;
use moe_geom::{FingerParams, HandModel, HandPreset, Transform, WorldFromHand};
use moe_touch::contact_eval::study_shape_estimator;
use moe_touch::perception::score::episode_intrinsics;
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::pipeline::load_contact_model;
use moe_touch::{Pipeline, RgbdFrame, TouchError};

use crate::common::fixtures;

fn hand() -> HandModel {
    HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap()
}

fn episode() -> moe_io::Episode {
    moe_io::read_episode(&fixtures().join("episodes/plate_tip_front_small.mcap")).unwrap()
}

fn detector(hand: &HandModel, episode: &moe_io::Episode) -> MarkerDetector {
    MarkerDetector::new(
        episode_intrinsics(&episode.info),
        Transform::new(episode.info.hand_from_camera),
        hand,
        DetectorConfig::default(),
    )
    .unwrap()
}

fn model_path() -> std::path::PathBuf {
    fixtures().join("../models/contact-two-finger.safetensors")
}

#[test]
fn the_pipeline_equals_the_stages_run_one_by_one() {
    let hand = hand();
    let episode = episode();
    let model = load_contact_model(&model_path(), &hand).unwrap();
    let threshold = model.threshold();
    let options = ShapeOptions::default();
    let mut pipeline = Pipeline::new(
        hand.clone(),
        detector(&hand, &episode),
        study_shape_estimator(&hand, &options).unwrap(),
        load_contact_model(&model_path(), &hand).unwrap(),
        threshold,
    )
    .unwrap();
    let mut d = detector(&hand, &episode);
    let mut arap = study_shape_estimator(&hand, &options).unwrap();
    let mut contact_frames = 0;
    for frame in &episode.frames {
        let pose = WorldFromHand::new(frame.world_from_hand);
        let est = pipeline
            .process(
                RgbdFrame {
                    color_rgb8: &frame.color_rgb8,
                    depth_m: &frame.depth_m,
                },
                pose,
            )
            .unwrap();
        let det = d.detect(&frame.color_rgb8, &frame.depth_m).unwrap();
        let shape = arap.estimate(&det.keypoints).unwrap().shape;
        let map = model.estimate(&shape, Some(&det.keypoints)).unwrap();
        assert_eq!(est.keypoints, det.keypoints);
        assert_eq!(est.shape, shape);
        assert_eq!(est.contact, map);
        let points = map.contacts_above(threshold, &shape).unwrap();
        assert_eq!(est.contacts_in_hand, points);
        assert_eq!(est.contacts_in_world.len(), points.len());
        for (w, h) in est.contacts_in_world.iter().zip(&points) {
            assert!((w.point - frame.world_from_hand * h.point).norm() < 1e-12);
            assert_eq!((w.finger, w.vertex), (h.finger, h.vertex));
        }
        contact_frames += usize::from(!points.is_empty());
        let t = est.timings;
        assert!(t.total_ms >= t.markers_ms + t.shape_ms + t.contact_ms - 1e-9);
        assert!(est.fingers_without_markers.is_empty());
    }
    assert!(
        contact_frames > 0,
        "the plate presses the tip: some contact is found"
    );
}

#[test]
fn a_finger_without_markers_is_reported_and_the_stream_goes_on() {
    let hand = hand();
    let episode = episode();
    let model = load_contact_model(&model_path(), &hand).unwrap();
    let threshold = model.threshold();
    let mut pipeline = Pipeline::new(
        hand.clone(),
        detector(&hand, &episode),
        study_shape_estimator(&hand, &ShapeOptions::default()).unwrap(),
        model,
        threshold,
    )
    .unwrap();
    let width = episode.info.camera.width as usize;
    for (k, frame) in episode.frames.iter().enumerate() {
        // Frames 2–4: no depth on the right half of the image, where finger 0 is.
        let mut depth = frame.depth_m.clone();
        if (2..5).contains(&k) {
            for (i, d) in depth.iter_mut().enumerate() {
                if i % width >= width / 2 {
                    *d = 0.0;
                }
            }
        }
        let est = pipeline
            .process(
                RgbdFrame {
                    color_rgb8: &frame.color_rgb8,
                    depth_m: &depth,
                },
                WorldFromHand::new(frame.world_from_hand),
            )
            .unwrap();
        if (2..5).contains(&k) {
            assert_eq!(est.fingers_without_markers, vec![0], "frame {k}");
            assert_eq!(
                est.shape.fingers[0],
                hand.rest_vertices_in_hand(0),
                "frame {k}"
            );
        } else {
            assert!(est.fingers_without_markers.is_empty(), "frame {k}");
        }
    }
    // Images of the wrong size are an error, not a panic.
    let err = pipeline
        .process(
            RgbdFrame {
                color_rgb8: &[],
                depth_m: &[],
            },
            WorldFromHand::identity(),
        )
        .unwrap_err();
    assert!(matches!(err, TouchError::ImageSize { .. }), "{err}");
}
