//! Temporal filters for a stream of frames (the paper's stated limitation, §8: no
//! frame-to-frame consistency): a constant-velocity Kalman filter per marker on the keypoints,
//! and exponential smoothing of the contact map.

use moe_geom::{ContactMap, HandKeypoints, Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::TouchError;

/// Noise levels of the keypoint filter, per frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KalmanConfig {
    /// Standard deviation of a detected marker's position, metres. Default 0.0004 (the
    /// detector's mean error on the plate scenes is 0.25 mm, its 95th percentile 1.1 mm).
    pub measurement_std_m: Real,
    /// Standard deviation of the change of a marker's velocity from one frame to the next,
    /// metres per frame. Default 0.0005.
    pub acceleration_std_m: Real,
}

impl Default for KalmanConfig {
    fn default() -> Self {
        Self {
            measurement_std_m: 4e-4,
            acceleration_std_m: 5e-4,
        }
    }
}

impl KalmanConfig {
    /// Checks the noise levels.
    ///
    /// # Errors
    /// [`TouchError::InvalidParameter`] for a level that is not finite and positive.
    pub fn validate(&self) -> Result<(), TouchError> {
        for (name, value) in [
            ("kalman measurement_std_m", self.measurement_std_m),
            ("kalman acceleration_std_m", self.acceleration_std_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(TouchError::InvalidParameter {
                    name,
                    value,
                    reason: "must be finite and positive",
                });
            }
        }
        Ok(())
    }
}

/// Position and velocity along one axis with their 2 × 2 covariance.
#[derive(Debug, Clone, Copy)]
struct Axis {
    x: Real,
    v: Real,
    p: [[Real; 2]; 2],
}

/// One marker's filter state: three independent axes (the noise is isotropic).
#[derive(Debug, Clone, Copy)]
struct MarkerState {
    axes: [Axis; 3],
}

/// A constant-velocity Kalman filter per marker. A marker not detected in a frame stays
/// `None` in the output (the filter predicts through the gap but never reports a marker it did
/// not see); its state is forgotten after `max_gap_frames` frames without a detection.
#[derive(Debug, Clone)]
pub struct KeypointFilter {
    config: KalmanConfig,
    states: Vec<Vec<Option<(MarkerState, u32)>>>,
}

/// Frames a marker may go undetected before its filter state is dropped.
const MAX_GAP_FRAMES: u32 = 10;

impl KeypointFilter {
    /// A filter with `config`'s noise levels.
    ///
    /// # Errors
    /// As [`KalmanConfig::validate`].
    pub fn new(config: KalmanConfig) -> Result<Self, TouchError> {
        config.validate()?;
        Ok(Self {
            config,
            states: Vec::new(),
        })
    }

    /// Forgets every marker.
    pub fn reset(&mut self) {
        self.states.clear();
    }

    /// Filters one frame's keypoints (frames one unit of time apart).
    pub fn filter(&mut self, keypoints: &HandKeypoints) -> HandKeypoints {
        if self.states.len() != keypoints.fingers.len()
            || self
                .states
                .iter()
                .zip(&keypoints.fingers)
                .any(|(s, k)| s.len() != k.len())
        {
            self.states = keypoints
                .fingers
                .iter()
                .map(|k| vec![None; k.len()])
                .collect();
        }
        let r = self.config.measurement_std_m.powi(2);
        let q = self.config.acceleration_std_m.powi(2);
        let mut out = keypoints.clone();
        for (f, markers) in keypoints.fingers.iter().enumerate() {
            for (m, z) in markers.iter().enumerate() {
                let slot = &mut self.states[f][m];
                *slot = match (slot.take(), z) {
                    (None, None) => None,
                    (None, Some(z)) => Some((MarkerState::start(z, r), 0)),
                    (Some((mut s, gap)), z) => {
                        s.predict(q);
                        match z {
                            Some(z) => {
                                s.update(z, r);
                                out.fingers[f][m] = Some(s.position());
                                Some((s, 0))
                            }
                            None if gap < MAX_GAP_FRAMES => Some((s, gap + 1)),
                            None => None,
                        }
                    }
                };
            }
        }
        out
    }
}

impl MarkerState {
    fn start(z: &Point3, r: Real) -> Self {
        let axis = |x: Real| Axis {
            x,
            v: 0.0,
            // Unknown velocity: a wide prior (1 cm per frame).
            p: [[r, 0.0], [0.0, 1e-4]],
        };
        Self {
            axes: [axis(z.x), axis(z.y), axis(z.z)],
        }
    }

    /// x ← x + v, with the white-acceleration process noise of one frame.
    fn predict(&mut self, q: Real) {
        for a in &mut self.axes {
            a.x += a.v;
            let [[p00, p01], [p10, p11]] = a.p;
            a.p = [
                [p00 + p01 + p10 + p11 + 0.25 * q, p01 + p11 + 0.5 * q],
                [p10 + p11 + 0.5 * q, p11 + q],
            ];
        }
    }

    fn update(&mut self, z: &Point3, r: Real) {
        for (a, z) in self.axes.iter_mut().zip([z.x, z.y, z.z]) {
            let s = a.p[0][0] + r;
            let (k0, k1) = (a.p[0][0] / s, a.p[1][0] / s);
            let y = z - a.x;
            a.x += k0 * y;
            a.v += k1 * y;
            let [[p00, p01], [p10, p11]] = a.p;
            a.p = [
                [(1.0 - k0) * p00, (1.0 - k0) * p01],
                [p10 - k1 * p00, p11 - k1 * p01],
            ];
        }
    }

