//! Gaussian-process implicit surfaces (GPIS) for reconstructing occluded surfaces from contacts.
//!
//! Architecture invariant: depends only on `moe-geom`, faer and parry3d-f64. No file IO.

/// Reproducible head and arm benchmark scenes and their evaluation.
pub mod bench_scene;
/// The crate's error type.
pub mod error;
/// Hyper-parameter fitting by maximum marginal likelihood.
pub mod fit;
/// Exact GP regression, marginal likelihood and its gradient.
pub mod gp;
/// Regular query grids.
pub mod grid;
/// Covariance kernels (RBF, Matérn 3/2) and hyper-parameters.
pub mod kernel;
/// A bounded limited-memory BFGS minimiser.
pub mod lbfgs;
/// Marching tetrahedra: closed, manifold iso-surfaces.
pub mod marching;
/// Mean functions: constant, fitted sphere, prior-mesh signed distance.
pub mod mean;
/// The non-probabilistic baseline: nearest-vertex pull and Laplacian smoothing.
pub mod nonprob;
/// SDF observations: contacts, normal offsets, free space, interior points.
pub mod observations;
/// The GPIS posterior and its grid queries (dense and narrow band).
pub mod posterior;
/// Conditioning, grid query, meshing and per-vertex variance.
pub mod reconstruct;
/// ICP registration of the prior mesh to the contacts.
pub mod register;
/// A seeded pseudo-random generator.
pub mod rng;
/// Procedural closed meshes (icospheres, star-shaped surfaces).
pub mod shapes;
/// Subset-of-regressors sparse approximation for many observations.
pub mod sparse;

pub use bench_scene::{SceneConfig, SceneKind, SceneReport, build_scene, evaluate_scene};
pub use error::GpisError;
pub use fit::{FitConfig, FitReport, HyperBounds, fit_hyper};
pub use gp::{ExactGp, Jitter, log_marginal_likelihood_and_grad};
pub use grid::Grid3;
pub use kernel::{Hyper, Kernel, KernelKind};
pub use lbfgs::{LbfgsConfig, LbfgsReport, minimize_bounded};
pub use marching::{MeshingOptions, extract_surface};
pub use mean::{ConstantMean, MeanFunction, MeshSdfMean, SphereMean};
pub use nonprob::{NonProbConfig, nonprobabilistic};
pub use observations::{ObservationKind, Observations};
pub use posterior::{Gpis, ResidualGp};
pub use reconstruct::{
    ConditionReport, GpisConfig, Reconstruction, SurfaceConfig, Timings, bounds_of, condition,
    reconstruct,
};
pub use register::{IcpConfig, IcpReport, RegistrationKind, Similarity, register_prior};
pub use rng::SplitMix64;
pub use sparse::SparseGp;
