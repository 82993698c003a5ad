//! The error type of `moe-tendon-sim`.

use moe_geom::{GeomError, Real};

/// Everything that can go wrong when building or running a simulation.
///
/// Every variant names the offending item (parameter, element, node, tendon, step) so that a user
/// can find it in their scene file or mesh.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A parameter is outside its valid range (material, time step, resolution, stiffness …).
    /// Fix the value named by `name`.
    #[error("parameter '{name}' = {value} is invalid: {reason}")]
    InvalidParameter {
        /// Parameter name, with its unit.
        name: &'static str,
        /// The value given.
        value: Real,
        /// What is required.
        reason: &'static str,
    },
    /// A geometric input (surface mesh, finger, hand) was rejected by `moe-geom`: for example an
    /// open or non-manifold surface.
    #[error("invalid geometry: {0}")]
    Geometry(#[from] GeomError),
    /// A tetrahedron of an input tet mesh refers to a node that does not exist.
    #[error("tet {tet} refers to node {index}, but the mesh has {len} nodes")]
    TetIndexOutOfRange {
        /// Index of the tetrahedron.
        tet: usize,
        /// The out-of-range node index.
        index: u32,
        /// Number of nodes.
        len: usize,
    },
    /// A tetrahedron of an input tet mesh has (numerically) zero or negative volume.
    #[error("tet {tet} is degenerate or inverted in the rest shape (volume {volume:e} m³)")]
    DegenerateTet {
        /// Index of the tetrahedron.
        tet: usize,
        /// Its signed volume.
        volume: Real,
    },
    /// The voxelisation of a surface kept no tetrahedron: the resolution is too coarse for the
    /// body. Use a smaller cell size.
    #[error("the surface is too thin for cell size {cell_size_m} m: no tetrahedron kept")]
    EmptyVolume {
        /// The cell size used.
        cell_size_m: Real,
    },
    /// No node of the tet mesh lies on the fixed base, so the body would float away. Check that
    /// the finger's base is at z = 0 in the finger frame.
    #[error("no tet node lies on the fixed base (z ≤ {base_z_m} m in the finger frame)")]
    NoFixedNodes {
        /// The base height used.
        base_z_m: Real,
    },
    /// A tendon route point lies outside the body's tet mesh.
    #[error(
        "tendon {tendon}: route point {point} at ({x:.4}, {y:.4}, {z:.4}) m lies outside the body"
    )]
    TendonOutsideBody {
        /// Index of the tendon in its finger.
        tendon: usize,
        /// Index of the route point.
        point: usize,
        /// Coordinates of the point, finger frame.
        x: Real,
        /// y coordinate.
        y: Real,
        /// z coordinate.
        z: Real,
    },
    /// A finger's tendon schedule is invalid (the source says how).
    #[error("actuation of finger {finger}: {source}")]
    Actuation {
        /// Index of the finger.
        finger: usize,
        /// What is wrong with its schedule.
        #[source]
        source: Box<SimError>,
    },
    /// Two arrays that must have the same length do not (positions, commands, loads …).
    #[error("{what}: expected {expected} items, got {got}")]
    LengthMismatch {
        /// What was being compared.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// An index given by the user (finger, tendon, node) is out of range.
    #[error("{what} index {index} is out of range (there are {len})")]
    IndexOutOfRange {
        /// What was indexed.
        what: &'static str,
        /// The index.
        index: usize,
        /// Number of items.
        len: usize,
    },
    /// An obstacle shape could not be built (empty or degenerate convex hull, invalid triangle
    /// mesh, non-positive size).
    #[error("obstacle {obstacle}: {reason}")]
    InvalidObstacle {
        /// Index of the obstacle in the scene.
        obstacle: usize,
        /// What is wrong.
        reason: String,
    },
    /// A trajectory or schedule is malformed (no keyframes, times not increasing, NaN).
    #[error("{what}: keyframe {index} is invalid: {reason}")]
    InvalidKeyframe {
        /// Which trajectory.
        what: &'static str,
        /// Index of the keyframe.
        index: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// The system matrix of a step was not positive definite (a bug or a wildly unstable
    /// configuration).
    #[error("step {step}, finger {finger}: the system matrix is not positive definite")]
    NotPositiveDefinite {
        /// Step index.
        step: u64,
        /// Finger index.
        finger: usize,
    },
    /// The small dense system of the rank-one (tendon length) penalties' active set was
    /// singular: neither its Cholesky nor its LU factorisation could solve it, so the step
    /// cannot honour those penalties (an infinite or overflowing stiffness on a vanishing
    /// gradient, for example). Check the tendon stiffness and the interaction terms.
    #[error(
        "step {step}, finger {finger}: the system of the rank-one (tendon) penalties is singular"
    )]
    SingularRankOneSystem {
        /// Step index.
        step: u64,
        /// Finger index.
        finger: usize,
    },
    /// An element inside out (det F ≤ 0) at a converged static equilibrium, or one whose
    /// deformation gradient is not finite: the load is far too large for the resolution.
    /// (A dynamic step that inverts an element goes on: the inversion-safe stress pushes it
    /// back out.) Reduce the press depth or the contact stiffness, or refine the mesh.
    #[error("step {step}, finger {finger}: element {element} is inverted (det F = {det_f:e})")]
    InvertedElement {
        /// Step index.
        step: u64,
        /// Finger index.
        finger: usize,
        /// Index of the tetrahedron.
        element: usize,
        /// Determinant of its deformation gradient.
        det_f: Real,
    },
    /// A node position or velocity became NaN or infinite.
    #[error("step {step}, finger {finger}: node {node} has a non-finite position or velocity")]
    NonFinite {
        /// Step index.
        step: u64,
        /// Finger index.
        finger: usize,
        /// Index of the node.
        node: usize,
    },
    /// The kinetic energy exceeded the divergence limit. `node` is the fastest node.
    #[error(
        "step {step}, finger {finger}: kinetic energy {energy_j:e} J exceeds the limit {limit_j:e} J (fastest node {node})"
    )]
    ExplodingEnergy {
        /// Step index.
        step: u64,
        /// Finger index.
        finger: usize,
        /// The fastest node.
        node: usize,
        /// Kinetic energy, joules.
        energy_j: Real,
        /// The configured limit, joules.
        limit_j: Real,
    },
    /// The static (quasi-static) Newton solve did not converge.
    #[error(
        "step {step}, finger {finger}: static solve did not converge in {iterations} iterations (last update {update_m:e} m)"
    )]
    StaticNotConverged {
        /// Step index.
        step: u64,
        /// Finger index.
        finger: usize,
        /// Iterations run.
        iterations: usize,
        /// Size of the last update, metres.
        update_m: Real,
    },
    /// The state does not belong to this scene (wrong number of fingers or nodes).
    #[error("state does not match the scene: {what}")]
    StateMismatch {
        /// What differs.
        what: &'static str,
    },
    /// A run was asked for more steps than the scene's duration covers (the scene's limits
    /// bound its duration, so a run may only be shorter).
    #[error(
        "{steps} steps asked, but the scene's duration covers {covered}: a run may only be \
         shorter (lengthen duration_secs instead)"
    )]
    StepsBeyondScene {
        /// Steps asked for.
        steps: u64,
        /// Steps the scene's duration covers (`Scene::num_steps`).
        covered: u64,
    },
    /// A tendon pull (metres) was asked of a tendon driven by force, whose commanded value is a
    /// tension (newtons): data sets and episodes record pulls only.
    #[error(
        "finger {finger}, tendon {tendon} is force-driven (tension in newtons); only \
         displacement-driven tendons have a pull in metres to record"
    )]
    ForceDriven {
        /// Index of the finger.
        finger: usize,
        /// Index of the tendon in its finger.
        tendon: usize,
    },
}

/// Checks that `value` is finite and strictly positive.
pub(crate) fn require_positive(name: &'static str, value: Real) -> Result<(), SimError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(SimError::InvalidParameter {
            name,
            value,
            reason: "must be finite and positive",
        })
    }
}

/// Checks that `value` is finite and non-negative.
pub(crate) fn require_non_negative(name: &'static str, value: Real) -> Result<(), SimError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(SimError::InvalidParameter {
            name,
            value,
            reason: "must be finite and non-negative",
        })
    }
}
