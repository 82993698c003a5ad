//! Tests of the contact study: marker subsets and perturbations, estimated shapes, plate trials.

use super::*;
use moe_arap::ShapeConfig;
use moe_geom::{
    FingerParams, HandKeypoints, HandPreset, HandShape, LabelledFrame, SeededRng, Vector3,
    WorldFromHand,
};
use moe_tendon_sim::{ObstacleConfig, ObstacleShape, PoseKeyframe, PoseTrajectory, SceneConfig};

#[test]
fn marker_subsets_keep_the_asked_number_per_finger_and_are_seeded() {
    let hand = HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default()).unwrap();
    let all = hand.rest_keypoints();
    let rng = SeededRng::new(4);
    let a = marker_subset(&all, 4, &mut rng.split(1));
    for (f, g) in a.fingers.iter().zip(&all.fingers) {
        assert_eq!(f.iter().flatten().count(), 4);
        // Kept markers are unchanged.
        for (p, q) in f.iter().zip(g) {
            if let Some(p) = p {
                assert_eq!(Some(*p), *q);
            }
        }
    }
    assert_eq!(a, marker_subset(&all, 4, &mut rng.split(1)));
    assert_ne!(a, marker_subset(&all, 4, &mut rng.split(2)));
    assert_eq!(marker_subset(&all, 9, &mut rng.split(1)), all);
}

#[test]
fn marker_augmentation_moves_and_drops_markers_at_the_asked_rates() {
    let hand = HandModel::preset(HandPreset::FiveFinger, &FingerParams::default()).unwrap();
    let mut all = hand.rest_keypoints();
    // An occluded marker stays occluded.
    all.fingers[0][0] = None;
    let order = distal_marker_order(&hand);
    let none = MarkerAugmentation {
        seed: 1,
        ..MarkerAugmentation::default()
    };
    assert_eq!(none.apply(&all, &order, &mut SeededRng::new(3)), all);
    let aug = MarkerAugmentation {
        noise_sd_m: 2e-4,
        drop_probability: 0.25,
        seed: 1,
        ..MarkerAugmentation::default()
    };
    let (mut kept, mut dropped, mut sq) = (0usize, 0usize, 0.0);
    for k in 0..400 {
        let out = aug.apply(&all, &order, &mut SeededRng::new(7).split(k));
        assert_eq!(
            out,
            aug.apply(&all, &order, &mut SeededRng::new(7).split(k))
        );
        assert_eq!(out.fingers[0][0], None);
        for (f, g) in out.fingers.iter().zip(&all.fingers) {
            for (p, q) in f.iter().zip(g).skip(1) {
                match p {
                    Some(p) => {
                        kept += 1;
                        sq += (p - q.unwrap()).norm_squared();
                    }
                    None => dropped += 1,
                }
            }
        }
    }
    let rate = dropped as Real / (kept + dropped) as Real;
    assert!((rate - 0.25).abs() < 0.02, "drop rate {rate}");
    // E‖n‖² = 3σ² for isotropic noise.
    let sd = (sq / (3 * kept) as Real).sqrt();
    assert!((sd - 2e-4).abs() < 5e-6, "noise sd {sd}");
    for bad in [
        MarkerAugmentation {
            noise_sd_m: Real::NAN,
            ..aug
        },
        MarkerAugmentation {
            noise_sd_m: 0.01,
            ..aug
        },
        MarkerAugmentation {
            drop_probability: 1.5,
            ..aug
        },
        MarkerAugmentation {
            drop_probability: -0.1,
            ..aug
        },
        MarkerAugmentation {
            distal_occlusion_probability: 1.1,
            ..aug
        },
        MarkerAugmentation {
            distal_occlusion_probability: 0.5,
            max_distal_occluded: 0,
            ..aug
        },
    ] {
        assert!(bad.validate().is_err(), "{bad:?}");
    }
}

