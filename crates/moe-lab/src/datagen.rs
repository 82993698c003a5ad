//! Sharded, resumable, deterministic data set generation.
//!
//! A run produces `trajectories` trajectories numbered `0..trajectories`; trajectory `t` is a
//! pure function of `(seed, t)`, so the same seed gives the same bytes whatever the machine,
//! the thread count or the split. Trajectories are grouped into output shards of
//! `trajectories_per_shard` consecutive ids; shard `k` is one safetensors file plus a small JSON
//! sidecar with its statistics. A run on machine `I` of `N` (`--shard I/N`, 1-based) produces the
//! shards `k` with `k mod N = I − 1`, so an array job splits the work without coordination, and
//! the union of the machines' shards equals an unsplit run's, byte for byte.
//!
//! Shards are written atomically (temporary file, then rename) and a shard whose file already
//! exists is skipped, so an interrupted run loses at most the shards in progress and a rerun
//! resumes. Whenever every shard of the plan is present, the run (re)writes the data set card
//! from the sidecars.
//!
//! Within a shard, trajectories are generated in parallel (rayon) and collected in id order.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use moe_io::dataset::{
    CARD_FILE, DatasetCard, DatasetFrame, DatasetLayout, FORMAT_VERSION, FrameStats, ShardEntry,
    shard_file_name, shard_stats, write_shard,
};
use moe_tendon_sim::randomize::{
    OBJECT_PARAM_LEN, ObjectFamily, RandomSceneParams, simulate_trajectory,
};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::LabError;

/// What to generate, and which part of it this machine does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct GenPlan {
    /// Trajectories in the whole data set.
    pub trajectories: u64,
    /// Trajectories per output shard.
    pub trajectories_per_shard: u64,
    /// Seed of the whole data set.
    pub seed: u64,
    /// This machine's 1-based index.
    pub machine: u32,
    /// Number of machines.
    pub machines: u32,
}

/// Most trajectories of one data set.
pub const MAX_TRAJECTORIES: u64 = 10_000_000;
/// Most trajectories of one shard (a shard's frames are held in memory until it is written).
pub const MAX_TRAJECTORIES_PER_SHARD: u64 = 1_000;

impl GenPlan {
    /// Checks the plan.
    ///
    /// # Errors
    /// [`LabError::InvalidPlan`].
    pub fn validate(&self) -> Result<(), LabError> {
        let bad = |reason: String| Err(LabError::InvalidPlan { reason });
        if !(1..=MAX_TRAJECTORIES).contains(&self.trajectories) {
            return bad(format!(
                "{} trajectories: a data set holds between 1 and {MAX_TRAJECTORIES}",
                self.trajectories
            ));
        }
        if !(1..=MAX_TRAJECTORIES_PER_SHARD).contains(&self.trajectories_per_shard) {
            return bad(format!(
                "{} trajectories per shard: a shard (held in memory while it is written) holds \
                 between 1 and {MAX_TRAJECTORIES_PER_SHARD}",
                self.trajectories_per_shard
            ));
        }
        if self.machines == 0 || self.machine == 0 || self.machine > self.machines {
            return bad(format!(
                "shard {}/{} is not of the form I/N with 1 ≤ I ≤ N",
                self.machine, self.machines
            ));
        }
        Ok(())
    }

    /// Number of output shards.
    pub fn num_shards(&self) -> u64 {
        self.trajectories.div_ceil(self.trajectories_per_shard)
    }

    /// The shards this machine produces.
    pub fn shards_for_machine(&self) -> Vec<u64> {
        (0..self.num_shards())
            .filter(|k| k % u64::from(self.machines) == u64::from(self.machine - 1))
            .collect()
    }

    /// Trajectory ids of shard `k`.
    pub fn trajectories_of(&self, k: u64) -> std::ops::Range<u64> {
        let start = k * self.trajectories_per_shard;
        start..(start + self.trajectories_per_shard).min(self.trajectories)
    }

    /// File name of shard `k`.
    pub fn shard_file(&self, k: u64) -> String {
        shard_file_name(k as usize, self.num_shards() as usize)
    }
}

