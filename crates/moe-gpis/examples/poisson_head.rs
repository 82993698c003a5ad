//! Times the screened Poisson mesher on the head benchmark's GP mesh and compares the UCD of the
//! Poisson and marching-tetrahedra meshes to the hidden surface.
//!
//! `cargo run --release -p moe-gpis --example poisson_head -- [depth] [cg_iterations] [refine] [screening]`

use moe_gpis::bench_scene::{BenchScene, BenchSceneConfig, build_scene, ucd_to_surface_mm};
use moe_gpis::{
    GpisError, MeshSdfMean, Mesher, Observations, PoissonOptions, ReconstructOptions, bounds_of,
    reconstruct,
};

fn arg<T: std::str::FromStr>(i: usize, default: T) -> T {
    std::env::args()
        .nth(i)
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn run(scene: &BenchScene, mesher: Mesher) -> Result<(), GpisError> {
    let mean = MeshSdfMean::new(&scene.prior)?;
    let truth = MeshSdfMean::new(&scene.truth)?;
    let mut obs = Observations::from_contacts(&scene.contacts)?;
    obs.add_mean_normal_offsets(&mean, 0.005)?;
    let bounds = bounds_of(&scene.contacts, Some(&scene.prior)).expect("the scene has contacts");
    let config = ReconstructOptions {
        mesher,
        vertex_variance: false,
        ..ReconstructOptions::default()
    };
    let (rec, _) = reconstruct(&mean, &obs, &bounds, &config)?;
    rec.mesh.require_closed()?;
    let ucd = ucd_to_surface_mm(rec.mesh.vertices(), &truth)?;
    println!(
        "{mesher:?}: {} vertices, UCD to truth {ucd:.3} mm, marching {:.3} s, poisson {:.3} s",
        rec.mesh.num_vertices(),
        rec.timings.mesh_secs,
        rec.timings.poisson_secs
    );
    Ok(())
}

fn main() -> Result<(), GpisError> {
    let scene = build_scene(&BenchSceneConfig::head())?;
    let defaults = PoissonOptions::default();
    let depth = arg(1, defaults.depth);
    let options = PoissonOptions {
        depth,
        density_depth: defaults.density_depth.min(depth),
        cg_iterations: arg(2, defaults.cg_iterations),
        refine: arg(3, defaults.refine),
        screening: arg(4, defaults.screening),
    };
    run(&scene, Mesher::MarchingTetrahedra)?;
    run(&scene, Mesher::Poisson(options))
}
