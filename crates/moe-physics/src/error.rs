//! The error type of `moe-physics`.

use moe_geom::{GeomError, Real};
use moe_tendon_sim::SimError;

/// Everything that can go wrong when building or running the physics estimator. Every variant
/// names the offending item (finger, marker, parameter).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PhysicsError {
    /// A parameter is outside its valid range.
    #[error("parameter '{name}' = {value} is invalid: {reason}")]
    InvalidParameter {
        /// Parameter name, with its unit.
        name: &'static str,
        /// The value given.
        value: Real,
        /// What is required.
        reason: &'static str,
    },
    /// The finger's mechanical model could not be built or solved (the source says how).
    #[error("finger {finger}: {source}")]
    Model {
        /// Finger index.
        finger: usize,
        /// What the simulator reported.
        #[source]
        source: SimError,
    },
    /// A static solve did not converge for this finger and frame: the estimate of that finger
    /// is unavailable for the frame (the stream goes on).
    #[error(
        "finger {finger}: the static solve did not converge in {iterations} iterations \
         (last update {update_m:.3e} m) {stage}"
    )]
    StaticNotConverged {
        /// Finger index.
        finger: usize,
        /// What was being solved (the free shape under the pulls, or the shape under the
        /// estimated loads).
        stage: &'static str,
        /// Iterations run.
        iterations: usize,
        /// Size of the last Newton update, metres.
        update_m: Real,
    },
    /// A load search spent the frame's budget of solves
    /// ([`crate::PhysicsConfig::frame_solve_budget`]). The search keeps the best loads found
    /// before it and reports the finger degraded; this error does not end an estimate.
    #[error("finger {finger}: the load search spent its budget of {budget} solves this frame")]
    FrameBudgetSpent {
        /// Finger index.
        finger: usize,
        /// The budget.
        budget: usize,
    },
    /// A finger has fewer observed markers than the method needs.
    #[error(
        "finger {finger}: {observed} observed markers, the physics estimator needs at least \
         {needed}"
    )]
    TooFewMarkers {
        /// Finger index.
        finger: usize,
        /// Markers observed in the frame.
        observed: usize,
        /// Markers needed.
        needed: usize,
    },
    /// An input does not fit the hand (counts of fingers, markers or tendons).
    #[error("{what}: expected {expected}, got {got}")]
    LengthMismatch {
        /// What was counted.
        what: &'static str,
        /// Expected count.
        expected: usize,
        /// Count given.
        got: usize,
    },
    /// An input does not fit the hand for one finger.
    #[error("finger {finger}: {what}: expected {expected}, got {got}")]
    FingerLengthMismatch {
        /// What was counted.
        what: &'static str,
        /// Finger index.
        finger: usize,
        /// Expected count.
        expected: usize,
        /// Count given.
        got: usize,
    },
    /// A tendon pull no tendon of the hand can take: longer than a quarter of the tendon's
    /// length either way (the generator's are within ±6 mm of an 80 mm tendon).
    #[error(
        "finger {finger}: tendon pull {tendon} = {pull_m} m is out of range (at most {limit_m:.4} m either way)"
    )]
    PullOutOfRange {
        /// Finger index.
        finger: usize,
        /// Tendon index.
        tendon: usize,
        /// The pull, metres.
        pull_m: Real,
        /// The largest pull taken either way, metres.
        limit_m: Real,
    },
    /// A marker further from the finger's base than twice the finger's length: not a marker of
    /// this finger, however it bends (markers in another frame than the hand's, a blob taken
    /// for one). The finger has no estimate in the frame; the others go on.
    #[error(
        "finger {finger}: marker {marker} is {distance_m:.3} m from the finger's base, further than it can reach ({reach_m:.3} m)"
    )]
    MarkerOffFinger {
        /// Finger index.
        finger: usize,
        /// Marker slot.
        marker: usize,
        /// Its distance from the finger's base, metres.
        distance_m: Real,
        /// Twice the finger's length, metres.
        reach_m: Real,
    },
    /// A non-finite input value.
    #[error("finger {finger}: {what} {index} is not finite")]
    NonFinite {
        /// What it is (a marker, a tendon pull).
        what: &'static str,
        /// Finger index.
        finger: usize,
        /// Index within the finger.
        index: usize,
    },
    /// The material file was fitted to another hand: recalibrate on this hand
    /// (`moe-touch calibrate`), or remove its `hand` section to use it anyway.
    #[error(
        "the material was fitted to another hand (this hand's {difference}): calibrate on this \
         hand with `moe-touch calibrate`"
    )]
    MaterialOfAnotherHand {
        /// How this hand differs from the one the material records.
        difference: moe_geom::HandDifference,
    },
    /// A value the estimator needs was not given.
    #[error("the physics estimator needs {what}")]
    Missing {
        /// What is missing.
        what: &'static str,
    },
    /// A geometric input was rejected.
    #[error("invalid geometry: {0}")]
    Geometry(#[from] GeomError),
}

impl PhysicsError {
    /// A geometry parameter's error as this crate's own [`PhysicsError::InvalidParameter`] (for
    /// the settings `moe-geom` checks on the physics estimator's behalf, such as the depth
    /// noise); any other geometry error as [`PhysicsError::Geometry`].
    pub fn from_parameter(error: GeomError) -> Self {
        match error {
            GeomError::InvalidParameter {
                name,
                value,
                reason,
            } => Self::InvalidParameter {
                name,
                value,
                reason,
            },
            other => Self::Geometry(other),
        }
    }

    /// The finger an error is about, when it is about one finger (the estimator then reports it
    /// for that finger and goes on with the others).
    pub fn finger(&self) -> Option<usize> {
        match self {
            Self::Model { finger, .. }
            | Self::StaticNotConverged { finger, .. }
            | Self::FrameBudgetSpent { finger, .. }
            | Self::TooFewMarkers { finger, .. }
            | Self::PullOutOfRange { finger, .. }
            | Self::MarkerOffFinger { finger, .. }
            | Self::FingerLengthMismatch { finger, .. }
            | Self::NonFinite { finger, .. } => Some(*finger),
            _ => None,
        }
    }
}