/// Distal occlusion hides a run of the most distal markers (never all of them) of the asked
/// share of fingers, with run lengths spread from 1 to the maximum; switched off, it draws
/// nothing, so the plain perturbation is reproduced draw for draw.
#[test]
fn distal_occlusion_hides_runs_of_tip_markers_at_the_asked_rate() {
    let hand = HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default()).unwrap();
    let all = hand.rest_keypoints();
    let order = distal_marker_order(&hand);
    // The built-in finger's markers run base to tip, so the tip's is the last.
    for o in &order {
        assert_eq!(o.len(), 7);
        assert_eq!(o[0], 6);
        assert_eq!(o[6], 0);
    }
    let aug = MarkerAugmentation {
        distal_occlusion_probability: 0.3,
        max_distal_occluded: 3,
        ..MarkerAugmentation::default()
    };
    let mut runs = [0usize; 4];
    let mut fingers = 0;
    for k in 0..600 {
        let out = aug.apply(&all, &order, &mut SeededRng::new(11).split(k));
        for (f, o) in out.fingers.iter().zip(&order) {
            fingers += 1;
            let hidden = f.iter().filter(|p| p.is_none()).count();
            assert!(hidden <= 3, "{f:?}");
            // The hidden ones are exactly the `hidden` most distal.
            for (rank, &m) in o.iter().enumerate() {
                assert_eq!(f[m].is_none(), rank < hidden, "{f:?}");
            }
            runs[hidden] += 1;
        }
    }
    let rate = (fingers - runs[0]) as Real / fingers as Real;
    assert!((rate - 0.3).abs() < 0.03, "occluded fingers {rate}");
    for (len, &n) in runs.iter().enumerate().skip(1) {
        let share = n as Real / (fingers - runs[0]) as Real;
        assert!((share - 1.0 / 3.0).abs() < 0.06, "runs of {len}: {share}");
    }
    // A run never hides a finger's last marker: a finger of one marker keeps it, a finger
    // of two loses exactly its distal one, whatever the draws.
    let m = all.fingers[0][0];
    let small = HandKeypoints {
        fingers: vec![vec![m], vec![m, m]],
    };
    let small_order = vec![vec![0], vec![1, 0]];
    let every = MarkerAugmentation {
        distal_occlusion_probability: 1.0,
        ..aug
    };
    for k in 0..50 {
        let out = every.apply(&small, &small_order, &mut SeededRng::new(1).split(k));
        assert_eq!(out.fingers[0], vec![m]);
        assert_eq!(out.fingers[1], vec![m, None]);
    }
    // Off: exactly the draws of the plain perturbation (drop, then three normals, per
    // observed marker), and none more.
    let plain = MarkerAugmentation {
        noise_sd_m: 1e-4,
        drop_probability: 0.2,
        ..MarkerAugmentation::default()
    };
    let mut rng = SeededRng::new(5);
    let out = plain.apply(&all, &order, &mut rng);
    let mut reference = SeededRng::new(5);
    for (f, g) in out.fingers.iter().zip(&all.fingers) {
        for (p, q) in f.iter().zip(g) {
            let q = q.unwrap();
            let expected = if reference.uniform() < 0.2 {
                None
            } else {
                let n = Vector3::new(reference.normal(), reference.normal(), reference.normal());
                Some(q + n * 1e-4)
            };
            assert_eq!(*p, expected);
        }
    }
    assert_eq!(rng.uniform(), reference.uniform());
}

