//! The error type of the experiments: what only generating data and running studies can hit,
//! and the runtime's errors unchanged.

use moe_touch::TouchError;

/// Everything that can go wrong in an experiment.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LabError {
    /// The runtime (pipeline, perception, files, estimators) failed; its error unchanged.
    #[error(transparent)]
    Touch(#[from] TouchError),
    /// Surface reconstruction failed.
    #[error(transparent)]
    Surface(#[from] moe_gpis::GpisError),
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
    /// A parameter of an experiment is out of range.
    #[error("{name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong.
        reason: &'static str,
    },
    /// A training run cannot go on (its options, its data sets or its initial model).
    #[error("{reason}")]
    Training {
        /// What is wrong.
        reason: String,
    },
    /// A data set's card does not say what is needed (its generator's parameters, a hand that
    /// fits its layout).
    #[error("data set card: {reason}")]
    DatasetCard {
        /// What is wrong.
        reason: String,
    },
    /// An evaluation's inputs do not fit together.
    #[error("evaluation: {reason}")]
    InvalidEvaluation {
        /// What is wrong.
        reason: String,
    },
    /// A material calibration's source does not give what it needs (the named markers, a
    /// camera the detector can use, readable frames).
    #[error("{reason}")]
    Calibration {
        /// What is wrong, naming the source.
        reason: String,
    },
}

/// A frame the pipeline could not estimate, where an experiment cannot go on without it: its
/// error, through [`LabError::Touch`].
impl From<Box<moe_touch::FrameFailure>> for LabError {
    fn from(f: Box<moe_touch::FrameFailure>) -> Self {
        Self::Touch(f.error)
    }
}

/// The runtime's errors reach an experiment's caller through [`LabError::Touch`], by one path.
macro_rules! through_touch {
    ($($t:ty),*) => {$(
        impl From<$t> for LabError {
            fn from(e: $t) -> Self {
                Self::Touch(TouchError::from(e))
            }
        }
    )*};
}
through_touch!(
    moe_io::IoError,
    moe_arap::ArapError,
    moe_contact::ContactError,
    moe_physics::PhysicsError,
    moe_geom::GeomError
);

#[cfg(test)]
mod tests {
    use super::*;
    use moe_touch::error::one_line;

    #[test]
    fn one_line_names_each_cause_once() {
        let err = LabError::Trajectory {
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
        #[derive(Debug, thiserror::Error)]
        #[error("generating shard 2")]
        struct Context(#[source] LabError);
        let line = one_line(&Context(err));
        assert!(
            line.starts_with("generating shard 2: trajectory 13"),
            "{line}"
        );
        assert_eq!(line.matches("step 7").count(), 1, "{line}");
    }
}
