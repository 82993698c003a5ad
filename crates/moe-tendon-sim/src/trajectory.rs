//! Kinematic trajectories: rigid poses and tendon commands interpolated between keyframes
//! (piecewise linear; rotations by spherical interpolation; held constant before the first and
//! after the last keyframe).

use moe_geom::math::UnitQuat;
use moe_geom::{Iso3, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::SimError;

/// A pose at a time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseKeyframe {
    /// Time, seconds.
    pub time_secs: Real,
    /// Translation, metres.
    #[serde(default)]
    pub translation_m: [Real; 3],
    /// Rotation as an axis-angle vector (axis × angle), radians.
    #[serde(default)]
    pub rotation_rad: [Real; 3],
}

impl PoseKeyframe {
    /// A keyframe at `time_secs` with a translation only.
    pub fn at(time_secs: Real, translation_m: [Real; 3]) -> Self {
        Self {
            time_secs,
            translation_m,
            rotation_rad: [0.0; 3],
        }
    }

    fn iso(&self) -> Iso3 {
        Iso3::new(
            Vector3::from(self.translation_m),
            Vector3::from(self.rotation_rad),
        )
    }
}

/// A rigid motion over time given by keyframes (approach, press, hold, retract … are simply
/// keyframes). An empty trajectory is the identity pose.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseTrajectory {
    /// Keyframes with strictly increasing times.
    #[serde(default)]
    pub keyframes: Vec<PoseKeyframe>,
}

impl PoseTrajectory {
    /// A constant pose.
    pub fn fixed(translation_m: [Real; 3], rotation_rad: [Real; 3]) -> Self {
        Self {
            keyframes: vec![PoseKeyframe {
                time_secs: 0.0,
                translation_m,
                rotation_rad,
            }],
        }
    }

    /// Checks the keyframes.
    ///
    /// # Errors
    /// [`SimError::InvalidKeyframe`] for a non-finite value or non-increasing times.
    pub fn validate(&self, what: &'static str) -> Result<(), SimError> {
        for (index, k) in self.keyframes.iter().enumerate() {
            let finite = k.time_secs.is_finite()
                && k.translation_m
                    .iter()
                    .chain(&k.rotation_rad)
                    .all(|v| v.is_finite());
            if !finite {
                return Err(SimError::InvalidKeyframe {
                    what,
                    index,
                    reason: "non-finite value",
                });
            }
            if index > 0 && k.time_secs <= self.keyframes[index - 1].time_secs {
                return Err(SimError::InvalidKeyframe {
                    what,
                    index,
                    reason: "times must increase strictly",
                });
            }
        }
        Ok(())
    }

    /// The pose at time `t`.
    pub fn pose_at(&self, t: Real) -> Iso3 {
        let k = &self.keyframes;
        match k.len() {
            0 => Iso3::identity(),
            _ if t <= k[0].time_secs => k[0].iso(),
            _ if t >= k[k.len() - 1].time_secs => k[k.len() - 1].iso(),
            _ => {
                let i = k.partition_point(|f| f.time_secs <= t) - 1;
                let (a, b) = (&k[i], &k[i + 1]);
                let s = (t - a.time_secs) / (b.time_secs - a.time_secs);
                let (ia, ib) = (a.iso(), b.iso());
                let tr = ia.translation.vector.lerp(&ib.translation.vector, s);
                let rot: UnitQuat = ia.rotation.slerp(&ib.rotation, s);
                Iso3::from_parts(tr.into(), rot)
            }
        }
    }
}

/// Tendon commands of one finger at a time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuationKeyframe {
    /// Time, seconds.
    pub time_secs: Real,
    /// One value per tendon: pulled length in metres (displacement mode) or tension in newtons
    /// (force mode).
    pub values: Vec<Real>,
}

/// How a finger's tendon values are interpreted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActuationMode {
    /// Values are pulled lengths, metres (the paper's input).
    #[default]
    Displacement,
    /// Values are tensions, newtons.
    Force,
}