/// Environment variables that carry an array job's task index, in the order they are tried:
/// Slurm's (`SLURM_ARRAY_TASK_ID`, offset by `SLURM_ARRAY_TASK_MIN` when set, so that
/// `--array=0-7` and `--array=1-8` both work) and a Kubernetes Indexed Job's 0-based
/// `JOB_COMPLETION_INDEX`.
pub const SHARD_INDEX_VARIABLES: [&str; 2] = ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"];

/// Parses a machine split: `I/N` (1-based) or `auto/N`, which takes `I` from the scheduler's
/// environment ([`SHARD_INDEX_VARIABLES`]); `env` looks a variable up (`std::env::var` in the
/// tools, a map in tests).
///
/// # Errors
/// [`LabError::InvalidPlan`] for a malformed split, `auto` with none of the variables set or
/// with a value that is not an index, or an index outside `1..=N`.
pub fn parse_shard_spec(
    spec: &str,
    env: &dyn Fn(&str) -> Option<String>,
) -> Result<(u32, u32), LabError> {
    let bad = |reason: String| LabError::InvalidPlan { reason };
    let (i, n) = spec
        .split_once('/')
        .ok_or_else(|| bad(format!("--shard {spec}: expected I/N or auto/N")))?;
    let n: u32 = n
        .trim()
        .parse()
        .map_err(|_| bad(format!("--shard {spec}: N is not a positive integer")))?;
    let number = |name: &str, v: &str| -> Result<u32, LabError> {
        v.trim()
            .parse()
            .map_err(|_| bad(format!("{name}={v} is not an array index")))
    };
    let i = if i.trim() == "auto" {
        if let Some(id) = env("SLURM_ARRAY_TASK_ID") {
            let id = number("SLURM_ARRAY_TASK_ID", &id)?;
            match env("SLURM_ARRAY_TASK_MIN") {
                Some(min) => {
                    let min = number("SLURM_ARRAY_TASK_MIN", &min)?;
                    id.checked_sub(min).map(|k| k + 1).ok_or_else(|| {
                        bad(format!(
                            "SLURM_ARRAY_TASK_ID={id} is below SLURM_ARRAY_TASK_MIN={min}"
                        ))
                    })?
                }
                None => id,
            }
        } else if let Some(idx) = env("JOB_COMPLETION_INDEX") {
            number("JOB_COMPLETION_INDEX", &idx)?.saturating_add(1)
        } else {
            return Err(bad(format!(
                "--shard {spec}: none of {} is set (run it as an array job, or give I/N)",
                SHARD_INDEX_VARIABLES.join(", ")
            )));
        }
    } else {
        i.trim()
            .parse()
            .map_err(|_| bad(format!("--shard {spec}: I is not a positive integer")))?
    };
    if n == 0 || i == 0 || i > n {
        return Err(bad(format!(
            "--shard {spec}: machine {i} of {n} is not in 1..={n}"
        )));
    }
    Ok((i, n))
}

/// Writes the card of a data set whose shards were generated by several machines into one
/// directory (the last step of an array job), after checking that the directory was generated
/// with these settings.
///
/// # Errors
/// [`LabError::NotADataset`], [`LabError::SettingsMismatch`] (settings that differ from the
/// directory's), [`LabError::MissingShards`] naming the missing shards, or file-system errors.
pub fn merge_card(
    plan: &GenPlan,
    dir: &Path,
    layout: &DatasetLayout,
    generator: serde_json::Value,
) -> Result<DatasetCard, LabError> {
    plan.validate()?;
    if !dir.join(SETTINGS_FILE).exists() {
        return Err(LabError::NotADataset {
            dir: dir.to_owned(),
            file: SETTINGS_FILE,
        });
    }
    check_settings(plan, dir, layout, &generator)?;
    let missing: Vec<u64> = (0..plan.num_shards())
        .filter(|&k| !dir.join(plan.shard_file(k)).exists())
        .collect();
    if !missing.is_empty() {
        return Err(LabError::MissingShards {
            dir: dir.to_owned(),
            missing,
            total: plan.num_shards(),
        });
    }
    // `None` only if a shard vanished between the check above and the card.
    write_card_if_complete(plan, dir, layout, generator)?.ok_or_else(|| {
        let missing: Vec<u64> = (0..plan.num_shards())
            .filter(|&k| !dir.join(plan.shard_file(k)).exists())
            .collect();
        LabError::MissingShards {
            dir: dir.to_owned(),
            missing,
            total: plan.num_shards(),
        }
    })
}

