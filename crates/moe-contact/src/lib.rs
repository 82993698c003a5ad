//! Contact estimation on deformed soft-finger meshes.
//!
//! The estimator seam, [`moe_geom::ContactEstimator`], lives in `moe-geom` beside the shape
//! estimator's, so that an estimator that needs no network (a physical one) does not depend on
//! candle: it takes a hand's observation ([`moe_geom::ContactInput`]: the deformed shape and,
//! where the estimator needs them, keypoints and tendon pulls) and returns a
//! [`moe_geom::ContactEstimate`], whose [`moe_geom::ContactMap`] gives per vertex the probability
//! that it touches the world. This crate holds its learned and baseline implementations. The
//! DGCNN of the paper (§4.3.2, App. D) is [`Dgcnn`], a candle module with fused CPU kernels (a
//! partial-selection kNN and EdgeConv reductions that never form the per-edge tensor), and
//! [`DgcnnEstimator`] puts it behind the trait for one hand; [`KnnIndex`] is the paper's
//! nearest-keypoints baseline behind the same trait. Both also estimate through `&self`
//! (`estimate_map`, and the DGCNN's batched `estimate_batch`), so that evaluations run them on
//! many frames at once. [`Trainer`] trains the network on labelled point sets in memory
//! ([`TrainingSets`]), with checkpoints that resume to the same weights.
//!
//! # Example
//!
//! Contact on one finger from its rest mesh alone (no hand model or markers): a model's files
//! as bytes, the finger's deformed vertices in, a probability per vertex out.
//! `cargo run -p moe-contact --example own_finger` runs the shipped model this way.
//!
//! ```
//! use moe_contact::{DgcnnConfig, DgcnnEstimator, FeatureFrame, ModelCard, ModelWeights, PointSet};
//! use moe_geom::{FingerModel, FingerParams};
//!
//! // Stand-ins for `std::fs::read("NAME.safetensors")` and the card `NAME.json` of a model
//! // trained for this finger: a small seeded per-finger network.
//! let mut card = ModelCard::new(DgcnnConfig { k: 8, edge_widths: [8, 16, 32], head_widths: [16, 8], ..DgcnnConfig::default() });
//! card.architecture.input.point_set = PointSet::PerFinger;
//! card.architecture.input.frame = FeatureFrame::Finger;
//! let channels = card.architecture.input.channels();
//! let weights = ModelWeights::seeded(&card.architecture, channels, 1)?.to_bytes()?;
//!
//! let finger = FingerModel::from_params(&FingerParams { vertex_budget: 200, ..FingerParams::default() })?;
//! let rest = finger.mesh(); // your finger's rest mesh (finger frame, metres)
//! let model = DgcnnEstimator::finger_from_bytes(&weights, &card.to_json()?, rest)?;
//! let p = model.finger_map(rest.vertices())?; // the deformed vertices, same order
//! assert_eq!(p.len(), rest.num_vertices());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Architecture invariant: this is the only crate that depends on candle. It takes and returns
//! in-memory values (shapes in the hand frame, model-file bytes, per-vertex probabilities) and
//! does no file IO; files are read and written by the caller. It depends on `moe-geom` for
//! the vocabulary types and on nothing else of this workspace.

/// The model card: what the weights are, which finger they fit, how they were made.
pub mod card;
/// The architecture and its input features.
pub mod config;
/// Local deformation measures (an input feature).
mod deformation;
/// Choosing the device.
pub mod device;
/// The crate's error type.
pub mod error;
/// The DGCNN behind the contact-estimator seam, and its input features.
pub mod estimator;
/// The KNN baselines.
pub mod knn;
/// Contact metrics: BCD, UCD, misses, false alarms, pooled per-vertex scores.
pub mod metrics;
/// The network.
pub mod network;
/// Custom CPU kernels (kNN selection, EdgeConv reductions).
mod ops;
/// Safetensors reading and writing shared by the crate's files.
mod tensor_file;
/// Training on labelled point sets in memory.
pub mod train;
/// Model files.
pub mod weights;

/// candle, re-exported so that users name the same version.
pub use candle_core;
pub use candle_nn;

pub use card::{
    CardDataSource, CardDataset, CardHand, CardMetrics, CardTraining, EpochRecord, ModelCard,
};
pub use config::{
    Aggregation, DgcnnConfig, FeatureFrame, InputFeature, InputSpec, Normalisation, PointSet,
};
pub use device::{DeviceKind, open_device};
pub use error::ContactError;
pub use estimator::{DgcnnEstimator, FeatureBuilder};
pub use knn::{KnnIndex, KnnMatch};
pub use metrics::{ContactMetrics, ContactReport};
pub use network::{
    Dgcnn, ForwardOutput, ForwardTimings, Mode, contact_probability, tensor_names, tensor_shapes,
};
pub use train::{
    Checkpoint, Confusion, Evaluation, OptimizerConfig, THRESHOLDS, TrainConfig, Trainer,
    TrainingSets, evaluate, evaluation_of, predict, weighted_cross_entropy,
};
pub use weights::ModelWeights;
