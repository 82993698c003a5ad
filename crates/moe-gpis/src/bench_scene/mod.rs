//! A reproducible benchmark of occluded-surface reconstruction (paper §6.1, Table 3): procedural
//! heads and arms, patting contacts, and the UCD of every method to the ground truth.
//!
//! **Heads.** A skull-like family: an ellipsoid (half-width `a` along x, half-length `b` along y
//! towards the face, half-height `c` along z up) modulated by a flatter forehead, an occipital
//! bulge, a jaw/neck taper below the equator and six random smooth bumps (Gaussian in the
//! direction, a few millimetres high). Every parameter is drawn from a seeded distribution around
//! adult head dimensions (breadth ≈ 152 mm, length ≈ 192 mm), so two seeds give two plausible,
//! different people: one is the ground truth, another the prior. Every member is cropped at the
//! same level below the skull ([`moe_geom::bodies::NECK_CROP_DEPTH`]), as the heads of a shape
//! data set are: the flat cut is an artefact of the crop, and a per-person crop level would put
//! a centimetre-scale error on the cut disk that no contact can correct.
//!
//! **Arms.** The paper's elongated 2:20:1 case: an ellipsoid of half-axes 30 × 300 × 15 mm whose
//! cross-section is modulated along the length (wrist, forearm bulge, elbow, upper arm) with
//! seeded amplitudes.
//!
//! **Contacts** are sampled in patches a hand can pat — top, back and sides of the head (not the
//! face); top and outer side along the arm — exactly on the ground truth, plus isotropic Gaussian
//! noise (1 mm by default).
//!
//! **Metric.** UCD from the reconstruction's vertices to the ground-truth *surface* (exact
//! point-to-triangle distance through parry, so the truth's tessellation does not bias it), in mm.
//!
//! By concern: building the scenes ([`build_scene`], `scene.rs`), scoring every method on one
//! scene ([`evaluate_scene`], `evaluate.rs`) and summarising a family of scenes
//! ([`evaluate_family`], `family.rs`).

mod evaluate;
mod family;
mod scene;

pub use evaluate::{
    MeshSink, MethodResult, SceneReport, evaluate_scene, evaluate_scene_with, ucd_to_surface_mm,
};
pub use family::{FamilyReport, MethodSummary, Spread, evaluate_family};
pub use scene::{BenchScene, BenchSceneConfig, SceneKind, build_scene};