/// Sidecar of one shard: its statistics, for the card.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShardSidecar {
    stats: FrameStats,
    families: BTreeMap<String, FrameStats>,
}

fn sidecar_path(shard: &Path) -> PathBuf {
    shard.with_extension("json")
}

/// What a run did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GenReport {
    /// Shards written by this run.
    pub shards_written: Vec<u64>,
    /// Shards found complete and skipped.
    pub shards_skipped: Vec<u64>,
    /// Frames written by this run.
    pub frames_written: u64,
    /// The card, when every shard of the plan is present.
    pub card: Option<DatasetCard>,
}

/// Generates this machine's shards of `plan` into `dir`.
///
/// `trajectory` produces the frames of one trajectory id (it must be a pure function of the id
/// and the seed it captured); `progress` is called with `(trajectories done, trajectories to do)`
/// after each trajectory, from worker threads.
///
/// # Errors
/// An invalid plan, a trajectory that fails (naming it), or a write failure. Shards finished
/// before the failure stay on disk and are skipped by the next run.
pub fn generate(
    plan: &GenPlan,
    dir: &Path,
    layout: &DatasetLayout,
    generator: serde_json::Value,
    trajectory: &(dyn Fn(u64) -> Result<Vec<DatasetFrame>, LabError> + Sync),
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<GenReport, LabError> {
    plan.validate()?;
    check_settings(plan, dir, layout, &generator)?;
    let mine = plan.shards_for_machine();
    let (todo, skipped): (Vec<u64>, Vec<u64>) = mine
        .iter()
        .partition(|&&k| !dir.join(plan.shard_file(k)).exists());
    let total: u64 = todo
        .iter()
        .map(|&k| plan.trajectories_of(k).count() as u64)
        .sum();
    let done = AtomicU64::new(0);
    progress(0, total);
    let mut frames_written = 0;
    for &k in &todo {
        let ids: Vec<u64> = plan.trajectories_of(k).collect();
        let per_trajectory: Vec<Vec<DatasetFrame>> = ids
            .par_iter()
            .map(|&t| {
                let frames = trajectory(t)?;
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                Ok(frames)
            })
            .collect::<Result<_, LabError>>()?;
        let frames: Vec<DatasetFrame> = per_trajectory.into_iter().flatten().collect();
        if frames.is_empty() {
            return Err(LabError::EmptyShard { shard: k });
        }
        let path = dir.join(plan.shard_file(k));
        let (stats, families) = shard_stats(layout, &frames);
        // Sidecar first: a shard file never exists without its statistics.
        moe_io::write_json(&sidecar_path(&path), &ShardSidecar { stats, families })?;
        write_shard(&path, layout, &frames)?;
        frames_written += frames.len() as u64;
    }
    let card = write_card_if_complete(plan, dir, layout, generator)?;
    Ok(GenReport {
        shards_written: todo,
        shards_skipped: skipped,
        frames_written,
        card,
    })
}

/// What every machine of a data set must agree on, kept in `plan.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Settings {
    /// The shard format ([`FORMAT_VERSION`]; 1 in directories of writers before it was
    /// recorded), so that shards of two formats never share a directory.
    #[serde(default = "format_version_1")]
    format_version: u32,
    trajectories: u64,
    trajectories_per_shard: u64,
    seed: u64,
    layout: DatasetLayout,
    generator: serde_json::Value,
}

/// File holding the settings of a data set directory (shard format, seed, sizes, layout,
/// randomisation).
pub const SETTINGS_FILE: &str = "plan.json";

fn format_version_1() -> u32 {
    1
}