    fn position(&self) -> Point3 {
        Point3::from(Vector3::new(self.axes[0].x, self.axes[1].x, self.axes[2].x))
    }
}

/// Exponential smoothing of the contact map: `p ← α·p_new + (1 − α)·p_previous`.
#[derive(Debug, Clone)]
pub struct ContactSmoother {
    alpha: Real,
    previous: Option<ContactMap>,
}

impl ContactSmoother {
    /// A smoother with weight `alpha` on the new frame.
    ///
    /// # Errors
    /// [`TouchError::InvalidParameter`] for `alpha` outside `(0, 1]`.
    pub fn new(alpha: Real) -> Result<Self, TouchError> {
        if !(alpha > 0.0 && alpha <= 1.0) {
            return Err(TouchError::InvalidParameter {
                name: "contact smoothing",
                value: alpha,
                reason: "must be in (0, 1]",
            });
        }
        Ok(Self {
            alpha,
            previous: None,
        })
    }

    /// Forgets the previous map.
    pub fn reset(&mut self) {
        self.previous = None;
    }

    /// Smooths one frame's map.
    pub fn smooth(&mut self, map: &ContactMap) -> ContactMap {
        let out = match &self.previous {
            Some(prev)
                if prev.fingers.len() == map.fingers.len()
                    && prev
                        .fingers
                        .iter()
                        .zip(&map.fingers)
                        .all(|(a, b)| a.len() == b.len()) =>
            {
                ContactMap {
                    fingers: prev
                        .fingers
                        .iter()
                        .zip(&map.fingers)
                        .map(|(a, b)| {
                            a.iter()
                                .zip(b)
                                .map(|(p, n)| self.alpha * n + (1.0 - self.alpha) * p)
                                .collect()
                        })
                        .collect(),
                }
            }
            _ => map.clone(),
        };
        self.previous = Some(out.clone());
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::SeededRng;

    fn kp(p: Option<Point3>) -> HandKeypoints {
        HandKeypoints {
            fingers: vec![vec![p]],
        }
    }

    /// RMS error of the raw and the filtered positions of a marker moving 0.2 mm per frame
    /// along x, measured with 0.4 mm noise per axis and missed every tenth frame.
    fn steady_motion(config: KalmanConfig) -> (Real, Real) {
        let mut rng = SeededRng::new(4);
        let mut f = KeypointFilter::new(config).unwrap();
        let (mut raw_sq, mut filtered_sq, mut n) = (0.0, 0.0, 0);
        for k in 0..300 {
            let truth = Point3::new(2e-4 * Real::from(k), 0.01, 0.05);
            let noise = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * 4e-4;
            let z = truth + noise;
            let seen = k % 10 != 5;
            let out = f.filter(&kp(seen.then_some(z)));
            match out.fingers[0][0] {
                Some(p) => {
                    assert!(seen);
                    if k > 30 {
                        raw_sq += (z - truth).norm_squared();
                        filtered_sq += (p - truth).norm_squared();
                        n += 1;
                    }
                }
                None => assert!(!seen, "frame {k}: a missed marker must stay missing"),
            }
        }
        (
            (raw_sq / n as Real).sqrt(),
            (filtered_sq / n as Real).sqrt(),
        )
    }

    #[test]
    fn the_filter_reduces_noise_on_a_steady_motion_and_never_invents_a_marker() {
        // The default follows accelerations of 0.5 mm per frame, so it smooths little; a filter
        // told the motion is steadier removes most of the noise without lagging behind it.
        let (raw, filtered) = steady_motion(KalmanConfig::default());
        assert!(
            filtered < 0.9 * raw,
            "default: filtered {filtered} vs raw {raw}"
        );
        let (raw, filtered) = steady_motion(KalmanConfig {
            acceleration_std_m: 2e-5,
            ..KalmanConfig::default()
        });
        assert!(
            filtered < 0.5 * raw,
            "steady: filtered {filtered} vs raw {raw}"
        );
    }

    #[test]
    fn smoothing_is_an_exponential_average() {
        let mut s = ContactSmoother::new(0.5).unwrap();
        let map = |p: Real| ContactMap {
            fingers: vec![vec![p, 1.0 - p]],
        };
        assert_eq!(s.smooth(&map(1.0)), map(1.0));
        assert_eq!(s.smooth(&map(0.0)).fingers[0], vec![0.5, 0.5]);
        assert_eq!(s.smooth(&map(0.0)).fingers[0], vec![0.25, 0.75]);
        for alpha in [0.0, 1.5, Real::NAN] {
            assert!(matches!(
                ContactSmoother::new(alpha),
                Err(TouchError::InvalidParameter {
                    name: "contact smoothing",
                    ..
                })
            ));
        }
        assert!(ContactSmoother::new(1.0).is_ok());
        assert!(matches!(
            KeypointFilter::new(KalmanConfig {
                measurement_std_m: -1.0,
                ..KalmanConfig::default()
            }),
            Err(TouchError::InvalidParameter {
                name: "kalman measurement_std_m",
                ..
            })
        ));
    }
}
