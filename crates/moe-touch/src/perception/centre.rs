//! The centre of a marker from the camera-frame points of its red pixels.
//!
//! A painted marker is the patch of the finger surface within the marker radius of its vertex.
//! The plain centroid of the patch's points lies *inside* the surface (a curved patch's centroid is below
//! its apex: for a marker of radius a on a cylinder of radius R, by about a²/(8R)),
//! and the camera samples the patch unevenly (fewer pixels where it is seen obliquely). The
//! surface-fit centre corrects both: it fits a quadric height field to the patch in its own
//! principal frame, takes the centroid of the patch *area* (each pixel weighted by the surface
//! area it sees, `z²·cos α / cos θ`), and puts the centre on the fitted surface there.
//!
//! Where part of the patch is hidden — beyond the finger's silhouette when the marker is seen
//! nearly edge-on — no weighting recovers the missing part: the tip markers, seen some 80° from
//! their normal by the wrist camera, keep an error of about 0.5 mm (noise-free), against 0.8 mm
//! for the plain centroid.

use moe_geom::nalgebra::{Matrix3, Matrix6, SymmetricEigen, Vector6};
use moe_geom::{Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

/// How a cluster's centre is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CentreMethod {
    /// The mean of the cluster's points (biased toward the inside of a curved marker).
    Centroid,
    /// Area-weighted centre on a quadric fitted to the patch (see the module documentation).
    #[default]
    SurfaceFit,
}

/// Smallest `cos θ` used in the area weights: a pixel seen more obliquely counts as this.
const MIN_COS_VIEW: Real = 0.03;

/// Mean of `points` (not empty).
pub(super) fn centroid(points: &[Point3]) -> Point3 {
    let n = points.len() as Real;
    Point3::from(points.iter().map(|p| p.coords).sum::<Vector3>() / n)
}

/// The centre of a marker whose visible points, in the camera frame (camera at the origin),
/// are `points`. Falls back to the centroid when the points do not span a surface.
pub(super) fn marker_centre(points: &[Point3], method: CentreMethod) -> Point3 {
    let c = centroid(points);
    if method == CentreMethod::Centroid || points.len() < 12 {
        return c;
    }
    surface_fit(points).unwrap_or(c)
}

/// A weighted quadric height field over a patch: centre, principal frame (normal toward the
/// camera), coefficients on coordinates divided by `scale`.
struct PatchFit {
    centre: Point3,
    t1: Vector3,
    t2: Vector3,
    n: Vector3,
    beta: Vector6<Real>,
    scale: Real,
}

impl PatchFit {
    /// Weighted principal frame and least-squares h = β0 + β1 a + β2 b + β3 a² + β4 ab + β5 b².
    fn new(points: &[Point3], weights: &[Real]) -> Option<Self> {
        let sw: Real = weights.iter().sum();
        if sw.is_nan() || sw <= 0.0 {
            return None;
        }
        let centre = Point3::from(
            points
                .iter()
                .zip(weights)
                .map(|(p, w)| p.coords * *w)
                .sum::<Vector3>()
                / sw,
        );
        let mut cov = Matrix3::zeros();
        for (p, w) in points.iter().zip(weights) {
            let d = p - centre;
            cov += d * d.transpose() * *w;
        }
        let eig = SymmetricEigen::new(cov);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        // Degenerate spread (a line of pixels): no surface to fit.
        if eig.eigenvalues[order[1]] <= 1e-6 * eig.eigenvalues[order[0]].max(Real::MIN_POSITIVE) {
            return None;
        }
        let t1: Vector3 = eig.eigenvectors.column(order[0]).into();
        let t2: Vector3 = eig.eigenvectors.column(order[1]).into();
        let mut n: Vector3 = eig.eigenvectors.column(order[2]).into();
        if n.dot(&centre.coords) > 0.0 {
            n = -n;
        }
        let local = |p: &Point3| {
            let d = p - centre;
            (d.dot(&t1), d.dot(&t2), d.dot(&n))
        };
        let scale = points
            .iter()
            .map(|p| {
                let (a, b, _) = local(p);
                a.abs().max(b.abs())
            })
            .fold(0.0, Real::max)
            .max(1e-9);
        let mut ata = Matrix6::zeros();
        let mut atb = Vector6::zeros();
        for (p, w) in points.iter().zip(weights) {
            let (a, b, h) = local(p);
            let (a, b) = (a / scale, b / scale);
            let row = Vector6::new(1.0, a, b, a * a, a * b, b * b);
            ata += row * row.transpose() * *w;
            atb += row * (h * *w);
        }
        let beta = ata.cholesky()?.solve(&atb);
        Some(Self {
            centre,
            t1,
            t2,
            n,
            beta,
            scale,
        })
    }

    /// Unit surface normal at point `p` of the patch.
    fn normal_at(&self, p: &Point3) -> Vector3 {
        let d = p - self.centre;
        let (a, b) = (d.dot(&self.t1) / self.scale, d.dot(&self.t2) / self.scale);
        let beta = &self.beta;
        let grad_a = (beta[1] + 2.0 * beta[3] * a + beta[4] * b) / self.scale;
        let grad_b = (beta[2] + beta[4] * a + 2.0 * beta[5] * b) / self.scale;
        (self.n - self.t1 * grad_a - self.t2 * grad_b).normalize()
    }
}

