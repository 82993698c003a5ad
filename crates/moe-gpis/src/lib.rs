//! Gaussian-process implicit surfaces (GPIS) for reconstructing occluded surfaces from contacts.
//!
//! Architecture invariant: depends only on `moe-geom`, faer and parry3d-f64. No file IO.

/// The crate's error type.
pub mod error;
/// Hyper-parameter fitting by maximum marginal likelihood.
pub mod fit;
/// Exact GP regression, marginal likelihood and its gradient.
pub mod gp;
/// Covariance kernels (RBF, Matérn 3/2) and hyper-parameters.
pub mod kernel;
/// A bounded limited-memory BFGS minimiser.
pub mod lbfgs;
/// Mean functions: constant, fitted sphere, prior-mesh signed distance.
pub mod mean;
/// A seeded pseudo-random generator.
pub mod rng;
/// Procedural closed meshes (icospheres, star-shaped surfaces).
pub mod shapes;

pub use error::GpisError;
pub use fit::{FitConfig, FitReport, HyperBounds, fit_hyper};
pub use gp::{ExactGp, Jitter, log_marginal_likelihood_and_grad};
pub use kernel::{Hyper, Kernel, KernelKind};
pub use lbfgs::{LbfgsConfig, LbfgsReport, minimize_bounded};
pub use mean::{ConstantMean, MeanFunction, MeshSdfMean, SphereMean};
pub use rng::SplitMix64;
