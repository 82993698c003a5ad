//! The MOE-Touch runtime: what a robot links to feel contact from a soft hand's deformation.
//!
//! - [`Pipeline`]: one wrist RGB-D frame (and the tendon pulls) in, the hand's markers, its
//!   deformed shape, contact per vertex and contact points in the world out, with per-stage
//!   timings; frames of a stream carry memory ([`StreamEvent`]).
//!   `PhysicsPipeline::physics` (feature `physics`) builds the default pipeline of the
//!   `moe-touch` tool (contact from physics, no model); [`Pipeline::new`] takes any shape and
//!   contact estimator, such as SR-ARAP and a trained network
//!   ([`pipeline::load_contact_model`]).
//! - [`perception`]: red markers in an RGB-D frame to tracked keypoints per finger.
//! - [`filter`]: temporal filters on keypoints and contact maps.
//!
//! # Features
//! - `physics`: the physics estimator's pipeline (`PhysicsPipeline`). It simulates the fingers
//!   with the FEM model of `moe-tendon-sim`, which is therefore in the dependency tree only
//!   with this feature.
//! - `cuda`: the contact network on a CUDA device.
//!
//! Architecture invariant: library code that takes and returns in-memory values (file access
//! goes through `moe-io`); no simulator (without `physics`), no command-line parsing, no image
//! codecs in the dependency tree. The experiments that score the pipeline live in `moe-lab`, the `moe-touch`
//! binary in `moe-touch-cli`.

/// The crate's error type.
pub mod error;
/// Temporal filters: a Kalman filter on the keypoints, smoothing of the contact map.
pub mod filter;
/// Marker perception: wrist RGB-D frames to tracked keypoints per finger.
pub mod perception;
/// The per-frame pipeline: markers, shape, contact, contact points in the world.
pub mod pipeline;

pub use error::TouchError;
#[cfg(feature = "physics")]
pub use pipeline::PhysicsPipeline;
pub use pipeline::{FrameEstimate, Pipeline, RgbdFrame, StageTimings, StreamEvent};