/// Refuses to add shards to a directory generated with other settings (a resumed run with
/// another seed or other ranges would otherwise mix two data sets); records the settings on the
/// first run.
fn check_settings(
    plan: &GenPlan,
    dir: &Path,
    layout: &DatasetLayout,
    generator: &serde_json::Value,
) -> Result<(), LabError> {
    let settings = Settings {
        format_version: FORMAT_VERSION,
        trajectories: plan.trajectories,
        trajectories_per_shard: plan.trajectories_per_shard,
        seed: plan.seed,
        layout: layout.clone(),
        generator: generator.clone(),
    };
    let path = dir.join(SETTINGS_FILE);
    if path.exists() {
        let existing: Settings = moe_io::read_json(&path)?;
        if existing != settings {
            return Err(LabError::SettingsMismatch {
                dir: dir.to_owned(),
            });
        }
        return Ok(());
    }
    moe_io::write_json(&path, &settings)?;
    Ok(())
}

fn write_card_if_complete(
    plan: &GenPlan,
    dir: &Path,
    layout: &DatasetLayout,
    generator: serde_json::Value,
) -> Result<Option<DatasetCard>, LabError> {
    let mut shards = Vec::new();
    for k in 0..plan.num_shards() {
        let file = plan.shard_file(k);
        let path = dir.join(&file);
        if !path.exists() {
            return Ok(None);
        }
        let sidecar: ShardSidecar = moe_io::read_json(&sidecar_path(&path))?;
        shards.push((
            ShardEntry {
                file,
                stats: sidecar.stats,
            },
            sidecar.families,
        ));
    }
    let card = DatasetCard::new(layout.clone(), plan.seed, generator, shards);
    moe_io::write_json(&dir.join(CARD_FILE), &card)?;
    Ok(Some(card))
}

/// Draws per trajectory before a failing simulation is reported.
pub const MAX_DRAWS: u64 = 4;

/// The frame layout of a data set simulated with `params`, after checking the parameters (so
/// that a bad parameter file stops a run before it writes anything).
///
/// # Errors
/// [`LabError::Simulation`] naming an invalid randomisation parameter
/// ([`RandomSceneParams::validate`]); [`LabError::Touch`] for invalid finger parameters
/// or fingers with different numbers of tendons ([`moe_geom::HandModel::tendons_per_finger`]).
pub fn simulated_layout(params: &RandomSceneParams) -> Result<DatasetLayout, LabError> {
    params.validate()?;
    let hand = moe_geom::HandModel::preset(params.preset, &params.finger)?;
    let fingers = hand.fingers();
    let tendons_per_finger = hand.tendons_per_finger()?;
    Ok(DatasetLayout {
        finger_num_vertices: fingers
            .iter()
            .map(|f| f.model.mesh().num_vertices())
            .collect(),
        markers_per_finger: fingers
            .iter()
            .map(|f| f.model.marker_vertices().len())
            .collect(),
        tendons_per_finger,
        object_param_len: OBJECT_PARAM_LEN,
        object_families: ObjectFamily::ALL
            .iter()
            .map(|f| f.name().to_owned())
            .collect(),
    })
}

