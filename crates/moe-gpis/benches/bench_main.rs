//! Criterion benches of `moe-gpis`: the head benchmark's GP-with-prior reconstruction (fit +
//! 64³ narrow-band query + marching tetrahedra), its parts, the per-vertex variance, and the
//! optional screened Poisson mesher on the head's GP mesh (`head_poisson`).
//!
//! Run: `cargo bench -p moe-gpis --bench bench_main`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use moe_gpis::bench_scene::{BenchSceneConfig, build_scene};
use moe_gpis::parts::{extract_surface, poisson_surface};
use moe_gpis::{
    MeshSdfMean, MeshingOptions, Observations, PoissonOptions, ReconstructOptions, bounds_of,
    condition, reconstruct,
};

fn head_inputs() -> (moe_gpis::bench_scene::BenchScene, MeshSdfMean, Observations) {
    let scene = build_scene(&BenchSceneConfig::head()).expect("head scene");
    let prior = MeshSdfMean::new(&scene.prior).expect("watertight prior");
    let mut obs = Observations::from_contacts(&scene.contacts).expect("finite contacts");
    obs.add_mean_normal_offsets(&prior, 0.005).expect("offsets");
    (scene, prior, obs)
}

fn bench_head(c: &mut Criterion) {
    let (scene, prior, obs) = head_inputs();
    let bounds = bounds_of(&scene.contacts, Some(&scene.prior)).expect("bounds");
    let no_variance = ReconstructOptions {
        vertex_variance: false,
        ..ReconstructOptions::default()
    };
    let mut group = c.benchmark_group("head_gp_prior");
    group.sample_size(20);
    group.bench_function("fit_query64_mesh", |b| {
        b.iter(|| {
            let (rec, _) =
                reconstruct(&prior, black_box(&obs), &bounds, &no_variance).expect("rec");
            black_box(rec.mesh.num_faces())
        })
    });
    group.bench_function("fit_and_condition", |b| {
        b.iter(|| {
            let (gpis, _) = condition(&prior, black_box(&obs), &no_variance.gpis).expect("cond");
            black_box(gpis.gp.jitter())
        })
    });
    let (rec, gpis) = reconstruct(&prior, &obs, &bounds, &no_variance).expect("rec");
    group.bench_function("query64_narrow_band", |b| {
        b.iter(|| black_box(gpis.grid_values_for_meshing(black_box(&rec.grid)).len()))
    });
    let values = gpis.grid_values_for_meshing(&rec.grid);
    group.bench_function("marching_tetrahedra64", |b| {
        b.iter(|| {
            let mesh = extract_surface(&rec.grid, black_box(&values), &MeshingOptions::default())
                .expect("mesh");
            black_box(mesh.num_faces())
        })
    });
    group.bench_function("vertex_variance", |b| {
        b.iter(|| black_box(gpis.variances(black_box(rec.mesh.vertices())).len()))
    });
    group.finish();
}

/// The Poisson step alone (solve, calibration, band evaluation, meshing) with the default
/// options, from the head's marching-tetrahedra mesh and grid values.
fn bench_head_poisson(c: &mut Criterion) {
    let (scene, prior, obs) = head_inputs();
    let bounds = bounds_of(&scene.contacts, Some(&scene.prior)).expect("bounds");
    let no_variance = ReconstructOptions {
        vertex_variance: false,
        ..ReconstructOptions::default()
    };
    let (rec, gpis) = reconstruct(&prior, &obs, &bounds, &no_variance).expect("rec");
    let values = gpis.grid_values_for_meshing(&rec.grid);
    let mut group = c.benchmark_group("head_poisson");
    group.sample_size(10);
    group.bench_function("poisson_head", |b| {
        b.iter(|| {
            let mesh = poisson_surface(
                black_box(&rec.mesh),
                &rec.grid,
                &values,
                &PoissonOptions::default(),
                &MeshingOptions::default(),
            )
            .expect("poisson");
            black_box(mesh.num_faces())
        })
    });
    group.finish();
}

criterion_group!(benches, bench_head, bench_head_poisson);
criterion_main!(benches);
