//! Tetrahedral corotational FEM simulation of tendon-driven soft fingers pressed against rigid
//! obstacles: the source of training data and ground truth (paper §4.3.1).
//!
//! Architecture invariant: depends only on `moe-geom`, faer and parry3d-f64. No file IO; scene
//! files are parsed by `moe-io`, and results are returned as in-memory values.

/// A simulated finger: tet mesh, fixed base, embedded surface and tendons.
pub mod body;
/// Penalty contact, friction and contact labels.
pub mod contact;
/// Linear embedding of points in tetrahedra.
pub mod embedding;
/// The crate's error type.
pub mod error;
/// Corotational elasticity, mass, damping and the implicit step.
pub mod fem;
/// The sparse system pattern and its Cholesky factorisation.
mod linsys;
/// Material parameters.
pub mod material;
/// Rigid obstacles from parry3d shapes.
pub mod obstacle;
/// Polar decomposition.
pub mod polar;
/// Hand-level scenes with explicit state.
pub mod scene;
/// Tendons: embedded cables driven by displacement or force.
pub mod tendon;
/// Interaction terms (forces at embedded points, couplings, rank-one penalties).
pub mod terms;
/// Tetrahedral meshes.
pub mod tetmesh;
/// Pose and actuation keyframes.
pub mod trajectory;
/// Surface-to-volume discretisation.
pub mod voxelize;

pub use body::{BASE_TOLERANCE_M, FingerBody, FingerInputs};
pub use contact::{ContactParams, PosedObstacles, contact_labels, surface_distances};
pub use embedding::{Embedded, Embedding};
pub use error::SimError;
pub use fem::{FemModel, FemWorkspace, Integrator, StepContext, StepReport, TermsFn};
pub use material::Material;
pub use obstacle::{Obstacle, ObstacleConfig, ObstacleShape, SignedDistance};
pub use scene::{
    BodyState, FingerFrame, Frame, HandConfig, Scene, SceneConfig, SimState, SolverConfig,
    SolverMode, StepInfo,
};
pub use tendon::{Tendon, TendonCommand, TendonParams, TendonState};
pub use terms::{PairTerm, PointTerm, RankOneTerm, Terms};
pub use tetmesh::TetMesh;
pub use trajectory::{
    ActuationKeyframe, ActuationMode, ActuationSchedule, PoseKeyframe, PoseTrajectory,
};
pub use voxelize::{VolumeMesh, VoxelParams, VoxelStats, voxelize};
