//! Geometry core of MOE-Touch: the vocabulary types every other crate speaks, and the geometric
//! algorithms they share.
//!
//! Architecture invariant: depends on no other crate of this workspace, does no file IO, and
//! never panics on user data — constructors validate and return [`GeomError`].

/// Procedural heads and arms.
pub mod bodies;
/// k-d tree queries and Chamfer distances.
pub mod chamfer;
/// Cotangent edge weights and the cotangent Laplacian.
pub mod cotan;
/// The crate's error type.
pub mod error;
/// The parametric tendon-driven finger.
pub mod finger;
/// Multi-finger hands and their keypoints.
pub mod hand;
/// One instant of a hand: deformed shape, contact map, labelled frame.
pub mod instant;
/// Scalar and linear-algebra aliases, and the seam to parry's glam types.
pub mod math;
/// Validated triangle meshes, welding, areas, normals, bounding boxes.
pub mod mesh;
/// Plane fitting by RANSAC with a least-squares refit.
pub mod plane;
/// A small seeded random-number generator (SplitMix64).
pub mod rng;
/// Procedural closed meshes: icospheres, star-shaped surfaces, superquadrics.
pub mod shapes;
/// Edges, one-rings, boundary loops, connected components.
pub mod topology;
/// Rigid transforms named by frame.
pub mod transform;

/// nalgebra, re-exported so that users name the same version.
pub use nalgebra;

pub use chamfer::{Neighbor, PointIndex, bcd, ucd};
pub use cotan::{CotanLaplacian, cotan_weights};
pub use error::GeomError;
pub use finger::{FingerModel, FingerParams, TendonRoute};
pub use hand::{HandFinger, HandKeypoints, HandModel, HandPreset};
pub use instant::{ContactMap, ContactPoint, HandShape, LabelledFrame, ShapeEstimator};
pub use math::{Iso3, Matrix3, Point3, Real, Vector3};
pub use mesh::{Aabb, TriMesh};
pub use plane::{PlaneFit, RansacConfig, fit_plane_ransac};
pub use rng::SeededRng;
pub use topology::{Topology, largest_component};
pub use transform::{
    CameraFromHand, HandFromCamera, HandFromFinger, Transform, WorldFromHand, frame,
};
