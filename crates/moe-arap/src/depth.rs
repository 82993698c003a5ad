//! SR-ARAP registered to the wrist camera's depth image as well as to the markers.
//!
//! The markers stay hard handles. Each finger's visible surface enters as soft point-to-plane
//! pulls: the pixels that see a finger are predicted from the current estimate (a z-buffer of
//! the estimated meshes, [`moe_geom::depth::associate_depth`]), pooled over patches of the
//! surface ([`moe_geom::depth::pool_pixels`]), and each patch pulls the mesh's surface towards
//! the mean of its pixels along the normal, weighted by the inverse variance of that mean. A
//! patch whose pixels lie in front of the estimate (they may see the object that touches the
//! finger) is weighted down by a Cauchy loss; behind it, where nothing but the finger can be
//! seen, it keeps its whole weight. The registration runs in passes, each from the previous
//! one's shape: the pixels are associated again and the robust weights recomputed, so a dent
//! deeper than the association gates is followed.

use moe_geom::depth::{AssociationOptions, DepthNoise, PooledPatch};
use moe_geom::{GeomError, Real};
use serde::{Deserialize, Serialize};

use crate::error::ArapError;
use crate::solver::SurfaceRow;

/// How SR-ARAP uses a depth image (serde; every field defaulted; off by default).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShapeDepth {
    /// Register to the observation's depth image when it carries one. Default false (the
    /// paper's SR-ARAP reads markers only).
    pub enabled: bool,
    /// Weight of a patch whose mean is known to 1 mm, relative to SR-ARAP's energy (squared
    /// metres of edge change, cotangent-weighted); a patch of variance `σ²` weighs
    /// `weight · (1 mm)² / σ²`. Default 0.3, chosen on validation trajectories by the shape's
    /// error (docs/results.md). Much heavier patches slow the iterations down: a vertex held
    /// on a patch's plane slides along it only by small steps.
    pub weight: Real,
    /// Association and re-weighting passes after the markers-only solve. Default 2.
    pub passes: usize,
    /// Every `stride_px`-th pixel in both directions is sampled. Default 4.
    pub stride_px: u32,
    /// Pixels this close to a predicted silhouette (flying pixels) are left out. Default 2.
    pub edge_band_px: u32,
    /// Pixels that see further than this behind the estimated surface are not the finger's,
    /// metres. Default 0.003.
    pub gate_m: Real,
    /// Pixels that see further than this in front of it are not the finger's, metres. Default
    /// 0.001: two standard deviations of a pixel's white noise at a finger's range, so the
    /// object that touches the finger, which lies in front of it about the contact, is mostly
    /// left out pixel by pixel (leaving out the finger's own pixels beyond two standard
    /// deviations biases a patch's mean by about 0.06 σ).
    pub front_gate_m: Real,
    /// Spacing of the patches pixels are pooled over, metres. Default 0.003.
    pub patch_spacing_m: Real,
    /// Fewest pixels of a patch. Default 4.
    pub min_pixels: usize,
    /// The camera's noise (the virtual camera's by default).
    pub noise: DepthNoise,
    /// Scale of the Cauchy loss of a patch in front of the estimated surface, in standard
    /// deviations of the patch's mean (0: quadratic on both sides). Default 1, as the physics
    /// estimator's.
    pub front_loss_sigma: Real,
}

impl Default for ShapeDepth {
    fn default() -> Self {
        Self {
            enabled: false,
            weight: 0.3,
            passes: 2,
            stride_px: 4,
            edge_band_px: 2,
            gate_m: 0.003,
            front_gate_m: 0.001,
            patch_spacing_m: 0.003,
            min_pixels: 4,
            noise: DepthNoise::default(),
            front_loss_sigma: 1.0,
        }
    }
}

