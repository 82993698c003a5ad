//! A scripted scene's run written out: the hand's surface meshes per saved frame with a
//! summary (`moe-touch sim --out DIR`), or a recorded episode (`--out EP.mcap`). Nothing is left
//! behind by a run that fails: frames are written to a staging directory and moved into place
//! only when the whole run succeeded, and an episode is written atomically.

use std::path::Path;
use std::time::Instant;

use moe_tendon_sim::{Scene, SimFrame, SimState, run_with};
use serde::Serialize;

use crate::LabError;

/// Mesh format of the saved frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (geometry only).
    Obj,
    /// PLY with per-vertex scalars `contact` (0/1) and `distance_m`.
    Ply,
}

/// Frame in which the saved vertices are expressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OutputFrame {
    /// The hand (palm) frame: the frame of the training data.
    Hand,
    /// The world frame (where the obstacles are).
    World,
}

/// One saved frame in the summary.
#[derive(Debug, Clone, Serialize)]
pub struct FrameRecord {
    /// Simulation step.
    pub step: u64,
    /// Simulated time, seconds.
    pub time_secs: f64,
    /// The mesh files written, one per finger (names in the output directory).
    pub files: Vec<String>,
    /// Vertices in contact, per finger.
    pub contact_vertices: Vec<usize>,
    /// Deepest penetration of an obstacle, per finger, metres.
    pub max_penetration_m: Vec<f64>,
}

/// Per-finger discretisation figures.
#[derive(Debug, Clone, Serialize)]
pub struct FingerRecord {
    /// Surface vertices.
    pub surface_vertices: usize,
    /// Tetrahedral mesh nodes.
    pub tet_nodes: usize,
    /// Tetrahedra.
    pub tets: usize,
    /// Nodes fixed to the palm.
    pub fixed_nodes: usize,
    /// Tetrahedral volume over the surface's enclosed volume.
    pub volume_ratio: f64,
    /// Largest distance of a surface vertex from its embedding tetrahedron, metres.
    pub max_embedding_distance_m: f64,
}

/// `summary.json` of a run written as meshes (and `moe-touch sim --json`'s output).
#[derive(Debug, Clone, Serialize)]
pub struct SimSummary {
    /// The scene, as named.
    pub scene: String,
    /// The frame of the saved vertices.
    pub frame: OutputFrame,
    /// Time step, seconds.
    pub dt_secs: f64,
    /// Steps run.
    pub steps: u64,
    /// Simulated time, seconds.
    pub simulated_secs: f64,
    /// Wall time, seconds.
    pub wall_secs: f64,
    /// Steps per wall second.
    pub steps_per_sec: f64,
    /// Per finger.
    pub fingers: Vec<FingerRecord>,
    /// Kinetic energy per finger after the last step, joules.
    pub final_kinetic_energy_j: Vec<f64>,
    /// Tension of every tendon segment per finger after the last step, newtons.
    pub final_tendon_tension_n: Vec<Vec<f64>>,
    /// Digest of the final state (bit-for-bit reproducibility).
    pub state_digest: String,
    /// The saved frames.
    pub frames: Vec<FrameRecord>,
}

impl SimSummary {
    /// The summary as text (naming `out`, the output directory), lines ending in `\n`.
    pub fn table(&self, out: &Path) -> String {
        let mut text = format!(
            "simulated {:.3} s in {} steps ({:.1} steps/s); {} frames written to {}\n",
            self.simulated_secs,
            self.steps,
            self.steps_per_sec,
            self.frames.len(),
            out.display()
        );
        if let Some(f) = self.frames.last() {
            let depth_mm: Vec<f64> = f.max_penetration_m.iter().map(|p| p * 1e3).collect();
            text.push_str(&format!(
                "final frame: contact vertices per finger {:?}, max penetration {:?} mm\n",
                f.contact_vertices, depth_mm
            ));
        }
        text
    }
}

/// Runs `scene` (named `name` in the summary) for `steps` steps (default: its duration) and
/// writes every saved frame's finger meshes into `out` as `frame_<k>_finger_<i>.<ext>`, with
/// `summary.json`. `progress` hears of each saved step (step, steps, simulated seconds).
///
/// # Errors
/// A simulation that fails (diverges, or is asked for more steps than the scene covers), or a
/// file that cannot be written; `out` then holds nothing new (and is removed if it was created
/// empty).
pub fn write_frames(
    scene: Scene,
    name: &str,
    (format, frame): (MeshFormat, OutputFrame),
    steps: Option<u64>,
    out: &Path,
    progress: &mut dyn FnMut(u64, u64, f64),
) -> Result<SimSummary, LabError> {
    let staging = out.join(".moe-sim-partial");
    std::fs::create_dir_all(&staging).map_err(|e| moe_io::IoError::io(&staging, e))?;
    let moved =
        simulate(scene, name, (format, frame), steps, &staging, progress).and_then(|summary| {
            for name in summary.frames.iter().flat_map(|f| &f.files) {
                let to = out.join(name);
                std::fs::rename(staging.join(name), &to)
                    .map_err(|e| moe_io::IoError::io(&to, e))?;
            }
            std::fs::remove_dir(&staging).map_err(|e| moe_io::IoError::io(&staging, e))?;
            Ok(summary)
        });
    match moved {
        Ok(summary) => {
            moe_io::write_json(&out.join("summary.json"), &summary)?;
            Ok(summary)
        }
        Err(err) => {
            let _ = std::fs::remove_dir_all(&staging);
            if std::fs::read_dir(out).is_ok_and(|mut d| d.next().is_none()) {
                let _ = std::fs::remove_dir(out);
            }
            Err(err)
        }
    }
}

