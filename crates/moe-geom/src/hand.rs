//! The MOE hand: N fingers on a palm, each with its `hand_from_finger` pose.

use std::f64::consts::PI;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::GeomError;
use crate::finger::{FingerModel, FingerParams};
use crate::math::{Iso3, Point3, Real, Vector3};
use crate::transform::HandFromFinger;

/// A finger mounted on the palm.
#[derive(Debug, Clone, PartialEq)]
pub struct HandFinger {
    /// The finger's rest geometry, in its own frame.
    pub model: FingerModel,
    /// Where the finger's base sits on the palm.
    pub hand_from_finger: HandFromFinger,
}

/// The built-in hand layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum HandPreset {
    /// Two fingers facing each other (the paper's main configuration).
    TwoFinger,
    /// Three fingers at 120° (the paper's paper-grasping configuration).
    ThreeFinger,
    /// Five fingers evenly around the palm.
    FiveFinger,
}

impl HandPreset {
    /// All presets.
    pub const ALL: [HandPreset; 3] = [Self::TwoFinger, Self::ThreeFinger, Self::FiveFinger];

    /// The preset's command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Self::TwoFinger => "two-finger",
            Self::ThreeFinger => "three-finger",
            Self::FiveFinger => "five-finger",
        }
    }

    /// Number of fingers.
    pub fn num_fingers(self) -> usize {
        match self {
            Self::TwoFinger => 2,
            Self::ThreeFinger => 3,
            Self::FiveFinger => 5,
        }
    }

    /// Distance from the palm centre to each finger's base centre, metres.
    pub fn palm_radius_m(self) -> Real {
        match self {
            Self::TwoFinger => 0.025,
            Self::ThreeFinger => 0.028,
            Self::FiveFinger => 0.035,
        }
    }
}

impl FromStr for HandPreset {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown hand preset '{s}' (expected two-finger, three-finger or five-finger)"
                )
            })
    }
}

impl std::fmt::Display for HandPreset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Pose of finger `k` of `n` evenly spaced on a circle of radius `palm_radius_m`, its +x (marker)
/// side facing the palm's axis.
pub fn ring_pose(k: usize, n: usize, palm_radius_m: Real) -> HandFromFinger {
    let theta = 2.0 * PI * k as Real / n as Real;
    let position = Vector3::new(
        palm_radius_m * theta.cos(),
        palm_radius_m * theta.sin(),
        0.0,
    );
    HandFromFinger::new(Iso3::new(position, Vector3::z() * (theta + PI)))
}

/// A multi-finger hand.
#[derive(Debug, Clone, PartialEq)]
pub struct HandModel {
    fingers: Vec<HandFinger>,
}

impl HandModel {
    /// A hand from explicitly placed fingers.
    ///
    /// # Errors
    /// [`GeomError::EmptyPointSet`] when there are no fingers.
    pub fn new(fingers: Vec<HandFinger>) -> Result<Self, GeomError> {
        if fingers.is_empty() {
            return Err(GeomError::EmptyPointSet {
                what: "hand fingers",
            });
        }
        Ok(Self { fingers })
    }

    /// A built-in layout with identical parametric fingers.
    ///
    /// # Errors
    /// Invalid finger parameters.
    pub fn preset(preset: HandPreset, params: &FingerParams) -> Result<Self, GeomError> {
        let model = FingerModel::from_params(params)?;
        let n = preset.num_fingers();
        let fingers = (0..n)
            .map(|k| HandFinger {
                model: model.clone(),
                hand_from_finger: ring_pose(k, n, preset.palm_radius_m()),
            })
            .collect();
        Self::new(fingers)
    }

    /// The fingers.
    pub fn fingers(&self) -> &[HandFinger] {
        &self.fingers
    }

    /// Number of fingers.
    pub fn num_fingers(&self) -> usize {
        self.fingers.len()
    }

    /// The number of tendons of each finger, for formats that record one count for the hand
    /// (data sets, episodes).
    ///
    /// # Errors
    /// [`GeomError::FingerLengthMismatch`] naming the first finger whose count differs from
    /// finger 0's.
    pub fn tendons_per_finger(&self) -> Result<usize, GeomError> {
        let expected = self.fingers[0].model.tendon_routes().len();
        match self
            .fingers
            .iter()
            .enumerate()
            .find(|(_, f)| f.model.tendon_routes().len() != expected)
        {
            Some((finger, f)) => Err(GeomError::FingerLengthMismatch {
                what: "tendons (one count for every finger)",
                finger,
                expected,
                got: f.model.tendon_routes().len(),
            }),
            None => Ok(expected),
        }
    }

