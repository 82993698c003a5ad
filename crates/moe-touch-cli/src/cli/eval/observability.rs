//! `moe-touch eval observability`: how well a marker layout lets the physics estimator locate
//! a press, whatever the estimator — the Cramér–Rao bound of the press's place along and around
//! the finger and of its force (`moe_physics::PhysicsEstimator::location_bounds`), at every
//! movable surface vertex of finger 0 of the two-finger hand (default finger, default material
//! and settings, zero pulls, gravity along the hand's −z), for each layout of the study: the
//! camera row of 7 (the paper's), two rows of 7 at ±35°, the camera row and rows of 7 on the
//! sides (±90°), and the camera row with a ring of 6 at the tip. Per layout and region (tip
//! z > 80 % of the length with the cap, middle 40–70 %, base 12–35 %): median and 90th
//! percentile, for one frame and for `--frames` frames of a held press (independent marker
//! noise per frame: the bound over √N). With `--out DIR`: `DIR/bound_map.svg`, each layout's
//! surface unrolled (angle around the axis, camera side at 0°, against height) with every
//! vertex coloured by its along-axis bound on a shared log scale and the markers as black
//! rings, and `DIR/observability.json`, the summary (`moe_lab::observability`, which also draws
//! the figure and makes the tables).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::Real;
use moe_lab::observability::{ObservabilityOptions, bound_map_svg, run_observability_study};
use moe_physics::BoundOptions;

/// Arguments of `moe-touch eval observability`.
#[derive(Debug, Args)]
pub(crate) struct ObservabilityEvalArgs {
    /// Write `DIR/bound_map.svg` (the bound on every layout's unrolled surface) and
    /// `DIR/observability.json`.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Frames of the held press of the second summary (the first is one frame).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(2..=10_000))]
    frames: u64,
    /// Force of the press, newtons.
    #[arg(long, value_name = "N", default_value_t = BoundOptions::default().force_n)]
    force: Real,
    /// Noise of a marker coordinate, metres (default: the perception stage's, 0.16 mm).
    #[arg(long, value_name = "M", default_value_t = BoundOptions::default().marker_sigma_m)]
    sigma: Real,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: &ObservabilityEvalArgs) -> Result<()> {
    let options = ObservabilityOptions {
        force_n: args.force,
        marker_sigma_m: args.sigma,
        held_frames: usize::try_from(args.frames)?,
        ..ObservabilityOptions::default()
    };
    let report = run_observability_study(&options, |observed| {
        eprintln!("eval observability: {observed} done");
    })?;
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        moe_io::write_atomic(
            &dir.join("bound_map.svg"),
            bound_map_svg(&report.layouts).as_bytes(),
        )?;
        moe_io::write_json(&dir.join("observability.json"), &report)?;
        eprintln!(
            "eval observability: wrote bound_map.svg and observability.json to {}",
            dir.display()
        );
    }
    if args.json {
        // In the report's field order, as it has always been printed.
        crate::cli::outln!("{}", serde_json::to_string(&report)?);
    } else {
        crate::cli::print_text(&report.table());
    }
    Ok(())
}
