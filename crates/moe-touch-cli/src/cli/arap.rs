//! `moe-touch arap`: deform any mesh with SR-ARAP so that handle vertices reach their targets.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_arap::{ArapConfig, ArapEnergy};
use moe_lab::shape_job::{ArapConstraints, deform_mesh};

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

pub(crate) fn run(args: ArapArgs) -> Result<()> {
    let mesh = moe_io::read_mesh(&args.mesh)?;
    let handles = ArapConstraints::read(&args.constraints)?
        .targets(mesh.num_vertices())
        .with_context(|| format!("constraints {}", args.constraints.display()))?;
    let config = ArapConfig {
        energy: args.energy,
        alpha: args.alpha,
        iterations: args.iterations,
        parallel: true,
    };
    let deformation = deform_mesh(&mesh, &handles, &config)
        .with_context(|| format!("setting up ARAP on {}", args.mesh.display()))?;
    deformation.write(&args.out, args.energy_log.as_deref())?;
    let summary = deformation.summary(&args.mesh, &args.out);
    if args.json {
        return super::print_json(&summary);
    }
    super::outln!("{}", summary.line());
    Ok(())
}