impl ShapeDepth {
    /// Checks every setting.
    ///
    /// # Errors
    /// [`ArapError::InvalidConfig`] naming the first bad one.
    pub fn validate(&self) -> Result<(), ArapError> {
        let named = |e: GeomError| match e {
            GeomError::InvalidParameter {
                name,
                value,
                reason,
            } => ArapError::InvalidConfig {
                name,
                value,
                reason,
            },
            other => ArapError::Geom(other),
        };
        moe_geom::depth::check_depth_settings(
            &self.noise,
            &self.association(),
            self.patch_spacing_m,
            self.min_pixels,
        )
        .map_err(named)?;
        for (name, v) in [
            ("depth.weight", self.weight),
            ("depth.front_loss_sigma", self.front_loss_sigma),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ArapError::InvalidConfig {
                    name,
                    value: v,
                    reason: "must be finite and non-negative",
                });
            }
        }
        if self.passes > 100 {
            return Err(ArapError::InvalidConfig {
                name: "depth.passes",
                value: self.passes as Real,
                reason: "must be at most 100",
            });
        }
        if self.noise.correlated_sigma_m <= 0.0 {
            return Err(ArapError::InvalidConfig {
                name: "noise.correlated_sigma_m",
                value: self.noise.correlated_sigma_m,
                reason: "must be positive: without it a patch of many pixels would be trusted \
                         without limit",
            });
        }
        Ok(())
    }

    /// The association of pixels with fingers these settings ask for.
    pub fn association(&self) -> AssociationOptions {
        AssociationOptions {
            stride_px: self.stride_px,
            edge_band_px: self.edge_band_px,
            gate_m: self.gate_m,
            front_gate_m: self.front_gate_m,
        }
    }

    /// The soft row of a pooled patch, its weight from its variance and from where its pixels
    /// lie: `predicted` is what the current estimate predicts for it.
    pub(crate) fn row(&self, patch: PooledPatch, predicted: Real) -> SurfaceRow {
        const MM: Real = 1e-3;
        let ahead = patch.value - predicted;
        let scale = self.front_loss_sigma * patch.variance.sqrt();
        let robust = if ahead > 0.0 && scale > 0.0 {
            1.0 / (1.0 + (ahead / scale).powi(2))
        } else {
            1.0
        };
        SurfaceRow {
            weight: self.weight * MM * MM / patch.variance * robust,
            terms: patch.terms,
            value: patch.value,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::Vector3;

    #[test]
    fn defaults_are_valid_and_bad_settings_are_named() {
        ShapeDepth::default().validate().unwrap();
        for (bad, name) in [
            (
                ShapeDepth {
                    weight: -1.0,
                    ..Default::default()
                },
                "depth.weight",
            ),
            (
                ShapeDepth {
                    gate_m: Real::NAN,
                    ..Default::default()
                },
                "depth.gate_m",
            ),
            (
                ShapeDepth {
                    stride_px: 0,
                    ..Default::default()
                },
                "depth.stride_px",
            ),
            (
                ShapeDepth {
                    noise: DepthNoise {
                        correlated_sigma_m: 0.0,
                        ..DepthNoise::default()
                    },
                    ..Default::default()
                },
                "noise.correlated_sigma_m",
            ),
            (
                ShapeDepth {
                    noise: DepthNoise {
                        sigma_base_m: -1.0,
                        ..DepthNoise::default()
                    },
                    ..Default::default()
                },
                "noise.sigma_base_m",
            ),
        ] {
            match bad.validate() {
                Err(ArapError::InvalidConfig { name: n, .. }) => assert_eq!(n, name),
                other => panic!("{name}: {other:?}"),
            }
        }
    }

    /// A patch behind the estimate keeps its whole inverse-variance weight; one in front of
    /// it by one standard deviation keeps half, and one ten in front almost none.
    #[test]
    fn patches_in_front_weigh_less() {
        let s = ShapeDepth::default();
        let patch = PooledPatch {
            terms: vec![(0, Vector3::z())],
            value: 0.0,
            pixels: 10,
            patch: 0,
            variance: 1e-8,
        };
        let w = |predicted| s.row(patch.clone(), predicted).weight;
        let full = s.weight * 1e-6 / 1e-8;
        assert!((w(0.001) - full).abs() < 1e-9 * full);
        // σ = 0.1 mm.
        assert!((w(-1e-4) - 0.5 * full).abs() < 1e-9 * full);
        assert!(w(-0.001) < 0.01 * full);
    }
}