fn surface_fit(points: &[Point3]) -> Option<Point3> {
    // Pass 1: an unweighted fit gives every pixel's surface normal, hence the area it sees: a
    // pixel at depth z, `α` off the optical axis, seeing a surface at `θ` from its normal
    // covers z²·cos α / cos θ (up to the constant 1/f²).
    let first = PatchFit::new(points, &vec![1.0; points.len()])?;
    let weights: Vec<Real> = points
        .iter()
        .map(|p| {
            let ray = p.coords.normalize();
            let cos_view = first.normal_at(p).dot(&ray).abs().max(MIN_COS_VIEW);
            p.z * p.z * ray.z.abs() / cos_view
        })
        .collect();
    // Pass 2: the area-weighted fit. Its centre is the patch's area centroid, which lies on
    // the patch's symmetry axis (the normal at the marker vertex), so the fitted surface
    // meets that axis at the vertex: β0 along the weighted normal.
    let fit = PatchFit::new(points, &weights)?;
    let centre = fit.centre + fit.n * fit.beta[0];
    moe_geom::math::is_finite_point(&centre).then_some(centre)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What a pinhole camera at the origin (focal length 380 px, looking along +z) sees of a
    /// marker of radius `a` painted on a cylinder of radius `r` (axis along y through
    /// `axis_point`) around the surface point at angle `psi` from the cylinder's camera-facing
    /// direction: the marker vertex and the visible painted points, one per pixel.
    fn seen_marker(r: Real, a: Real, axis_point: Point3, psi: Real) -> (Point3, Vec<Point3>) {
        let f = 380.0;
        let toward_camera = Vector3::new(-axis_point.x, 0.0, -axis_point.z).normalize();
        let side = Vector3::y().cross(&toward_camera);
        let vertex = axis_point + (toward_camera * psi.cos() + side * psi.sin()) * r;
        let (u0, v0) = (f * vertex.x / vertex.z, f * vertex.y / vertex.z);
        let mut out = Vec::new();
        let half = (2.0 * a * f / vertex.z).ceil() as i32 + 2;
        for i in -half..=half {
            for j in -half..=half {
                let d = Vector3::new(
                    (u0.round() + Real::from(i)) / f,
                    (v0.round() + Real::from(j)) / f,
                    1.0,
                );
                // Ray–cylinder: |(t d − c) projected off y|² = r².
                let (dx, dz) = (d.x, d.z);
                let (cx, cz) = (axis_point.x, axis_point.z);
                let qa = dx * dx + dz * dz;
                let qb = -2.0 * (dx * cx + dz * cz);
                let qc = cx * cx + cz * cz - r * r;
                let disc = qb * qb - 4.0 * qa * qc;
                if disc < 0.0 {
                    continue;
                }
                let t = (-qb - disc.sqrt()) / (2.0 * qa);
                let p = Point3::from(d * t);
                if (p - vertex).norm() <= a {
                    out.push(p);
                }
            }
        }
        (vertex, out)
    }

    #[test]
    fn the_surface_fit_removes_the_centroid_bias_of_a_curved_marker() {
        // A 2.5 mm marker on a 9 mm finger 6 cm away, seen head-on and at 40° and 60° from its
        // normal (all of it in view: the silhouette is 82° round the finger): the centroid sits behind the painted vertex (about a²/(8R) = 0.09 mm head-on)
        // and, obliquely, toward the side nearer the camera; the fitted centre is on it.
        let (r, a) = (0.009, 0.0025);
        for psi in [0.0, 40f64.to_radians(), 60f64.to_radians()] {
            let (vertex, pts) = seen_marker(r, a, Point3::new(0.0, 0.0, 0.069), psi);
            assert!(pts.len() > 100, "{} pixels", pts.len());
            let plain = marker_centre(&pts, CentreMethod::Centroid);
            let fit = marker_centre(&pts, CentreMethod::SurfaceFit);
            let bias = (plain - vertex).norm();
            let err = (fit - vertex).norm();
            assert!(bias > 7e-5, "psi {psi}: centroid bias {bias}");
            assert!(
                err < 0.1 * bias,
                "psi {psi}: fit error {err} vs centroid {bias}"
            );
        }
    }

    #[test]
    fn degenerate_clusters_fall_back_to_the_centroid() {
        let line: Vec<Point3> = (0..20)
            .map(|i| Point3::new(Real::from(i) * 1e-4, 0.0, 0.05))
            .collect();
        let c = marker_centre(&line, CentreMethod::SurfaceFit);
        assert!((c - centroid(&line)).norm() < 1e-12);
        let few = [Point3::new(0.0, 0.0, 0.05), Point3::new(1e-3, 0.0, 0.05)];
        assert_eq!(
            marker_centre(&few, CentreMethod::SurfaceFit),
            centroid(&few)
        );
    }
}
