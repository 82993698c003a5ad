//! `moe-touch shape`: estimate the deformed finger meshes of a hand from one frame of keypoints.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_arap::{ArapEnergy, MultiShapeEstimator, ShapeConfig};
use moe_geom::HandKeypoints;
use serde::{Deserialize, Serialize};

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

/// A keypoints file: the keypoints, optionally with the time of their frame.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct KeypointsInput {
    #[serde(default, rename = "time_ns")]
    _time_ns: Option<u64>,
    fingers: Vec<Vec<Option<moe_geom::Point3>>>,
}

/// One finger of `shape.json`.
#[derive(Debug, Serialize)]
struct FingerShapeRecord {
    mesh: String,
    frame: &'static str,
    iterations: usize,
    markers_used: Vec<usize>,
    missing_markers: Vec<usize>,
    handle_vertices: Vec<Option<u32>>,
    all_markers_missing: bool,
    final_energy: Option<f64>,
    energy: Vec<f64>,
    max_displacement_m: f64,
}

/// `shape.json`, also the `--json` report.
#[derive(Debug, Serialize)]
struct ShapeRecord {
    hand: String,
    keypoints: String,
    energy: ArapEnergy,
    alpha: f64,
    iterations: usize,
    fingers: Vec<FingerShapeRecord>,
}

pub(crate) fn run(args: ShapeArgs) -> Result<()> {
    let hand = super::load_hand(&args.hand)?;
    let input: KeypointsInput = moe_io::read_json(&args.keypoints)?;
    let keypoints = HandKeypoints {
        fingers: input.fingers,
    };
    let options = ShapeConfig {
        iterations: args.iterations,
        alpha: args.alpha,
        energy: args.energy,
        warm_start: false,
    };
    let mut estimator = MultiShapeEstimator::new(hand.clone(), options.clone())?;
    let estimate = estimator
        .estimate(&keypoints)
        .with_context(|| format!("keypoints {}", args.keypoints.display()))?;
    // Build every output in memory first, so a failure leaves nothing half-written.
    let mut meshes = Vec::with_capacity(hand.num_fingers());
    let mut fingers = Vec::with_capacity(hand.num_fingers());
    for (i, (vertices, report)) in estimate
        .shape
        .fingers
        .iter()
        .zip(&estimate.reports)
        .enumerate()
    {
        let rest = hand.rest_vertices_in_hand(i);
        let max_displacement_m = vertices
            .iter()
            .zip(&rest)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        meshes.push(
            hand.fingers()[i]
                .model
                .mesh()
                .with_vertices(vertices.clone())?,
        );
        fingers.push(FingerShapeRecord {
            mesh: format!("finger_{i}.obj"),
            frame: "hand",
            iterations: report.iterations,
            missing_markers: (0..report.handle_vertices.len())
                .filter(|m| !report.markers_used.contains(m))
                .collect(),
            markers_used: report.markers_used.clone(),
            handle_vertices: report.handle_vertices.clone(),
            all_markers_missing: report.all_markers_missing,
            final_energy: report.energy.last().copied(),
            energy: report.energy.clone(),
            max_displacement_m,
        });
    }
    let record = ShapeRecord {
        hand: args.hand.clone(),
        keypoints: args.keypoints.display().to_string(),
        energy: args.energy,
        alpha: args.alpha,
        iterations: args.iterations,
        fingers,
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating output directory {}", args.out.display()))?;
    for (mesh, f) in meshes.iter().zip(&record.fingers) {
        moe_io::write_mesh(&args.out.join(&f.mesh), mesh)?;
    }
    moe_io::write_json(&args.out.join("shape.json"), &record)?;
    if args.json {
        super::print_json(&record)?;
    } else {
        super::outln!("hand '{}': {} fingers", record.hand, record.fingers.len());
        for (i, f) in record.fingers.iter().enumerate() {
            if f.all_markers_missing {
                eprintln!("finger {i}: every marker missing, left at the rest shape");
            }
            super::outln!(
                "  finger {i}: {} of {} markers, {} iterations, max displacement {:.2} mm, wrote {}",
                f.markers_used.len(),
                f.handle_vertices.len(),
                f.iterations,
                f.max_displacement_m * 1e3,
                f.mesh
            );
        }
    }
    Ok(())
}
