//! The depth image's pixels on a finger as observations of its surface.
//!
//! The pixels of a patch of surface pool into one observation, their mean point-to-plane
//! position, with the variance of that mean under the camera's noise
//! ([`moe_geom::depth::pool_pixels`]). Here each is given the model's own error at a patch and
//! whitened to the markers' units (scaled by `marker_sigma / σ`), so markers and depth share
//! one χ² and every test and search works on both unchanged.

use moe_geom::depth::{DepthImage, SurfacePixel, pool_pixels};
use moe_geom::{Iso3, Point3, Real};

use super::FingerInverse;
use crate::mechanics::Axis;

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

impl FingerInverse {
    /// The observations of a finger's depth pixels (finger frame) on the predicted surface
    /// they were associated with: one per patch with at least `min_pixels`, whitened.
    pub(crate) fn depth_rows(
        &self,
        pixels: &[SurfacePixel],
        predicted: &[Point3],
    ) -> Vec<DepthRow> {
        let settings = &self.config.depth;
        let sigma_m = self.config.marker_sigma_m;
        pool_pixels(
            pixels,
            &self.faces,
            predicted,
            &self.depth_patches,
            settings.min_pixels,
            &settings.noise,
        )
        .into_iter()
        .map(|p| {
            let variance = p.variance + settings.model_sigma_m * settings.model_sigma_m;
            let scale = sigma_m / variance.sqrt();
            DepthRow {
                terms: p.terms.into_iter().map(|(v, a)| (v, a * scale)).collect(),
                value: p.value * scale,
                pixels: p.pixels,
                patch: p.patch,
                unit: scale,
            }
        })
        .collect()
    }

    /// Per candidate: whether the depth image sees through the place an object touching the
    /// finger there would fill ([`crate::DepthSettings::seen_through_prior`]), for the
    /// predicted surface `surface` (finger frame) of a finger at `hand_from_finger`.
    ///
    /// An opaque object touching the finger at a place fills the space just outside it, so the
    /// line of sight to a point [`crate::SEEN_THROUGH_PROBE_M`] out along the normal enters the
    /// object before reaching the point: no pixel there can see a surface well behind it. A
    /// probe the finger itself or anything else hides (seen in front of it), or whose pixels
    /// are holes, says nothing. With `guarded`, nor does a place about which every pixel sees
    /// behind the surface (by more than `gate_m`), some of them within `reach_m`: a press the
    /// free finger does not show has pushed the finger there, and the prediction is wrong (a
    /// surface fitted with the press's load needs no guard).
    pub(crate) fn seen_through(
        &self,
        depth: &DepthImage<'_>,
        surface: &[Point3],
        hand_from_finger: &Iso3,
        guarded: bool,
    ) -> Vec<bool> {
        let probe = SeenThrough::new(self, depth, surface, hand_from_finger);
        (0..self.candidates.len())
            .map(|c| probe.at(self, c, guarded))
            .collect()
    }

