//! `moe-touch hand`: write a hand model's rest meshes and vertex ids; with `--bound`, the
//! Cramér–Rao bound of a press's place on finger 0 for its marker layout.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::{FingerParams, HandModel, HandPreset, MarkerLayoutPreset, Real};
use moe_lab::hand_job;
use moe_physics::BoundOptions;

/// Arguments of `moe-touch hand`.
#[derive(Debug, Args)]
pub(crate) struct HandArgs {
    /// Built-in layout: two-finger (facing each other), three-finger (120°) or five-finger.
    #[arg(long, default_value = "two-finger", conflicts_with = "config")]
    preset: HandPreset,
    /// Hand config (TOML or JSON) describing a preset with custom finger parameters, or your own
    /// finger meshes with marker and base vertex ids.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Vertices per parametric finger (preset hands only).
    #[arg(long, default_value_t = FingerParams::default().vertex_budget, conflicts_with = "config")]
    vertex_budget: usize,
    /// Marker layout of every finger (preset hands only; a config sets `marker_layout`):
    /// camera-row (7 on the camera side), two-rows (7 at ±35°), sides (the camera row and 7 at
    /// ±90°) or tip-ring (the camera row and 6 around the finger at 90 % of its length).
    #[arg(long, default_value = "camera-row", conflicts_with = "config")]
    marker_layout: MarkerLayoutPreset,
    /// Also report the Cramér–Rao bound of a press's place along and around finger 0 and of its
    /// force, for its markers (physics model with the default material, zero pulls, gravity
    /// along the hand's −z), per region (tip, middle, base), and write the per-vertex map
    /// `bound_finger_0.ply`.
    #[arg(long)]
    bound: bool,
    /// Force of the press the bound assumes, newtons.
    #[arg(long, value_name = "N", default_value_t = BoundOptions::default().force_n, requires = "bound")]
    bound_force: Real,
    /// Independent frames of a held press (the bound shrinks as one over their square root).
    #[arg(long, value_name = "N", default_value_t = BoundOptions::default().frames as u64,
          value_parser = clap::value_parser!(u64).range(1..=1_000_000), requires = "bound")]
    bound_frames: u64,
    /// Noise of a marker coordinate, metres (default: the perception stage's, 0.16 mm).
    #[arg(long, value_name = "M", default_value_t = BoundOptions::default().marker_sigma_m, requires = "bound")]
    bound_sigma: Real,
    /// With --bound: what the bound observes: the markers, the depth image of the default wrist
    /// camera (each visible surface vertex along its normal, with the camera's depth noise), or
    /// both.
    #[arg(long, value_enum, default_value = "markers", requires = "bound")]
    bound_observe: BoundObserve,
    /// With --bound and depth: twice the depth noise (white and correlated) and depth quantised
    /// to whole millimetres (as a ROS 2 16UC1 topic gives it).
    #[arg(long, requires = "bound")]
    bound_harsher_depth: bool,
    /// With --bound and depth: another depth camera than the default wrist camera, TOML or
    /// JSON: a rendering camera (`RgbdCamera`, as `eval physics --camera` takes it, e.g.
    /// fixtures/cameras/d405-wrist.toml) or the bound's own `DepthBoundModel` (`intrinsics`,
    /// `hand_from_camera`, `noise` (`sigma_base_m`, `sigma_per_m2`, `correlated_sigma_m`,
    /// `quantum_m`), `min_range_m`, `max_range_m`, `grazing_deg`); fields not given keep the
    /// default camera's.
    #[arg(long, value_name = "CAMERA.toml", requires = "bound")]
    bound_camera: Option<PathBuf>,
    /// Output directory: finger_<i>.obj (rest mesh in the hand frame, metres) and hand.json.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
}

/// What `hand --bound` observes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum BoundObserve {
    /// The finger's markers.
    Markers,
    /// The depth image alone.
    Depth,
    /// The markers and the depth image.
    Both,
}

pub(crate) fn run(args: HandArgs) -> Result<()> {
    let (hand, source, layout) = match &args.config {
        Some(path) => {
            let (hand, layout) = hand_job::read_hand_config(path)?;
            (hand, path.display().to_string(), layout)
        }
        None => {
            let params = FingerParams {
                vertex_budget: args.vertex_budget,
                marker_layout: args.marker_layout.layout(),
                ..FingerParams::default()
            };
            let hand = HandModel::preset(args.preset, &params).with_context(|| {
                format!(
                    "building the {} preset with the {} marker layout",
                    args.preset, args.marker_layout
                )
            })?;
            let layout = args.marker_layout.to_string();
            (hand, args.preset.to_string(), layout)
        }
    };
    if args.bound_observe == BoundObserve::Markers {
        for (given, flag) in [
            (args.bound_harsher_depth, "--bound-harsher-depth"),
            (args.bound_camera.is_some(), "--bound-camera"),
        ] {
            if given {
                anyhow::bail!("{flag} is for --bound-observe depth or both");
            }
        }
    }
    let camera = match &args.bound_camera {
        Some(path) => bound_camera(path).context("--bound-camera")?,
        None => moe_physics::DepthBoundModel::default(),
    };
    let depth = (args.bound_observe != BoundObserve::Markers).then(|| {
        if args.bound_harsher_depth {
            camera.harsher()
        } else {
            camera
        }
    });
    let options = BoundOptions {
        force_n: args.bound_force,
        marker_sigma_m: args.bound_sigma,
        frames: args.bound_frames as usize,
        markers: args.bound_observe != BoundObserve::Depth,
        depth,
    };
    let bound = args
        .bound
        .then(|| hand_job::finger_bound(&hand, &options, layout))
        .transpose()
        .context("the Cramér–Rao bound of finger 0")?;
    let output = hand_job::hand_output(&hand, source, bound)?;
    output.files.write(&args.out)?;
    if args.json {
        return super::print_json(&output.record);
    }
    super::outln!("{}", output.record.summary(&args.out));
    Ok(())
}

/// The bound's depth camera from a file: the bound's own `DepthBoundModel` when the file reads
/// as one (its fields and nothing else), or else a rendering camera (`RgbdCamera`, as `eval
/// physics --camera` takes it), whose errors are then the ones reported.
fn bound_camera(path: &std::path::Path) -> Result<moe_physics::DepthBoundModel> {
    let context = || path.display().to_string();
    let model = match moe_io::read_config::<moe_physics::DepthBoundModel>(path) {
        Ok(model) => model,
        Err(_) => moe_lab::observability::depth_bound_model(&super::load_camera(path)?),
    };
    model.validate().with_context(context)?;
    Ok(model)
}
