//! Benches of the geometry core: Chamfer distances at the size the issue asks for (20,000 ×
//! 20,000 points) and the parametric finger generation.

use criterion::{Criterion, criterion_group, criterion_main};
use moe_geom::{FingerModel, FingerParams, Point3, SeededRng, bcd};

/// Uniform random points in a 10 cm cube, the same on every run.
fn uniform_points(n: usize, seed: u64) -> Vec<Point3> {
    let mut rng = SeededRng::new(seed);
    (0..n)
        .map(|_| Point3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 0.1)
        .collect()
}

fn chamfer(c: &mut Criterion) {
    let a = uniform_points(20_000, 1);
    let b = uniform_points(20_000, 2);
    c.bench_function("chamfer_bcd_20k_x_20k", |bench| {
        bench.iter(|| bcd(&a, &b).unwrap())
    });
}

fn finger(c: &mut Criterion) {
    let params = FingerParams::default();
    c.bench_function("finger_mesh_1024", |bench| {
        bench.iter(|| FingerModel::from_params(&params).unwrap())
    });
}

criterion_group!(benches, chamfer, finger);
criterion_main!(benches);
