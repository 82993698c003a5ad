//! `moe-touch shape`: estimate the deformed finger meshes of a hand from one frame of keypoints.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_arap::{ArapEnergy, MultiShapeEstimator, ShapeConfig};
use moe_lab::keypoints_file::KeypointsFile;
use moe_lab::shape_job::estimate_hand_shape;

/// Arguments of `moe-touch shape`.
#[derive(Debug, Args)]
pub(crate) struct ShapeArgs {
    /// The hand: a preset (two-finger, three-finger, five-finger) or a hand config file (TOML or
    /// JSON, as for `moe-touch hand --config`).
    #[arg(long, value_name = "PRESET|CONFIG")]
    hand: String,
    /// Keypoints in the hand frame (metres): {"fingers": [[[x, y, z] or null, ...], ...]}, one
    /// list per finger with one entry per marker, null for an occluded marker; an optional
    /// "time_ns" is ignored, so a line of `moe-touch markers --out` is such a file.
    #[arg(long, value_name = "KP.json")]
    keypoints: PathBuf,
    /// Local/global iterations from the rest shape.
    #[arg(long, default_value_t = ShapeConfig::default().iterations)]
    iterations: usize,
    /// Smoothing weight α; 0 gives plain ARAP.
    #[arg(long, default_value_t = ShapeConfig::default().alpha)]
    alpha: f64,
    /// Energy: smoothed, spokes or spokes-and-rims.
    #[arg(long, default_value = "smoothed")]
    energy: ArapEnergy,
    /// Output directory: finger_<i>.obj (deformed, hand frame, metres) and shape.json.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Print the report as one JSON object.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: ShapeArgs) -> Result<()> {
    let hand = super::load_hand(&args.hand)?;
    let keypoints = KeypointsFile::read(&args.keypoints)?.into_keypoints();
    let config = ShapeConfig {
        iterations: args.iterations,
        alpha: args.alpha,
        energy: args.energy,
        ..ShapeConfig::default()
    };
    let mut estimator = MultiShapeEstimator::new(hand, config)?;
    let output = estimate_hand_shape(&mut estimator, &keypoints, &args.hand, &args.keypoints)
        .with_context(|| format!("keypoints {}", args.keypoints.display()))?;
    output.files.write(&args.out)?;
    if args.json {
        return super::print_json(&output.record);
    }
    for warning in output.record.warnings() {
        eprintln!("{warning}");
    }
    super::outln!("{}", output.record.summary());
    Ok(())
}
