//! The error type of `moe-gpis`.

use moe_geom::{GeomError, Real};

/// Everything that can go wrong when reconstructing a surface from user data.
///
/// Every variant names the offending item (observation index, parameter name, method) so that a
/// user can find it in their input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GpisError {
    /// An observation point or value is NaN or infinite. Remove or repair that row of the input.
    #[error("observation {index} ({what}) has a non-finite coordinate or value")]
    NonFiniteObservation {
        /// Which kind of observation (contact, normal offset, free space, query point).
        what: &'static str,
        /// Index of the observation within its kind.
        index: usize,
    },
    /// The chosen method needs more observations than were given.
    #[error("method '{method}' needs at least {needed} {what}, got {got}")]
    TooFewObservations {
        /// The method or stage that needs them.
        method: &'static str,
        /// What is counted (contacts, observations, interior observations).
        what: &'static str,
        /// How many are needed.
        needed: usize,
        /// How many were given.
        got: usize,
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
    /// A hyper-parameter or configuration value is outside its valid range.
    #[error("parameter '{name}' = {value} is invalid: {reason}")]
    InvalidParameter {
        /// Parameter name (with its unit).
        name: &'static str,
        /// The value given.
        value: Real,
        /// What is required.
        reason: &'static str,
    },
    /// The kernel matrix stayed numerically singular (not positive definite) even after adding
    /// the largest allowed diagonal jitter. Typical causes: duplicated observation points with a
    /// zero noise variance, or a length scale far larger than the data's extent. Raise the noise
    /// variance, remove duplicates, or allow more jitter.
    #[error(
        "kernel matrix of {n} observations is not positive definite even with relative jitter \
         {max_relative_jitter:e} (raise the noise variance or remove duplicate points)"
    )]
    SingularKernel {
        /// Number of observations.
        n: usize,
        /// The largest jitter tried, relative to the mean diagonal.
        max_relative_jitter: Real,
    },
    /// The prior mesh is not watertight, so its signed distance is undefined. Close the holes
    /// (or use the sphere / constant mean).
    #[error("prior mesh is not watertight: edge ({a}, {b}) lies on a boundary")]
    NonWatertightPrior {
        /// Smaller vertex index of the boundary edge.
        a: u32,
        /// Larger vertex index of the boundary edge.
        b: u32,
    },
    /// parry3d rejected the prior mesh when building its signed-distance structure.
    #[error("prior mesh is unusable for signed distances: {reason}")]
    InvalidPriorMesh {
        /// parry's explanation.
        reason: String,
    },
    /// A least-squares sphere could not be fitted: the points are (nearly) coplanar or collinear.
    #[error("sphere fit is degenerate ({reason})")]
    DegenerateSphereFit {
        /// Why the fit failed.
        reason: &'static str,
    },
    /// The implicit surface has no zero crossing inside the query grid, so there is nothing to
    /// mesh. Usually the observations and the mean disagree in sign everywhere; check units.
    #[error("the posterior mean has no zero level set inside the {nx}x{ny}x{nz} grid")]
    EmptySurface {
        /// Grid nodes along x.
        nx: usize,
        /// Grid nodes along y.
        ny: usize,
        /// Grid nodes along z.
        nz: usize,
    },
    /// A normal (of an oriented point given to Poisson reconstruction, or of a contact given
    /// normal offsets) is NaN, infinite or zero. Every oriented point needs a usable outward
    /// direction.
    #[error("normal {index} is not finite or has zero length")]
    InvalidNormal {
        /// Index of the oriented point.
        index: usize,
    },
    /// Screened Poisson reconstruction gave no usable surface: degenerate samples (all points
    /// coincide), a non-finite solution, or a function that does not change sign across the
    /// samples (normals that disagree in orientation).
    #[error("Poisson reconstruction failed: {reason}")]
    PoissonFailed {
        /// What went wrong.
        reason: &'static str,
    },
    /// The method reconstructs from a prior mesh and none was given.
    #[error("method {method} needs a prior mesh")]
    MissingPrior {
        /// The method's report name.
        method: &'static str,
    },
    /// A geometry routine rejected its input (mesh validation, k-d tree, ...).
    #[error(transparent)]
    Geom(#[from] GeomError),
}

/// The most iterations any iterative method of the crate (hyper-parameter fit, ICP,
/// non-probabilistic smoothing) may be asked for.
pub const MAX_ITERATIONS: usize = 10_000;

/// Checks an iteration count against [`MAX_ITERATIONS`].
pub(crate) fn check_iterations(name: &'static str, n: usize) -> Result<(), GpisError> {
    if n > MAX_ITERATIONS {
        return Err(GpisError::InvalidParameter {
            name,
            value: n as Real,
            reason: "at most 10,000 iterations",
        });
    }
    Ok(())
}
