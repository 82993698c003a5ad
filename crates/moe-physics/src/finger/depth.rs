//! The depth image's pixels on a finger as observations of its surface.
//!
//! A pixel that sees the finger measures a point `p` of its surface. Against the model's
//! surface at nodes `x` it gives the point-to-plane residual `n · (p − q(x))`, where `q(x)` is
//! the point of the predicted face the pixel's ray met (fixed barycentric weights on the
//! face's vertices) and `n` that face's outward normal: only the normal component is seen, a
//! pixel says nothing about sliding along the surface. The residual is linear in the surface
//! vertices, so the pixels of a patch of surface pool exactly into one observation, their mean:
//! `value = mean(n·p)` observed, `Σ_v a_v · s_v(x)` predicted with `a_v = mean(w_v n)`. Its
//! variance is that of a mean of pixels under the camera's noise (the white part averages, the
//! correlated part does not) plus the model's own error at a patch; the observation is
//! whitened to the markers' units (scaled by `marker_sigma / σ`), so markers and depth share
//! one χ² and every test and search works on both unchanged.

use moe_geom::{Point3, Real, Vector3};

use super::FingerInverse;
use crate::mechanics::Axis;

/// One depth pixel seen on a finger, finger frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FingerPixel {
    /// The face of the predicted surface the pixel's ray meets.
    pub(crate) face: u32,
    /// Where the ray meets the predicted surface.
    pub(crate) predicted: Point3,
    /// The face's outward unit normal.
    pub(crate) normal: Vector3,
    /// The measured point.
    pub(crate) measured: Point3,
    /// Variance of the measured point along the normal (the depth noise projected), m².
    pub(crate) variance: Real,
}

/// The pixels of one patch pooled into one observation, whitened to the markers' units: the
/// model predicts `Σ a · s_v` over `terms`, the pixels measured `value`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DepthRow {
    /// `(surface vertex, a)`.
    pub(crate) terms: Axis,
    /// The measured value.
    pub(crate) value: Real,
    /// Pixels pooled.
    pub(crate) pixels: usize,
    /// The patch of the rest surface pooled.
    pub(crate) patch: u32,
    /// The whitening: a residual of `r` is a mean point-to-plane distance of `r / unit` metres.
    pub(crate) unit: Real,
}

/// The patches pixels are pooled over: per face of the surface, its patch.
#[derive(Debug, Clone)]
pub(super) struct DepthPatches {
    /// Per face: the patch it belongs to.
    pub(super) of_face: Vec<u32>,
    /// Number of patches.
    pub(super) count: usize,
}

impl DepthPatches {
    /// Patches about `spacing_m` across on the rest surface (`vertices`, `faces`): centres
    /// chosen greedily at least the spacing apart, every face given to the centre nearest its
    /// centroid.
    pub(super) fn new(vertices: &[Point3], faces: &[[u32; 3]], spacing_m: Real) -> Self {
        let mut centres: Vec<Point3> = Vec::new();
        for p in vertices {
            if centres.iter().all(|c| (c - p).norm() >= spacing_m) {
                centres.push(*p);
            }
        }
        let of_face = faces
            .iter()
            .map(|f| {
                let centroid = Point3::from(
                    f.iter()
                        .map(|&i| vertices[i as usize].coords)
                        .sum::<Vector3>()
                        / 3.0,
                );
                centres
                    .iter()
                    .enumerate()
                    .min_by(|a, b| {
                        (a.1 - centroid)
                            .norm_squared()
                            .total_cmp(&(b.1 - centroid).norm_squared())
                    })
                    .map_or(0, |(k, _)| k as u32)
            })
            .collect();
        Self {
            of_face,
            count: centres.len(),
        }
    }
}

