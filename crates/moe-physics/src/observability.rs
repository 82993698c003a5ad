//! The physical limit of locating a press from the markers: the Cramér–Rao bound of the
//! place along and around the finger, from the model's Jacobian of the marker coordinates with
//! respect to the press's place and force vector and the markers' noise.

use moe_geom::{Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::PhysicsError;
use crate::estimator::PhysicsEstimator;
use crate::finger::FingerObservation;

/// What the bound assumes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BoundOptions {
    /// Force of the press, along the inward normal, newtons. Default 0.2.
    pub force_n: Real,
    /// Noise of a marker coordinate, metres. Default 1.6e-4: the perception stage's markers
    /// are 0.25 mm from the truth on average, the mean norm of an isotropic 3-D Gaussian of
    /// 0.16 mm per coordinate.
    pub marker_sigma_m: Real,
    /// Independent frames of a held press (the bound shrinks as one over their square root).
    /// Default 1.
    pub frames: usize,
}

impl Default for BoundOptions {
    fn default() -> Self {
        Self {
            force_n: 0.2,
            marker_sigma_m: 1.6e-4,
            frames: 1,
        }
    }
}

impl BoundOptions {
    /// Checks the options.
    ///
    /// # Errors
    /// [`PhysicsError::InvalidParameter`] naming the bad one.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        for (name, v) in [
            ("force_n", self.force_n),
            ("marker_sigma_m", self.marker_sigma_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(PhysicsError::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be finite and positive",
                });
            }
        }
        if self.frames == 0 {
            return Err(PhysicsError::InvalidParameter {
                name: "frames",
                value: 0.0,
                reason: "must be at least 1",
            });
        }
        Ok(())
    }
}

/// The bound at one place of a finger.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlaceBound {
    /// The surface vertex at the centre of the pressed patch.
    pub vertex: u32,
    /// Its rest position, finger frame, metres.
    pub rest_in_finger: Point3,
    /// Standard deviation bound of the place along the finger's axis, metres.
    pub along_m: Real,
    /// Standard deviation bound of the place around the axis (arc length), metres.
    pub around_m: Real,
    /// Standard deviation bound of the force's magnitude, newtons.
    pub force_sd_n: Real,
}

impl PlaceBound {
    /// The bound over `frames` independent frames of the same held press: their Fisher
    /// information adds up, so every standard deviation shrinks by √frames (what
    /// [`BoundOptions::frames`] gives, without solving again).
    #[must_use]
    pub fn over_frames(&self, frames: usize) -> Self {
        let k = (frames.max(1) as Real).sqrt();
        Self {
            along_m: self.along_m / k,
            around_m: self.around_m / k,
            force_sd_n: self.force_sd_n / k,
            ..self.clone()
        }
    }
}

impl PhysicsEstimator {
    /// The Cramér–Rao bound of a press at every place of finger `finger` that can move: the
    /// model linearised at the finger's static shape under `pulls` and gravity, every marker of
    /// the finger observed.
    ///
    /// # Errors
    /// A finger index out of range, pulls of the wrong length, invalid options, or a static
    /// solve that fails.
    pub fn location_bounds(
        &mut self,
        finger: usize,
        pulls: &[Real],
        gravity_in_hand: Vector3,
        options: &BoundOptions,
    ) -> Result<Vec<PlaceBound>, PhysicsError> {
        options.validate()?;
        let n = self.hand().num_fingers();
        if finger >= n {
            return Err(PhysicsError::LengthMismatch {
                what: "finger index (fingers of the hand)",
                expected: n,
                got: finger,
            });
        }
        let hf = self.hand().fingers()[finger].clone();
        let expected = hf.model.tendon_routes().len();
        if pulls.len() != expected {
            return Err(PhysicsError::FingerLengthMismatch {
                what: "tendon pulls",
                finger,
                expected,
                got: pulls.len(),
            });
        }
        let finger_from_hand = hf.hand_from_finger.iso().inverse();
        let markers = vec![None; hf.model.marker_vertices().len()];
        let obs = FingerObservation {
            markers: &markers,
            gravity: finger_from_hand * gravity_in_hand,
            world_from_finger: *hf.hand_from_finger.iso(),
            pulls,
            time_secs: None,
        };
        let rest = hf.model.mesh().vertices();
        let bounds = self.finger_mut(finger).location_bounds(
            &obs,
            options.force_n,
            options.marker_sigma_m,
            options.frames,
        )?;
        Ok(bounds
            .into_iter()
            .map(|(vertex, [along_m, around_m, force_sd_n])| PlaceBound {
                vertex,
                rest_in_finger: rest[vertex as usize],
                along_m,
                around_m,
                force_sd_n,
            })
            .collect())
    }
}

/// Median and 90th percentile of a quantity over a set of places.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    /// The median.
    pub median: Real,
    /// The 90th percentile.
    pub p90: Real,
}

impl Spread {
    /// Nearest-rank quantiles of `values` (infinite values sort last; NaN for none).
    pub fn of(values: &[Real]) -> Self {
        Self {
            median: quantile(values, 0.5),
            p90: quantile(values, 0.9),
        }
    }
}

/// The `q` quantile of `values` by nearest rank (infinite values sort last; NaN for none).
pub fn quantile(values: &[Real], q: Real) -> Real {
    if values.is_empty() {
        return Real::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(Real::total_cmp);
    v[((q * (v.len() - 1) as Real).round() as usize).min(v.len() - 1)]
}

/// The regions a bound is summarised over: name and heights as fractions of the finger's
/// length (the tip includes the cap).
pub const BOUND_REGIONS: [(&str, Real, Real); 3] = [
    ("tip", 0.8, 1.0),
    ("middle", 0.4, 0.7),
    ("base", 0.12, 0.35),
];

/// The bound over one region of a finger.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegionBound {
    /// `tip`, `middle` or `base` ([`BOUND_REGIONS`]).
    pub region: &'static str,
    /// The region's lowest height, a fraction of the finger's length.
    pub z_from: Real,
    /// Its highest height.
    pub z_to: Real,
    /// Movable surface vertices in the region.
    pub vertices: usize,
    /// Of those, the ones whose bound is infinite (the markers do not determine a press there).
    pub unobservable: usize,
    /// Along-the-axis bound, mm.
    pub along_mm: Spread,
    /// Around-the-axis bound, mm.
    pub around_mm: Spread,
    /// Force-magnitude bound, newtons.
    pub force_sd_n: Spread,
}

/// The bounds of a finger of `length_m` summarised over [`BOUND_REGIONS`].
pub fn region_bounds(bounds: &[PlaceBound], length_m: Real) -> Vec<RegionBound> {
    BOUND_REGIONS
        .iter()
        .map(|&(region, lo, hi)| {
            let inside: Vec<&PlaceBound> = bounds
                .iter()
                .filter(|b| (lo..=hi).contains(&(b.rest_in_finger.z / length_m)))
                .collect();
            let spread = |f: fn(&PlaceBound) -> Real| {
                Spread::of(&inside.iter().map(|b| f(b)).collect::<Vec<_>>())
            };
            RegionBound {
                region,
                z_from: lo,
                z_to: hi,
                vertices: inside.len(),
                unobservable: inside
                    .iter()
                    .filter(|b| !(b.along_m.is_finite() && b.around_m.is_finite()))
                    .count(),
                along_mm: spread(|b| b.along_m * 1e3),
                around_mm: spread(|b| b.around_m * 1e3),
                force_sd_n: spread(|b| b.force_sd_n),
            }
        })
        .collect()
}
