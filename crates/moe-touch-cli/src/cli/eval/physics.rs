//! `moe-touch eval physics`: contact from physics on held-out trajectories, as tactile
//! sensors are specified (detection, location and force error by the finger's true force),
//! beside the paper's per-vertex metrics for the physics estimator, the DGCNN on its shapes and
//! the paper's chain (SR-ARAP + DGCNN) on the same markers — a thin command over
//! `moe_lab::physics_study`, whose report makes the tables.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::Real;
use moe_lab::physics_study::{PhysicsFrames, PhysicsStudyOptions, physics_study};
use moe_tendon_sim::randomize::RandomSceneParams;

/// Arguments of `moe-touch eval physics`.
#[derive(Debug, Args)]
pub(crate) struct PhysicsEvalArgs {
    /// Data set directory (its frames, exact or with `--marker-noise`). Without it,
    /// `--trajectories` are simulated afresh from `--seed` (`--perceived` needs that: the
    /// frames are rendered and their markers detected).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Which frames of the data set: all (the physics estimator is not trained) or the test
    /// trajectories.
    #[arg(long, value_enum, default_value = "all")]
    frames: crate::cli::eval::contact::FrameSet,
    /// Evaluate at most this many trajectories (the first ones).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    max_trajectories: Option<u64>,
    /// Without `--data`: trajectories to simulate (ids 0..N of `--seed`).
    #[arg(long, default_value_t = 20)]
    trajectories: u64,
    /// Without `--data`: the seed of the simulated trajectories (a data set made with this seed
    /// has the same frames); with `--marker-noise`, the noise's.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Without `--data`: randomisation parameters (TOML or JSON, as `gen-data --params`).
    #[arg(long)]
    params: Option<PathBuf>,
    /// Another marker layout on the same fingers (`camera-row`, `two-rows`, `sides`,
    /// `tip-ring`): with `--data`, its markers are read off each frame's true surface.
    #[arg(long, value_name = "PRESET")]
    marker_layout: Option<moe_geom::MarkerLayoutPreset>,
    /// Gaussian noise on every marker coordinate, metres.
    #[arg(long, value_name = "M")]
    marker_noise: Option<Real>,
    /// Markers detected by the perception stage in the rendered frames (needs simulation).
    #[arg(long, conflicts_with_all = ["data", "marker_noise"])]
    perceived: bool,
    /// With `--perceived`: render with a harsher depth (twice the white noise, a 0.2 mm error
    /// shared by neighbouring pixels, whole millimetres, as a ROS 2 `16UC1` topic).
    #[arg(long, requires = "perceived")]
    harsher_camera_noise: bool,
    /// With `--perceived`: render with this wrist camera (TOML or JSON `RgbdCamera`:
    /// `intrinsics`, `hand_from_camera`, `noise`; e.g. fixtures/cameras/d405-wrist.toml)
    /// instead of the scenes' own; `--harsher-camera-noise` then applies to its noise.
    #[arg(long, value_name = "CAMERA.toml", requires = "perceived")]
    camera: Option<PathBuf>,
    /// With `--perceived`: the marker detector's parameters (TOML or JSON `DetectorConfig`);
    /// default: the documented ones.
    #[arg(long, value_name = "FILE", requires = "perceived")]
    detector_config: Option<PathBuf>,
    /// The hand's material (TOML, as `moe-touch calibrate` writes it); default: nominal.
    #[arg(long)]
    material: Option<PathBuf>,
    /// Calibrate first: simulate this contact-free scene (e.g. fixtures/scenes/calibration.toml)
    /// with the evaluated hand's material and mesh (the data set's, or `--params`'), fit the
    /// material to its markers from `--material` (or the nominal one), and evaluate with the
    /// fitted material.
    #[arg(long, value_name = "SCENE.toml")]
    calibrate: Option<PathBuf>,
    /// The estimator's settings (TOML or JSON `PhysicsConfig`); default: the documented ones.
    #[arg(long)]
    config: Option<PathBuf>,
    /// A contact model for the comparison rows (the DGCNN on the physics shapes and on SR-ARAP
    /// shapes from the same markers).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Also Table 2: trials per plate scene (trial 0 as committed), the physics estimator and
    /// (with `--model`) the DGCNN on its shapes; UCD predicted → true per region. 0 skips it.
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u64).range(0..=100))]
    plates: u64,
    /// SR-ARAP's settings for the comparison rows (TOML or JSON `ShapeConfig`); with
    /// `--perceived` and `--model`, a row of the DGCNN on SR-ARAP registered to the markers and
    /// the depth image uses its `[depth]` part. Default: the paper's settings.
    #[arg(long, value_name = "FILE")]
    shape_config: Option<PathBuf>,
    /// Every frame on its own (the estimator reset before each frame): Table 1 without memory
    /// across frames.
    #[arg(long)]
    no_memory: bool,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: &PhysicsEvalArgs) -> Result<()> {
    if args.shape_config.is_some() && args.model.is_none() {
        anyhow::bail!("--shape-config sets SR-ARAP of the comparison rows: it needs --model");
    }
    let frames = match &args.data {
        Some(dir) => PhysicsFrames::Dataset {
            dir: dir.clone(),
            frames: args.frames.into(),
        },
        None => PhysicsFrames::Simulated {
            trajectories: args.trajectories,
            params: Box::new(match &args.params {
                Some(p) => moe_io::read_config(p)?,
                None => RandomSceneParams::default(),
            }),
            perceived: args.perceived,
            camera: crate::cli::eval_camera(args.camera.as_deref(), args.harsher_camera_noise)?,
            detector: Box::new(crate::cli::load_detector_config(
                args.detector_config.as_deref(),
                "--detector-config",
            )?),
        },
    };
    let options = PhysicsStudyOptions {
        frames,
        max_trajectories: args.max_trajectories,
        seed: args.seed,
        marker_layout: args.marker_layout,
        marker_noise_m: args.marker_noise,
        material: crate::cli::load_material(args.material.as_deref())?.0,
        calibration_scene: match &args.calibrate {
            Some(p) => Some(
                moe_io::read_config(p)
                    .with_context(|| format!("calibration scene {}", p.display()))?,
            ),
            None => None,
        },
        config: crate::cli::load_physics_config(args.config.as_deref())?.0,
        model: args.model.clone(),
        shape: crate::cli::load_shape_config(args.shape_config.as_deref())?,
        plates: args.plates,
        no_memory: args.no_memory,
    };
    let study = physics_study(&options, &mut |t, n| {
        eprintln!("eval physics: simulated trajectory {t} of {n}");
    })?;
    if let Some(line) = study.calibration_summary() {
        eprintln!("eval physics: {line}");
    }
    if args.json {
        super::print_json(&study.report, false)
    } else {
        crate::cli::print_text(&study.report.tables());
        Ok(())
    }
}
