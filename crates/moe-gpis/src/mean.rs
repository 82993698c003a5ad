//! Mean functions of the GP: the surface's signed distance before any contact is seen.
//!
//! **Sign convention** (used throughout the crate): the SDF is *negative inside* the surface,
//! zero on it and positive outside. The paper's sphere SDF (App. E, Eq. 8) is written
//! `r − ‖p − c‖` (positive inside); we use its negation `‖p − c‖ − r`, which describes the same
//! surface.
//!
//! Three implementations sit behind [`MeanFunction`]: a constant, a sphere fitted to the contacts
//! (App. E.0.1–E.0.2, Eqs. 5–8), and the signed distance to a watertight prior mesh (the task
//! prior of §6.1; docs/design.md: the prior's SDF is the mean, instead of pretraining on a dense grid).

use moe_geom::math::{from_parry, to_parry};
use moe_geom::{Matrix3, Point3, Real, TriMesh, Vector3};
use parry3d_f64::query::{PointQuery, PointQueryWithLocation};
use parry3d_f64::shape::{TriMesh as ParryTriMesh, TriMeshFlags};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::GpisError;
use crate::lbfgs::{LbfgsOptions, minimize_bounded};

/// The prior signed distance `m(x)` of a GPIS (negative inside).
pub trait MeanFunction: Send + Sync + std::fmt::Debug {
    /// `m(p)`.
    fn value(&self, p: &Point3) -> Real;

    /// A Lipschitz constant of `m` (`|m(a) − m(b)| ≤ L‖a − b‖`). Exact signed distances have
    /// `L = 1` (the default); a constant has 0. Used to skip grid regions far from the surface.
    fn lipschitz(&self) -> Real {
        1.0
    }

    /// `∇m(p)` by central differences with a 0.1 mm step (override when known analytically).
    fn gradient(&self, p: &Point3) -> Vector3 {
        let h = 1e-4;
        Vector3::from_fn(|i, _| {
            let mut e = Vector3::zeros();
            e[i] = h;
            (self.value(&(p + e)) - self.value(&(p - e))) / (2.0 * h)
        })
    }

    /// `m` at many points, in parallel.
    fn values(&self, points: &[Point3]) -> Vec<Real> {
        points.par_iter().map(|p| self.value(p)).collect()
    }

    /// `Some(m(p))`, or `None` only when `|m(p)| > max_abs` is certain. Implementations can answer
    /// `None` cheaply for points far from the surface (a bounded nearest-feature search); the
    /// default always evaluates.
    fn value_within(&self, p: &Point3, max_abs: Real) -> Option<Real> {
        let _ = max_abs;
        Some(self.value(p))
    }
}

impl<T: MeanFunction + ?Sized> MeanFunction for Box<T> {
    fn value(&self, p: &Point3) -> Real {
        (**self).value(p)
    }
    fn lipschitz(&self) -> Real {
        (**self).lipschitz()
    }
    fn gradient(&self, p: &Point3) -> Vector3 {
        (**self).gradient(p)
    }
    fn values(&self, points: &[Point3]) -> Vec<Real> {
        (**self).values(points)
    }
    fn value_within(&self, p: &Point3, max_abs: Real) -> Option<Real> {
        (**self).value_within(p, max_abs)
    }
}

impl<T: MeanFunction + ?Sized> MeanFunction for &T {
    fn value(&self, p: &Point3) -> Real {
        (**self).value(p)
    }
    fn lipschitz(&self) -> Real {
        (**self).lipschitz()
    }
    fn gradient(&self, p: &Point3) -> Vector3 {
        (**self).gradient(p)
    }
    fn values(&self, points: &[Point3]) -> Vec<Real> {
        (**self).values(points)
    }
    fn value_within(&self, p: &Point3, max_abs: Real) -> Option<Real> {
        (**self).value_within(p, max_abs)
    }
}

/// A constant mean `m(x) = c` (positive: "outside" far from the data).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ConstantMean {
    /// The constant, metres.
    pub value: Real,
}

impl MeanFunction for ConstantMean {
    fn value(&self, _p: &Point3) -> Real {
        self.value
    }
    fn lipschitz(&self) -> Real {
        0.0
    }
    fn gradient(&self, _p: &Point3) -> Vector3 {
        Vector3::zeros()
    }
}

/// A sphere's signed distance `m(x) = ‖x − c‖ − r`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SphereMean {
    /// Centre `c`.
    pub center: Point3,
    /// Radius `r`, metres.
    pub radius: Real,
}

impl MeanFunction for SphereMean {
    fn value(&self, p: &Point3) -> Real {
        (p - self.center).norm() - self.radius
    }
    fn gradient(&self, p: &Point3) -> Vector3 {
        (p - self.center)
            .try_normalize(1e-300)
            .unwrap_or_else(Vector3::z)
    }
}