    /// Total vertex count over all fingers.
    pub fn num_vertices(&self) -> usize {
        self.fingers
            .iter()
            .map(|f| f.model.mesh().num_vertices())
            .sum()
    }

    /// Rest vertices of finger `i` in the hand frame.
    pub fn rest_vertices_in_hand(&self, i: usize) -> Vec<Point3> {
        let f = &self.fingers[i];
        f.hand_from_finger
            .transform_points(f.model.mesh().vertices())
    }

    /// The markers every finger shows when its surface vertices are `fingers[f]` (one list per
    /// finger, in whatever frame they are given): each marker at its vertex, observed. A marker
    /// whose vertex a list lacks, or a finger without a list, is unobserved.
    pub fn keypoints_on<V: AsRef<[Point3]>>(&self, fingers: &[V]) -> HandKeypoints {
        HandKeypoints {
            fingers: self
                .fingers
                .iter()
                .enumerate()
                .map(|(i, f)| {
                    let v = fingers.get(i).map_or(&[][..], AsRef::as_ref);
                    f.model
                        .marker_vertices()
                        .iter()
                        .map(|&m| v.get(m as usize).copied())
                        .collect()
                })
                .collect(),
        }
    }

    /// Rest marker positions of every finger in the hand frame (all present).
    pub fn rest_keypoints(&self) -> HandKeypoints {
        HandKeypoints {
            fingers: self
                .fingers
                .iter()
                .map(|f| {
                    f.model
                        .marker_positions()
                        .iter()
                        .map(|p| Some(f.hand_from_finger.transform_point(p)))
                        .collect()
                })
                .collect(),
        }
    }
}

/// Observed marker keypoints of a hand in the hand frame: per finger, per marker, `None` when the
/// marker was not seen in this frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandKeypoints {
    /// `fingers[f][m]` is marker `m` of finger `f`.
    pub fingers: Vec<Vec<Option<Point3>>>,
}

impl HandKeypoints {
    /// The same keypoints, every observed one moved by independent Gaussian noise of
    /// `sigma_m` per coordinate (drawn from `rng` marker by marker, x, y then z); unobserved
    /// ones stay unobserved.
    #[must_use]
    pub fn with_noise(&self, sigma_m: Real, rng: &mut crate::SeededRng) -> Self {
        Self {
            fingers: self
                .fingers
                .iter()
                .map(|f| {
                    f.iter()
                        .map(|m| {
                            m.map(|p| {
                                Point3::new(
                                    p.x + sigma_m * rng.normal(),
                                    p.y + sigma_m * rng.normal(),
                                    p.z + sigma_m * rng.normal(),
                                )
                            })
                        })
                        .collect()
                })
                .collect(),
        }
    }

