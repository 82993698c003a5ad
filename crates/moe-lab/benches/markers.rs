//! Marker perception speed: one 640 × 480 wrist-camera frame to keypoints.
//!
//! `cargo bench -p moe-lab --bench markers`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use moe_geom::{FingerParams, HandModel, HandPreset, Point3};
use moe_lab::episode::{finger_items, markers_of};
use moe_tendon_sim::camera::{RgbdCamera, RgbdImage};
use moe_touch::perception::{DetectorConfig, MarkerDetector};

/// The hand at rest seen by the default (noisy) wrist camera.
fn frame(hand: &HandModel, camera: &RgbdCamera) -> RgbdImage {
    let fingers: Vec<Vec<Point3>> = (0..hand.num_fingers())
        .map(|i| hand.rest_vertices_in_hand(i))
        .collect();
    let views: Vec<&[Point3]> = fingers.iter().map(Vec::as_slice).collect();
    let markers = markers_of(hand, &views);
    camera
        .render(&finger_items(hand, &views, &markers), 1)
        .expect("renders")
}

fn bench_markers(c: &mut Criterion) {
    let camera = RgbdCamera::default();
    for preset in [HandPreset::TwoFinger, HandPreset::ThreeFinger] {
        let hand = HandModel::preset(preset, &FingerParams::default()).expect("preset");
        let img = frame(&hand, &camera);
        let mut detector = MarkerDetector::new(
            camera.intrinsics,
            camera.hand_from_camera,
            &hand,
            DetectorConfig::default(),
        )
        .expect("detector");
        let first = detector.detect(&img.color, &img.depth_m).expect("detects");
        assert_eq!(first.diagnostics.missing, 0, "every marker found");
        c.bench_function(&format!("markers/640x480 {preset} tracked"), |b| {
            b.iter(|| black_box(detector.detect(black_box(&img.color), &img.depth_m)))
        });
        c.bench_function(&format!("markers/640x480 {preset} first frame"), |b| {
            b.iter(|| {
                detector.reset();
                black_box(detector.detect(black_box(&img.color), &img.depth_m))
            })
        });
    }
}

criterion_group!(benches, bench_markers);
criterion_main!(benches);
