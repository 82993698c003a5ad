//! `cargo xtask eval <target>`: evaluation benchmarks as thin commands over library code.
//!
//! `surface`: the occluded-surface reconstruction benchmark of `moe_gpis::bench_scene` (paper
//! §6.1, Table 3) on the procedural head and the 2:20:1 arm: UCD from each reconstruction to the
//! ground truth for GP + prior, GP + sphere, the non-probabilistic baseline and the prior itself,
//! plus runtimes. Each scene family is evaluated on several truth/prior/contact seed triples
//! (`--pairs`, default 8 at full size): the first scene's table, then every method's mean ± sd
//! over the family and how often it was the best. `--size small` with one pair is the
//! golden-checked configuration (coarser meshes and grid, fewer contacts).

use anyhow::Result;
use clap::{Args, Subcommand, ValueEnum};
use moe_gpis::bench_scene::{FamilyReport, evaluate_family};
use moe_gpis::{SceneConfig, SceneReport, SurfaceConfig};
use serde_json::{Value, json};

/// Arguments of `cargo xtask eval`.
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
}

/// Benchmark size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Size {
    /// Golden-checked: level-4 meshes, 20 contacts per patch, 32³ grid.
    Small,
    /// The reported benchmark: level-5 meshes, 50 (head) / 35 (arm) contacts per patch, 64³ grid.
    Full,
}

/// Arguments of `cargo xtask eval surface`.
#[derive(Debug, Args)]
pub(crate) struct SurfaceEvalArgs {
    /// Benchmark size.
    #[arg(long, value_enum, default_value = "full")]
    pub(crate) size: Size,
    /// Scenes per family (different truth, prior and contact seeds); default 8 at full size,
    /// 1 at small size.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub(crate) pairs: Option<u64>,
    /// Print one JSON object on stdout instead of a table.
    #[arg(long)]
    pub(crate) json: bool,
}

pub(crate) fn run(args: &EvalArgs) -> Result<()> {
    match &args.target {
        EvalTarget::Surface(a) => run_surface(a),
    }
}

/// Offset of the ±d points along the mean's normals at each contact (metres).
const NORMAL_OFFSET_M: f64 = 0.005;

fn surface_reports(size: Size, pairs: usize) -> Result<Vec<FamilyReport>> {
    let mut out = Vec::new();
    for base in [SceneConfig::head(), SceneConfig::arm()] {
        let (scene_cfg, surface) = match size {
            Size::Full => (base, SurfaceConfig::default()),
            Size::Small => (
                SceneConfig {
                    mesh_level: 4,
                    contacts_per_patch: 20,
                    ..base
                },
                SurfaceConfig {
                    max_grid_nodes: 32 * 32 * 32,
                    vertex_variance: false,
                    ..SurfaceConfig::default()
                },
            ),
        };
        out.push(evaluate_family(
            &scene_cfg,
            pairs,
            &surface,
            Some(NORMAL_OFFSET_M),
        )?);
    }
    Ok(out)
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
    let pairs = args.pairs.map_or(
        match args.size {
            Size::Full => 8,
            Size::Small => 1,
        },
        |p| p as usize,
    );
    let families = surface_reports(args.size, pairs)?;
    if args.json {
        println!(
            "{}",
            serde_json::to_string(
                &json!({ "size": format!("{:?}", args.size).to_lowercase(), "families": families })
            )?
        );
        return Ok(());
    }
    for f in &families {
        print_scene(&f.scenes[0]);
        if f.scenes.len() > 1 {
            print_family(f);
        }
        println!();
    }
    Ok(())
}

fn round3(v: f64) -> f64 {
    (v * 1e3).round() / 1e3
}

/// The golden content of `eval surface --size small`: Chamfer figures rounded to µm (timings and
/// vertex counts are left out: they depend on the machine).
pub(crate) fn surface_fixture() -> Result<Value> {
    let families = surface_reports(Size::Small, 1)?;
    let scenes: Vec<Value> = families
        .iter()
        .map(|f| {
            let r = &f.scenes[0];
            let methods: Vec<Value> = r
                .methods
                .iter()
                .map(|m| {
                    json!({
                        "method": m.method,
                        "ucd_mm": round3(m.ucd_mm),
                        "ucd_truth_to_recon_mm": round3(m.ucd_truth_to_recon_mm),
                        "bcd_mm": round3(m.bcd_mm),
                    })
                })
                .collect();
            json!({ "scene": r.scene, "contacts": r.contacts, "grid_nodes": r.grid_nodes, "methods": methods })
        })
        .collect();
    Ok(json!({ "scenes": scenes }))
}
