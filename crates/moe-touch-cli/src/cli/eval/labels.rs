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
use moe_lab::labels::{LabelStudyOptions, run_label_study};

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
        return super::print_json(&report, true);
    }
    crate::cli::print_text(&report.table());
    Ok(())
}