    /// Checks that the keypoints fit `hand` (one list per finger, one entry per marker, finite).
    ///
    /// # Errors
    /// [`GeomError::LengthMismatch`] or [`GeomError::NonFinitePoint`].
    pub fn check_against(&self, hand: &HandModel) -> Result<(), GeomError> {
        if self.fingers.len() != hand.num_fingers() {
            return Err(GeomError::LengthMismatch {
                what: "keypoint fingers",
                expected: hand.num_fingers(),
                got: self.fingers.len(),
            });
        }
        for (kp, f) in self.fingers.iter().zip(hand.fingers()) {
            let expected = f.model.marker_vertices().len();
            if kp.len() != expected {
                return Err(GeomError::LengthMismatch {
                    what: "keypoints of a finger",
                    expected,
                    got: kp.len(),
                });
            }
            if let Some(index) = kp
                .iter()
                .position(|p| p.is_some_and(|p| !crate::math::is_finite_point(&p)))
            {
                return Err(GeomError::NonFinitePoint {
                    what: "keypoints",
                    index,
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::chamfer::PointIndex;

    /// The two-finger hand with small meshes (128 vertices a finger), for tests of this crate.
    pub(crate) fn small_hand() -> HandModel {
        let params = FingerParams {
            vertex_budget: 128,
            ..FingerParams::default()
        };
        HandModel::preset(HandPreset::TwoFinger, &params).unwrap()
    }

    #[test]
    fn one_tendon_count_for_the_hand_or_the_finger_that_differs() {
        let hand = HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default()).unwrap();
        assert_eq!(hand.tendons_per_finger().unwrap(), 4);
        let mut fingers = hand.fingers().to_vec();
        let f = &fingers[2].model;
        fingers[2].model = FingerModel::from_parts(
            f.mesh().clone(),
            f.marker_vertices().to_vec(),
            f.base_vertices().to_vec(),
            f.tendon_routes()[..2].to_vec(),
        )
        .unwrap();
        crate::assert_err!(
            HandModel::new(fingers).unwrap().tendons_per_finger(),
            GeomError::FingerLengthMismatch {
                finger: 2,
                expected: 4,
                got: 2,
                ..
            }
        );
    }

    #[test]
    fn noise_moves_observed_keypoints_by_its_scale_and_keeps_the_unobserved() {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let mut kp = hand.rest_keypoints();
        kp.fingers[1][2] = None;
        let draw = |sigma| kp.with_noise(sigma, &mut crate::SeededRng::new(5));
        assert_eq!(draw(0.0), kp);
        assert_eq!(draw(1e-3), draw(1e-3));
        let noisy = draw(1e-3);
        assert_eq!(noisy.fingers[1][2], None);
        let moves: Vec<Real> = noisy
            .fingers
            .iter()
            .flatten()
            .zip(kp.fingers.iter().flatten())
            .filter_map(|(a, b)| Some((a.as_ref()? - b.as_ref()?).norm()))
            .collect();
        assert_eq!(moves.len(), 13);
        // A 3-D Gaussian of 1 mm per coordinate: every move under 6 mm, their RMS about √3 mm.
        assert!(moves.iter().all(|&m| m > 0.0 && m < 6e-3), "{moves:?}");
        let rms = (moves.iter().map(|m| m * m).sum::<Real>() / 13.0).sqrt();
        assert!((0.8e-3..2.8e-3).contains(&rms), "{rms}");
    }

    #[test]
    fn keypoints_on_the_rest_surfaces_are_the_rest_keypoints_and_missing_vertices_unobserved() {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let rest: Vec<Vec<Point3>> = (0..2).map(|i| hand.rest_vertices_in_hand(i)).collect();
        let kp = hand.keypoints_on(&rest);
        let expected = hand.rest_keypoints();
        for (a, b) in kp
            .fingers
            .iter()
            .flatten()
            .zip(expected.fingers.iter().flatten())
        {
            assert!((a.unwrap() - b.unwrap()).norm() < 1e-12);
        }
        // Finger 1 without vertices, finger 0 cut before its last marker's vertex.
        let last = *hand.fingers()[0]
            .model
            .marker_vertices()
            .iter()
            .max()
            .unwrap() as usize;
        let kp = hand.keypoints_on(&[rest[0][..last].to_vec()]);
        assert!(kp.fingers[1].iter().all(Option::is_none));
        assert_eq!(kp.fingers[0].iter().filter(|m| m.is_none()).count(), 1);
    }

    #[test]
    fn presets_place_fingers_apart_and_facing_inward() {
        for preset in HandPreset::ALL {
            let hand = HandModel::preset(preset, &FingerParams::default()).unwrap();
            assert_eq!(hand.num_fingers(), preset.num_fingers());
            assert_eq!(
                hand.num_vertices(),
                preset.num_fingers() * hand.fingers()[0].model.mesh().num_vertices()
            );
            for (i, f) in hand.fingers().iter().enumerate() {
                // The marker side (+x of the finger) points toward the palm axis.
                let base = f.hand_from_finger.transform_point(&Point3::origin());
                let inward = f.hand_from_finger.transform_vector(&Vector3::x());
                assert!(inward.dot(&(-base.coords)) > 0.99 * base.coords.norm());
                // Fingers do not overlap: the closest vertices of two fingers are apart.
                let vi = hand.rest_vertices_in_hand(i);
                for j in (i + 1)..hand.num_fingers() {
                    let index = PointIndex::new(&hand.rest_vertices_in_hand(j), "finger").unwrap();
                    let gap = index
                        .nearest_distances(&vi)
                        .into_iter()
                        .fold(Real::INFINITY, Real::min);
                    assert!(
                        gap > 0.002,
                        "{preset}: fingers {i} and {j} are {gap} m apart"
                    );
                }
            }
        }
    }

    #[test]
    fn preset_names_round_trip() {
        for p in HandPreset::ALL {
            assert_eq!(p.name().parse::<HandPreset>().unwrap(), p);
        }
        let e = "four-finger".parse::<HandPreset>().unwrap_err();
        assert!(e.contains("'four-finger'"), "{e}");
    }

    #[test]
    fn keypoints_are_checked_against_the_hand() {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let mut kp = hand.rest_keypoints();
        kp.check_against(&hand).unwrap();
        kp.fingers[1][3] = Some(Point3::new(0.0, Real::INFINITY, 0.0));
        assert_eq!(
            kp.check_against(&hand),
            Err(GeomError::NonFinitePoint {
                what: "keypoints",
                index: 3
            })
        );
        kp.fingers.pop();
        assert!(matches!(
            kp.check_against(&hand),
            Err(GeomError::LengthMismatch { .. })
        ));
    }
}
