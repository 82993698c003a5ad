//! Benches of the geometry core: Chamfer distances at the size the issue asks for (20,000 ×
//! 20,000 points) and the parametric finger generation.

use criterion::{Criterion, criterion_group, criterion_main};
use moe_geom::{FingerModel, FingerParams, Point3, bcd};

/// SplitMix64: a tiny seeded generator, so the point sets are the same on every run.
fn uniform_points(n: usize, seed: u64) -> Vec<Point3> {
    let mut s = seed;
    let mut next = || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z ^ (z >> 31)) as f64 / u64::MAX as f64
    };
    (0..n)
        .map(|_| Point3::new(next(), next(), next()) * 0.1)
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
