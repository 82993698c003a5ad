//! Benchmarks of the simulator: voxelising the default finger.

use criterion::{Criterion, criterion_group, criterion_main};
use moe_geom::{FingerModel, FingerParams};
use moe_tendon_sim::{VoxelParams, voxelize};

fn bench_voxelize(c: &mut Criterion) {
    let finger = FingerModel::from_params(&FingerParams::default()).expect("default finger");
    let params = VoxelParams::default();
    c.bench_function("voxelize_finger", |b| {
        b.iter(|| voxelize(finger.mesh(), &params).expect("closed finger"));
    });
}

criterion_group!(benches, bench_voxelize);
criterion_main!(benches);
