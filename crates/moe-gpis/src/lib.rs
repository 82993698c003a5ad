//! Gaussian-process implicit surfaces (GPIS) for reconstructing occluded surfaces from contacts
//! (paper §6.1 and App. E): pat a scalp under a wig or an arm under a gown, collect contact
//! points, and recover the hidden surface as the zero level set of a GP posterior over the
//! signed distance function (SDF).
//!
//! # Model
//!
//! The SDF is negative inside, zero on the surface, positive outside (the paper's sphere SDF,
//! Eq. 8, has the opposite sign; we negate it). With a mean function `m` and observations
//! `(x_i, y_i)` — contacts (`y = 0`), points offset along normals (`±d`), free-space (`> 0`) or
//! interior (`< 0`) points — the residuals `r_i = y_i − m(x_i)` get a zero-mean GP prior with an
//! RBF (paper Eq. 2) or Matérn 3/2 kernel and Gaussian noise (Eq. 3):
//!
//! ```text
//! f(x) = m(x) + k(x, X) α,   α = (K + σ_n² I)⁻¹ r,   var f(x) = k(x, x) − k(x, X) (K + σ_n² I)⁻¹ k(X, x)
//! ```
//!
//! Inference is exact by a dense Cholesky factorisation (faer) up to 5 000 observations
//! ([`GpisConfig::exact_limit`]), with a documented diagonal-jitter fallback ([`Jitter`]); beyond,
//! a subset-of-regressors approximation on farthest-point inducing points ([`parts::SparseGp`]), whose
//! error against exact inference is measured in its tests. The hyper-parameters `(σ², l, σ_n²)`
//! maximise the exact log marginal likelihood (Eq. 4) with its analytic gradient, by a bounded
//! L-BFGS on the log-parameters ([`parts::minimize_bounded`], [`parts::fit_hyper`]).
//!
//! # Method decisions
//!
//! - **The prior is the mean** (docs/design.md): the task prior enters as the signed distance of a
//!   watertight prior mesh ([`MeshSdfMean`], parry3d BVH with pseudo-normal inside tests), not
//!   as 125k pretraining grid points; conditioning on the contacts is then one exact solve. The
//!   sphere (fitted by L-BFGS from the centroid / mean-radius start, Eqs. 5–7) and a constant are
//!   the other [`MeanFunction`]s.
//! - **Normal offsets pin the slope.** From contacts alone, position noise makes the residual
//!   look like `−m(x)` near the contacts, and the marginal likelihood prefers a field that cancels
//!   the mean's slope — the posterior SDF flattens into a slab. Adding `±d` points along the
//!   mean's normals at every contact ([`Observations::add_mean_normal_offsets`], `d = 5 mm` in the
//!   benchmark and the CLI) fixes this; the fitted noise then matches the contact noise. `d` must
//!   stay well below the body's half-thickness (the inner point must remain inside): on the
//!   15 mm-thick arm, 5 mm gives 0.85 mm UCD and 20 mm gives 5.8 mm.
//! - **Meshing** is marching tetrahedra (Freudenthal split of every cell) with vertices welded
//!   per grid edge: always closed, manifold and outward oriented ([`parts::extract_surface`]); no ambiguous
//!   cases. The paper's final screened Poisson reconstruction is an option
//!   ([`Mesher::Poisson`], [`parts::poisson_surface`]): the `poisson_reconstruction` crate solves for an
//!   indicator from the marching-tetrahedra vertices and normals; its value, calibrated to a
//!   signed distance, replaces the posterior mean at grid nodes within one octree cell of the
//!   surface, and the same marching tetrahedra mesh it (the crate's marching cubes can leave
//!   cracks), so the result is closed too; an unconverged solve is reported, not meshed. It is
//!   not the default: it costs seconds (the crate's solve grows ~8× per octree level) and does
//!   not beat marching tetrahedra on the head benchmark (the figures are in
//!   docs/results.md).
//! - **Fast grid queries**: the RBF residual is separable over the axes, so its value at all
//!   `64³` nodes is one matrix product; the expensive prior SDF is evaluated exactly only in a
//!   certified narrow band around the zero level set, giving the same mesh as a dense evaluation
//!   ([`Gpis::grid_values_for_meshing`]).
//! - **Baselines**: the non-probabilistic method moves the prior vertices nearest to the contacts
//!   onto them and smooths with a normalised cotangent Laplacian filter ([`parts::nonprobabilistic`]); GP with a
//!   sphere mean. Optional ICP registration (rigid or similarity, point-to-plane with a Gaussian
//!   pose prior by default) of the prior ([`parts::register_prior`], [`PosePrior`]).
//!
//! The benchmark of [`bench_scene`] (procedural heads and 2:20:1 arms, patting contacts, UCD to
//! the ground truth) is run by `moe-touch eval surface`.
//!
//! Architecture invariant: depends only on `moe-geom`, faer, parry3d-f64, poisson_reconstruction,
//! rayon and serde. No file IO: observations, meshes and grids come in and go out as values.

// The surface pipeline's API is re-exported at the root; its stages, for tools, tests and
// benchmarks that run one alone, are gathered in `parts`; the benchmark is the separate
// namespace `bench_scene`. Every item has one public path.

pub mod bench_scene;
// The crate's error type.
mod error;
// Hyper-parameter fitting by maximum marginal likelihood.
mod fit;
// Exact GP regression, marginal likelihood and its gradient.
mod gp;
// Regular query grids.
mod grid;
// Covariance kernels (RBF, Matérn 3/2) and hyper-parameters.
mod kernel;
// A bounded limited-memory BFGS minimiser.
mod lbfgs;
// Marching tetrahedra: closed, manifold iso-surfaces.
mod marching;
// Mean functions: constant, fitted sphere, prior-mesh signed distance.
mod mean;
// The non-probabilistic baseline: nearest-vertex pull and Laplacian smoothing.
mod nonprob;
// SDF observations: contacts, normal offsets, free space, interior points.
mod observations;
pub mod parts;
// Screened Poisson surface reconstruction of the level-set mesh (paper §6.1), meshed crack-free.
mod poisson;
// The GPIS posterior and its grid queries (dense and narrow band).
mod posterior;
// Conditioning, grid query, meshing and per-vertex variance.
mod reconstruct;
// ICP registration of the prior mesh to the contacts.
mod register;
// Subset-of-regressors sparse approximation for many observations.
mod sparse;
// One entry point for every reconstruction method.
mod surface;

pub use error::{GpisError, MAX_ITERATIONS};
pub use fit::{FitConfig, FitReport, HyperBounds};
pub use gp::Jitter;
pub use kernel::{Hyper, KernelKind};
pub use marching::MeshingOptions;
pub use mean::{ConstantMean, MeanFunction, MeshSdfMean, SphereMean};
pub use nonprob::NonProbConfig;
pub use observations::{ObservationKind, Observations};
pub use poisson::PoissonOptions;
pub use posterior::{Gpis, ResidualGp};
pub use reconstruct::{
    ConditionReport, GpisConfig, MAX_EXACT_OBSERVATIONS, Mesher, ReconstructOptions,
    Reconstruction, Timings, bounds_of, condition, reconstruct,
};
pub use register::{IcpConfig, IcpMetric, IcpReport, PosePrior, RegistrationKind, Similarity};
pub use surface::{
    PreparedMean, PreparedMeanReport, SurfaceMethod, SurfaceOptions, SurfacePosterior,
    SurfaceResult, condition_surface, prepare_mean, query_bounds, reconstruct_surface,
};
