//! The MOE-Touch pipeline: ties shape estimation, contact estimation and the applications
//! together, and hosts the `moe-touch` command-line tool (`src/main.rs`).
//!
//! Architecture invariant: the pipeline is library code that takes and returns in-memory values
//! (file access goes through `moe-io`); the binary only parses arguments, reads and writes files,
//! and reports.

/// The simulation study of contact estimation (paper Tables 1–2).
pub mod contact_eval;
/// Sharded, resumable, deterministic data set generation.
pub mod datagen;
/// Drawing on images: text, labels that do not overlap, meshes coloured by a value.
pub mod draw;
/// Recording simulated episodes (rendered camera frames with ground truth).
pub mod episode;
/// The crate's error type.
pub mod error;
/// Temporal filters: a Kalman filter on the keypoints, smoothing of the contact map.
pub mod filter;
/// Grasping paper on an unknown incline: press, fit the plane, reorient, press again.
pub mod grasp;
/// Patting a hidden body: simulated pats, contacts from the pipeline, and their error.
pub mod patting;
/// Marker perception: wrist RGB-D frames to tracked keypoints per finger.
pub mod perception;
/// Contact from physics evaluated as tactile sensors are specified (detection, location and
/// force by the finger's true force), beside the paper's metrics.
pub mod physics_eval;
/// The per-frame pipeline: markers, shape, contact, contact points in the world.
pub mod pipeline;
/// Running the pipeline over a recorded episode, with figures against its ground truth.
pub mod run;

pub use error::TouchError;
pub use pipeline::{
    FrameEstimate, PhysicsPipeline, Pipeline, RgbdFrame, StageTimings, StreamEvent,
};