/// Barycentric weights of `p` in triangle `t` (projected onto its plane), clamped to the
/// triangle; equal thirds for a degenerate one.
fn barycentric(t: [Point3; 3], p: &Point3) -> [Real; 3] {
    let (e0, e1, d) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (a, b, c) = (e0.dot(&e0), e0.dot(&e1), e1.dot(&e1));
    let (u, v) = (d.dot(&e0), d.dot(&e1));
    let det = a * c - b * b;
    if det.abs() <= 1e-12 * (a * c).max(Real::MIN_POSITIVE) {
        return [1.0 / 3.0; 3];
    }
    let w1 = ((c * u - b * v) / det).clamp(0.0, 1.0);
    let w2 = ((a * v - b * u) / det).clamp(0.0, 1.0 - w1);
    [1.0 - w1 - w2, w1, w2]
}

impl FingerInverse {
    /// The observations of a finger's depth pixels (finger frame) on the predicted surface
    /// they were associated with: one per patch with at least `min_pixels`, whitened.
    pub(crate) fn depth_rows(&self, pixels: &[FingerPixel], predicted: &[Point3]) -> Vec<DepthRow> {
        let settings = &self.config.depth;
        let patches = &self.depth_patches;
        #[derive(Clone, Default)]
        struct Pool {
            terms: Vec<(u32, Vector3)>,
            value: Real,
            white: Real,
            pixels: usize,
        }
        let mut pools = vec![Pool::default(); patches.count];
        for px in pixels {
            let Some(&patch) = patches.of_face.get(px.face as usize) else {
                continue;
            };
            let face = self.faces[px.face as usize];
            let w = barycentric(face.map(|i| predicted[i as usize]), &px.predicted);
            let pool = &mut pools[patch as usize];
            for (&v, w) in face.iter().zip(w) {
                match pool.terms.iter_mut().find(|t| t.0 == v) {
                    Some(t) => t.1 += px.normal * w,
                    None => pool.terms.push((v, px.normal * w)),
                }
            }
            pool.value += px.normal.dot(&px.measured.coords);
            pool.white += px.variance;
            pool.pixels += 1;
        }
        let sigma_m = self.config.marker_sigma_m;
        pools
            .into_iter()
            .zip(0u32..)
            .filter(|(p, _)| p.pixels >= settings.min_pixels)
            .map(|(p, patch)| {
                let n = p.pixels as Real;
                let variance = settings.noise.mean_variance(p.white, p.pixels)
                    + settings.model_sigma_m * settings.model_sigma_m;
                let scale = sigma_m / variance.sqrt() / n;
                DepthRow {
                    terms: p.terms.into_iter().map(|(v, a)| (v, a * scale)).collect(),
                    value: p.value * scale,
                    pixels: p.pixels,
                    patch,
                    unit: scale * n,
                }
            })
            .collect()
    }

    /// What row `row` predicts for nodes `x`.
    pub(super) fn depth_predicted(&self, x: &[Point3], row: &DepthRow) -> Real {
        row.terms
            .iter()
            .map(|&(v, a)| a.dot(&self.mech.surface_position(x, v).coords))
            .sum()
    }

    /// The scale of the loss in front of the surface, in the rows' whitened units (infinite:
    /// quadratic on both sides).
    fn front_scale(&self) -> Real {
        match self.config.depth.front_loss_sigma {
            s if s > 0.0 => s * self.config.marker_sigma_m,
            _ => Real::INFINITY,
        }
    }

    /// The loss of `rows` at nodes `x` ([`depth_loss`]), in the markers' χ² units.
    pub(super) fn depth_residual_sq(&self, x: &[Point3], rows: &[DepthRow]) -> Real {
        let c = self.front_scale();
        rows.iter()
            .map(|row| depth_loss(row.value - self.depth_predicted(x, row), c))
            .sum()
    }

    /// Row `row`'s residual at nodes `x` and the square root of its weight in a linearisation
    /// there ([`depth_weight`]).
    pub(super) fn depth_linearised(&self, x: &[Point3], row: &DepthRow) -> (Real, Real) {
        let r = row.value - self.depth_predicted(x, row);
        (r, depth_weight(r, self.front_scale()).sqrt())
    }

