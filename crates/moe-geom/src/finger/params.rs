//! The finger's geometry parameters and the body profile they define.

use serde::{Deserialize, Serialize};

use super::layout::MarkerLayout;
use crate::error::GeomError;
use crate::math::Real;

/// Geometry of the parametric finger. SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FingerParams {
    /// Length from the base plane to the tip apex, metres. Default 0.08.
    pub length_m: Real,
    /// Radius at the base, metres. Default 0.011.
    pub base_radius_m: Real,
    /// Radius of the hemispherical tip (and of the body where it joins), metres. Default 0.008.
    pub tip_radius_m: Real,
    /// Requested number of surface vertices. Default 1024; the mesh has this many within a few
    /// percent.
    pub vertex_budget: usize,
    /// Number of markers in each row of the [`MarkerLayout`] that does not give its own
    /// `count`: with the default layout, the markers along the camera-facing side. Default 7
    /// (paper §4.2).
    pub marker_count: usize,
    /// Distance of the tendons from the axis, as a fraction of the local body radius. Default 0.6.
    pub tendon_offset_ratio: Real,
    /// Where the markers are painted: a preset name (`"camera-row"`, `"two-rows"`, `"sides"`,
    /// `"tip-ring"`) or a table `{ rows = [{ angle_deg = 0, count = 7 }], tip_ring = 0 }`.
    /// Default: one row of `marker_count` on the camera side (left out of the serialised form
    /// when it is the default, so files written before layouts existed are unchanged).
    #[serde(skip_serializing_if = "MarkerLayout::is_default")]
    pub marker_layout: MarkerLayout,
}

impl Default for FingerParams {
    fn default() -> Self {
        Self {
            length_m: 0.08,
            base_radius_m: 0.011,
            tip_radius_m: 0.008,
            vertex_budget: 1024,
            marker_count: 7,
            tendon_offset_ratio: 0.6,
            marker_layout: MarkerLayout::default(),
        }
    }
}

impl FingerParams {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] naming the first bad one.
    pub fn validate(&self) -> Result<(), GeomError> {
        let bad = |name, value, reason| {
            Err(GeomError::InvalidParameter {
                name,
                value,
                reason,
            })
        };
        for (name, v) in [
            ("length_m", self.length_m),
            ("base_radius_m", self.base_radius_m),
            ("tip_radius_m", self.tip_radius_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, v, "must be finite and positive");
            }
        }
        if self.length_m <= 1.5 * self.tip_radius_m {
            return bad("length_m", self.length_m, "must exceed 1.5 × tip_radius_m");
        }
        if !(16..=1_000_000).contains(&self.vertex_budget) {
            return bad(
                "vertex_budget",
                self.vertex_budget as Real,
                "must be in 16..=1000000",
            );
        }
        if !(1..=64).contains(&self.marker_count) {
            return bad(
                "marker_count",
                self.marker_count as Real,
                "must be in 1..=64",
            );
        }
        if !(self.tendon_offset_ratio > 0.0 && self.tendon_offset_ratio < 0.95) {
            return bad(
                "tendon_offset_ratio",
                self.tendon_offset_ratio,
                "must be in (0, 0.95)",
            );
        }
        self.marker_layout.validate(self.marker_count)
    }

    /// Height where the cylindrical-conical body meets the hemispherical tip.
    pub fn cap_start_z(&self) -> Real {
        self.length_m - self.tip_radius_m
    }

    /// Radius of the body surface at height `z` (0 outside `[0, length]`).
    pub fn radius_at(&self, z: Real) -> Real {
        let zc = self.cap_start_z();
        if !(0.0..=self.length_m).contains(&z) {
            0.0
        } else if z <= zc {
            self.base_radius_m + (self.tip_radius_m - self.base_radius_m) * z / zc
        } else {
            let dz = z - zc;
            (self.tip_radius_m * self.tip_radius_m - dz * dz)
                .max(0.0)
                .sqrt()
        }
    }
}
