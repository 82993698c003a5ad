//! `moe-touch arap`: deform any mesh with SR-ARAP so that handle vertices reach their targets.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use moe_arap::{ArapConfig, ArapEnergy, ArapSolver, HandleTargets, Start};
use moe_geom::Point3;
use serde::{Deserialize, Serialize};

/// Arguments of `moe-touch arap`.
#[derive(Debug, Args)]
pub(crate) struct ArapArgs {
    /// Rest mesh (OBJ, PLY or STL): a manifold triangle mesh.
    #[arg(long, value_name = "REST")]
    mesh: PathBuf,
    /// Constraints JSON: {"handles": [{"vertex": 12, "target": [x, y, z]}, ...]}, targets in the
    /// mesh's units. Every connected part of the mesh needs at least one handle.
    #[arg(long, value_name = "C.json")]
    constraints: PathBuf,
    /// Energy: smoothed (SR-ARAP, spokes cells), spokes (plain ARAP) or spokes-and-rims.
    #[arg(long, default_value = "smoothed")]
    energy: ArapEnergy,
    /// Smoothing weight α (multiplied by the rest surface area); 0 gives plain ARAP.
    #[arg(long, default_value_t = ArapConfig::default().alpha)]
    alpha: f64,
    /// Local/global iterations, starting from the rest mesh.
    #[arg(long, default_value_t = ArapConfig::default().iterations)]
    iterations: usize,
    /// Output mesh (OBJ or PLY): the rest mesh's faces with the deformed vertices.
    #[arg(long, value_name = "DEFORMED")]
    out: PathBuf,
    /// Also write the energy after every iteration as CSV (iteration, energy).
    #[arg(long, value_name = "E.csv")]
    energy_log: Option<PathBuf>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
}

/// The constraints file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Constraints {
    handles: Vec<HandleRecord>,
}

/// One handle of the constraints file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct HandleRecord {
    vertex: u32,
    target: [f64; 3],
}

/// The `--json` summary.
#[derive(Debug, Serialize)]
struct ArapSummary {
    mesh: String,
    out: String,
    num_vertices: usize,
    num_faces: usize,
    num_handles: usize,
    energy: ArapEnergy,
    alpha: f64,
    iterations: usize,
    /// Energy after the first and the last iteration (squared mesh units).
    first_energy: Option<f64>,
    final_energy: Option<f64>,
    /// Largest vertex displacement from the rest mesh (mesh units).
    max_displacement: f64,
    svd_fallbacks: usize,
}

pub(crate) fn run(args: ArapArgs) -> Result<()> {
    let mesh = moe_io::read_mesh(&args.mesh)?;
    let constraints: Constraints = moe_io::read_json(&args.constraints)?;
    let pairs: Vec<(u32, Point3)> = constraints
        .handles
        .iter()
        .map(|h| (h.vertex, Point3::from(h.target)))
        .collect();
    let handles = HandleTargets::from_pairs(&pairs, mesh.num_vertices())
        .with_context(|| format!("constraints {}", args.constraints.display()))?;
    let config = ArapConfig {
        energy: args.energy,
        alpha: args.alpha,
        iterations: args.iterations,
        parallel: true,
    };
    let solver = ArapSolver::new(&mesh, &config, &handles.vertices, &[])
        .with_context(|| format!("setting up ARAP on {}", args.mesh.display()))?;
    let solution = solver.solve(&handles.targets, &[], Start::Rest)?;
    let max_displacement = solution
        .vertices
        .iter()
        .zip(mesh.vertices())
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    let info = &solution.info;
    let deformed = mesh.with_vertices(solution.vertices.clone())?;
    moe_io::write_mesh(&args.out, &deformed)?;
    if let Some(path) = &args.energy_log {
        write_energy_log(path, &info.energy)?;
    }
    let summary = ArapSummary {
        mesh: args.mesh.display().to_string(),
        out: args.out.display().to_string(),
        num_vertices: mesh.num_vertices(),
        num_faces: mesh.num_faces(),
        num_handles: handles.vertices.len(),
        energy: args.energy,
        alpha: config.effective_alpha(),
        iterations: info.iterations,
        first_energy: info.energy.first().copied(),
        final_energy: info.energy.last().copied(),
        max_displacement,
        svd_fallbacks: info.svd_fallbacks,
    };
    if args.json {
        super::print_json(&summary)?;
    } else {
        super::outln!(
            "{}: {} vertices, {} handles, {} iterations of {} ARAP (α = {}); energy {} → {}; \
             max displacement {:.4e}; wrote {}",
            summary.mesh,
            summary.num_vertices,
            summary.num_handles,
            summary.iterations,
            summary.energy,
            summary.alpha,
            fmt_energy(summary.first_energy),
            fmt_energy(summary.final_energy),
            summary.max_displacement,
            summary.out
        );
    }
    Ok(())
}

fn fmt_energy(e: Option<f64>) -> String {
    e.map_or_else(|| "-".to_owned(), |e| format!("{e:.4e}"))
}

fn write_energy_log(path: &Path, energy: &[f64]) -> Result<()> {
    let mut csv = String::from("iteration,energy\n");
    for (t, e) in energy.iter().enumerate() {
        csv.push_str(&format!("{t},{e:e}\n"));
    }
    moe_io::write_atomic(path, csv.as_bytes())?;
    Ok(())
}
