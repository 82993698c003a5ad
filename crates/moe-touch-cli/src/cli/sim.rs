//! `moe-touch sim`: run a scripted tendon-FEM scene and write the hand's surface meshes per saved
//! frame (OBJ, or PLY with the contact label and obstacle distance as vertex scalars) and a JSON
//! summary.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use moe_lab::sim_output;
use moe_tendon_sim::{Scene, SceneConfig};

/// Mesh format of the saved frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum MeshFormat {
    /// Wavefront OBJ (geometry only).
    Obj,
    /// PLY with per-vertex scalars `contact` (0/1) and `distance_m`.
    Ply,
}

/// Frame in which the saved vertices are expressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum OutputFrame {
    /// The hand (palm) frame: the frame of the training data.
    Hand,
    /// The world frame (where the obstacles are).
    World,
}

/// Arguments of `moe-touch sim`.
#[derive(Debug, Args)]
pub(crate) struct SimArgs {
    /// Scene file (TOML or JSON): hand, material, solver, wrist trajectory, tendon schedules,
    /// obstacles. See fixtures/scenes/ for examples.
    #[arg(long, value_name = "FILE")]
    scene: PathBuf,
    /// Use this hand (a `moe-touch hand` config: a preset or your own finger meshes) instead of
    /// the scene's parametric hand.
    #[arg(long, value_name = "FILE")]
    hand: Option<PathBuf>,
    /// Output: a directory for frame_<k>_finger_<i>.<format> and summary.json, or a file
    /// ending in .mcap for an episode (wrist-camera colour and depth, calibration, transforms,
    /// tendons, ground-truth meshes coloured by contact, markers and obstacles; opens in
    /// Foxglove). Written only when the whole run succeeds.
    #[arg(long, value_name = "DIR|EPISODE.mcap")]
    out: PathBuf,
    /// Seed of the camera noise (episodes only).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Mesh format of the saved frames.
    #[arg(long, value_enum, default_value = "ply")]
    format: MeshFormat,
    /// Frame of the saved vertices.
    #[arg(long, value_enum, default_value = "hand")]
    frame: OutputFrame,
    /// Run only this many steps (default: the scene's duration).
    #[arg(long)]
    steps: Option<u64>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: SimArgs) -> Result<()> {
    let config: SceneConfig = moe_io::read_config(&args.scene)
        .with_context(|| format!("reading scene {}", args.scene.display()))?;
    let scene = match &args.hand {
        Some(path) => Scene::with_hand(config, moe_io::load_hand_config(path)?),
        None => Scene::new(config),
    }
    .with_context(|| format!("building scene {}", args.scene.display()))?;
    let simulating = || format!("simulating {}", args.scene.display());
    if args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
    {
        let summary =
            sim_output::write_episode(scene, &args.scene, args.seed, args.steps, &args.out)
                .with_context(simulating)?;
        if args.json {
            return super::print_json(&summary);
        }
        super::print_text(&summary.table());
        return Ok(());
    }
    let format = match args.format {
        MeshFormat::Obj => sim_output::MeshFormat::Obj,
        MeshFormat::Ply => sim_output::MeshFormat::Ply,
    };
    let frame = match args.frame {
        OutputFrame::Hand => sim_output::OutputFrame::Hand,
        OutputFrame::World => sim_output::OutputFrame::World,
    };
    let summary = sim_output::write_frames(
        scene,
        &args.scene.display().to_string(),
        (format, frame),
        args.steps,
        &args.out,
        &mut |step, steps, t| eprintln!("step {step}/{steps} (t = {t:.3} s)"),
    )
    .with_context(simulating)?;
    if args.json {
        return super::print_json(&summary);
    }
    super::print_text(&summary.table(&args.out));
    Ok(())
}