/// Simulates trajectory `trajectory_id` of a data set with `seed` and returns its labelled frames
/// (all fingers concatenated in the hand frame; markers are the marker vertices).
///
/// # Errors
/// [`LabError::Trajectory`] naming the trajectory and carrying the simulator's error of the
/// last draw (which names the step and element on divergence);
/// [`LabError::Simulation`] with [`moe_tendon_sim::SimError::ForceDriven`] for a scene whose
/// tendons are force-driven (a data set records pulls in metres).
pub fn simulated_frames(
    params: &RandomSceneParams,
    seed: u64,
    trajectory_id: u64,
) -> Result<Vec<DatasetFrame>, LabError> {
    // A draw whose simulation diverges (an element inverted by an extreme press, say) is
    // replaced by a redraw from a derived seed; the redraws are part of the pure function of
    // (seed, trajectory), so determinism holds.
    let mut attempt: u64 = 0;
    let (sampled, scene, frames) = loop {
        let attempt_seed = seed ^ attempt.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        attempt += 1;
        match simulate_trajectory(params, attempt_seed, trajectory_id) {
            Ok(r) => break r,
            Err(source) if attempt == MAX_DRAWS => {
                return Err(LabError::Trajectory {
                    trajectory: trajectory_id,
                    draws: MAX_DRAWS,
                    source,
                });
            }
            Err(_) => {}
        }
    };
    let hand = scene.hand();
    let object_params: Vec<f32> = sampled.object_params.iter().map(|&v| v as f32).collect();
    frames
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let pulls = f.tendon_pulls_m()?;
            let to32 = |p: &moe_geom::Point3| [p.x as f32, p.y as f32, p.z as f32];
            let vertices = f
                .fingers
                .iter()
                .flat_map(|g| g.vertices_in_hand.iter().map(to32))
                .collect();
            let contact = f
                .fingers
                .iter()
                .flat_map(|g| g.labels.iter().map(|&l| u8::from(l)))
                .collect();
            let contact_force_n = f
                .fingers
                .iter()
                .flat_map(|g| g.contact_force_n.iter().map(|&v| v as f32))
                .collect();
            let obstacle_distance_m = f
                .fingers
                .iter()
                .flat_map(|g| g.distances_m.iter().map(|&v| v as f32))
                .collect();
            let finger_force_n = f
                .fingers
                .iter()
                .map(|g| {
                    let n = g.force_in_hand_n;
                    [n.x as f32, n.y as f32, n.z as f32]
                })
                .collect();
            let markers = f
                .fingers
                .iter()
                .zip(hand.fingers())
                .flat_map(|(g, hf)| {
                    hf.model
                        .marker_vertices()
                        .iter()
                        .map(|&m| to32(&g.vertices_in_hand[m as usize]))
                })
                .collect();
            let iso = f.world_from_hand;
            let (t, q) = (iso.translation.vector, iso.rotation.quaternion());
            Ok(DatasetFrame {
                trajectory_id,
                frame_index: k as u32,
                vertices,
                contact,
                contact_force_n,
                obstacle_distance_m,
                finger_force_n: Some(finger_force_n),
                markers,
                world_from_hand: [t.x, t.y, t.z, q.i, q.j, q.k, q.w],
                tendon_pull_m: pulls.iter().flatten().map(|&v| v as f32).collect(),
                object_family: sampled.family.code(),
                object_params: object_params.clone(),
            })
        })
        .collect()
}

/// The generator parameters a data set was simulated with, from its card.
///
/// # Errors
/// [`LabError::DatasetCard`] when the card records none or they do not parse.
pub fn dataset_params(card: &moe_io::DatasetCard) -> Result<RandomSceneParams, LabError> {
    let params = card
        .generator
        .get("params")
        .cloned()
        .ok_or_else(|| LabError::DatasetCard {
            reason: "it records no simulator parameters".into(),
        })?;
    serde_json::from_value(params).map_err(|e| LabError::DatasetCard {
        reason: format!("its simulator parameters: {e}"),
    })
}

/// The hand a data set was simulated with, from its card, checked against its layout.
///
/// # Errors
/// As [`dataset_params`]; [`LabError::DatasetCard`] when the hand does not fit the layout.
pub fn dataset_hand(reader: &moe_io::DatasetReader) -> Result<moe_geom::HandModel, LabError> {
    let card = reader.card();
    let params = dataset_params(card)?;
    let hand = moe_geom::HandModel::preset(params.preset, &params.finger)?;
    let counts: Vec<usize> = hand
        .fingers()
        .iter()
        .map(|f| f.model.mesh().num_vertices())
        .collect();
    if counts != card.layout.finger_num_vertices {
        return Err(LabError::DatasetCard {
            reason: format!(
                "the data set's layout ({:?} vertices per finger) is not its recorded hand's \
                 ({counts:?})",
                card.layout.finger_num_vertices
            ),
        });
    }
    Ok(hand)
}

