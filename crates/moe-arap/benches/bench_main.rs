//! Benchmarks of the SR-ARAP shape estimator on the paper's workload: the default two-finger hand
//! (2 × 1024 vertices), 7 keypoints per finger plus the fixed base.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use moe_arap::{MultiShapeEstimator, ShapeOptions};
use moe_geom::{FingerParams, HandKeypoints, HandModel, HandPreset, Point3, Vector3};

/// Keypoints of a gentle bend toward each finger's +x side: marker `m` moves by a displacement
/// growing with its height (deterministic, no randomness needed).
fn bent_keypoints(hand: &HandModel, amount: f64) -> HandKeypoints {
    let fingers = hand
        .fingers()
        .iter()
        .map(|f| {
            f.model
                .marker_positions()
                .iter()
                .map(|p| {
                    let s = p.z / 0.08;
                    let moved = Point3::from(
                        p.coords + Vector3::new(amount * s * s, 0.0, -0.3 * amount * s * s * s),
                    );
                    Some(f.hand_from_finger.transform_point(&moved))
                })
                .collect()
        })
        .collect();
    HandKeypoints { fingers }
}

fn arap(c: &mut Criterion) {
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).expect("preset");
    assert_eq!(hand.num_vertices(), 2048);
    let frame = bent_keypoints(&hand, 0.015);

    let mut from_rest =
        MultiShapeEstimator::new(hand.clone(), ShapeOptions::default()).expect("estimator");
    from_rest.estimate(&frame).expect("first frame");
    c.bench_function("arap/two-finger/50-iterations-from-rest", |b| {
        b.iter(|| black_box(from_rest.estimate(black_box(&frame)).expect("solve")))
    });

    let tracking = ShapeOptions {
        iterations: 10,
        warm_start: true,
        ..ShapeOptions::default()
    };
    let mut warm = MultiShapeEstimator::new(hand.clone(), tracking).expect("estimator");
    let frames: Vec<HandKeypoints> = (0..32)
        .map(|k| bent_keypoints(&hand, 0.015 + 0.001 * (k as f64 * 0.4).sin()))
        .collect();
    warm.estimate(&frames[0]).expect("first frame");
    let mut k = 0;
    c.bench_function("arap/two-finger/10-iterations-warm-start", |b| {
        b.iter(|| {
            k = (k + 1) % frames.len();
            black_box(warm.estimate(black_box(&frames[k])).expect("solve"))
        })
    });
}

criterion_group!(benches, arap);
criterion_main!(benches);
