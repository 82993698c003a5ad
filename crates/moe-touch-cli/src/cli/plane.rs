//! `moe-touch plane`: fit a plane to 3-D points (contact points of a pressed surface) by RANSAC
//! with a least-squares refit on the inliers.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::{Point3, RansacConfig, fit_plane_ransac};
use serde_json::json;

#[derive(Debug, Args)]
pub(crate) struct PlaneArgs {
    /// Points, CSV with `x,y,z` columns (a fourth column is ignored), metres; optional header.
    #[arg(long, value_name = "P.csv")]
    points: PathBuf,
    /// Inlier distance to the plane, metres.
    #[arg(long, value_name = "M", default_value_t = RansacConfig::default().distance_threshold_m)]
    threshold: f64,
    /// Most samples of three points (the fit stops early once it is 99.9999 % sure).
    #[arg(long, value_name = "N", default_value_t = RansacConfig::default().iterations)]
    iterations: usize,
    /// Seed of the sampling.
    #[arg(long, value_name = "S", default_value_t = 0)]
    seed: u64,
    /// Print the result as one JSON object.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: PlaneArgs) -> Result<()> {
    let rows = moe_io::read_points_csv(&args.points)?;
    let points: Vec<Point3> = rows.iter().map(|r| Point3::new(r[0], r[1], r[2])).collect();
    let config = RansacConfig {
        distance_threshold_m: args.threshold,
        iterations: args.iterations,
        seed: args.seed,
        ..RansacConfig::default()
    };
    let fit = fit_plane_ransac(&points, &config)
        .with_context(|| format!("fitting a plane to {}", args.points.display()))?;
    if args.json {
        return super::print_json(&json!({
            "points": points.len(),
            "normal": [fit.normal.x, fit.normal.y, fit.normal.z],
            "offset_m": fit.offset,
            "inliers": fit.inliers,
            "num_inliers": fit.inliers.len(),
            "rms_m": fit.rms_m,
            "iterations": fit.iterations,
            "threshold_m": args.threshold,
            "seed": args.seed,
        }));
    }
    super::outln!(
        "plane: n = ({:.6}, {:.6}, {:.6}), d = {:.6} m (n·x + d = 0); {} of {} points within {} m, \
         RMS {:.3} mm; {} samples",
        fit.normal.x,
        fit.normal.y,
        fit.normal.z,
        fit.offset,
        fit.inliers.len(),
        points.len(),
        args.threshold,
        1e3 * fit.rms_m,
        fit.iterations
    );
    Ok(())
}
