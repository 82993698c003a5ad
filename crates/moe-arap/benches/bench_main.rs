//! Benchmarks of the SR-ARAP shape estimator on the paper's workload: the default two-finger hand
//! (2 × 1024 vertices), 7 keypoints per finger plus the fixed base.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use moe_arap::{ArapConfig, ArapSolver, MultiShapeEstimator, ShapeConfig, Start};
use moe_geom::{FingerParams, HandKeypoints, HandModel, HandPreset, Point3, TriMesh, Vector3};

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
        MultiShapeEstimator::new(hand.clone(), ShapeConfig::default()).expect("estimator");
    from_rest.estimate(&frame).expect("first frame");
    c.bench_function("arap/two-finger/50-iterations-from-rest", |b| {
        b.iter(|| black_box(from_rest.estimate(black_box(&frame)).expect("solve")))
    });

    let tracking = ShapeConfig {
        iterations: 10,
        warm_start: true,
        ..ShapeConfig::default()
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

/// The hand as one mesh (the fingers' meshes in the hand frame, side by side) with its base and
/// marker vertices fixed at the bent keypoints: what `moe-touch arap` solves for an exported hand.
fn hand_as_one_mesh(
    hand: &HandModel,
    keypoints: &HandKeypoints,
) -> (TriMesh, Vec<u32>, Vec<Point3>) {
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    let mut fixed = Vec::new();
    let mut targets = Vec::new();
    for (i, (f, kp)) in hand.fingers().iter().zip(&keypoints.fingers).enumerate() {
        let offset = vertices.len() as u32;
        let rest = hand.rest_vertices_in_hand(i);
        faces.extend(f.model.mesh().faces().iter().map(|t| t.map(|v| v + offset)));
        for &b in f.model.base_vertices() {
            fixed.push(b + offset);
            targets.push(rest[b as usize]);
        }
        for (&m, p) in f.model.marker_vertices().iter().zip(kp) {
            fixed.push(m + offset);
            targets.push(p.expect("every marker seen"));
        }
        vertices.extend(rest);
    }
    (TriMesh::new(vertices, faces).expect("mesh"), fixed, targets)
}

fn arap_single_mesh(c: &mut Criterion) {
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).expect("preset");
    let (mesh, fixed, targets) = hand_as_one_mesh(&hand, &bent_keypoints(&hand, 0.015));
    let config = ArapConfig::default();
    let split = ArapSolver::new(&mesh, &config, &fixed, &[]).expect("solver");
    assert_eq!(split.num_parts(), 2);
    c.bench_function("arap/two-finger-one-mesh/50-iterations-by-part", |b| {
        b.iter(|| {
            black_box(
                split
                    .solve(black_box(&targets), &[], Start::Rest)
                    .expect("solve"),
            )
        })
    });
}

criterion_group!(benches, arap, arap_single_mesh);
criterion_main!(benches);
