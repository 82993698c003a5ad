//! `moe-touch sim`: run a scripted tendon-FEM scene and write the hand's surface meshes per saved
//! frame (OBJ, or PLY with the contact label and obstacle distance as vertex scalars) and a JSON
//! summary.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use moe_tendon_sim::{Scene, SceneConfig, SimFrame, SimState, run_with};
use serde::Serialize;

/// Mesh format of the saved frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum MeshFormat {
    /// Wavefront OBJ (geometry only).
    Obj,
    /// PLY with per-vertex scalars `contact` (0/1) and `distance_m`.
    Ply,
}

/// Frame in which the saved vertices are expressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
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

/// One saved frame in the summary.
#[derive(Debug, Serialize)]
struct FrameRecord {
    step: u64,
    time_secs: f64,
    files: Vec<String>,
    contact_vertices: Vec<usize>,
    max_penetration_m: Vec<f64>,
}

/// Per-finger discretisation figures.
#[derive(Debug, Serialize)]
struct FingerRecord {
    surface_vertices: usize,
    tet_nodes: usize,
    tets: usize,
    fixed_nodes: usize,
    volume_ratio: f64,
    max_embedding_distance_m: f64,
}

/// `summary.json`, also the `--json` output.
#[derive(Debug, Serialize)]
struct SimSummary {
    scene: String,
    frame: OutputFrame,
    dt_secs: f64,
    steps: u64,
    simulated_secs: f64,
    wall_secs: f64,
    steps_per_sec: f64,
    fingers: Vec<FingerRecord>,
    final_kinetic_energy_j: Vec<f64>,
    final_tendon_tension_n: Vec<Vec<f64>>,
    state_digest: String,
    frames: Vec<FrameRecord>,
}

pub(crate) fn run(args: SimArgs) -> Result<()> {
    let config: SceneConfig = moe_io::read_config(&args.scene)
        .with_context(|| format!("reading scene {}", args.scene.display()))?;
    let scene = match &args.hand {
        Some(path) => Scene::with_hand(config, moe_io::load_hand_config(path)?),
        None => Scene::new(config),
    }
    .with_context(|| format!("building scene {}", args.scene.display()))?;
    if args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
    {
        return record_episode(scene, &args);
    }
    // Frames go to a staging directory and move into place only when the whole run succeeded,
    // so a diverging simulation leaves no partial output.
    let staging = args.out.join(".moe-sim-partial");
    std::fs::create_dir_all(&staging)
        .with_context(|| format!("creating output directory {}", staging.display()))?;
    let result = simulate(scene, &args, &staging);
    match result {
        Ok(summary) => {
            for frame in &summary.frames {
                for name in &frame.files {
                    std::fs::rename(staging.join(name), args.out.join(name))
                        .with_context(|| format!("moving {name} into {}", args.out.display()))?;
                }
            }
            std::fs::remove_dir(&staging)
                .with_context(|| format!("removing {}", staging.display()))?;
            moe_io::write_json(&args.out.join("summary.json"), &summary)?;
            report(&summary, &args)
        }
        Err(err) => {
            let _ = std::fs::remove_dir_all(&staging);
            if std::fs::read_dir(&args.out).is_ok_and(|mut d| d.next().is_none()) {
                let _ = std::fs::remove_dir(&args.out);
            }
            Err(err)
        }
    }
}

fn simulate(mut scene: Scene, args: &SimArgs, staging: &Path) -> Result<SimSummary> {
    let steps = args.steps.unwrap_or_else(|| scene.num_steps());
    let mut frames = Vec::new();
    let start = Instant::now();
    let outcome = run_with(&mut scene, steps, |scene, state| -> Result<()> {
        frames.push(save_frame(scene, state, args, staging)?);
        if state.step > 0 {
            eprintln!("step {}/{steps} (t = {:.3} s)", state.step, state.time_secs);
        }
        Ok(())
    })
    .with_context(|| format!("simulating {}", args.scene.display()))?;
    let (state, last) = (outcome.final_state, outcome.last_step);
    let wall_secs = start.elapsed().as_secs_f64();
    Ok(SimSummary {
        scene: args.scene.display().to_string(),
        frame: args.frame,
        dt_secs: scene.config().solver.dt_secs,
        steps,
        simulated_secs: state.time_secs,
        wall_secs,
        steps_per_sec: if wall_secs > 0.0 {
            steps as f64 / wall_secs
        } else {
            0.0
        },
        fingers: scene
            .bodies()
            .iter()
            .map(|b| FingerRecord {
                surface_vertices: b.surface().len(),
                tet_nodes: b.fem().mesh().num_nodes(),
                tets: b.fem().mesh().num_tets(),
                fixed_nodes: b.fem().fixed().iter().filter(|&&f| f).count(),
                volume_ratio: b.voxel_stats().volume_ratio,
                max_embedding_distance_m: b.voxel_stats().max_embedding_distance_m,
            })
            .collect(),
        final_kinetic_energy_j: last
            .as_ref()
            .map(|i| i.kinetic_energy_j.clone())
            .unwrap_or_default(),
        final_tendon_tension_n: last
            .as_ref()
            .map(|i| {
                i.tendons
                    .iter()
                    .map(|t| t.iter().map(|s| s.tension_n).collect())
                    .collect()
            })
            .unwrap_or_default(),
        state_digest: format!("{:#018x}", state.digest()),
        frames,
    })
}