fn simulate(
    mut scene: Scene,
    name: &str,
    (format, frame): (MeshFormat, OutputFrame),
    steps: Option<u64>,
    staging: &Path,
    progress: &mut dyn FnMut(u64, u64, f64),
) -> Result<SimSummary, LabError> {
    let steps = steps.unwrap_or_else(|| scene.num_steps());
    let mut frames = Vec::new();
    let start = Instant::now();
    let outcome = run_with(&mut scene, steps, |scene, state| -> Result<(), LabError> {
        frames.push(save_frame(scene, state, (format, frame), staging)?);
        if state.step > 0 {
            progress(state.step, steps, state.time_secs);
        }
        Ok(())
    })?;
    let (state, last) = (outcome.final_state, outcome.last_step);
    let wall_secs = start.elapsed().as_secs_f64();
    Ok(SimSummary {
        scene: name.to_owned(),
        frame,
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

fn save_frame(
    scene: &Scene,
    state: &SimState,
    (format, output): (MeshFormat, OutputFrame),
    dir: &Path,
) -> Result<FrameRecord, LabError> {
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
        let vertices = match output {
            OutputFrame::Hand => f.vertices_in_hand.clone(),
            OutputFrame::World => f.vertices_in_world.clone(),
        };
        let ext = match format {
            MeshFormat::Obj => "obj",
            MeshFormat::Ply => "ply",
        };
        let name = format!("frame_{k:06}_finger_{i}.{ext}");
        let path = dir.join(&name);
        match format {
            MeshFormat::Obj => moe_io::write_mesh(&path, &rest.with_vertices(vertices)?)?,
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

/// What `moe-touch sim --out EP.mcap` prints.
#[derive(Debug, Clone, Serialize)]
pub struct EpisodeSummary {
    /// The scene, as named.
    pub scene: String,
    /// The episode file.
    pub episode: String,
    /// Steps run.
    pub steps: u64,
    /// Frames recorded.
    pub frames: usize,
    /// Frames in which something touches the hand.
    pub contact_frames: usize,
    /// Size of the file, bytes.
    pub bytes: u64,
    /// Wall time, seconds.
    pub wall_secs: f64,
}

impl EpisodeSummary {
    /// The summary as one line of text, ending in `\n`.
    pub fn table(&self) -> String {
        format!(
            "{}: {} frames ({} with contact) from {} steps in {:.1} s, {:.1} MB\n",
            self.episode,
            self.frames,
            self.contact_frames,
            self.steps,
            self.wall_secs,
            self.bytes as f64 / 1e6
        )
    }
}

/// Runs `scene` (from the file `scene_path`, whose stem names the episode) for `steps` steps
/// (default: its duration) and records it as an episode at `out`, the camera noise seeded by
/// `seed`.
///
/// # Errors
/// A simulation that fails, or a file that cannot be written (the episode is written
/// atomically: nothing is left of a failed run).
pub fn write_episode(
    mut scene: Scene,
    scene_path: &Path,
    seed: u64,
    steps: Option<u64>,
    out: &Path,
) -> Result<EpisodeSummary, LabError> {
    let started = Instant::now();
    let steps = steps.unwrap_or_else(|| scene.num_steps());
    let name = scene_path
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let recorder = crate::episode::EpisodeRecorder::new(&scene, &name, seed)?;
    let frames = moe_tendon_sim::run_saving(&mut scene, steps)?;
    let mut writer = moe_record::create_episode(out, recorder.info())?;
    let mut contact_frames = 0;
    for (k, saved) in frames.iter().enumerate() {
        let frame = recorder.frame(&scene, saved, k as u64)?;
        contact_frames += usize::from(frame.contact_vertices.iter().any(|c| !c.is_empty()));
        writer.write_frame(&frame)?;
    }
    writer.commit()?;
    Ok(EpisodeSummary {
        scene: scene_path.display().to_string(),
        episode: out.display().to_string(),
        steps,
        frames: frames.len(),
        contact_frames,
        bytes: std::fs::metadata(out).map(|m| m.len()).unwrap_or(0),
        wall_secs: started.elapsed().as_secs_f64(),
    })
}
