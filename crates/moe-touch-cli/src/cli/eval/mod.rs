//! `moe-touch eval <target>`: evaluation benchmarks as thin commands over library code.
//!
//! `surface`: the occluded-surface reconstruction benchmark of `moe_lab::surface_eval` (paper
//! §6.1, Table 3) on the procedural head and the 2:20:1 arm: UCD from each reconstruction to the
//! ground truth for GP + prior, GP + sphere, the non-probabilistic baseline and the prior itself,
//! plus runtimes. Each scene family is evaluated on several truth/prior/contact seed triples
//! (`--pairs`, default 8 at full size): the first scene's table, then every method's mean ± sd
//! over the family and how often it was the best. `--size small` with one pair is the
//! golden-checked configuration (coarser meshes and grid, fewer contacts).

pub(crate) mod contact;
pub(crate) mod grasp;
pub(crate) mod labels;
pub(crate) mod markers;
pub(crate) mod observability;
pub(crate) mod patting;
pub(crate) mod physics;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use moe_gpis::bench_scene::{FamilyReport, SceneReport};
use moe_lab::surface_eval::{
    SurfaceBenchSize, SurfaceEvalOptions, evaluate_surfaces, surface_meshes,
};

/// Arguments of `moe-touch eval`.
#[derive(Debug, Args)]
pub(crate) struct EvalArgs {
    #[command(subcommand)]
    pub(crate) target: EvalTarget,
}

/// What to evaluate.
#[derive(Debug, Subcommand)]
pub(crate) enum EvalTarget {
    /// Occluded-surface reconstruction (GPIS) on procedural head and arm scenes.
    Surface(SurfaceEvalArgs),
    /// Contact estimation on held-out trajectories and the plate scenes (paper Tables 1–2).
    Contact(crate::cli::eval::contact::ContactEvalArgs),
    /// Contact-label rules on simulated trajectories against their obstacle-free twins.
    Labels(crate::cli::eval::labels::LabelsEvalArgs),
    /// Marker perception on the paper's scenes rendered by the simulated wrist camera.
    Markers(crate::cli::eval::markers::MarkersEvalArgs),
    /// Patting a head and an arm through the pipeline: estimated contacts and the surfaces
    /// reconstructed from them (paper Tables 2–3).
    Patting(crate::cli::eval::patting::PattingEvalArgs),
    /// Grasping on the inclined plates: press, fit the plane, reorient, press again (paper
    /// Table 4).
    Grasp(crate::cli::eval::grasp::GraspEvalArgs),
    /// Contact from physics as tactile sensors are specified (detection, location and force by
    /// the true force), beside the paper's metrics, from exact, noisy or perceived markers.
    Physics(crate::cli::eval::physics::PhysicsEvalArgs),
    /// The Cramér–Rao bound of a press's place and force for each marker layout of the study
    /// (camera row, two rows, sides, tip ring), per region, and the bound map figure.
    Observability(crate::cli::eval::observability::ObservabilityEvalArgs),
}

/// Benchmark size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Size {
    /// The golden-checked configuration (each evaluation's `--size` says what it holds).
    Small,
    /// The reported benchmark.
    Full,
}

/// Arguments of `moe-touch eval surface`.
#[derive(Debug, Args)]
pub(crate) struct SurfaceEvalArgs {
    /// Benchmark size: small = level-4 meshes, 20 contacts per patch, 32³ grid (the
    /// golden-checked configuration); full = level-5 meshes, 50 (head) / 35 (arm) contacts per
    /// patch, 64³ grid.
    #[arg(long, value_enum, default_value = "full")]
    pub(crate) size: Size,
    /// Scenes per family (different truth, prior and contact seeds); default 8 at full size,
    /// 1 at small size.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub(crate) pairs: Option<u64>,
    /// Standard deviation of the contact noise, mm (default 1; the paper's estimated contacts
    /// were 3–6 mm from the true surface).
    #[arg(long, value_name = "MM", value_parser = parse_noise_mm)]
    pub(crate) noise_mm: Option<f64>,
    /// Also write the first scene of each family to `DIR/<scene>/`: the truth, the contacts and
    /// every method's surface (PLY with the posterior `variance` and `std` for the GP methods),
    /// to look at.
    #[arg(long, value_name = "DIR")]
    pub(crate) out: Option<std::path::PathBuf>,
    /// Print one JSON object on stdout instead of a table.
    #[arg(long)]
    pub(crate) json: bool,
}

pub(crate) fn run(args: &EvalArgs) -> Result<()> {
    match &args.target {
        EvalTarget::Surface(a) => run_surface(a),
        EvalTarget::Contact(a) => crate::cli::eval::contact::run(a),
        EvalTarget::Labels(a) => crate::cli::eval::labels::run(a),
        EvalTarget::Markers(a) => crate::cli::eval::markers::run(a),
        EvalTarget::Patting(a) => crate::cli::eval::patting::run(a),
        EvalTarget::Grasp(a) => crate::cli::eval::grasp::run(a),
        EvalTarget::Physics(a) => crate::cli::eval::physics::run(a),
        EvalTarget::Observability(a) => crate::cli::eval::observability::run(a),
    }
}