    /// `rows` with what they measure moved by the surface's change from nodes `from` to `to`
    /// (as the markers are moved from the simulated free finger onto the static one).
    pub(super) fn shifted_rows(
        &self,
        rows: &[DepthRow],
        from: &[Point3],
        to: &[Point3],
    ) -> Vec<DepthRow> {
        rows.iter()
            .map(|row| DepthRow {
                value: row.value + self.depth_predicted(to, row) - self.depth_predicted(from, row),
                ..row.clone()
            })
            .collect()
    }
}

/// The loss of a depth observation's whitened residual `r` (positive: its pixels lie in front
/// of the model's surface): `r²` behind the surface, where nothing but the finger can be seen;
/// in front, where an object may hide the finger (the one pressing it lies in front of it
/// about the contact), the Cauchy loss `c² ln(1 + r²/c²)`, equal to `r²` near zero and growing
/// only with the log beyond the scale `c`: a patch that sees an object costs little, a patch
/// that sees the finger behind the model must be explained.
pub(super) fn depth_loss(r: Real, c: Real) -> Real {
    if r <= 0.0 || !c.is_finite() {
        r * r
    } else {
        c * c * (r * r / (c * c)).ln_1p()
    }
}

/// The weight of a residual `r` in iteratively reweighted least squares for [`depth_loss`]:
/// `ρ'(r) / 2r`.
pub(super) fn depth_weight(r: Real, c: Real) -> Real {
    if r <= 0.0 || !c.is_finite() {
        1.0
    } else {
        1.0 / (1.0 + r * r / (c * c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_loss_is_quadratic_behind_and_logarithmic_far_in_front() {
        let c = 2.0;
        for r in [-3.0, -0.5, 0.0] {
            assert_eq!(depth_loss(r, c), r * r);
            assert_eq!(depth_weight(r, c), 1.0);
        }
        // Near zero in front, the same as behind; far in front, much less.
        assert!((depth_loss(1e-3, c) - 1e-6).abs() < 1e-12);
        assert!(depth_loss(20.0, c) < 0.05 * 400.0);
        // The weight is the loss's derivative over 2r (checked by a central difference).
        for r in [0.3, 1.0, 4.0, 10.0] {
            let h = 1e-6;
            let slope = (depth_loss(r + h, c) - depth_loss(r - h, c)) / (2.0 * h);
            assert!((slope / (2.0 * r) - depth_weight(r, c)).abs() < 1e-6, "{r}");
        }
        // Without a scale, quadratic on both sides.
        assert_eq!(depth_loss(5.0, Real::INFINITY), 25.0);
    }

    #[test]
    fn barycentric_weights_rebuild_the_point() {
        let t = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 2.0, 0.0),
        ];
        let p = Point3::new(0.25, 0.5, 0.3);
        let w = barycentric(t, &p);
        let q: Vector3 = t.iter().zip(w).map(|(v, w)| v.coords * w).sum();
        assert!((q - Vector3::new(0.25, 0.5, 0.0)).norm() < 1e-12, "{q}");
        assert!((w.iter().sum::<Real>() - 1.0).abs() < 1e-12);
        // Outside the triangle: clamped onto it.
        let w = barycentric(t, &Point3::new(2.0, 0.0, 0.0));
        assert_eq!(w, [0.0, 1.0, 0.0]);
    }

    #[test]
    fn every_face_has_a_patch_and_patches_are_spaced() {
        let vertices: Vec<Point3> = (0..10)
            .flat_map(|i| {
                (0..10).map(move |j| Point3::new(i as Real * 1e-3, j as Real * 1e-3, 0.0))
            })
            .collect();
        let mut faces = Vec::new();
        for i in 0..9u32 {
            for j in 0..9u32 {
                let v = i * 10 + j;
                faces.push([v, v + 10, v + 1]);
                faces.push([v + 1, v + 10, v + 11]);
            }
        }
        let patches = DepthPatches::new(&vertices, &faces, 0.003);
        assert_eq!(patches.of_face.len(), faces.len());
        // A 9 mm square with 3 mm spacing: centres on a 3 mm grid, 4 × 4.
        assert_eq!(patches.count, 16);
        assert!(
            patches
                .of_face
                .iter()
                .all(|&p| (p as usize) < patches.count)
        );
    }
}
