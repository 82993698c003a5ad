//! The error type of the `moe-touch` library.

use moe_io::IoError;

/// Everything that can go wrong in the pipeline library.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TouchError {
    /// Reading or writing a file failed (the error names the file).
    #[error(transparent)]
    Io(#[from] IoError),
    /// A generation plan is inconsistent (zero trajectories, a machine index out of range, a
    /// malformed `--shard` split, ...).
    #[error("invalid generation plan: {reason}")]
    InvalidPlan {
        /// What is wrong.
        reason: String,
    },
    /// A directory given as a data set holds none (no settings file).
    #[error("{}: holds no data set (no {file})", dir.display())]
    NotADataset {
        /// The directory.
        dir: std::path::PathBuf,
        /// The file that is missing.
        file: &'static str,
    },
    /// A data set directory was generated with other settings than the ones given (seed,
    /// trajectories, shard size, layout or randomisation).
    #[error(
        "{}: holds a data set generated with other settings (seed, trajectories, shard size, \
         layout or randomisation); use another directory",
        dir.display()
    )]
    SettingsMismatch {
        /// The directory.
        dir: std::path::PathBuf,
    },
    /// Shards of a data set are missing when its card is written.
    #[error("{}: {} of {total} shards are missing: {missing:?}", dir.display(), missing.len())]
    MissingShards {
        /// The directory.
        dir: std::path::PathBuf,
        /// Indices of the missing shards.
        missing: Vec<u64>,
        /// Number of shards of the data set.
        total: u64,
    },
    /// A shard's trajectories produced no frames.
    #[error("shard {shard} produced no frames")]
    EmptyShard {
        /// Index of the shard.
        shard: u64,
    },
    /// Every draw of one trajectory failed to simulate.
    #[error("trajectory {trajectory}: {draws} draws failed; the last: {source}")]
    Trajectory {
        /// The trajectory id.
        trajectory: u64,
        /// How many draws were tried.
        draws: u64,
        /// The simulator's error of the last draw (it names the step and element).
        #[source]
        source: moe_tendon_sim::SimError,
    },
    /// A simulation failed (the error names the step, finger and element).
    #[error(transparent)]
    Simulation(#[from] moe_tendon_sim::SimError),
    /// Shape estimation failed.
    #[error(transparent)]
    Shape(#[from] moe_arap::ArapError),
    /// A contact model has no card beside its weights.
    #[error("{}: no model card beside the weights (the card carries the input features, their normalisation and the threshold)", path.display())]
    MissingModelCard {
        /// Where the card was looked for.
        path: std::path::PathBuf,
    },
    /// A shape estimator other than SR-ARAP failed.
    #[error("shape estimation: {0}")]
    ShapeEstimation(Box<dyn std::error::Error + Send + Sync>),
    /// Contact estimation failed.
    #[error(transparent)]
    Contact(#[from] moe_contact::ContactError),
    /// The contact estimator of a pipeline failed: its own error, boxed (for the DGCNN and the
    /// KNN baseline a [`moe_contact::ContactError`], which `downcast_ref` recovers).
    #[error("contact estimation: {0}")]
    ContactEstimation(Box<dyn std::error::Error + Send + Sync>),
    /// The physics estimator refused its input or failed.
    #[error(transparent)]
    Physics(#[from] moe_physics::PhysicsError),
    /// A geometric input is malformed.
    #[error(transparent)]
    Geometry(#[from] moe_geom::GeomError),
    /// Surface reconstruction failed.
    #[error(transparent)]
    Surface(#[from] moe_gpis::GpisError),
    /// An image does not have the size the camera intrinsics give.
    #[error("{what}: expected {expected}, got {got}")]
    ImageSize {
        /// Which image and unit.
        what: &'static str,
        /// Size from the intrinsics.
        expected: usize,
        /// Size given.
        got: usize,
    },
    /// A parameter of the pipeline (contact threshold, temporal filter) is out of range.
    #[error("{name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong.
        reason: &'static str,
    },
    /// A marker-detector parameter is out of range.
    #[error("marker detector: {name} = {value}: {reason}")]
    InvalidDetector {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong.
        reason: &'static str,
    },
    /// An evaluation's inputs do not fit together.
    #[error("evaluation: {reason}")]
    InvalidEvaluation {
        /// What is wrong.
        reason: String,
    },
    /// A frame of a stream is not after the previous one (out of order, or a repeated time).
    #[error(
        "frame time {time_secs} s is not after the previous frame's {previous_secs} s: a stream's \
         frames must arrive in time order without repeats (reset the pipeline to start another)"
    )]
    StreamOutOfOrder {
        /// The previous frame's time, seconds.
        previous_secs: f64,
        /// This frame's time, seconds.
        time_secs: f64,
    },
}

/// Formats an error and its causes on one line (`outer: inner: root`), without backtraces: a
/// cause whose text the previous message already includes is left out, so an error that names
/// its source in its own message is not printed twice. Both command-line tools print errors
/// this way.
pub fn one_line(err: &(dyn std::error::Error + 'static)) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut cause = Some(err);
    while let Some(e) = cause {
        let s = e.to_string();
        if parts.last().is_none_or(|prev| !prev.contains(&s)) {
            parts.push(s.lines().next().unwrap_or_default().to_owned());
        }
        cause = e.source();
    }
    parts.join(": ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_names_each_cause_once() {
        let err = TouchError::Trajectory {
            trajectory: 13,
            draws: 4,
            source: moe_tendon_sim::SimError::NonFinite {
                step: 7,
                finger: 0,
                node: 3,
            },
        };
        let line = one_line(&err);
        assert_eq!(line.matches("step 7").count(), 1, "{line}");
        assert!(line.starts_with("trajectory 13: 4 draws failed"), "{line}");
        let wrapped = anyhow::Error::new(err).context("generating shard 2");
        let line = one_line(wrapped.as_ref());
        assert!(
            line.starts_with("generating shard 2: trajectory 13"),
            "{line}"
        );
        assert_eq!(line.matches("step 7").count(), 1, "{line}");
    }
}