fn parse_noise_mm(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && (0.0..=50.0).contains(&v) => Ok(v),
        _ => Err(format!(
            "expected a noise level in mm between 0 and 50, got '{s}'"
        )),
    }
}

/// The benchmark size of `--size`.
fn bench_size(size: Size) -> SurfaceBenchSize {
    match size {
        Size::Small => SurfaceBenchSize::Small,
        Size::Full => SurfaceBenchSize::Full,
    }
}

/// Writes each family's first scene and every method's surface under `dir`; returns the files.
fn write_surfaces(size: Size, noise_m: Option<f64>, dir: &Path) -> Result<Vec<PathBuf>> {
    let meshes = surface_meshes(bench_size(size), noise_m)?;
    let mut written = Vec::with_capacity(meshes.len());
    for (name, ply) in &meshes {
        let path = dir.join(name);
        if let Some(sub) = path.parent() {
            std::fs::create_dir_all(sub).with_context(|| format!("creating {}", sub.display()))?;
        }
        moe_io::write_ply(&path, ply)?;
        written.push(path);
    }
    Ok(written)
}

fn print_scene(r: &SceneReport) {
    println!(
        "scene {:?}: {} contacts, {} grid nodes (UCD = reconstruction -> truth, the paper's metric; back = truth -> reconstruction)",
        r.scene, r.contacts, r.grid_nodes
    );
    println!(
        "  {:<10} {:>9} {:>9} {:>9} {:>10} {:>10} {:>9}",
        "method", "UCD mm", "back mm", "BCD mm", "time ms", "var ms", "vertices"
    );
    for m in &r.methods {
        if let Some(e) = &m.error {
            println!("  {:<10} failed: {e}", m.method);
            continue;
        }
        println!(
            "  {:<10} {:>9.3} {:>9.3} {:>9.3} {:>10.1} {:>10.1} {:>9}",
            m.method,
            m.ucd_mm,
            m.ucd_truth_to_recon_mm,
            m.bcd_mm,
            1e3 * m.secs,
            1e3 * m.variance_secs,
            m.vertices
        );
    }
}

fn print_family(f: &FamilyReport) {
    println!(
        "family {:?}: {} scenes (seeds +0, +10, ...), mean ± sd",
        f.scene,
        f.scenes.len()
    );
    println!(
        "  {:<10} {:>15} {:>15} {:>9} {:>8}",
        "method", "UCD mm", "BCD mm", "best UCD", "failed"
    );
    for m in &f.summary {
        println!(
            "  {:<10} {:>7.2} ± {:<5.2} {:>7.2} ± {:<5.2} {:>9} {:>8}",
            m.method,
            m.ucd_mm.mean,
            m.ucd_mm.sd,
            m.bcd_mm.mean,
            m.bcd_mm.sd,
            m.best_ucd,
            m.failures
        );
    }
}

fn run_surface(args: &SurfaceEvalArgs) -> Result<()> {
    let noise_m = args.noise_mm.map(|mm| 1e-3 * mm);
    let report = evaluate_surfaces(&SurfaceEvalOptions {
        size: bench_size(args.size),
        pairs: args.pairs.map(|p| p as usize),
        noise_m,
    })?;
    if let Some(dir) = &args.out {
        let files = write_surfaces(args.size, noise_m, dir)?;
        eprintln!(
            "eval surface: wrote {} files under {}",
            files.len(),
            dir.display()
        );
    }
    if args.json {
        println!("{}", serde_json::to_string(&sorted_json(&report)?)?);
        return Ok(());
    }
    for f in &report.families {
        print_scene(&f.scenes[0]);
        if f.scenes.len() > 1 {
            print_family(f);
        }
        println!();
    }
    Ok(())
}

/// `report` as JSON with every object's keys in order, as the commands have always printed them
/// (`serde_json::Value` keeps its maps sorted).
pub(crate) fn sorted_json(report: &impl serde::Serialize) -> Result<serde_json::Value> {
    Ok(serde_json::to_value(report)?)
}

/// The golden content of `eval surface --size small`: Chamfer figures rounded to µm (timings and
/// vertex counts are left out: they depend on the machine).
pub(crate) fn surface_fixture() -> Result<serde_json::Value> {
    sorted_json(&moe_lab::surface_eval::surface_fixture()?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_surfaces_read_back_closed_with_their_variance() {
        let dir = std::env::temp_dir().join(format!("xtask-eval-out-{}", std::process::id()));
        let files = write_surfaces(Size::Small, None, &dir).unwrap();
        for scene in ["head", "arm"] {
            for name in ["truth", "prior", "gp_prior", "nonprob"] {
                let path = dir.join(scene).join(format!("{name}.ply"));
                assert!(files.contains(&path), "{}", path.display());
                let ply = moe_io::read_ply(&path).unwrap();
                let has_variance = ply.scalar("variance").is_some();
                assert_eq!(has_variance, name == "gp_prior", "{}", path.display());
                ply.into_mesh().unwrap().require_closed().unwrap();
            }
            let contacts = moe_io::read_ply(&dir.join(scene).join("contacts.ply")).unwrap();
            assert!(contacts.faces.is_empty() && contacts.points.len() >= 120);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
