//! What an estimator is told about one instant of a hand: the one observation type.
//!
//! An [`Observation`] borrows what the caller has — the markers seen (keypoints), the tendon
//! pulls the robot commanded, the wrist pose, the time and the wrist camera's depth image
//! ([`DepthImage`]) — and an [`OwnedObservation`] holds
//! the same values (to store them, send them to another thread, or read them from a file).
//! Every field is optional: an estimator takes what it needs and refuses, naming it, what it
//! needs and was not given. Both types are `#[non_exhaustive]` and built with the `with_*`
//! methods, so that a new kind of observation is one more optional field (as the depth image
//! was), and code that builds observations keeps compiling.
//!
//! A camera frame itself is an [`RgbdFrame`]: the pipeline finds the markers in it and adds them,
//! with the frame's depth image and the camera that took it, to the caller's observation.

use serde::{Deserialize, Serialize};

use crate::depth::{DepthImage, OwnedDepthImage};
use crate::hand::HandKeypoints;
use crate::math::Real;
use crate::transform::WorldFromHand;

/// One observation of a hand, borrowed: the markers seen, the tendon pulls, the wrist pose and
/// the time, each where the caller has it.
///
/// ```
/// use moe_geom::{HandKeypoints, Observation, WorldFromHand};
///
/// let keypoints = HandKeypoints { fingers: vec![vec![None; 7]; 2] };
/// let pulls = vec![vec![0.002, 0.0], vec![0.0, 0.0]];
/// let obs = Observation::from_keypoints(&keypoints)
///     .with_tendon_pulls(&pulls)
///     .with_world_from_hand(WorldFromHand::identity())
///     .with_time(0.05);
/// assert_eq!(obs.time_secs, Some(0.05));
/// assert_eq!(obs.to_owned_observation().view(), obs);
/// ```
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[non_exhaustive]
pub struct Observation<'a> {
    /// The observed markers, hand frame, `None` per marker where it was not seen (`None` where
    /// the caller has no markers).
    pub keypoints: Option<&'a HandKeypoints>,
    /// `tendon_pull_m[f][t]`: pulled length of tendon `t` of finger `f`, metres, in the order of
    /// the finger model's tendon routes (negative pays the tendon out).
    pub tendon_pull_m: Option<&'a [Vec<Real>]>,
    /// Where the hand is (gravity's direction in the hand; contact points in the world).
    pub world_from_hand: Option<WorldFromHand>,
    /// Time of the observation, seconds on a clock that only moves forward: observations close
    /// in time form a stream for estimators that carry state; `None` for a lone frame.
    pub time_secs: Option<Real>,
    /// The wrist camera's depth image with its camera (`None` where the caller has none).
    pub depth: Option<DepthImage<'a>>,
}

impl<'a> Observation<'a> {
    /// An observation of nothing yet (add to it with the `with_*` methods).
    pub fn new() -> Self {
        Self::default()
    }

    /// The markers alone.
    pub fn from_keypoints(keypoints: &'a HandKeypoints) -> Self {
        Self::new().with_keypoints(keypoints)
    }

    /// The same observation with the markers.
    #[must_use]
    pub fn with_keypoints(self, keypoints: &'a HandKeypoints) -> Self {
        Self {
            keypoints: Some(keypoints),
            ..self
        }
    }

    /// The same observation with the tendon pulls `tendon_pull_m[f][t]`, metres.
    #[must_use]
    pub fn with_tendon_pulls(self, tendon_pull_m: &'a [Vec<Real>]) -> Self {
        Self {
            tendon_pull_m: Some(tendon_pull_m),
            ..self
        }
    }

    /// The same observation with the wrist pose.
    #[must_use]
    pub fn with_world_from_hand(self, world_from_hand: WorldFromHand) -> Self {
        Self {
            world_from_hand: Some(world_from_hand),
            ..self
        }
    }

    /// The same observation at `time_secs` seconds.
    #[must_use]
    pub fn with_time(self, time_secs: Real) -> Self {
        Self {
            time_secs: Some(time_secs),
            ..self
        }
    }

    /// The same observation with the depth image `depth`.
    #[must_use]
    pub fn with_depth(self, depth: DepthImage<'a>) -> Self {
        Self {
            depth: Some(depth),
            ..self
        }
    }

    /// The same observation without a time (a lone frame).
    #[must_use]
    pub fn untimed(self) -> Self {
        Self {
            time_secs: None,
            ..self
        }
    }

    /// A copy that owns its values.
    pub fn to_owned_observation(&self) -> OwnedObservation {
        OwnedObservation {
            keypoints: self.keypoints.cloned(),
            tendon_pull_m: self.tendon_pull_m.map(<[Vec<Real>]>::to_vec),
            world_from_hand: self.world_from_hand,
            time_secs: self.time_secs,
            depth: self.depth.map(|d| d.to_owned_image()),
        }
    }
}

