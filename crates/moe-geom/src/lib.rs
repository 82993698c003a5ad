//! Geometry core of MOE-Touch: the vocabulary types every other crate speaks, and the geometric
//! algorithms they share.
//!
//! Architecture invariant: depends on no other crate of this workspace, does no file IO, and
//! never panics on user data — constructors validate and return [`GeomError`].

/// Procedural heads and arms.
pub mod bodies;
/// The pinhole camera: intrinsics and projection.
pub mod camera;
/// k-d tree queries and Chamfer distances.
pub mod chamfer;
/// Cotangent edge weights and the cotangent Laplacian.
pub mod cotan;
/// The wrist camera's depth image as an observation.
pub mod depth;
/// The crate's error type.
pub mod error;
/// The estimator seams: observation to shape, contact and details.
pub mod estimate;
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
/// The one observation type (markers, tendon pulls, wrist pose, time) and the camera frame.
pub mod observation;
/// Plane fitting by RANSAC with a least-squares refit.
pub mod plane;
/// A small seeded random-number generator (SplitMix64).
pub mod rng;
/// Procedural closed meshes: icospheres, star-shaped surfaces, superquadrics.
pub mod shapes;
/// "Is this the same hand?": hand signatures and differences.
pub mod signature;
/// Edges, one-rings, boundary loops, connected components.
pub mod topology;
/// Rigid transforms named by frame.
pub mod transform;
/// Z-buffer rasterisation through the pinhole camera.
pub mod zbuffer;

/// nalgebra, re-exported so that users name the same version.
pub use nalgebra;

pub use camera::CameraIntrinsics;
pub use chamfer::{Neighbor, PointIndex, bcd, ucd};
pub use cotan::{CotanLaplacian, cotan_weights};
pub use depth::{DepthImage, OwnedDepthImage};
pub use error::GeomError;
pub use estimate::{
    ContactEstimate, ContactEstimator, ContactInput, HandEstimate, HandEstimator, ShapeEstimator,
    StageError, Staged,
};
pub use finger::{
    FingerModel, FingerParams, MarkerLayout, MarkerLayoutPreset, MarkerRow, TendonRoute,
};
pub use hand::{HandFinger, HandKeypoints, HandModel, HandPreset};
pub use instant::{ContactMap, ContactPoint, HandShape, LabelledFrame};
pub use math::{Iso3, Matrix3, Point3, Real, Vector3};
pub use mesh::{Aabb, TriMesh};
pub use observation::{Observation, OwnedObservation, RgbdFrame};
pub use plane::{PlaneFit, RansacConfig, fit_plane_ransac};
pub use rng::SeededRng;
pub use signature::{HandDifference, HandSignature};
pub use topology::{Topology, largest_component};
pub use transform::{
    CameraFromHand, HandFromCamera, HandFromFinger, Transform, WorldFromHand, frame,
};

/// Asserts that `result` is an `Err` matching `pattern` (optionally with an `if` guard), showing
/// the error otherwise: tests use it to check that an error names the offending item.
///
/// The pattern is matched against `&error`, so fields bind by reference; an `Ok` fails without
/// needing `Debug` of the `Ok` type. An optional format string and arguments after the pattern
/// are added to the failure message. The macro evaluates to the error, for further checks.
///
/// ```
/// use moe_geom::{GeomError, cotan::CotanLaplacian, topology::Topology};
///
/// # let mesh = moe_geom::shapes::icosphere(0, 1.0);
/// let topo = Topology::new(&mesh);
/// let e = moe_geom::assert_err!(
///     CotanLaplacian::from_weights(&topo, vec![1.0; 5]),
///     GeomError::LengthMismatch { what: "Laplacian edge weights", got: 5, .. }
/// );
/// assert!(e.to_string().contains("got 5"));
/// // A guard for what a pattern cannot say; a message for loops.
/// for n in [4, 6] {
///     moe_geom::assert_err!(
///         CotanLaplacian::from_weights(&topo, vec![1.0; n]),
///         GeomError::LengthMismatch { got, .. } if *got == n,
///         "with {n} weights"
///     );
/// }
/// ```
#[macro_export]
macro_rules! assert_err {
    ($result:expr, $pattern:pat $(if $guard:expr)? $(,)?) => {
        $crate::assert_err!($result, $pattern $(if $guard)?, "")
    };
    ($result:expr, $pattern:pat $(if $guard:expr)?, $($arg:tt)+) => {
        match $result {
            ::core::result::Result::Err(e) => {
                match &e {
                    $pattern $(if $guard)? => {}
                    #[allow(unreachable_patterns)]
                    other => {
                        let context = ::std::format!($($arg)+);
                        ::core::panic!(
                            "expected Err({}), got Err({:?}){}{}",
                            ::core::stringify!($pattern $(if $guard)?),
                            other,
                            if context.is_empty() { "" } else { ": " },
                            context,
                        )
                    }
                }
                e
            }
            ::core::result::Result::Ok(_) => {
                let context = ::std::format!($($arg)+);
                ::core::panic!(
                    "expected Err({}), got Ok{}{}",
                    ::core::stringify!($pattern $(if $guard)?),
                    if context.is_empty() { "" } else { ": " },
                    context,
                )
            }
        }
    };
}

#[cfg(test)]
mod assert_err_tests {
    use crate::GeomError;

    fn length_mismatch(got: usize) -> Result<(), GeomError> {
        Err(GeomError::LengthMismatch {
            what: "weights",
            expected: 3,
            got,
        })
    }

    #[test]
    fn passes_on_the_matching_variant_and_returns_the_error() {
        let e = crate::assert_err!(
            length_mismatch(2),
            GeomError::LengthMismatch {
                what: "weights",
                got: 2,
                ..
            }
        );
        assert_eq!(e, length_mismatch(2).unwrap_err());
        crate::assert_err!(
            length_mismatch(4),
            GeomError::LengthMismatch { got, .. } if *got > 3
        );
    }

    #[test]
    #[should_panic(expected = "got Err(EmptyPointSet")]
    fn fails_on_another_variant() {
        let r: Result<(), GeomError> = Err(GeomError::EmptyPointSet { what: "weights" });
        crate::assert_err!(r, GeomError::LengthMismatch { .. });
    }

    #[test]
    #[should_panic(expected = "got Err(LengthMismatch")]
    fn fails_on_another_item() {
        crate::assert_err!(length_mismatch(2), GeomError::LengthMismatch { got: 5, .. });
    }

    #[test]
    #[should_panic(expected = "got Err(LengthMismatch")]
    fn fails_when_the_guard_fails() {
        crate::assert_err!(
            length_mismatch(2),
            GeomError::LengthMismatch { what, .. } if *what == "points"
        );
    }

    #[test]
    #[should_panic(expected = "got Ok: cut at 7")]
    fn fails_on_ok_without_debug_of_the_value() {
        struct NoDebug;
        let r: Result<NoDebug, GeomError> = Ok(NoDebug);
        crate::assert_err!(r, GeomError::EmptyPointSet { .. }, "cut at {}", 7);
    }
}
