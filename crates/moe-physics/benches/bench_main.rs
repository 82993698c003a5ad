//! Benchmarks of the physics estimator on the default two-finger hand: one frame with a press on
//! finger 0 (0.2 N on its back, mid-height, both fingers bent by their tendons), estimated from
//! rest (a lone frame: static free shapes and a full search) and tracked (the press held in a
//! stream: the free fingers simulated from the previous frame, the search started from the
//! previous loads), and a frame without contact in a stream.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use moe_geom::{
    FingerParams, HandKeypoints, HandModel, HandPreset, Point3, Real, Vector3, WorldFromHand,
};
use moe_physics::{HandMaterial, PhysicsConfig, PhysicsEstimator, PhysicsObservation};
use moe_tendon_sim::mechanics::{FemInputs, FingerBody, Integrator, PointTerm, StepContext, Terms};
use moe_tendon_sim::{BodyState, Material, TendonCommand, TendonParams, VoxelParams};

/// Static markers of `hand` (held fingers-up) under `pulls`, with `load` (newtons, finger frame)
/// at the vertex of finger 0 nearest `at` (finger frame), by the data generator's model.
fn markers(hand: &HandModel, pulls: &[Vec<Real>], at: Point3, load: Real) -> HandKeypoints {
    let fingers = hand
        .fingers()
        .iter()
        .enumerate()
        .map(|(f, hf)| {
            let body =
                FingerBody::new(&hf.model, &Material::default(), &VoxelParams::default()).unwrap();
            let rest = body.fem().mesh().nodes().to_vec();
            let mesh = hf.model.mesh();
            let v = (0..mesh.num_vertices())
                .min_by(|&a, &b| {
                    (mesh.vertices()[a] - at)
                        .norm()
                        .total_cmp(&(mesh.vertices()[b] - at).norm())
                })
                .unwrap();
            let force = -mesh.vertex_normals()[v] * if f == 0 { load } else { 0.0 };
            let commands: Vec<TendonCommand> = pulls[f]
                .iter()
                .map(|&pull_m| TendonCommand::Displacement { pull_m })
                .collect();
            let gravity = hf.hand_from_finger.iso().inverse() * Vector3::new(0.0, 0.0, -9.81);
            let mut state = BodyState {
                x: rest.clone(),
                v: vec![Vector3::zeros(); rest.len()],
            };
            let params = TendonParams::default();
            let mut ws = body.workspace(0);
            body.fem()
                .step(
                    &mut ws,
                    StepContext::default(),
                    Integrator::Static {
                        tolerance_m: 1e-10,
                        max_iterations: 200,
                    },
                    &mut state,
                    FemInputs {
                        targets: &rest,
                        gravity,
                        terms: &mut |x: &[Point3], _: &[Vector3], t: &mut Terms| {
                            for (tendon, &c) in body.tendons().iter().zip(&commands) {
                                tendon.add_terms(x, c, &params, t);
                            }
                            t.points.push(PointTerm {
                                point: body.surface().points()[v],
                                force,
                                stiffness: Default::default(),
                                damping: Default::default(),
                                target_velocity: Vector3::zeros(),
                            });
                        },
                    },
                )
                .unwrap();
            hf.model
                .marker_vertices()
                .iter()
                .map(|&m| {
                    let p = body.surface().points()[m as usize].position(&state.x);
                    Some(hf.hand_from_finger.iso() * p)
                })
                .collect()
        })
        .collect();
    HandKeypoints { fingers }
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
                .estimate(&PhysicsObservation {
                    keypoints: &pressed,
                    tendon_pull_m: &pulls,
                    world_from_hand: &pose,
                    time_secs: None,
                })
                .unwrap();
            black_box(e.loads.len())
        })
    });
    // A held press in a stream: every iteration is the next frame, 50 ms later.
    let mut t = 0.0;
    est.reset();
    for _ in 0..3 {
        t += 0.05;
        est.estimate(&PhysicsObservation {
            keypoints: &pressed,
            tendon_pull_m: &pulls,
            world_from_hand: &pose,
            time_secs: Some(t),
        })
        .unwrap();
    }
    group.bench_function("two-finger frame tracked", |b| {
        b.iter(|| {
            t += 0.05;
            let e = est
                .estimate(&PhysicsObservation {
                    keypoints: &pressed,
                    tendon_pull_m: &pulls,
                    world_from_hand: &pose,
                    time_secs: Some(t),
                })
                .unwrap();
            black_box(e.loads.len())
        })
    });
    est.reset();
    group.bench_function("two-finger frame without contact, tracked", |b| {
        b.iter(|| {
            t += 0.05;
            let e = est
                .estimate(&PhysicsObservation {
                    keypoints: &free,
                    tendon_pull_m: &pulls,
                    world_from_hand: &pose,
                    time_secs: Some(t),
                })
                .unwrap();
            black_box(e.loads.len())
        })
    });
    group.finish();
}

criterion_group!(benches, physics);
criterion_main!(benches);