/// One observation of a hand that owns its values (see [`Observation`], its borrowed form).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct OwnedObservation {
    /// The observed markers, hand frame.
    #[serde(default)]
    pub keypoints: Option<HandKeypoints>,
    /// `tendon_pull_m[f][t]`: pulled length of tendon `t` of finger `f`, metres.
    #[serde(default)]
    pub tendon_pull_m: Option<Vec<Vec<Real>>>,
    /// Where the hand is.
    #[serde(default)]
    pub world_from_hand: Option<WorldFromHand>,
    /// Time of the observation, seconds.
    #[serde(default)]
    pub time_secs: Option<Real>,
    /// The wrist camera's depth image with its camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth: Option<OwnedDepthImage>,
}

impl OwnedObservation {
    /// An observation of nothing yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The same observation with the markers.
    #[must_use]
    pub fn with_keypoints(self, keypoints: HandKeypoints) -> Self {
        Self {
            keypoints: Some(keypoints),
            ..self
        }
    }

    /// The same observation with the tendon pulls `tendon_pull_m[f][t]`, metres.
    #[must_use]
    pub fn with_tendon_pulls(self, tendon_pull_m: Vec<Vec<Real>>) -> Self {
        Self {
            tendon_pull_m: Some(tendon_pull_m),
            ..self
        }
    }

    /// The same observation with the wrist pose.
    #[must_use]
    pub fn with_world_from_hand(self, world_from_hand: WorldFromHand) -> Self {
        Self {
            world_from_hand: Some(world_from_hand),
            ..self
        }
    }

    /// The same observation at `time_secs` seconds.
    #[must_use]
    pub fn with_time(self, time_secs: Real) -> Self {
        Self {
            time_secs: Some(time_secs),
            ..self
        }
    }

    /// The same observation with the depth image `depth`.
    #[must_use]
    pub fn with_depth(self, depth: OwnedDepthImage) -> Self {
        Self {
            depth: Some(depth),
            ..self
        }
    }

    /// The observation, borrowed (what estimators take).
    pub fn view(&self) -> Observation<'_> {
        Observation {
            keypoints: self.keypoints.as_ref(),
            tendon_pull_m: self.tendon_pull_m.as_deref(),
            world_from_hand: self.world_from_hand,
            time_secs: self.time_secs,
            depth: self.depth.as_ref().map(OwnedDepthImage::view),
        }
    }
}

impl From<Observation<'_>> for OwnedObservation {
    fn from(obs: Observation<'_>) -> Self {
        obs.to_owned_observation()
    }
}

/// One wrist-camera frame: colour (RGB8, row-major) and depth (metres along the optical axis,
/// row-major, 0 or NaN where missing), both of the camera's image size.
#[derive(Debug, Clone, Copy)]
pub struct RgbdFrame<'a> {
    /// RGB8, three bytes per pixel.
    pub color_rgb8: &'a [u8],
    /// Depth, metres.
    pub depth_m: &'a [f32],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Iso3, Point3, Vector3};

    #[test]
    fn an_observation_round_trips_through_its_owned_form_and_serde() {
        let keypoints = HandKeypoints {
            fingers: vec![vec![Some(Point3::new(0.01, 0.0, 0.05)), None]],
        };
        let pulls = vec![vec![0.003, -0.001]];
        let pose = WorldFromHand::new(Iso3::translation(0.1, 0.2, 0.3));
        let obs = Observation::from_keypoints(&keypoints)
            .with_tendon_pulls(&pulls)
            .with_world_from_hand(pose)
            .with_time(1.25);
        let owned = obs.to_owned_observation();
        assert_eq!(owned.view(), obs);
        assert_eq!(OwnedObservation::from(obs), owned);
        let text = serde_json::to_string(&owned).unwrap();
        let back: OwnedObservation = serde_json::from_str(&text).unwrap();
        assert_eq!(back, owned);
        assert_eq!(
            back.world_from_hand
                .unwrap()
                .transform_vector(&Vector3::x()),
            Vector3::x()
        );
        // Built owned, the same values.
        let built = OwnedObservation::new()
            .with_keypoints(keypoints.clone())
            .with_tendon_pulls(pulls.clone())
            .with_world_from_hand(pose)
            .with_time(1.25);
        assert_eq!(built, owned);
        // An empty observation has nothing; a lone frame has no time.
        assert_eq!(Observation::new().keypoints, None);
        assert_eq!(obs.untimed().time_secs, None);
        assert_eq!(obs.untimed().keypoints, Some(&keypoints));
        // A field a reader does not know is refused, not dropped.
        assert!(serde_json::from_str::<OwnedObservation>(r#"{"depth": 1}"#).is_err());
        assert_eq!(
            serde_json::from_str::<OwnedObservation>("{}").unwrap(),
            OwnedObservation::new()
        );
    }
}
