//! `cargo xtask eval grasp`: grasping paper on an unknown incline (paper §6.2, Table 4). The
//! three-finger hand presses the inclined plates (0°, 30°, 45°) from a perturbed level start;
//! with MOE-Touch the pipeline's contacts give a RANSAC plane, the hand turns onto its normal
//! and presses again; without, it keeps its orientation. The simulator judges the final press
//! (`moe_touch::grasp`). Seeded trials per angle; the table beside the paper's, and the
//! estimated incline against the true one per trial.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use moe_geom::{FingerParams, HandModel, HandPreset, Real};
use moe_touch::grasp::{GraspContacts, GraspOptions, GraspTrial, run_grasp_trial};
use moe_touch::pipeline::load_contact_model;
use serde_json::{Value, json};

use crate::ci::workspace_root;
use crate::eval_contact::SHIPPED_MODEL;

/// The paper's inclines and its Table 4 (successes of 5 with and without MOE-Touch).
const INCLINES: [(Real, usize, usize); 3] = [(0.0, 5, 5), (30.0, 5, 1), (45.0, 4, 0)];

/// Arguments of `cargo xtask eval grasp`.
#[derive(Debug, Args)]
pub(crate) struct GraspEvalArgs {
    /// Seeded trials per incline.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=100))]
    trials: u64,
    /// Contact model (per-finger, so that it runs on the three-finger hand).
    #[arg(long, value_name = "M.safetensors", default_value = SHIPPED_MODEL)]
    model: PathBuf,
    /// Seed of the camera noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Fit the plane to the simulator's own contacts instead of the pipeline's (the upper bound
    /// a perfect contact estimator reaches).
    #[arg(long, conflicts_with = "true_labels")]
    true_contacts: bool,
    /// Fit the plane to the simulator's contact vertices placed on the pipeline's estimated
    /// shape (a perfect contact classifier on the shape the markers give: separates the shape
    /// estimate's error from the contact model's).
    #[arg(long)]
    true_labels: bool,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    json: bool,
}

/// Where the plane's points come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    /// The pipeline's contacts.
    Pipeline,
    /// The simulator's labels on the pipeline's shape.
    TrueLabels,
    /// The simulator's contact vertices.
    TrueContacts,
}

impl Source {
    fn name(self) -> &'static str {
        match self {
            Self::Pipeline => "pipeline",
            Self::TrueLabels => "true-labels",
            Self::TrueContacts => "true-contacts",
        }
    }
}

fn evaluate(trials: u64, model: &std::path::Path, seed: u64, source: Source) -> Result<Value> {
    let hand = HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default())?;
    let estimator = load_contact_model(&workspace_root().join(model), &hand)?;
    let threshold = estimator.threshold();
    let options = GraspOptions::default();
    let mut rows = Vec::new();
    for (incline, paper_with, paper_without) in INCLINES {
        let t = std::time::Instant::now();
        let results: Vec<GraspTrial> = (0..trials)
            .map(|k| {
                let contacts = match source {
                    Source::Pipeline => GraspContacts::Pipeline {
                        contact: &estimator,
                        threshold,
                    },
                    Source::TrueLabels => GraspContacts::SimulatorLabelsOnEstimatedShape {
                        contact: &estimator,
                    },
                    Source::TrueContacts => GraspContacts::Simulator,
                };
                run_grasp_trial(&hand, contacts, incline, k, seed, &options)
            })
            .collect::<Result<_, _>>()?;
        eprintln!(
            "eval grasp: {incline}°: {trials} trials in {:.1} s",
            t.elapsed().as_secs_f64()
        );
        let with = results.iter().filter(|r| r.success_with).count();
        let without = results.iter().filter(|r| r.success_without).count();
        let errors: Vec<Real> = results
            .iter()
            .filter_map(|r| r.estimated_incline_deg.map(|e| (e - incline).abs()))
            .collect();
        rows.push(json!({
            "incline_deg": incline,
            "trials": trials,
            "success_with": with,
            "success_without": without,
            "paper_with_of_5": paper_with,
            "paper_without_of_5": paper_without,
            "max_incline_error_deg": errors.iter().copied().fold(None, |m: Option<Real>, e| Some(m.map_or(e, |m| m.max(e)))),
            "fits_failed": results.iter().filter(|r| r.estimated_normal.is_none()).count(),
            "trials_detail": results,
        }));
    }
    Ok(
        json!({ "options": options, "threshold": threshold, "contacts": source.name(), "rows": rows }),
    )
}

fn print_table(v: &Value) {
    println!("plane from: {}", v["contacts"].as_str().unwrap_or("?"));
    println!(
        "incline   with MOE-Touch  (paper)   without  (paper)   incline error max   fits failed"
    );
    for r in v["rows"].as_array().into_iter().flatten() {
        println!(
            "{:>5}°    {:>3} / {:<3}      ({} / 5)    {:>3} / {:<3} ({} / 5)    {:>8}          {}",
            r["incline_deg"],
            r["success_with"],
            r["trials"],
            r["paper_with_of_5"],
            r["success_without"],
            r["trials"],
            r["paper_without_of_5"],
            r["max_incline_error_deg"]
                .as_f64()
                .map_or("—".to_owned(), |e| format!("{e:.2}°")),
            r["fits_failed"],
        );
    }
    println!(
        "\nper trial: true incline → estimated (contacts, inliers; first press fingers touching)"
    );
    for r in v["rows"].as_array().into_iter().flatten() {
        for t in r["trials_detail"].as_array().into_iter().flatten() {
            println!(
                "  {:>4}° trial {}: {:>7}  ({} contacts, {} inliers; first press {}) {}",
                t["incline_deg"],
                t["trial"],
                t["estimated_incline_deg"]
                    .as_f64()
                    .map_or("no fit".to_owned(), |e| format!("{e:.2}°")),
                t["estimated_contacts"],
                t["inliers"],
                t["first_press"]["contact_vertices"],
                if t["success_with"].as_bool() == Some(true) {
                    "success"
                } else {
                    "failed"
                }
            );
        }
    }
}

pub(crate) fn run(args: &GraspEvalArgs) -> Result<()> {
    let source = if args.true_contacts {
        Source::TrueContacts
    } else if args.true_labels {
        Source::TrueLabels
    } else {
        Source::Pipeline
    };
    let v = evaluate(args.trials, &args.model, args.seed, source)?;
    if args.json {
        println!("{}", serde_json::to_string(&v)?);
    } else {
        print_table(&v);
    }
    Ok(())
}

/// The golden content of one trial per incline, rounded to 1e-3.
pub(crate) fn grasp_fixture() -> Result<Value> {
    let mut v = evaluate(1, std::path::Path::new(SHIPPED_MODEL), 0, Source::Pipeline)?;
    crate::eval_patting::round3(&mut v);
    Ok(v)
}
