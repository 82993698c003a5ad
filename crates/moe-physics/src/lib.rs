//! Contact from physics: the finger's FEM model read backwards, from the observed markers and
//! the tendon pulls to the external loads that explain them — where each finger is pressed, how
//! hard, how sure the estimate is — and the dented shape those loads produce.
//!
//! Each finger is modelled with `moe-tendon-sim`'s corotational FEM on its own voxel mesh (not
//! the data generator's) and a material that calibration fits ([`HandMaterial`]). Per finger
//! and frame ([`moe_geom::HandEstimator::estimate`] on a [`PhysicsEstimator`]):
//!
//! 1. **Free finger.** In a stream of observations the finger is simulated from one to the next
//!    under the commanded pulls and gravity, without loads: the shape an untouched finger
//!    would have now, its lag behind the pulls included. A lone observation uses the static
//!    equilibrium.
//! 2. **Test.** `χ²₀ = ‖m − m_free‖² / σ²` over the observed marker coordinates (σ: marker
//!    noise and model error). Below the detection threshold no load can explain enough, and
//!    the free shape is the estimate.
//! 3. **Compliance by reciprocity.** The exact tangent of the static problem (tendons as an
//!    exact rank-one update) is factorised once and solved once per observed coordinate; by
//!    the tangent's symmetry each solution, read at a surface point, is that coordinate's
//!    response to a unit force there — for every candidate place at once.
//! 4. **Search.** Every candidate patch (a disc of the rest surface around a movable vertex)
//!    gets the non-negative force along its admissible directions (the inward normal, or a
//!    friction pyramid) that best explains the residual; the best wins. A second load at
//!    least a set distance away is kept when it lowers χ² by enough.
//! 5. **Gauss–Newton.** The loads are applied in a static solve, the tangent is factorised
//!    again about the loaded shape and the search repeated until the places stop moving; in a
//!    stream the previous frame's loads are the start.
//! 6. **Decision and uncertainty.** The likelihood-ratio statistic of the loads against none
//!    decides; each load reports the standard deviation of its magnitude (Fisher information)
//!    and of its place along and around the finger (the posterior over candidates).
//!
//! Architecture invariant: depends on `moe-geom` and `moe-tendon-sim` (no candle, no file IO).
//! The estimator implements `moe_geom::HandEstimator`: an `Observation` (markers, tendon pulls,
//! wrist pose, time) in; the dented shape, per-vertex contact probability and force, and the
//! loads with their finger reports ([`PhysicsDetails`]) out.

/// Fitting the hand's material to contact-free observations.
mod calibration;
/// Settings and the hand's material.
mod config;
/// The crate's error type.
mod error;
/// The hand-level estimator.
mod estimator;
/// One finger read backwards.
mod finger;
/// One finger's FEM model as the inverse uses it.
mod mechanics;
/// Non-negative least squares.
mod nnls;
/// The Cramér–Rao bound of a press's place.
mod observability;
pub mod testing;

pub use calibration::{CalibrationOptions, CalibrationReport, calibrate};
pub use config::{DepthNoise, DepthSettings, HandMaterial, PhysicsConfig, SEEN_THROUGH_PROBE_M};
pub use error::PhysicsError;
pub use estimator::{
    CONTACT_THRESHOLD, ContactLoad, FingerReport, MAX_PULL_FRACTION, PhysicsDetails,
    PhysicsEstimate, PhysicsEstimator,
};
/// What a fitted material records of its hand (the one signature type, `moe_geom`'s).
pub use moe_geom::HandSignature;
pub use observability::{
    BOUND_REGIONS, BoundOptions, DepthBoundModel, DepthCoverage, PlaceBound, RegionBound, Spread,
    quantile, region_bounds,
};
