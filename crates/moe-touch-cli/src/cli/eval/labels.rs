//! `moe-touch eval labels`: what each contact-label rule labels, and whether the finger's
//! deformation can show it.
//!
//! Every trajectory of a randomised data set is simulated twice: as generated, and as its
//! *free twin* — the same wrist motion and tendon schedule with the obstacle removed. The
//! difference between the two surfaces at the same instant (hand frame) is the deformation the
//! contact causes, the only signal a shape-based estimator has. For each rule the study counts,
//! over all frames: labelled vertices, frames with a label, connected patches of labelled
//! vertices (mesh edges) and how many are single vertices, labels on vertices held by the fixed
//! base, and labelled frames whose markers moved less than 0.1 mm from the twin's (the
//! "no visible deformation" frames), plus the same with every surface vertex instead of the
//! markers (`moe_lab::labels::run_label_study`).

use anyhow::Result;
use clap::Args;
use moe_geom::Real;
use moe_lab::labels::{
    LabelStudyOptions, LabelStudyReport, VISIBLE_DEFORMATION_M, run_label_study,
};

/// Arguments of `moe-touch eval labels`.
#[derive(Debug, Args)]
pub(crate) struct LabelsEvalArgs {
    /// Trajectories to simulate (each twice).
    #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub(crate) trajectories: u64,
    /// Seed of the randomised scenes (the data set seed).
    #[arg(long, default_value_t = 11)]
    pub(crate) seed: u64,
    /// Print one JSON object on stdout instead of a table.
    #[arg(long)]
    pub(crate) json: bool,
}

pub(crate) fn run(args: &LabelsEvalArgs) -> Result<()> {
    let options = LabelStudyOptions {
        trajectories: args.trajectories,
        seed: args.seed,
    };
    let report = run_label_study(&options, |done| {
        eprint!("\r{done}/{} trajectories", args.trajectories);
    })?;
    eprintln!();
    if args.json {
        // Keys sorted, as the report has always been printed.
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::to_value(&report)?)?
        );
        return Ok(());
    }
    print_table(&report);
    Ok(())
}

fn print_table(r: &LabelStudyReport) {
    println!(
        "label rules on {} trajectories of seed {} ({} diverged and skipped)",
        r.trajectories, r.seed, r.failed
    );
    println!(
        "{:<26} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>9}",
        "rule",
        "ratio",
        "frames",
        "v/frame",
        "patches",
        "single",
        "on base",
        "mk still",
        "sf still",
        "mk def mm"
    );
    for s in &r.rules {
        let lf = s.labelled_frames.max(1) as Real;
        println!(
            "{:<26} {:>8.3}% {:>8.1}% {:>8.1} {:>8} {:>8} {:>8} {:>8.1}% {:>8.1}% {:>9.3}",
            s.rule,
            100.0 * s.labelled_vertices as Real / s.vertices.max(1) as Real,
            100.0 * s.labelled_frames as Real / s.frames.max(1) as Real,
            s.labelled_vertices as Real / lf,
            s.patches,
            s.single_vertex_patches,
            s.labels_on_base,
            100.0 * s.frames_markers_still as Real / lf,
            100.0 * s.frames_surface_still as Real / lf,
            1e3 * s.sum_marker_deformation_m / lf,
        );
    }
    println!(
        "ratio: labelled vertices; frames: frames with a label; single: one-vertex patches; \
         still: labelled frames whose markers (mk) or whole surface (sf) moved < {} mm from \
         the obstacle-free twin; mk def: mean largest marker deformation of labelled frames",
        VISIBLE_DEFORMATION_M * 1e3
    );
}