impl SphereMean {
    /// Fits a sphere to points by least squares (paper Eq. 5), `min Σ (‖P_i − c‖ − r)²`, with
    /// L-BFGS from the centroid / mean-radius start (Eqs. 6–7). Coordinates are centred and
    /// scaled by the start radius during the solve so that tolerances are unit-free.
    ///
    /// # Errors
    /// [`GpisError::TooFewObservations`] below 4 points, [`GpisError::NonFiniteObservation`],
    /// and [`GpisError::DegenerateSphereFit`] for (nearly) coplanar points or a runaway radius.
    pub fn fit(points: &[Point3]) -> Result<Self, GpisError> {
        if points.len() < 4 {
            return Err(GpisError::TooFewObservations {
                method: "sphere",
                what: "contacts",
                needed: 4,
                got: points.len(),
            });
        }
        crate::observations::check_finite(points, "contact")?;
        let n = points.len() as Real;
        let c0 = Point3::from(points.iter().map(|p| p.coords).sum::<Vector3>() / n);
        let r0 = points.iter().map(|p| (p - c0).norm()).sum::<Real>() / n;
        if r0 <= 0.0 {
            return Err(GpisError::DegenerateSphereFit {
                reason: "all points coincide",
            });
        }
        // Coplanarity: smallest/largest eigenvalue of the scatter matrix.
        let scatter = points.iter().fold(Matrix3::zeros(), |s, p| {
            let d = (p - c0) / r0;
            s + d * d.transpose()
        });
        let eig = scatter.symmetric_eigenvalues();
        let (lo, hi) = (eig.min(), eig.max());
        if lo <= 1e-9 * hi {
            return Err(GpisError::DegenerateSphereFit {
                reason: "points are coplanar or collinear",
            });
        }
        let q: Vec<Vector3> = points.iter().map(|p| (p - c0) / r0).collect();
        let objective = |x: &[Real]| -> Result<(Real, Vec<Real>), GpisError> {
            let c = Vector3::new(x[0], x[1], x[2]);
            let r = x[3];
            let mut f = 0.0;
            let mut g = [0.0; 4];
            for p in &q {
                let d = p - c;
                let dist = d.norm().max(1e-300);
                let e = dist - r;
                f += e * e;
                let gc = -2.0 * e * d / dist;
                g[0] += gc.x;
                g[1] += gc.y;
                g[2] += gc.z;
                g[3] -= 2.0 * e;
            }
            Ok((f, g.to_vec()))
        };
        let cfg = LbfgsOptions {
            max_iterations: 200,
            gradient_tolerance: 1e-10,
            function_tolerance: 1e-14,
            ..LbfgsOptions::default()
        };
        let big = 1e3;
        let report = minimize_bounded(
            objective,
            &[0.0, 0.0, 0.0, 1.0],
            &[-big, -big, -big, 0.0],
            &[big, big, big, big],
            &cfg,
        )?;
        let radius = report.x[3] * r0;
        if !(radius.is_finite() && radius > 0.0 && report.x[3] < 0.5 * big) {
            return Err(GpisError::DegenerateSphereFit {
                reason: "radius diverged (points too flat)",
            });
        }
        Ok(Self {
            center: c0 + Vector3::new(report.x[0], report.x[1], report.x[2]) * r0,
            radius,
        })
    }
}

/// The signed distance to a watertight prior mesh (negative inside), through parry3d-f64's
/// BVH point projection with pseudo-normal inside tests.
#[derive(Clone)]
pub struct MeshSdfMean {
    mesh: TriMesh,
    shape: ParryTriMesh,
}

impl std::fmt::Debug for MeshSdfMean {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshSdfMean")
            .field("vertices", &self.mesh.num_vertices())
            .field("faces", &self.mesh.num_faces())
            .finish_non_exhaustive()
    }
}

impl MeshSdfMean {
    /// Builds the SDF of a closed, outward-oriented mesh.
    ///
    /// # Errors
    /// [`GpisError::NonWatertightPrior`] for an open mesh; [`GpisError::InvalidPriorMesh`] if
    /// parry rejects it.
    pub fn new(mesh: &TriMesh) -> Result<Self, GpisError> {
        if let Err(moe_geom::GeomError::OpenMesh { a, b }) = mesh.require_closed() {
            return Err(GpisError::NonWatertightPrior { a, b });
        }
        // An inward-oriented mesh would flip the sign: orient outward first.
        let mesh = if mesh.signed_volume() < 0.0 {
            mesh.flipped()
        } else {
            mesh.clone()
        };
        let vertices = mesh.vertices().iter().map(to_parry).collect();
        let shape =
            ParryTriMesh::with_flags(vertices, mesh.faces().to_vec(), TriMeshFlags::ORIENTED)
                .map_err(|e| GpisError::InvalidPriorMesh {
                    reason: e.to_string(),
                })?;
        Ok(Self { mesh, shape })
    }

