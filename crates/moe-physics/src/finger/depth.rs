//! The depth image's pixels on a finger as observations of its surface.
//!
//! The pixels of a patch of surface pool into one observation, their mean point-to-plane
//! position, with the variance of that mean under the camera's noise
//! ([`moe_geom::depth::pool_pixels`]). Here each is given the model's own error at a patch and
//! whitened to the markers' units (scaled by `marker_sigma / σ`), so markers and depth share
//! one χ² and every test and search works on both unchanged.

use moe_geom::depth::{SurfacePixel, pool_pixels};
use moe_geom::{Point3, Real};

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
}