#[test]
fn estimated_shapes_with_every_marker_dropped_are_the_rest_shapes() {
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let rest = HandShape::rest(&hand);
    let mut bent = hand.rest_keypoints();
    for p in bent.fingers.iter_mut().flatten().flatten() {
        p.x += 0.2 * (p.z - 0.01).max(0.0);
    }
    let frame = LabelledFrame {
        trajectory_id: 0,
        frame_index: 0,
        shape: rest.clone(),
        contact: rest.fingers.iter().map(|f| vec![false; f.len()]).collect(),
        markers: bent,
        world_from_hand: WorldFromHand::identity(),
        tendon_pull_m: vec![vec![0.0; 4]; rest.fingers.len()],
    };
    let frames = vec![frame.clone(), frame];
    let options = ShapeConfig::default();
    let largest_move = |shape: &HandShape| {
        shape
            .fingers
            .iter()
            .zip(&rest.fingers)
            .flat_map(|(a, b)| a.iter().zip(b).map(|(p, q)| (p - q).norm()))
            .fold(0.0, Real::max)
    };
    let plain = with_estimated_shapes(&hand, &frames, &options, None).unwrap();
    assert!(
        largest_move(&plain[0].shape) > 1e-3,
        "the bend moves the shape"
    );
    let drop_all = MarkerAugmentation {
        noise_sd_m: 1e-4,
        drop_probability: 1.0,
        ..MarkerAugmentation::default()
    };
    let dropped = with_estimated_shapes(&hand, &frames, &options, Some(&drop_all)).unwrap();
    for f in &dropped {
        assert!(largest_move(&f.shape) < 1e-12);
    }
    // Noise alone: the two identical frames get different draws, and a repeat is identical.
    let noisy = MarkerAugmentation {
        drop_probability: 0.0,
        ..drop_all
    };
    let a = with_estimated_shapes(&hand, &frames, &options, Some(&noisy)).unwrap();
    assert_ne!(a[0].shape, a[1].shape);
    assert_eq!(
        a,
        with_estimated_shapes(&hand, &frames, &options, Some(&noisy)).unwrap()
    );
    let bad = MarkerAugmentation {
        drop_probability: 2.0,
        ..noisy
    };
    assert!(with_estimated_shapes(&hand, &frames, &options, Some(&bad)).is_err());
}

/// Registered to the depth image the camera renders of the true fingers, SR-ARAP's shape
/// explains that image better where the markers do not say (here finger 0's surface is 0.6
/// mm off the markers' rest places); the same seed gives the same shapes, another seed other
/// noise.
#[test]
fn depth_registered_shapes_move_towards_the_rendered_surface() {
    use moe_arap::ShapeDepth;
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let rest = HandShape::rest(&hand);
    let mut truth = rest.clone();
    for p in &mut truth.fingers[0] {
        p.x -= 0.0006;
    }
    let frame = LabelledFrame {
        trajectory_id: 3,
        frame_index: 1,
        shape: truth.clone(),
        contact: rest.fingers.iter().map(|f| vec![false; f.len()]).collect(),
        markers: hand.rest_keypoints(),
        world_from_hand: WorldFromHand::identity(),
        tendon_pull_m: vec![vec![0.0; 4]; rest.fingers.len()],
    };
    let frames = vec![frame];
    let options = ShapeConfig {
        depth: ShapeDepth {
            enabled: true,
            ..ShapeDepth::default()
        },
        ..ShapeConfig::default()
    };
    let camera = moe_tendon_sim::camera::RgbdCamera::default();
    let markers_only = with_estimated_shapes(&hand, &frames, &options, None).unwrap();
    let registered =
        with_depth_registered_shapes(&hand, &frames, &options, None, &camera, 7).unwrap();
    // How far the image's pixels on finger 0 lie from each shape's surface (median).
    let image = super::augmentation::render_fingers(&hand, &frames[0], &camera, 7).unwrap();
    let depth = moe_geom::depth::DepthImage::new(
        &image.depth_m,
        camera.intrinsics,
        camera.hand_from_camera,
    )
    .unwrap();
    let residual = |shape: &HandShape| {
        let found = moe_geom::depth::associate_depth(
            &hand,
            shape,
            &depth,
            &moe_geom::depth::AssociationOptions::default(),
        )
        .unwrap();
        let mut r: Vec<Real> = found[0].points.iter().map(|p| p.residual_m.abs()).collect();
        r.sort_by(Real::total_cmp);
        r[r.len() / 2]
    };
    let (before, after) = (
        residual(&markers_only[0].shape),
        residual(&registered[0].shape),
    );
    assert!(
        after < 0.7 * before,
        "median pixel residual {after:e} m against {before:e} m"
    );
    let again = with_depth_registered_shapes(&hand, &frames, &options, None, &camera, 7).unwrap();
    assert_eq!(again, registered);
    let other = with_depth_registered_shapes(&hand, &frames, &options, None, &camera, 8).unwrap();
    assert_ne!(
        other[0].shape, registered[0].shape,
        "another seed, other noise"
    );
}