    /// [`Self::seen_through`] without the guard, for candidate `c` alone.
    pub(crate) fn seen_through_at(
        &self,
        depth: &DepthImage<'_>,
        surface: &[Point3],
        hand_from_finger: &Iso3,
        c: usize,
    ) -> bool {
        SeenThrough::new(self, depth, surface, hand_from_finger).at(self, c, false)
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

/// A surface, its normals and the camera, ready to probe candidates for
/// [`FingerInverse::seen_through`].
struct SeenThrough<'a, 'b> {
    depth: &'a DepthImage<'b>,
    surface: &'a [Point3],
    normals: Vec<moe_geom::Vector3>,
    camera_from_finger: Iso3,
}

impl<'a, 'b> SeenThrough<'a, 'b> {
    fn new(
        inverse: &FingerInverse,
        depth: &'a DepthImage<'b>,
        surface: &'a [Point3],
        hand_from_finger: &Iso3,
    ) -> Self {
        Self {
            depth,
            surface,
            normals: inverse.normals_of(surface),
            camera_from_finger: depth.hand_from_camera().iso().inverse() * hand_from_finger,
        }
    }

    /// Whether candidate `c` of `inverse` is seen through (see
    /// [`FingerInverse::seen_through`]).
    fn at(&self, inverse: &FingerInverse, c: usize, guarded: bool) -> bool {
        let settings = &inverse.config.depth;
        let sigma = |z: Real| 3.0 * settings.noise.pixel_variance(z).sqrt();
        let v = inverse.candidates[c] as usize;
        let p = self.camera_from_finger * self.surface[v];
        // Where the image sees a surface just behind the predicted place itself, and nothing at
        // it, the finger has been pushed there by a press the free finger does not show (what
        // is seen past the probe may be the finger itself or the object that pushed it).
        let pushed =
            |z: Real| z > p.z + settings.gate_m + sigma(p.z) && z <= p.z + settings.reach_m;
        if guarded && nearest_depth(self.depth, &p).is_some_and(pushed) {
            return false;
        }
        let q = self.camera_from_finger
            * (self.surface[v] + self.normals[v] * crate::config::SEEN_THROUGH_PROBE_M);
        nearest_depth(self.depth, &q)
            .is_some_and(|z| z > q.z + settings.seen_through_margin_m + sigma(q.z))
    }
}

/// The nearest valid depth among the 3 × 3 pixels about the projection of `q` (camera frame);
/// `None` where they are all holes or `q` is not in front of the camera.
pub(crate) fn nearest_depth(depth: &DepthImage<'_>, q: &Point3) -> Option<Real> {
    let (u, w) = depth.intrinsics().project(q)?;
    let (i, j) = (u.round(), w.round());
    (-1..=1)
        .flat_map(|dj| (-1..=1).map(move |di| (i + Real::from(di), j + Real::from(dj))))
        .filter(|&(x, y)| x >= 0.0 && y >= 0.0)
        .filter_map(|(x, y)| depth.depth(x as u32, y as u32))
        .reduce(Real::min)
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
}

#[cfg(test)]
mod seen_through_tests {
    use super::*;
    use crate::config::{HandMaterial, PhysicsConfig};
    use moe_geom::{CameraIntrinsics, FingerParams, HandFromCamera, HandModel, HandShape};
    use moe_geom::{HandPreset, Vector3};

    /// Finger 0's model, the hand at rest with finger 1 moved out of view, and the default
    /// wrist camera.
    fn scene() -> (HandModel, FingerInverse, HandShape, Iso3, HandFromCamera) {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let inverse = FingerInverse::new(
            0,
            &hand.fingers()[0].model,
            &HandMaterial::default(),
            &PhysicsConfig::default(),
        )
        .unwrap();
        let away = Vector3::new(1.0, 0.0, 0.0);
        let shape = HandShape {
            fingers: vec![
                hand.rest_vertices_in_hand(0),
                hand.rest_vertices_in_hand(1)
                    .into_iter()
                    .map(|p| p + away)
                    .collect(),
            ],
        };
        let hand_from_finger = *hand.fingers()[0].hand_from_finger.iso();
        let mount = HandFromCamera::new(Iso3::translation(0.0, 0.0, -0.02));
        (hand, inverse, shape, hand_from_finger, mount)
    }

    /// Two triangles: the rectangle centred at `c` with edge vectors `x` and `y`.
    fn rectangle(c: Point3, x: Vector3, y: Vector3) -> Vec<[Point3; 3]> {
        let q = |s: Real, t: Real| c + x * (0.5 * s) + y * (0.5 * t);
        vec![
            [q(-1.0, -1.0), q(1.0, -1.0), q(1.0, 1.0)],
            [q(-1.0, -1.0), q(1.0, 1.0), q(-1.0, 1.0)],
        ]
    }

    fn flags(occluders: &[[Point3; 3]]) -> (FingerInverse, Vec<bool>, Vec<Point3>, Iso3) {
        let (hand, inverse, shape, hand_from_finger, mount) = scene();
        let image = moe_geom::depth::render_hand(
            &hand,
            &shape,
            occluders,
            CameraIntrinsics::default(),
            mount,
        )
        .unwrap();
        let surface = inverse.rest_surface.clone();
        let seen = inverse.seen_through(&image.view(), &surface, &hand_from_finger, true);
        (inverse, seen, surface, hand_from_finger)
    }

    /// Against a wall behind the finger, the camera sees past the finger's flanks, so the
    /// places there are seen through; a place facing the camera is not (its probe's pixels see
    /// the finger itself just behind it), nor a place with nothing behind it to see, and a
    /// block laid on a flank place fills its space again.
    #[test]
    fn the_space_beside_a_flank_is_seen_through_unless_an_object_fills_it() {
        let wall = rectangle(Point3::new(0.0, 0.0, 0.25), Vector3::x(), Vector3::y());
        let (inverse, seen, surface, hand_from_finger) = flags(&wall);
        let flagged: Vec<usize> = (0..seen.len()).filter(|&c| seen[c]).collect();
        assert!(flagged.len() > 20, "{} places seen through", flagged.len());
        let normals = inverse.normals_of(&surface);
        let eye = Point3::new(0.0, 0.0, -0.02);
        let facing = |c: usize| {
            let v = inverse.candidates[c] as usize;
            let p = hand_from_finger * surface[v];
            let n = hand_from_finger * normals[v];
            n.dot(&(eye - p).normalize())
        };
        assert!(flagged.iter().all(|&c| facing(c) < 0.7));
        assert!((0..seen.len()).any(|c| facing(c) > 0.7 && !seen[c]));
        // Without the wall most probes see holes, which say nothing; what is left is seen
        // through to the finger's own surface further along.
        let (_, bare, _, _) = flags(&[]);
        let left = bare.iter().filter(|&&s| s).count();
        assert!(left < flagged.len() / 2, "{left} of {}", flagged.len());
        assert!((0..seen.len()).all(|c| !bare[c] || seen[c]));
        // The flank place the camera sees most squarely of those seen through.
        let &c = flagged
            .iter()
            .max_by(|&&a, &&b| facing(a).total_cmp(&facing(b)))
            .unwrap();
        let v = inverse.candidates[c] as usize;
        let n = hand_from_finger * normals[v];
        let p = hand_from_finger * surface[v] + n * 2e-4;
        let a = n.cross(&Vector3::z()).normalize();
        let b = n.cross(&a);
        // A block 12 mm square and 6 mm thick on the place.
        let (w, t) = (0.012, 0.006);
        let mid = p + n * (t / 2.0);
        let mut occluders = wall.clone();
        for (c0, x, y) in [
            (p, a * w, b * w),
            (p + n * t, a * w, b * w),
            (mid + a * (w / 2.0), n * t, b * w),
            (mid - a * (w / 2.0), n * t, b * w),
            (mid + b * (w / 2.0), n * t, a * w),
            (mid - b * (w / 2.0), n * t, a * w),
        ] {
            occluders.extend(rectangle(c0, x, y));
        }
        let (_, covered, _, _) = flags(&occluders);
        assert!(!covered[c]);
        assert!(covered.contains(&true));
    }
}
