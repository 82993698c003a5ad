//! The stages the surface pipeline is built from, for tools, tests and benchmarks that run one
//! alone (the pipeline itself is [`reconstruct_surface`](crate::reconstruct_surface) and
//! [`reconstruct`](crate::reconstruct) at the crate root):
//!
//! - **Kernels** ([`Kernel`]): RBF and Matérn 3/2 with their derivatives in the log-parameters.
//! - **Exact GP** ([`ExactGp`], [`log_marginal_likelihood_and_grad`]): Cholesky conditioning of
//!   the residuals with the diagonal-jitter fallback of [`Jitter`](crate::Jitter), and the log
//!   marginal likelihood (paper Eq. 4) with its analytic gradient.
//! - **Sparse GP** ([`SparseGp`], [`farthest_point_indices`]): subset of regressors on
//!   farthest-point inducing points, used beyond
//!   [`GpisConfig::exact_limit`](crate::GpisConfig::exact_limit).
//! - **Fitting** ([`fit_hyper`], [`default_initial`]) by the bounded L-BFGS
//!   [`minimize_bounded`] ([`LbfgsOptions`], [`LbfgsReport`]).
//! - **Query grids** ([`Grid3`], [`MAX_GRID_NODES`]) and **meshing** by marching tetrahedra
//!   ([`extract_surface`]: closed, manifold, outward oriented).
//! - **Screened Poisson** remeshing of a level set ([`poisson_surface`], [`PoissonField`],
//!   [`MIN_POISSON_SAMPLES`]).
//! - **Registration** of the prior to the contacts by ICP ([`register_prior`],
//!   [`best_transform`]).
//! - **The non-probabilistic baseline** ([`nonprobabilistic`]).
//!
//! Their configurations and reports ([`FitConfig`](crate::FitConfig), [`Hyper`](crate::Hyper),
//! [`MeshingOptions`](crate::MeshingOptions), [`PoissonOptions`](crate::PoissonOptions),
//! [`IcpConfig`](crate::IcpConfig), [`NonProbConfig`](crate::NonProbConfig) …) are at the crate
//! root, where the pipeline uses them.

pub use crate::fit::{default_initial, fit_hyper};
pub use crate::gp::{ExactGp, log_marginal_likelihood_and_grad};
pub use crate::grid::{Grid3, MAX_GRID_NODES};
pub use crate::kernel::Kernel;
pub use crate::lbfgs::{LbfgsOptions, LbfgsReport, minimize_bounded};
pub use crate::marching::extract_surface;
pub use crate::nonprob::nonprobabilistic;
pub use crate::poisson::{MIN_POISSON_SAMPLES, PoissonField, poisson_surface};
pub use crate::register::{best_transform, register_prior};
pub use crate::sparse::{SparseGp, farthest_point_indices};
