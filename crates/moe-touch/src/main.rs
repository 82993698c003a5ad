//! The `moe-touch` command-line tool. Every subcommand lives in its own module under `cli/`;
//! this file only parses arguments, dispatches, and turns errors into one line on stderr and a
//! non-zero exit code.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cli;

/// Shape and contact estimation for soft tendon-driven hands, from deformation alone.
#[derive(Debug, Parser)]
#[command(
    name = "moe-touch",
    version,
    about = "Shape and contact estimation for soft tendon-driven hands, from deformation alone",
    long_about = None,
    propagate_version = true
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The whole pipeline on the committed example episode with the shipped model: a short
    /// table, a result MCAP for Foxglove, meshes coloured by contact and a picture.
    Demo(cli::demo::DemoArgs),
    /// Generate a hand model (rest meshes, marker and base vertex ids) from a preset or a config.
    Hand(cli::hand::HandArgs),
    /// Deform any mesh with SR-ARAP so that handle vertices reach their targets.
    Arap(cli::arap::ArapArgs),
    /// Detect and track the red markers in every frame of an episode (wrist RGB-D → keypoints
    /// per finger); report detection against the ground truth when the episode has it.
    Markers(cli::markers::MarkersArgs),
    /// Run the whole pipeline (markers → SR-ARAP → contact, or markers → physics) over an
    /// episode: a result MCAP for Foxglove and a report against the ground truth.
    Run(cli::run::RunArgs),
    /// Estimate a hand's deformed finger meshes from one frame of marker keypoints (SR-ARAP).
    Shape(cli::shape::ShapeArgs),
    /// Estimate per-vertex contact with the DGCNN (on a point cloud, or on a hand shape as
    /// `moe-touch shape` writes it), or with physics from one frame of markers and tendon pulls
    /// (loads with force and uncertainty, the dented shape): meshes coloured by contact
    /// probability, contact points.
    Contact(cli::contact::ContactArgs),
    /// Fit the hand's material (Young's modulus, damping) for the physics estimator to the
    /// contact-free frames of an episode or a data set.
    Calibrate(cli::calibrate::CalibrateArgs),
    /// Run a scripted tendon-FEM scene; write surface meshes per saved frame and a summary.
    Sim(cli::sim::SimArgs),
    /// Reconstruct an occluded surface from contact points (GPIS with a prior, sphere or constant
    /// mean, or the non-probabilistic baseline); query the posterior at points.
    Surface(cli::surface::SurfaceArgs),
    /// Fit a plane to 3-D points (RANSAC with a least-squares refit): unit normal, offset,
    /// inliers and RMS distance.
    Plane(cli::plane::PlaneArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(args) => cli::demo::run(args),
        Command::Hand(args) => cli::hand::run(args),
        Command::Arap(args) => cli::arap::run(args),
        Command::Markers(args) => cli::markers::run(args),
        Command::Run(args) => cli::run::run(args),
        Command::Shape(args) => cli::shape::run(args),
        Command::Contact(args) => cli::contact::run(args),
        Command::Calibrate(args) => cli::calibrate::run(args),
        Command::Sim(args) => cli::sim::run(args),
        Command::Surface(args) => cli::surface::run(args),
        Command::Plane(args) => cli::plane::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", moe_touch::error::one_line(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}