/// Name of the rule that labelled a data set's contacts, from its card (`proximity` for data
/// sets made before the rule was recorded).
pub fn label_rule(card: &moe_io::DatasetCard) -> String {
    card.generator["params"]["contact"]["label_rule"]
        .as_str()
        .unwrap_or("proximity")
        .to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::SeededRng;

    #[test]
    fn shard_specs_take_the_index_from_the_scheduler() {
        let env = |vars: &'static [(&'static str, &'static str)]| {
            move |k: &str| {
                vars.iter()
                    .find(|(n, _)| *n == k)
                    .map(|(_, v)| v.to_string())
            }
        };
        let none = env(&[]);
        assert_eq!(parse_shard_spec("2/4", &none).unwrap(), (2, 4));
        assert_eq!(
            parse_shard_spec("auto/4", &env(&[("SLURM_ARRAY_TASK_ID", "3")])).unwrap(),
            (3, 4)
        );
        assert_eq!(
            parse_shard_spec(
                "auto/4",
                &env(&[("SLURM_ARRAY_TASK_ID", "0"), ("SLURM_ARRAY_TASK_MIN", "0")])
            )
            .unwrap(),
            (1, 4)
        );
        assert_eq!(
            parse_shard_spec("auto/4", &env(&[("JOB_COMPLETION_INDEX", "3")])).unwrap(),
            (4, 4)
        );
        for (spec, vars, needle) in [
            ("auto/4", &[][..], "none of SLURM_ARRAY_TASK_ID"),
            (
                "auto/4",
                &[("JOB_COMPLETION_INDEX", "4")][..],
                "machine 5 of 4",
            ),
            (
                "auto/4",
                &[("SLURM_ARRAY_TASK_ID", "x")][..],
                "SLURM_ARRAY_TASK_ID=x",
            ),
            ("0/4", &[][..], "machine 0 of 4"),
            ("3", &[][..], "expected I/N"),
            ("1/0", &[][..], "not in 1..=0"),
        ] {
            let vars: &'static [(&'static str, &'static str)] =
                Box::leak(vars.to_vec().into_boxed_slice());
            let err = parse_shard_spec(spec, &env(vars)).unwrap_err().to_string();
            assert!(err.contains(needle), "{spec} {vars:?}: {err}");
        }
    }

    fn layout() -> DatasetLayout {
        DatasetLayout {
            finger_num_vertices: vec![4],
            markers_per_finger: vec![1],
            tendons_per_finger: 1,
            object_param_len: 1,
            object_families: vec!["a".into(), "b".into()],
        }
    }

    /// A stand-in generator: frames that are a pure function of (seed, trajectory).
    fn synthetic(seed: u64) -> impl Fn(u64) -> Result<Vec<DatasetFrame>, LabError> + Sync {
        move |t| {
            let mut rng = SeededRng::new(seed).split(t);
            let n = 1 + rng.below(3) as u32;
            Ok((0..n)
                .map(|k| DatasetFrame {
                    trajectory_id: t,
                    frame_index: k,
                    vertices: (0..4).map(|_| [rng.uniform() as f32; 3]).collect(),
                    contact: (0..4).map(|_| u8::from(rng.uniform() < 0.3)).collect(),
                    contact_force_n: (0..4).map(|_| rng.uniform() as f32).collect(),
                    obstacle_distance_m: vec![f32::INFINITY; 4],
                    finger_force_n: Some(vec![[0.0, 0.0, 0.1 * k as f32]]),
                    markers: vec![[0.0, 0.0, rng.uniform() as f32]],
                    world_from_hand: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
                    tendon_pull_m: vec![rng.uniform() as f32],
                    object_family: (t % 2) as u8,
                    object_params: vec![t as f32],
                })
                .collect())
        }
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("moe-datagen-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// `generate` with the test layout, the synthetic generator of `seed` and no progress.
    fn run(
        plan: &GenPlan,
        dir: &Path,
        generator: serde_json::Value,
        seed: u64,
    ) -> Result<GenReport, LabError> {
        generate(
            plan,
            dir,
            &layout(),
            generator,
            &synthetic(seed),
            &|_, _| {},
        )
    }

    fn plan(machine: u32, machines: u32) -> GenPlan {
        GenPlan {
            trajectories: 23,
            trajectories_per_shard: 4,
            seed: 9,
            machine,
            machines,
        }
    }

    fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .map(|p| {
                (
                    p.file_name().unwrap().to_string_lossy().into_owned(),
                    std::fs::read(&p).unwrap(),
                )
            })
            .collect()
    }

    #[test]
    fn split_runs_equal_one_run_byte_for_byte() {
        let whole = scratch("whole");
        let report = run(&plan(1, 1), &whole, serde_json::json!({}), 9).unwrap();
        assert_eq!(report.shards_written.len(), 6);
        let card = report.card.expect("complete");
        assert_eq!(card.totals.trajectories, 23);
        let split = scratch("split");
        let first = run(&plan(1, 2), &split, serde_json::json!({}), 9).unwrap();
        assert!(first.card.is_none(), "half the shards are missing");
        let second = run(&plan(2, 2), &split, serde_json::json!({}), 9).unwrap();
        assert!(second.card.is_some());
        assert_eq!(files(&whole), files(&split));
        // Rerunning skips every shard and rewrites the same card.
        let again = run(&plan(1, 1), &whole, serde_json::json!({}), 9).unwrap();
        assert!(again.shards_written.is_empty());
        assert_eq!(again.shards_skipped.len(), 6);
        assert_eq!(files(&whole), files(&split));
        std::fs::remove_dir_all(&whole).unwrap();
        std::fs::remove_dir_all(&split).unwrap();
    }

    #[test]
    fn a_failing_trajectory_keeps_finished_shards_and_is_named() {
        let dir = scratch("fail");
        let good = synthetic(9);
        let failing = move |t: u64| {
            if t == 13 {
                Err(LabError::Trajectory {
                    trajectory: t,
                    draws: MAX_DRAWS,
                    source: moe_tendon_sim::SimError::NonFinite {
                        step: 7,
                        finger: 0,
                        node: 3,
                    },
                })
            } else {
                good(t)
            }
        };
        let err = generate(
            &plan(1, 1),
            &dir,
            &layout(),
            serde_json::json!({}),
            &failing,
            &|_, _| {},
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                LabError::Trajectory {
                    trajectory: 13,
                    source: moe_tendon_sim::SimError::NonFinite { step: 7, .. },
                    ..
                }
            ),
            "{err:?}"
        );
        // Shards 0..=2 (trajectories 0..12) finished; shard 3 holds trajectory 13 and is absent.
        let names: Vec<String> = files(&dir)
            .into_keys()
            .filter(|n| n.ends_with(".safetensors"))
            .collect();
        assert_eq!(names.len(), 3, "{names:?}");
        assert!(!names.iter().any(|n| n.contains("00003")));
        // A rerun with a working generator completes only what is missing.
        let report = run(&plan(1, 1), &dir, serde_json::json!({}), 9).unwrap();
        assert_eq!(report.shards_written, vec![3, 4, 5]);
        assert!(report.card.is_some());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_directory_refuses_a_different_data_set() {
        let dir = scratch("settings");
        run(&plan(1, 2), &dir, serde_json::json!({"a": 1}), 9).unwrap();
        let other_seed = GenPlan {
            seed: 10,
            ..plan(2, 2)
        };
        let err = run(&other_seed, &dir, serde_json::json!({"a": 1}), 10).unwrap_err();
        assert!(
            matches!(&err, LabError::SettingsMismatch { dir: d } if *d == dir),
            "{err:?}"
        );
        let err = run(&plan(2, 2), &dir, serde_json::json!({"a": 2}), 9).unwrap_err();
        assert!(
            matches!(&err, LabError::SettingsMismatch { dir: d } if *d == dir),
            "{err:?}"
        );
        run(&plan(2, 2), &dir, serde_json::json!({"a": 1}), 9).unwrap();
        // A directory of a writer before format version 2 (no finger forces; its plan.json does
        // not record the format) takes no shard of this one.
        let settings = dir.join(SETTINGS_FILE);
        let mut old: serde_json::Value = moe_io::read_json(&settings).unwrap();
        assert_eq!(old["format_version"], FORMAT_VERSION);
        old.as_object_mut().unwrap().remove("format_version");
        moe_io::write_json(&settings, &old).unwrap();
        let err = run(&plan(2, 2), &dir, serde_json::json!({"a": 1}), 9).unwrap_err();
        assert!(
            matches!(&err, LabError::SettingsMismatch { dir: d } if *d == dir),
            "{err:?}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn plans_are_checked() {
        let refused = |p: GenPlan, what: &str| match p.validate() {
            Err(LabError::InvalidPlan { reason }) => assert!(reason.contains(what), "{reason}"),
            other => panic!("{what}: {other:?}"),
        };
        refused(plan(0, 2), "shard 0/2");
        refused(plan(3, 2), "shard 3/2");
        for (trajectories, what) in [(0, "0 trajectories"), (MAX_TRAJECTORIES + 1, "between 1")] {
            refused(
                GenPlan {
                    trajectories,
                    ..plan(1, 1)
                },
                what,
            );
        }
        for per_shard in [0, MAX_TRAJECTORIES_PER_SHARD + 1] {
            refused(
                GenPlan {
                    trajectories_per_shard: per_shard,
                    ..plan(1, 1)
                },
                "trajectories per shard",
            );
        }
        assert!(
            GenPlan {
                trajectories: MAX_TRAJECTORIES,
                trajectories_per_shard: MAX_TRAJECTORIES_PER_SHARD,
                ..plan(1, 1)
            }
            .validate()
            .is_ok()
        );
        assert_eq!(plan(2, 3).shards_for_machine(), vec![1, 4]);
        assert_eq!(plan(1, 1).trajectories_of(5), 20..23);
    }

    #[test]
    fn simulated_frames_fit_their_layout_and_are_deterministic() {
        let params = RandomSceneParams {
            press_secs: 0.25,
            hold_secs: 0.0,
            retract_secs: 0.05,
            save_every_steps: 5,
            ..RandomSceneParams::default()
        };
        let layout = simulated_layout(&params).unwrap();
        // A bad parameter is refused before anything is simulated, naming it.
        let soft = RandomSceneParams {
            material: moe_tendon_sim::Material {
                youngs_modulus_pa: 0.0,
                ..moe_tendon_sim::Material::default()
            },
            ..params.clone()
        };
        let err = simulated_layout(&soft).unwrap_err();
        assert!(
            matches!(
                err,
                LabError::Simulation(moe_tendon_sim::SimError::InvalidParameter {
                    name: "youngs_modulus_pa",
                    ..
                })
            ),
            "{err:?}"
        );
        let dir = scratch("simulated");
        let plan = GenPlan {
            trajectories: 2,
            trajectories_per_shard: 2,
            seed: 4,
            machine: 1,
            machines: 1,
        };
        let frames_of = |t| simulated_frames(&params, 4, t);
        let report = generate(
            &plan,
            &dir,
            &layout,
            serde_json::json!({}),
            &frames_of,
            &|_, _| {},
        )
        .unwrap();
        let card = report.card.unwrap();
        assert_eq!(card.totals.trajectories, 2);
        let (l, frames) = moe_io::read_shard(&dir.join(plan.shard_file(0))).unwrap();
        assert_eq!(l, layout);
        assert_eq!(
            frames,
            [frames_of(0).unwrap(), frames_of(1).unwrap()].concat()
        );
        // Every frame carries each finger's net contact force, no longer than the sum of its
        // vertices' force magnitudes, and the presses show in some.
        assert!(card.has_finger_force());
        let mut pressed = 0;
        for f in &frames {
            let forces = f.finger_force_n.as_ref().unwrap();
            let magnitudes = layout.per_finger(&f.contact_force_n, |&v| f64::from(v));
            assert_eq!(forces.len(), magnitudes.len());
            for (force, m) in forces.iter().zip(&magnitudes) {
                let net = force
                    .iter()
                    .map(|&c| f64::from(c).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let total: f64 = m.iter().sum();
                assert!(net <= total * (1.0 + 1e-5) + 1e-9, "{net} > {total}");
                pressed += usize::from(net > 1e-2);
            }
        }
        assert!(pressed > 0, "no frame presses a finger");
        // Frame 0 is the rest hand: its markers are the rest markers.
        let hand = moe_geom::HandModel::preset(params.preset, &params.finger).unwrap();
        let rest = hand.rest_keypoints();
        let m0 = rest.fingers[0][0].unwrap();
        let got = frames[0].markers[0];
        assert!((f64::from(got[0]) - m0.x).abs() < 1e-6 && (f64::from(got[2]) - m0.z).abs() < 1e-6);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
