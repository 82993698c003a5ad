//! The error type of `moe-arap`.

use moe_geom::{GeomError, Real};

/// Everything that can go wrong when building an ARAP solver or running it on user data.
///
/// Every variant names the offending item (vertex id, list, parameter) so that it can be found in
/// the input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ArapError {
    /// The observation carries no markers, which SR-ARAP estimates the shape from.
    #[error(
        "the observation carries no markers (keypoints): SR-ARAP estimates the shape from them"
    )]
    MissingKeypoints,
    /// The mesh or hand geometry was rejected by `moe-geom` (non-manifold, degenerate, ...).
    /// Fix the input mesh.
    #[error(transparent)]
    Geom(#[from] GeomError),
    /// A configuration value is outside its valid range.
    #[error("ARAP parameter '{name}' = {value} is invalid: {reason}")]
    InvalidConfig {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: Real,
        /// What is required.
        reason: &'static str,
    },
    /// A vertex id (fixed vertex, handle) does not exist in the mesh.
    #[error("{what} vertex {index} is out of range (mesh has {len} vertices)")]
    VertexOutOfRange {
        /// Which list the id came from.
        what: &'static str,
        /// The id.
        index: usize,
        /// Number of mesh vertices.
        len: usize,
    },
    /// A vertex is listed twice where ids must be distinct (for example both fixed and a handle).
    #[error("{what} vertex {vertex} is listed more than once")]
    DuplicateVertex {
        /// Which list the id came from.
        what: &'static str,
        /// The repeated id.
        vertex: usize,
    },
    /// The same vertex was given two different targets. Give each handle vertex one target.
    #[error("vertex {vertex} has two different targets: {first:?} and {second:?}")]
    ConflictingTargets {
        /// The vertex id.
        vertex: usize,
        /// The first target given.
        first: [Real; 3],
        /// The second, different target.
        second: [Real; 3],
    },
    /// A target or initial position has a NaN or infinite coordinate.
    #[error("{what} {index} has a non-finite coordinate")]
    NonFiniteTarget {
        /// Which list (fixed targets, handle targets, keypoints of finger f, initial positions).
        what: &'static str,
        /// Index within that list.
        index: usize,
    },
    /// A keypoint has a NaN or infinite coordinate.
    #[error("keypoint {marker} of finger {finger} has a non-finite coordinate")]
    NonFiniteKeypoint {
        /// Finger index.
        finger: usize,
        /// Marker index within the finger.
        marker: usize,
    },
    /// A list has the wrong length (targets per fixed vertex, initial positions per vertex, ...).
    #[error("{what}: expected {expected} items, got {got}")]
    LengthMismatch {
        /// What was being compared.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A part of the mesh is connected to no fixed vertex through edges of positive weight, so its
    /// position is undetermined. Fix a vertex in every connected component.
    #[error(
        "vertex {vertex} is not connected to any fixed vertex: fix at least one vertex per component"
    )]
    Unanchored {
        /// A vertex of the unanchored part.
        vertex: usize,
    },
    /// The sparse Cholesky factorisation of the reduced system failed.
    #[error("factorising the ARAP system failed: {reason}")]
    Factorization {
        /// What faer reported.
        reason: String,
    },
}