#[test]
fn plate_perturbations_are_small_seeded_and_rigid() {
    let config = SceneConfig {
        obstacles: vec![ObstacleConfig {
            shape: ObstacleShape::Cuboid {
                half_extents_m: [0.001, 0.02, 0.015],
            },
            trajectory: PoseTrajectory {
                keyframes: vec![
                    PoseKeyframe::at(0.0, [0.01, 0.0, 0.08]),
                    PoseKeyframe::at(1.0, [0.0, 0.0, 0.08]),
                ],
            },
        }],
        ..SceneConfig::default()
    };
    assert_eq!(perturbed_plate(&config, 3, 0).0, config);
    let (moved, offset, tilt) = perturbed_plate(&config, 3, 1);
    assert_eq!(perturbed_plate(&config, 3, 1).0, moved);
    assert!(offset.iter().all(|o| o.abs() <= PLATE_OFFSET_M));
    assert!(tilt.abs() <= PLATE_TILT_DEG && tilt != 0.0);
    let k = &moved.obstacles[0].trajectory.keyframes;
    // The first keyframe moves by the offset only (the tilt is about it); the distance
    // between the keyframes is kept; the rotation is the tilt.
    let d0: Vec<Real> = (0..3)
        .map(|i| k[0].translation_m[i] - [0.01, 0.0, 0.08][i])
        .collect();
    assert!(d0.iter().zip(&offset).all(|(a, b)| (a - b).abs() < 1e-15));
    let gap = Vector3::from(k[1].translation_m) - Vector3::from(k[0].translation_m);
    assert!((gap.norm() - 0.01).abs() < 1e-12);
    let angle = Vector3::from(k[1].rotation_rad).norm().to_degrees();
    assert!((angle - tilt.abs()).abs() < 1e-9, "{angle} vs {tilt}");
}

#[test]
fn the_plate_registry_lists_the_papers_six_scenes_in_order_with_their_regions() {
    let scenes = plate_scenes().unwrap();
    let names: Vec<(&str, &str)> = scenes
        .iter()
        .map(|s| (s.name.as_str(), s.region.as_str()))
        .collect();
    assert_eq!(names, PLATE_SCENES);
    for s in &scenes {
        assert!(!s.config.obstacles.is_empty(), "{}: a plate", s.name);
    }
}

#[test]
fn the_plate_table_summarises_each_region_and_counts_trials_all_missed() {
    let report = |ucd_mm: Real| moe_contact::ContactReport {
        ucd_mm,
        ..moe_contact::ContactReport::default()
    };
    let trial = |region: &str, dgcnn: Real, knn: Real| PlateTrial {
        scene: format!("plate_{region}_front"),
        region: region.to_owned(),
        trial: 0,
        offset_m: [0.0; 3],
        tilt_deg: 0.0,
        contact_frames: 1,
        dgcnn: report(dgcnn),
        knn_all: report(knn),
    };
    let table = PlateTable::new(vec![
        trial("tip", 1.0, 2.0),
        trial("tip", 3.0, Real::NAN),
        trial("base", 5.0, 6.0),
    ]);
    let tip = &table.regions.tip;
    assert_eq!(
        (tip.dgcnn.mean_mm, tip.dgcnn.sd_mm, tip.dgcnn.trials),
        (2.0, 1.0, 2)
    );
    assert_eq!((tip.knn_all.trials, tip.knn_all.trials_all_missed), (1, 1));
    assert_eq!(table.regions.middle.dgcnn.trials, 0);
    assert_eq!(table.regions.base.knn_all.mean_mm, 6.0);
    let names: Vec<&str> = table.regions.in_order().iter().map(|(n, _)| *n).collect();
    assert_eq!(names, ["tip", "middle", "base"]);
}
