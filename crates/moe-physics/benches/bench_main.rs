//! Benchmarks of the physics estimator on the default two-finger hand: one frame with a press on
//! finger 0 (0.2 N on its back, mid-height, both fingers bent by their tendons), estimated from
//! rest (a lone frame: static free shapes and a full search) and tracked (the press held in a
//! stream: the free fingers simulated from the previous frame, the search started from the
//! previous loads), and a frame without contact in a stream.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use moe_geom::{FingerParams, HandKeypoints, HandModel, HandPreset, Point3, Real, WorldFromHand};
use moe_geom::{HandEstimator as _, Observation};
use moe_physics::testing::{PointLoad, static_markers};
use moe_physics::{HandMaterial, PhysicsConfig, PhysicsEstimator};

/// Static markers of `hand` (held fingers-up) under `pulls`, with `load` (newtons, along the
/// inward normal) at the vertex of finger 0 nearest `at` (finger frame), by the data
/// generator's model.
fn markers(hand: &HandModel, pulls: &[Vec<Real>], at: Point3, load: Real) -> HandKeypoints {
    let mesh = hand.fingers()[0].model.mesh();
    let v = (0..mesh.num_vertices())
        .min_by(|&a, &b| {
            (mesh.vertices()[a] - at)
                .norm()
                .total_cmp(&(mesh.vertices()[b] - at).norm())
        })
        .unwrap();
    let loads = [PointLoad {
        finger: 0,
        vertex: v as u32,
        force: -mesh.vertex_normals()[v] * load,
    }];
    static_markers(hand, pulls, &WorldFromHand::identity(), &loads).unwrap()
}

fn physics(c: &mut Criterion) {
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let pulls = vec![vec![0.003, -0.003, 0.0, 0.0], vec![0.0, 0.0, 0.002, -0.002]];
    let pressed = markers(&hand, &pulls, Point3::new(-0.0095, 0.0, 0.045), 0.2);
    let free = markers(&hand, &pulls, Point3::new(-0.0095, 0.0, 0.045), 0.0);
    let pose = WorldFromHand::identity();
    let mut est =
        PhysicsEstimator::new(&hand, &HandMaterial::default(), &PhysicsConfig::default()).unwrap();
    let mut group = c.benchmark_group("physics_contact");
    group.sample_size(20);
    group.bench_function("two-finger frame from rest", |b| {
        b.iter(|| {
            est.reset();
            let e = est
                .estimate(
                    &Observation::from_keypoints(&pressed)
                        .with_tendon_pulls(&pulls)
                        .with_world_from_hand(pose),
                )
                .unwrap();
            black_box(e.details.loads.len())
        })
    });
    // A held press in a stream: every iteration is the next frame, 50 ms later.
    let mut t = 0.0;
    est.reset();
    for _ in 0..3 {
        t += 0.05;
        est.estimate(
            &Observation::from_keypoints(&pressed)
                .with_tendon_pulls(&pulls)
                .with_world_from_hand(pose)
                .with_time(t),
        )
        .unwrap();
    }
    group.bench_function("two-finger frame tracked", |b| {
        b.iter(|| {
            t += 0.05;
            let e = est
                .estimate(
                    &Observation::from_keypoints(&pressed)
                        .with_tendon_pulls(&pulls)
                        .with_world_from_hand(pose)
                        .with_time(t),
                )
                .unwrap();
            black_box(e.details.loads.len())
        })
    });
    est.reset();
    group.bench_function("two-finger frame without contact, tracked", |b| {
        b.iter(|| {
            t += 0.05;
            let e = est
                .estimate(
                    &Observation::from_keypoints(&free)
                        .with_tendon_pulls(&pulls)
                        .with_world_from_hand(pose)
                        .with_time(t),
                )
                .unwrap();
            black_box(e.details.loads.len())
        })
    });
    group.finish();
}

criterion_group!(benches, physics);
criterion_main!(benches);