    /// The prior mesh (outward oriented).
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// The closest point of the prior surface to `p`.
    pub fn closest_point(&self, p: &Point3) -> Point3 {
        from_parry(self.shape.project_local_point(to_parry(p), false).point)
    }

    /// The closest point of the prior surface to `p` and the outward unit normal of the
    /// triangle it lies on (for a closest point on an edge or a vertex: one of the triangles
    /// sharing it).
    pub fn closest_point_and_normal(&self, p: &Point3) -> (Point3, Vector3) {
        let (proj, (triangle, _)) = self
            .shape
            .project_local_point_and_get_location(to_parry(p), false);
        let [a, b, c] =
            self.mesh.faces()[triangle as usize].map(|i| self.mesh.vertices()[i as usize]);
        let normal = (b - a).cross(&(c - a)).normalize();
        (from_parry(proj.point), normal)
    }
}

impl MeanFunction for MeshSdfMean {
    fn value(&self, p: &Point3) -> Real {
        let q = to_parry(p);
        let proj = self.shape.project_local_point(q, false);
        let d = (proj.point - q).length();
        if proj.is_inside { -d } else { d }
    }
    fn value_within(&self, p: &Point3, max_abs: Real) -> Option<Real> {
        let q = to_parry(p);
        let proj = self
            .shape
            .project_local_point_with_max_dist(q, false, max_abs)?;
        let d = (proj.point - q).length();
        Some(if proj.is_inside { -d } else { d })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::SeededRng;

    fn sphere_points(c: Point3, r: Real, n: usize, noise: Real, seed: u64) -> Vec<Point3> {
        let mut rng = SeededRng::new(seed);
        (0..n)
            .map(|_| {
                let d = Vector3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
                c + d * (r + noise * rng.normal())
            })
            .collect()
    }

    #[test]
    fn sphere_fit_recovers_centre_and_radius_from_a_cap() {
        let c = Point3::new(0.1, -0.2, 0.05);
        // Only the upper half: the centroid start is biased, the fit must correct it.
        let pts: Vec<Point3> = sphere_points(c, 0.09, 400, 0.0, 1)
            .into_iter()
            .filter(|p| p.z > c.z)
            .collect();
        let s = SphereMean::fit(&pts).unwrap();
        assert!((s.center - c).norm() < 1e-6, "{s:?}");
        assert!((s.radius - 0.09).abs() < 1e-6, "{s:?}");
        assert!(s.value(&c) < 0.0, "negative inside");
    }

    #[test]
    fn sphere_fit_rejects_flat_and_tiny_inputs() {
        let flat: Vec<Point3> = (0..10)
            .map(|i| Point3::new(i as Real * 0.01, (i * i % 7) as Real * 0.01, 0.0))
            .collect();
        assert!(matches!(
            SphereMean::fit(&flat),
            Err(GpisError::DegenerateSphereFit { .. })
        ));
        assert!(matches!(
            SphereMean::fit(&flat[..3]),
            Err(GpisError::TooFewObservations {
                needed: 4,
                got: 3,
                ..
            })
        ));
        let mut nan = sphere_points(Point3::origin(), 1.0, 10, 0.0, 2);
        nan[4].x = Real::NAN;
        assert_eq!(
            SphereMean::fit(&nan),
            Err(GpisError::NonFiniteObservation {
                what: "contact",
                index: 4
            })
        );
    }

    #[test]
    fn mesh_sdf_matches_the_sphere_sdf_and_rejects_open_meshes() {
        let mesh = moe_geom::shapes::icosphere(3, 0.1);
        let sdf = MeshSdfMean::new(&mesh).unwrap();
        for p in [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.05, 0.02, -0.01),
            Point3::new(0.2, 0.1, 0.0),
        ] {
            let exact = p.coords.norm() - 0.1;
            // Faceting error of a level-3 icosphere of radius 0.1 is below 1 mm.
            assert!(
                (sdf.value(&p) - exact).abs() < 1.5e-3,
                "{p}: {}",
                sdf.value(&p)
            );
        }
        let (v, mut f) = mesh.into_parts();
        f.pop();
        let open = TriMesh::new(v, f).unwrap();
        assert!(matches!(
            MeshSdfMean::new(&open),
            Err(GpisError::NonWatertightPrior { .. })
        ));
    }
}
