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
pub(crate) mod soak;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use moe_io::PlyData;
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
    Contact(contact::ContactEvalArgs),
    /// Contact-label rules on simulated trajectories against their obstacle-free twins.
    Labels(labels::LabelsEvalArgs),
    /// Marker perception on the paper's scenes rendered by the simulated wrist camera.
    Markers(markers::MarkersEvalArgs),
    /// Patting a head and an arm through the pipeline: estimated contacts and the surfaces
    /// reconstructed from them (paper Tables 2–3).
    Patting(patting::PattingEvalArgs),
    /// Grasping on the inclined plates: press, fit the plane, reorient, press again (paper
    /// Table 4).
    Grasp(grasp::GraspEvalArgs),
    /// Contact from physics as tactile sensors are specified (detection, location and force by
    /// the true force), beside the paper's metrics, from exact, noisy or perceived markers.
    Physics(physics::PhysicsEvalArgs),
    /// The Cramér–Rao bound of a press's place and force for each marker layout of the study
    /// (camera row, two rows, sides, tip ring), per region, and the bound map figure.
    Observability(observability::ObservabilityEvalArgs),
    /// A long run: an episode looped for thousands of frames with gaps, resets and refused
    /// frames mixed in; frame times, failures and resident memory window by window.
    Soak(soak::SoakEvalArgs),
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
        EvalTarget::Contact(a) => contact::run(a),
        EvalTarget::Labels(a) => labels::run(a),
        EvalTarget::Markers(a) => markers::run(a),
        EvalTarget::Patting(a) => patting::run(a),
        EvalTarget::Grasp(a) => grasp::run(a),
        EvalTarget::Physics(a) => physics::run(a),
        EvalTarget::Observability(a) => observability::run(a),
        EvalTarget::Soak(a) => soak::run(a),
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

/// Writes every `(path, ply)` under `dir`, creating the directories; returns the files.
fn write_plys(dir: &Path, files: &[(PathBuf, PlyData)]) -> Result<Vec<PathBuf>> {
    let mut written = Vec::with_capacity(files.len());
    for (name, ply) in files {
        let path = dir.join(name);
        if let Some(sub) = path.parent() {
            std::fs::create_dir_all(sub).with_context(|| format!("creating {}", sub.display()))?;
        }
        moe_io::write_ply(&path, ply)?;
        written.push(path);
    }
    Ok(written)
}

fn run_surface(args: &SurfaceEvalArgs) -> Result<()> {
    let noise_m = args.noise_mm.map(|mm| 1e-3 * mm);
    let report = evaluate_surfaces(&SurfaceEvalOptions {
        size: bench_size(args.size),
        pairs: args.pairs.map(|p| p as usize),
        noise_m,
    })?;
    if let Some(dir) = &args.out {
        let files = write_plys(dir, &surface_meshes(bench_size(args.size), noise_m)?)?;
        eprintln!(
            "eval surface: wrote {} files under {}",
            files.len(),
            dir.display()
        );
    }
    if args.json {
        return print_json(&report, false);
    }
    crate::cli::print_text(&report.table());
    Ok(())
}

/// Prints `report` as one JSON object with its keys sorted, as the commands have always printed
/// it (`serde_json::Value` keeps its maps sorted): on one line, or indented.
fn print_json(report: &impl serde::Serialize, pretty: bool) -> Result<()> {
    let value = serde_json::to_value(report)?;
    if pretty {
        crate::cli::outln!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        crate::cli::outln!("{value}");
    }
    Ok(())
}
