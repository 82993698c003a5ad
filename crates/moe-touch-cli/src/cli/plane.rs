//! `moe-touch plane`: fit a plane to 3-D points (contact points of a pressed surface) by RANSAC
//! with a least-squares refit on the inliers.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::RansacConfig;

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
    let points = moe_lab::surface_job::read_points(&args.points)?;
    let config = RansacConfig {
        distance_threshold_m: args.threshold,
        iterations: args.iterations,
        seed: args.seed,
        ..RansacConfig::default()
    };
    let report = moe_lab::plane_job::fit_plane(&points, &config)
        .with_context(|| format!("fitting a plane to {}", args.points.display()))?;
    if args.json {
        return super::print_json(&report);
    }
    super::outln!("{}", report.line());
    Ok(())
}
