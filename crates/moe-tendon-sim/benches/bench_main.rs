//! Benchmarks of the simulator: one step of the default two-finger hand with a plate in contact
//! (`sim_step`), and voxelising the default finger.

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use moe_geom::{FingerModel, FingerParams};
use moe_tendon_sim::{
    ActuationKeyframe, ActuationMode, ActuationSchedule, ObstacleConfig, ObstacleShape,
    PoseKeyframe, PoseTrajectory, Scene, SceneConfig, VoxelParams, voxelize,
};

/// Default two-finger hand at the default resolution; finger 0 pulls a tendon, a plate presses
/// finger 1's outer side (in contact from step ~5 on).
fn contact_scene() -> SceneConfig {
    let p = FingerParams::default();
    let x0 = -0.025 - p.radius_at(0.03) - 0.0015;
    SceneConfig {
        duration_secs: 1.0,
        actuation: vec![ActuationSchedule {
            mode: ActuationMode::Displacement,
            keyframes: vec![
                ActuationKeyframe {
                    time_secs: 0.0,
                    values: vec![0.0; 4],
                },
                ActuationKeyframe {
                    time_secs: 0.2,
                    values: vec![0.002, -0.002, 0.0, 0.0],
                },
            ],
        }],
        obstacles: vec![ObstacleConfig {
            shape: ObstacleShape::Cuboid {
                half_extents_m: [0.001, 0.03, 0.02],
            },
            trajectory: PoseTrajectory {
                keyframes: vec![
                    PoseKeyframe::at(0.0, [x0, 0.0, 0.05]),
                    PoseKeyframe::at(0.2, [x0 + 0.004, 0.0, 0.05]),
                ],
            },
        }],
        ..SceneConfig::default()
    }
}

fn bench_sim_step(c: &mut Criterion) {
    let mut scene = Scene::new(contact_scene()).expect("valid scene");
    let mut state = scene.initial_state();
    for _ in 0..20 {
        scene.step(&mut state).expect("stable scene");
    }
    let frame = scene.frame(&state);
    let in_contact = frame.fingers[1].labels.iter().filter(|&&l| l).count();
    assert!(in_contact > 0, "the benchmark state must be in contact");
    c.bench_function("sim_step", |b| {
        b.iter_batched(
            || state.clone(),
            |mut s| scene.step(&mut s).expect("stable step"),
            BatchSize::SmallInput,
        );
    });
}

fn bench_voxelize(c: &mut Criterion) {
    let finger = FingerModel::from_params(&FingerParams::default()).expect("default finger");
    let params = VoxelParams::default();
    c.bench_function("voxelize_finger", |b| {
        b.iter(|| voxelize(finger.mesh(), &params).expect("closed finger"));
    });
}

criterion_group!(benches, bench_sim_step, bench_voxelize);
criterion_main!(benches);
