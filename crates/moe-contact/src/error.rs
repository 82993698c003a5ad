//! The error type of `moe-contact`.

use moe_geom::GeomError;

/// Everything that can go wrong when building, loading or running a contact estimator.
///
/// Every variant names the offending item (a tensor, a card field, a point, a finger).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ContactError {
    /// The weights are not a readable safetensors file (truncated, garbled, wrong header).
    #[error("weights are not a valid safetensors file: {message}")]
    MalformedWeights {
        /// What the safetensors reader reported.
        message: String,
    },
    /// A tensor the network needs is not in the weights. Export every tensor named in the
    /// model-file section of docs/design.md (`edge1.theta`, ..., `head.2.bias`).
    #[error("weights have no tensor '{name}'")]
    MissingTensor {
        /// The missing tensor's name.
        name: String,
    },
    /// The weights hold a tensor that no layer uses (a different architecture, or a state dict
    /// with extra entries).
    #[error("weights hold a tensor '{name}' that the network does not use")]
    UnexpectedTensor {
        /// The tensor's name.
        name: String,
    },
    /// A tensor has the wrong shape for its layer.
    #[error("tensor '{name}' has shape {got:?}, expected {expected:?}")]
    TensorShape {
        /// The tensor's name.
        name: String,
        /// The shape the architecture needs.
        expected: Vec<usize>,
        /// The shape in the file.
        got: Vec<usize>,
    },
    /// A tensor is not float32 (model files store float32, as PyTorch's default).
    #[error("tensor '{name}' is {got}, expected float32")]
    TensorDtype {
        /// The tensor's name.
        name: String,
        /// The dtype in the file.
        got: String,
    },
    /// A tensor holds a NaN or an infinity.
    #[error("tensor '{name}' holds a non-finite value at flat index {index}")]
    NonFiniteWeight {
        /// The tensor's name.
        name: String,
        /// Flat (row-major) index of the first non-finite value.
        index: usize,
    },
    /// The model card and the weights disagree.
    #[error("model card field '{field}' says {card}, but the weights have {weights}")]
    CardMismatch {
        /// The card field.
        field: &'static str,
        /// What the card says.
        card: String,
        /// What the weights imply.
        weights: String,
    },
    /// A configuration value is out of its range.
    #[error("invalid {field}: {message}")]
    InvalidConfig {
        /// The field.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A point set has fewer points than the neighbourhood size `k`.
    #[error("point set {set} has {points} points, fewer than k = {k}")]
    TooFewPoints {
        /// Index of the point set in the batch.
        set: usize,
        /// Its number of points.
        points: usize,
        /// The neighbourhood size.
        k: usize,
    },
    /// An input point has a NaN or infinite coordinate.
    #[error("point set {set}: point {index} has a non-finite coordinate")]
    NonFinitePoint {
        /// Index of the point set in the batch.
        set: usize,
        /// Index of the point.
        index: usize,
    },
    /// The input has the wrong number of feature channels for the network.
    #[error("the network takes {expected} input channels per point, got {got}")]
    InputWidth {
        /// Channels the first layer takes.
        expected: usize,
        /// Channels given.
        got: usize,
    },
    /// The input features the model needs cannot be made from what was given (for example a
    /// model that takes rest-pose coordinates, run on a bare point cloud).
    #[error("the model's input features ({features}) cannot be made from {given}")]
    UnavailableFeatures {
        /// The card's input features.
        features: String,
        /// What was given instead.
        given: &'static str,
    },
    /// The model was trained on another hand than the one it is asked to run on.
    #[error(
        "the model was trained on the hand '{card_hand}' ({card_vertices:?} vertices per finger); \
         this hand has {hand_vertices:?}{rule}; a model for this hand is trained on its own \
         simulated data (`moe-touch gen-data`, then `moe-touch train`)"
    )]
    HandMismatch {
        /// The card's hand name.
        card_hand: String,
        /// The card's vertices per finger.
        card_vertices: Vec<usize>,
        /// The given hand's vertices per finger.
        hand_vertices: Vec<usize>,
        /// What would fit (per-finger models: fingers of the trained finger's size).
        rule: &'static str,
    },
    /// The model was trained on another finger than the one it is asked to run on (the card's
    /// finger digests do not include this rest mesh's).
    #[error(
        "the model was trained on the finger(s) of '{card_hand}' (rest-mesh digest {card_digests:?}); \
         finger {finger} is another mesh (digest {digest}). A model learns one finger's geometry: \
         generate data for this finger (`moe-touch gen-data --params` with its finger \
         parameters) and train a model on it (`moe-touch train`)"
    )]
    FingerMismatch {
        /// The card's hand name.
        card_hand: String,
        /// The card's finger digests.
        card_digests: Vec<String>,
        /// The finger that does not fit.
        finger: usize,
        /// Its rest mesh's digest.
        digest: String,
    },
    /// A batch has no items, or items of different sizes where one size is needed.
    #[error("invalid batch: {message}")]
    InvalidBatch {
        /// What is wrong.
        message: String,
    },
    /// The hand shape or keypoints do not fit the estimator's hand (see [`GeomError`], which
    /// names the finger and vertex).
    #[error(transparent)]
    Geometry(#[from] GeomError),
    /// The requested device cannot be used.
    #[error("device '{device}' is unavailable: {reason}")]
    DeviceUnavailable {
        /// The device asked for.
        device: String,
        /// Why it cannot be used.
        reason: String,
    },
    /// The model card is not valid JSON of the card's form.
    #[error("model card: {message}")]
    MalformedCard {
        /// What the JSON reader reported.
        message: String,
    },
    /// A tensor operation failed inside candle (an internal error, or memory).
    #[error("tensor operation failed: {message}")]
    Tensor {
        /// candle's message, without its backtrace.
        message: String,
    },
}

impl From<candle_core::Error> for ContactError {
    fn from(e: candle_core::Error) -> Self {
        // candle captures a backtrace into its errors when RUST_BACKTRACE is set; keep the first
        // line, which is the message.
        let text = e.to_string();
        let message = text.lines().next().unwrap_or_default().to_string();
        Self::Tensor { message }
    }
}
