//! The simulator's lower layers, for tools and tests that drive a body directly instead of a
//! [`Scene`](crate::Scene): the volume discretisation ([`voxelize()`], [`TetMesh`]), the
//! barycentric embedding of surfaces and tendon points ([`Embedding`]), the corotational FEM
//! model and its step ([`FemModel`], [`FemModel::step`] with caller-supplied interaction
//! [`Terms`]), a simulated finger gathering tendon and contact terms ([`FingerBody`]), the
//! tendons themselves ([`Tendon`], [`TendonCommand`](crate::TendonCommand)), obstacles posed for a step
//! ([`PosedObstacles`]) and the polar decomposition ([`polar_rotation`], and its
//! inversion-safe extension [`corotation`]).
//!
//! Configuration and results shared with scenes ([`Material`](crate::Material),
//! [`VoxelParams`](crate::VoxelParams), [`TendonParams`](crate::TendonParams),
//! [`ContactParams`](crate::ContactParams), [`BodyState`](crate::BodyState),
//! [`SimError`](crate::SimError)) are at the crate root.

pub use crate::body::{BASE_TOLERANCE_M, FingerBody, FingerInputs};
pub use crate::contact::PosedObstacles;
pub use crate::embedding::{Embedded, Embedding, INSIDE_TOLERANCE};
pub use crate::fem::{
    FemInputs, FemModel, FemWorkspace, Integrator, StepContext, StepReport, Tangent, TermsFn,
};
pub use crate::polar::{corotation, polar_rotation};
pub use crate::tendon::Tendon;
pub use crate::terms::{PairTerm, PointTerm, RankOneTerm, Terms};
pub use crate::tetmesh::TetMesh;
pub use crate::voxelize::{VolumeMesh, VoxelStats, voxelize};
