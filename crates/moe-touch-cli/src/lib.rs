//! The `moe-touch` command-line tool. Every subcommand lives in its own module under `cli/`;
//! this file only parses arguments, dispatches, and turns errors into one line on stderr and a
//! non-zero exit code.

use std::ffi::OsString;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The subcommands, one module each.
mod cli;
/// Golden fixtures: committed reference results of the numerical stages, recomputed and
/// compared.
pub mod golden;

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
    /// Generate a labelled training set with the tendon FEM simulator (sharded, resumable).
    GenData(cli::gen_data::GenDataArgs),
    /// Train the contact network on a generated data set (checkpoints every epoch, resumable).
    Train(cli::train::TrainArgs),
    /// Run an evaluation: contact (paper Tables 1–2), physics, markers, labels, patting, grasp,
    /// surface, observability.
    Eval(cli::eval::EvalArgs),
    /// Write a small data set of held-out frames (the golden regression's input).
    HeldoutShard(cli::eval::contact::HeldoutArgs),
}

/// Runs the tool on `args` (the first being the program name), as the `moe-touch` binary does:
/// errors become one line on stderr and a failing exit code.
pub fn main_with(args: impl IntoIterator<Item = impl Into<OsString> + Clone>) -> ExitCode {
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(err) => err.exit(),
    };
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
        Command::GenData(args) => cli::gen_data::run(&args),
        Command::Train(args) => cli::train::run(&args),
        Command::Eval(args) => cli::eval::run(&args),
        Command::HeldoutShard(args) => cli::eval::contact::write_heldout(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", moe_touch::error::one_line(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}

/// Parses `args` (the first being the program name) as the tool does, without running the
/// command: `Ok` for a command line the tool accepts, clap's error (its kind, the argument it
/// names) for one it refuses; `--help` and `--version` come back as errors of their kinds.
///
/// # Errors
/// The command line does not parse.
pub fn check_args(
    args: impl IntoIterator<Item = impl Into<OsString> + Clone>,
) -> Result<(), clap::Error> {
    Cli::try_parse_from(args).map(drop)
}
