//! Benchmarks of the simulator: one step of the default two-finger hand with a plate in contact
//! (`sim_step`), and voxelising the default finger.

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use moe_geom::{FingerModel, FingerParams};
use moe_tendon_sim::mechanics::voxelize;
use moe_tendon_sim::testing::golden_short_scene;
use moe_tendon_sim::{Scene, VoxelParams};

fn bench_sim_step(c: &mut Criterion) {
    // The regression scene (default two-finger hand and resolution, finger 0 pulling a tendon, a
    // plate pressing finger 1), stepped to its end, where the plate is in contact.
    let mut scene = Scene::new(golden_short_scene()).expect("valid scene");
    let mut state = scene.initial_state();
    for _ in 0..scene.num_steps() {
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
