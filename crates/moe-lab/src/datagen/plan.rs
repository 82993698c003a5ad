//! The plan of a run: how many trajectories, how they are grouped into shards, and which shards
//! each machine of an array job produces.

use moe_io::dataset::shard_file_name;
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