/// The tendon schedule of one finger: values interpolated linearly between keyframes.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuationSchedule {
    /// Displacement or force.
    #[serde(default)]
    pub mode: ActuationMode,
    /// Keyframes with strictly increasing times; none means all tendons at 0.
    #[serde(default)]
    pub keyframes: Vec<ActuationKeyframe>,
}

impl ActuationSchedule {
    /// Checks the keyframes against the finger's tendon count.
    ///
    /// # Errors
    /// [`SimError::InvalidKeyframe`] or [`SimError::LengthMismatch`].
    pub fn validate(&self, num_tendons: usize) -> Result<(), SimError> {
        for (index, k) in self.keyframes.iter().enumerate() {
            if k.values.len() != num_tendons {
                return Err(SimError::LengthMismatch {
                    what: "actuation keyframe values (one per tendon)",
                    expected: num_tendons,
                    got: k.values.len(),
                });
            }
            if !k.time_secs.is_finite() || k.values.iter().any(|v| !v.is_finite()) {
                return Err(SimError::InvalidKeyframe {
                    what: "actuation",
                    index,
                    reason: "non-finite value",
                });
            }
            if index > 0 && k.time_secs <= self.keyframes[index - 1].time_secs {
                return Err(SimError::InvalidKeyframe {
                    what: "actuation",
                    index,
                    reason: "times must increase strictly",
                });
            }
        }
        Ok(())
    }

    /// Value of tendon `j` at time `t`.
    pub fn value_at(&self, j: usize, t: Real) -> Real {
        let k = &self.keyframes;
        match k.len() {
            0 => 0.0,
            _ if t <= k[0].time_secs => k[0].values[j],
            _ if t >= k[k.len() - 1].time_secs => k[k.len() - 1].values[j],
            _ => {
                let i = k.partition_point(|f| f.time_secs <= t) - 1;
                let (a, b) = (&k[i], &k[i + 1]);
                let s = (t - a.time_secs) / (b.time_secs - a.time_secs);
                a.values[j] + (b.values[j] - a.values[j]) * s
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_interpolate_between_keyframes_and_hold_outside() {
        let tr = PoseTrajectory {
            keyframes: vec![
                PoseKeyframe::at(0.0, [0.0, 0.0, 0.0]),
                PoseKeyframe {
                    time_secs: 2.0,
                    translation_m: [2.0, 0.0, -4.0],
                    rotation_rad: [0.0, 0.0, 1.0],
                },
            ],
        };
        tr.validate("test").unwrap();
        let mid = tr.pose_at(1.0);
        assert!((mid.translation.vector - Vector3::new(1.0, 0.0, -2.0)).norm() < 1e-12);
        assert!((mid.rotation.angle() - 0.5).abs() < 1e-12);
        assert_eq!(tr.pose_at(-1.0), tr.pose_at(0.0));
        assert_eq!(tr.pose_at(5.0), tr.pose_at(2.0));
        let bad = PoseTrajectory {
            keyframes: vec![
                PoseKeyframe::at(1.0, [0.0; 3]),
                PoseKeyframe::at(1.0, [0.0; 3]),
            ],
        };
        assert!(matches!(
            bad.validate("wrist"),
            Err(SimError::InvalidKeyframe {
                what: "wrist",
                index: 1,
                ..
            })
        ));
    }

    #[test]
    fn actuation_interpolates_per_tendon() {
        let s = ActuationSchedule {
            mode: ActuationMode::Displacement,
            keyframes: vec![
                ActuationKeyframe {
                    time_secs: 0.0,
                    values: vec![0.0, 0.0],
                },
                ActuationKeyframe {
                    time_secs: 1.0,
                    values: vec![0.004, -0.002],
                },
            ],
        };
        s.validate(2).unwrap();
        assert!((s.value_at(0, 0.5) - 0.002).abs() < 1e-15);
        assert!((s.value_at(1, 3.0) + 0.002).abs() < 1e-15);
        assert!(matches!(
            s.validate(4),
            Err(SimError::LengthMismatch { .. })
        ));
    }
}
