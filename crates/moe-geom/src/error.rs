//! The error type of `moe-geom`.

use crate::math::Real;

/// Everything that can go wrong when building or querying geometry from user data.
///
/// Every variant names the offending element so that a user can find it in their file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GeomError {
    /// The mesh has no vertices or no faces. Supply a non-empty mesh.
    #[error("mesh is empty ({vertices} vertices, {faces} faces)")]
    EmptyMesh {
        /// Number of vertices given.
        vertices: usize,
        /// Number of faces given.
        faces: usize,
    },
    /// A vertex has a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteVertex {
        /// Index of the vertex.
        vertex: usize,
    },
    /// A face refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {index}, but the mesh has {len} vertices")]
    FaceIndexOutOfRange {
        /// Index of the face.
        face: usize,
        /// The out-of-range vertex index.
        index: u32,
        /// Number of vertices.
        len: usize,
    },
    /// A face uses the same vertex twice.
    #[error("face {face} uses vertex {index} more than once")]
    RepeatedFaceIndex {
        /// Index of the face.
        face: usize,
        /// The repeated vertex index.
        index: u32,
    },
    /// A face has (numerically) zero area: its vertices are coincident or collinear.
    #[error("face {face} is degenerate (area {area:e})")]
    DegenerateFace {
        /// Index of the face.
        face: usize,
        /// Its area in squared mesh units.
        area: Real,
    },
    /// An edge is shared by more than two faces.
    #[error("edge ({a}, {b}) is non-manifold: it is shared by {faces} faces")]
    NonManifoldEdge {
        /// Smaller vertex index of the edge.
        a: u32,
        /// Larger vertex index of the edge.
        b: u32,
        /// Number of faces that share it.
        faces: usize,
    },
    /// Two faces traverse an edge in the same direction, so their orientations disagree.
    #[error("faces around edge ({a}, {b}) are inconsistently oriented")]
    InconsistentOrientation {
        /// Smaller vertex index of the edge.
        a: u32,
        /// Larger vertex index of the edge.
        b: u32,
    },
    /// The faces around a vertex form more than one fan (a "bow-tie" vertex).
    #[error("vertex {vertex} is non-manifold: its faces form {fans} separate fans")]
    NonManifoldVertex {
        /// Index of the vertex.
        vertex: usize,
        /// Number of separate fans.
        fans: usize,
    },
    /// A vertex is used by no face.
    #[error("vertex {vertex} is isolated (used by no face)")]
    IsolatedVertex {
        /// Index of the vertex.
        vertex: usize,
    },
    /// The mesh must be closed (watertight) but has a boundary edge.
    #[error("mesh is open: edge ({a}, {b}) lies on a boundary")]
    OpenMesh {
        /// Smaller vertex index of the edge.
        a: u32,
        /// Larger vertex index of the edge.
        b: u32,
    },
    /// Two arrays that must have the same length do not.
    #[error("{what}: expected {expected} items, got {got}")]
    LengthMismatch {
        /// What was being compared.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A per-finger array has the wrong length for that finger (for example a deformed shape
    /// of another hand). Supply one item per vertex (or marker) of the finger's mesh.
    #[error("finger {finger}: expected {expected} {what}, got {got}")]
    FingerLengthMismatch {
        /// What was counted.
        what: &'static str,
        /// Finger index.
        finger: usize,
        /// Expected length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A point of one finger has a NaN or infinite coordinate.
    #[error("finger {finger}: {what} {index} has a non-finite coordinate")]
    NonFiniteFingerPoint {
        /// Which point set.
        what: &'static str,
        /// Finger index.
        finger: usize,
        /// Index of the point within the finger.
        index: usize,
    },
    /// A point set that must be non-empty is empty.
    #[error("point set '{what}' is empty")]
    EmptyPointSet {
        /// Which point set.
        what: &'static str,
    },
    /// A point in a point set has a NaN or infinite coordinate.
    #[error("point {index} of '{what}' has a non-finite coordinate")]
    NonFinitePoint {
        /// Which point set.
        what: &'static str,
        /// Index of the point.
        index: usize,
    },
    /// A vertex id (marker, base, handle) is outside the mesh.
    #[error("{what} vertex id {index} is out of range (mesh has {len} vertices)")]
    VertexIdOutOfRange {
        /// Which list the id came from.
        what: &'static str,
        /// The id.
        index: usize,
        /// Number of vertices.
        len: usize,
    },
    /// A vertex id is listed twice where ids must be distinct.
    #[error("{what} vertex id {index} is listed more than once")]
    DuplicateVertexId {
        /// Which list the id came from.
        what: &'static str,
        /// The id.
        index: usize,
    },
    /// Too few points for the fit.
    #[error("'{what}': {got} points, at least {needed} needed")]
    TooFewPoints {
        /// Which point set.
        what: &'static str,
        /// Points needed.
        needed: usize,
        /// Points given.
        got: usize,
    },
    /// The points do not determine what is fitted (all collinear, all coincident).
    #[error("'{what}' are degenerate: {reason}")]
    DegeneratePoints {
        /// Which point set.
        what: &'static str,
        /// What is wrong with them.
        reason: &'static str,
    },
    /// A parameter is outside its valid range.
    #[error("parameter '{name}' = {value} is invalid: {reason}")]
    InvalidParameter {
        /// Parameter name (with its unit).
        name: &'static str,
        /// The value given.
        value: Real,
        /// What is required.
        reason: &'static str,
    },
}
