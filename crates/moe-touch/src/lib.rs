//! The MOE-Touch runtime: what a robot links to feel contact from a soft hand's deformation.
//!
//! - [`Pipeline`]: one wrist RGB-D frame and an [`Observation`] of what the robot knows (wrist
//!   pose, tendon pulls, time) in; the hand's markers, its deformed shape, contact per vertex,
//!   contact points in the world and the estimator's own details out, with per-stage timings;
//!   frames of a stream carry memory ([`StreamEvent`]). It runs any
//!   [`moe_geom::HandEstimator`]: `Pipeline::physics` (feature `physics`) builds the default
//!   pipeline of the `moe-touch` tool (contact from physics, no model; its details are the
//!   loads), `Pipeline::paper` (feature `dgcnn`) the paper's chain (SR-ARAP, then a trained
//!   network from `pipeline::load_contact_model`).
//! - [`prelude`]: the names a program that runs the pipeline uses, in one `use`.
//! - [`perception`]: red markers in an RGB-D frame to tracked keypoints per finger.
//! - [`filter`]: temporal filters on keypoints and contact maps.
//!
//! # Features
//! - `physics`: the physics estimator (`Pipeline::physics`, `PhysicsPipeline`). It simulates
//!   the fingers with the FEM model of `moe-tendon-sim`, which is therefore in the dependency
//!   tree only with this feature.
//! - `dgcnn`: the paper's chain (`Pipeline::paper`, `PaperPipeline`, `load_contact_model`) and
//!   with it `moe-contact` and candle.
//! - `mcap`: reading and writing MCAP episodes (`moe_record::read_episode`), with the Foxglove
//!   schemas (protobuf).
//! - `cuda`: the contact network on a CUDA device (implies `dgcnn`).
//!
//! Architecture invariant: library code that takes and returns in-memory values (file access
//! goes through `moe-io`); no simulator (without `physics`), no network (without `dgcnn`), no
//! surface reconstruction, command-line parsing or image codecs in the dependency tree. The
//! experiments that score the pipeline live in `moe-lab`, the `moe-touch` binary in
//! `moe-touch-cli`.

/// The crate's error type.
pub mod error;
/// Temporal filters: a Kalman filter on the keypoints, smoothing of the contact map.
pub mod filter;
/// Marker perception: wrist RGB-D frames to tracked keypoints per finger.
pub mod perception;
/// The per-frame pipeline: markers, shape, contact, contact points in the world.
pub mod pipeline;
/// The one loader of each settings file: detector parameters, material, physics settings.
pub mod settings;

pub use error::TouchError;
pub use moe_geom::{Observation, RgbdFrame};
#[cfg(feature = "physics")]
pub use pipeline::PhysicsPipeline;
pub use pipeline::{FrameEstimate, FrameFailure, FrameStage, Pipeline, StageTimings, StreamEvent};
#[cfg(feature = "dgcnn")]
pub use pipeline::{PaperEstimator, PaperPipeline};

// The crates the runtime is built on, so that one `moe-touch` dependency names all of them.
pub use moe_arap;
#[cfg(feature = "dgcnn")]
pub use moe_contact;
pub use moe_geom;
pub use moe_io;
#[cfg(feature = "physics")]
pub use moe_physics;
pub use moe_record;

/// The pipeline guide's Rust example, compiled by `cargo test` in the runtime's own crate (the
/// README's is the `moe-touch-quickstart` crate, which depends on `moe-touch` alone).
#[doc = include_str!("../../../docs/guide-pipeline.md")]
#[cfg(all(doctest, feature = "physics", feature = "dgcnn"))]
pub struct PipelineGuideExample;

/// What a program that runs the pipeline names, in one `use moe_touch::prelude::*;`: the
/// pipeline and its frame estimate, the observation and the camera frame, the hand, its
/// keypoints and shape, the estimator seams, the marker detector and its camera, the contact
/// model loader, and (with the `physics` feature) the physics estimator's material, settings
/// and details.
pub mod prelude {
    pub use crate::error::TouchError;
    pub use crate::perception::{DetectorConfig, MarkerDetector};
    #[cfg(feature = "physics")]
    pub use crate::pipeline::PhysicsPipeline;
    pub use crate::pipeline::{
        FrameEstimate, FrameFailure, FrameStage, Pipeline, StageTimings, StreamEvent,
    };
    #[cfg(feature = "dgcnn")]
    pub use crate::pipeline::{PaperEstimator, PaperPipeline, load_contact_model};
    pub use moe_arap::ShapeConfig;
    #[cfg(feature = "dgcnn")]
    pub use moe_contact::DgcnnEstimator;
    pub use moe_geom::{
        CameraIntrinsics, ContactEstimator, ContactMap, ContactPoint, DepthImage, FingerParams,
        HandEstimate, HandEstimator, HandFromCamera, HandKeypoints, HandModel, HandPreset,
        HandShape, Observation, OwnedObservation, Point3, Real, RgbdFrame, ShapeEstimator, Staged,
        Vector3, WorldFromHand,
    };
    #[cfg(feature = "physics")]
    pub use moe_physics::{
        ContactLoad, FingerReport, HandMaterial, PhysicsConfig, PhysicsDetails, PhysicsEstimator,
    };
    pub use moe_record::{Episode, EpisodeFrame, EpisodeInfo};
}