fn report(summary: &SimSummary, args: &SimArgs) -> Result<()> {
    if args.json {
        return super::print_json(summary);
    }
    super::outln!(
        "simulated {:.3} s in {} steps ({:.1} steps/s); {} frames written to {}",
        summary.simulated_secs,
        summary.steps,
        summary.steps_per_sec,
        summary.frames.len(),
        args.out.display()
    );
    if let Some(f) = summary.frames.last() {
        super::outln!(
            "final frame: contact vertices per finger {:?}, max penetration {:?} mm",
            f.contact_vertices,
            f.max_penetration_m
                .iter()
                .map(|p| p * 1e3)
                .collect::<Vec<_>>()
        );
    }
    Ok(())
}

fn save_frame(scene: &Scene, state: &SimState, args: &SimArgs, dir: &Path) -> Result<FrameRecord> {
    let frame: SimFrame = scene.frame(state);
    let k = frame.step;
    let mut record = FrameRecord {
        step: k,
        time_secs: frame.time_secs,
        files: Vec::new(),
        contact_vertices: Vec::new(),
        max_penetration_m: Vec::new(),
    };
    for (i, f) in frame.fingers.iter().enumerate() {
        let rest = scene.hand().fingers()[i].model.mesh();
        let vertices = match args.frame {
            OutputFrame::Hand => f.vertices_in_hand.clone(),
            OutputFrame::World => f.vertices_in_world.clone(),
        };
        let ext = match args.format {
            MeshFormat::Obj => "obj",
            MeshFormat::Ply => "ply",
        };
        let name = format!("frame_{k:06}_finger_{i}.{ext}");
        let path = dir.join(&name);
        match args.format {
            MeshFormat::Obj => {
                let mesh = rest
                    .with_vertices(vertices)
                    .with_context(|| format!("finger {i} at step {k}"))?;
                moe_io::write_mesh(&path, &mesh)?;
            }
            MeshFormat::Ply => {
                let data = moe_io::PlyData {
                    points: vertices,
                    faces: rest.faces().to_vec(),
                    colors: None,
                    scalars: vec![
                        (
                            "contact".to_owned(),
                            f.labels
                                .iter()
                                .map(|&l| if l { 1.0 } else { 0.0 })
                                .collect(),
                        ),
                        (
                            "distance_m".to_owned(),
                            f.distances_m.iter().map(|&d| d.min(1e3) as f32).collect(),
                        ),
                    ],
                };
                moe_io::write_ply(&path, &data)?;
            }
        }
        if !path.exists() {
            bail!("{} was not written", path.display());
        }
        record.files.push(name);
        record
            .contact_vertices
            .push(f.labels.iter().filter(|&&l| l).count());
        record
            .max_penetration_m
            .push((-f.distances_m.iter().copied().fold(f64::INFINITY, f64::min)).max(0.0));
    }
    Ok(record)
}

/// `--json` output of an episode run.
#[derive(Debug, Serialize)]
struct EpisodeSummary {
    scene: String,
    episode: String,
    steps: u64,
    frames: usize,
    contact_frames: usize,
    bytes: u64,
    wall_secs: f64,
}

/// Runs the scene and writes an MCAP episode (streamed to a temporary file, moved into place
/// when complete).
fn record_episode(mut scene: Scene, args: &SimArgs) -> Result<()> {
    let started = Instant::now();
    let steps = args.steps.unwrap_or_else(|| scene.num_steps());
    let name = args
        .scene
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let recorder = moe_lab::episode::EpisodeRecorder::new(&scene, &name, args.seed)?;
    let frames = moe_tendon_sim::run_saving(&mut scene, steps)
        .with_context(|| format!("simulating {}", args.scene.display()))?;
    let mut writer = moe_record::create_episode(&args.out, recorder.info())?;
    let mut contact_frames = 0;
    for (k, saved) in frames.iter().enumerate() {
        let frame = recorder.frame(&scene, saved, k as u64)?;
        contact_frames += usize::from(frame.contact_vertices.iter().any(|c| !c.is_empty()));
        writer.write_frame(&frame)?;
    }
    writer.commit()?;
    let summary = EpisodeSummary {
        scene: args.scene.display().to_string(),
        episode: args.out.display().to_string(),
        steps,
        frames: frames.len(),
        contact_frames,
        bytes: std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0),
        wall_secs: started.elapsed().as_secs_f64(),
    };
    if args.json {
        super::print_json(&summary)
    } else {
        super::outln!(
            "{}: {} frames ({} with contact) from {} steps in {:.1} s, {:.1} MB",
            summary.episode,
            summary.frames,
            summary.contact_frames,
            summary.steps,
            summary.wall_secs,
            summary.bytes as f64 / 1e6
        );
        Ok(())
    }
}
