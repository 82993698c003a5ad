//! The error type of the `moe-touch` library.

use moe_io::IoError;

/// Everything that can go wrong in the pipeline library.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TouchError {
    /// Reading or writing a file failed (the error names the file).
    #[error(transparent)]
    Io(#[from] IoError),
    /// A generation plan is inconsistent (zero trajectories, a machine index out of range, ...).
    #[error("invalid generation plan: {reason}")]
    InvalidPlan {
        /// What is wrong.
        reason: String,
    },
    /// Producing the frames of one trajectory failed.
    #[error("trajectory {trajectory}: {message}")]
    Trajectory {
        /// The trajectory id.
        trajectory: u64,
        /// What went wrong (e.g. the simulator's error, which names the step and element).
        message: String,
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
}
