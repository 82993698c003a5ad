//! What one instant of a hand is: its deformed shape, where it touches, its markers and its pose.
//!
//! These are the values that flow between the stages of the pipeline and that training and
//! evaluation consume in memory: a [`HandShape`] (from the simulator or from shape estimation), a
//! [`ContactMap`] (from a contact estimator), and a [`LabelledFrame`] (a simulated instant with its
//! ground truth, as a data set stores it).
//!
//! The two estimator seams live here too, beside the values they exchange, so that an estimator's
//! crate needs nothing of the others': a [`ShapeEstimator`] turns keypoints (a [`ShapeInput`])
//! into a [`HandShape`], and a [`ContactEstimator`] turns a shape with the rest of its observation
//! (a [`ContactInput`]) into a [`ContactEstimate`].

use serde::{Deserialize, Serialize};

use crate::error::GeomError;
use crate::hand::{HandKeypoints, HandModel};
use crate::math::{Point3, Real, Vector3, is_finite_point};
use crate::transform::WorldFromHand;

/// Deformed vertices of every finger, in the hand frame (metres).
///
/// Vertex `v` of finger `f` is vertex `v` of that finger's rest mesh: the shape is the rest mesh
/// with moved vertices.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandShape {
    /// `fingers[f][v]`: vertex `v` of finger `f`'s mesh.
    pub fingers: Vec<Vec<Point3>>,
}

impl HandShape {
    /// The rest shape of `hand`, in the hand frame.
    pub fn rest(hand: &HandModel) -> Self {
        Self {
            fingers: (0..hand.num_fingers())
                .map(|f| hand.rest_vertices_in_hand(f))
                .collect(),
        }
    }

    /// Total vertex count over all fingers.
    pub fn num_vertices(&self) -> usize {
        self.fingers.iter().map(Vec::len).sum()
    }

    /// Checks that the shape fits `hand` (one vertex list per finger, one vertex per rest vertex)
    /// and that every vertex is finite.
    ///
    /// # Errors
    /// [`GeomError::LengthMismatch`] naming the finger, or [`GeomError::NonFinitePoint`] naming
    /// the vertex.
    pub fn check_against(&self, hand: &HandModel) -> Result<(), GeomError> {
        if self.fingers.len() != hand.num_fingers() {
            return Err(GeomError::LengthMismatch {
                what: "fingers of the hand shape",
                expected: hand.num_fingers(),
                got: self.fingers.len(),
            });
        }
        for (f, (vertices, finger)) in self.fingers.iter().zip(hand.fingers()).enumerate() {
            let expected = finger.model.mesh().num_vertices();
            if vertices.len() != expected {
                return Err(GeomError::FingerLengthMismatch {
                    what: "vertices",
                    finger: f,
                    expected,
                    got: vertices.len(),
                });
            }
        }
        self.check_finite()
    }

    /// Checks that every vertex is finite.
    ///
    /// # Errors
    /// [`GeomError::NonFiniteFingerPoint`] naming the finger and the vertex.
    pub fn check_finite(&self) -> Result<(), GeomError> {
        for (finger, vertices) in self.fingers.iter().enumerate() {
            if let Some(index) = vertices.iter().position(|p| !is_finite_point(p)) {
                return Err(GeomError::NonFiniteFingerPoint {
                    what: "hand shape vertex",
                    finger,
                    index,
                });
            }
        }
        Ok(())
    }
}

/// One observation of a hand as a shape estimator sees it: its keypoints and, where the caller
/// has them, the tendon pulls, the wrist pose and the time.
#[derive(Debug, Clone, Copy)]
pub struct ShapeInput<'a> {
    /// The observed markers, hand frame (`None` where a marker was not seen).
    pub keypoints: &'a HandKeypoints,
    /// `tendon_pull_m[f][t]`: pulled length of tendon `t` of finger `f`, metres, in the order of
    /// the finger model's tendon routes (`None` where the caller has none).
    pub tendon_pull_m: Option<&'a [Vec<f64>]>,
    /// Where the hand is (`None` where the caller does not know).
    pub world_from_hand: Option<&'a WorldFromHand>,
    /// Time of the observation, seconds (`None` where the caller has none).
    pub time_secs: Option<f64>,
}

impl<'a> ShapeInput<'a> {
    /// Keypoints alone.
    pub fn keypoints(keypoints: &'a HandKeypoints) -> Self {
        Self {
            keypoints,
            tendon_pull_m: None,
            world_from_hand: None,
            time_secs: None,
        }
    }

    /// The same observation with the tendon pulls `tendon_pull_m[f][t]`, metres.
    #[must_use]
    pub fn with_tendon_pulls(self, tendon_pull_m: &'a [Vec<f64>]) -> Self {
        Self {
            tendon_pull_m: Some(tendon_pull_m),
            ..self
        }
    }

    /// The same observation with the wrist pose.
    #[must_use]
    pub fn with_world_from_hand(self, world_from_hand: &'a WorldFromHand) -> Self {
        Self {
            world_from_hand: Some(world_from_hand),
            ..self
        }
    }

    /// The same observation at `time_secs` seconds.
    #[must_use]
    pub fn with_time(self, time_secs: f64) -> Self {
        Self {
            time_secs: Some(time_secs),
            ..self
        }
    }
}

/// Something that estimates a hand's deformed shape from one frame of keypoints (SR-ARAP, or
/// the shape of the nearest training frame).
pub trait ShapeEstimator {
    /// What can go wrong.
    type Error: std::error::Error + Send + Sync + 'static;

    /// The shape of one frame. Estimators that track (warm starts, marker identities) keep their
    /// state between calls, hence `&mut self`.
    ///
    /// # Errors
    /// Keypoints that do not fit the estimator's hand, or a failed estimate.
    fn estimate_shape(&mut self, keypoints: &HandKeypoints) -> Result<HandShape, Self::Error>;

    /// The shape of one observation with everything the caller has of it. Estimators that use
    /// the pulls, the pose or the time override it; by default it is
    /// [`ShapeEstimator::estimate_shape`] of `input.keypoints`.
    ///
    /// # Errors
    /// As [`ShapeEstimator::estimate_shape`], and what an overriding estimator needs and was not
    /// given, or was given in a form that does not fit its hand.
    fn estimate_shape_with(&mut self, input: &ShapeInput<'_>) -> Result<HandShape, Self::Error> {
        self.estimate_shape(input.keypoints)
    }

    /// Forgets what was carried from frame to frame (a warm start, for example), so that the
    /// next frame is estimated as a first one. Stateless estimators keep the default, which
    /// does nothing.
    fn reset(&mut self) {}
}

/// One observation of a hand as a contact estimator sees it: its (estimated) deformed shape and,
/// where the caller has them, its keypoints, the tendon pulls the robot commanded, the wrist pose
/// and the time.
#[derive(Debug, Clone, Copy)]
pub struct ContactInput<'a> {
    /// The (estimated) deformed surface of every finger, hand frame.
    pub shape: &'a HandShape,
    /// The observed markers, hand frame (`None` where the caller has none).
    pub keypoints: Option<&'a HandKeypoints>,
    /// `tendon_pull_m[f][t]`: pulled length of tendon `t` of finger `f`, metres, in the order of
    /// the finger model's tendon routes (`None` where the caller has none).
    pub tendon_pull_m: Option<&'a [Vec<f64>]>,
    /// Where the hand is (a physical estimator takes gravity's direction from it; `None` where
    /// the caller does not know).
    pub world_from_hand: Option<&'a WorldFromHand>,
    /// Time of the observation, seconds, for estimators that carry state between frames (`None`
    /// where the caller has none).
    pub time_secs: Option<f64>,
}

impl<'a> ContactInput<'a> {
    /// A shape alone.
    pub fn shape(shape: &'a HandShape) -> Self {
        Self {
            shape,
            keypoints: None,
            tendon_pull_m: None,
            world_from_hand: None,
            time_secs: None,
        }
    }

    /// A labelled frame's observation with `shape` in place of its own (an estimate of it): the
    /// frame's markers, tendon pulls and wrist pose; no time (a data set's frames are not a
    /// stream).
    pub fn of_frame(frame: &'a LabelledFrame, shape: &'a HandShape) -> Self {
        Self {
            shape,
            keypoints: Some(&frame.markers),
            tendon_pull_m: Some(&frame.tendon_pull_m),
            world_from_hand: Some(&frame.world_from_hand),
            time_secs: None,
        }
    }

    /// The same observation with the keypoints.
    #[must_use]
    pub fn with_keypoints(self, keypoints: &'a HandKeypoints) -> Self {
        Self {
            keypoints: Some(keypoints),
            ..self
        }
    }

    /// The same observation with the tendon pulls `tendon_pull_m[f][t]`, metres.
    #[must_use]
    pub fn with_tendon_pulls(self, tendon_pull_m: &'a [Vec<f64>]) -> Self {
        Self {
            tendon_pull_m: Some(tendon_pull_m),
            ..self
        }
    }

    /// The same observation with the wrist pose.
    #[must_use]
    pub fn with_world_from_hand(self, world_from_hand: &'a WorldFromHand) -> Self {
        Self {
            world_from_hand: Some(world_from_hand),
            ..self
        }
    }

    /// The same observation at `time_secs` seconds.
    #[must_use]
    pub fn with_time(self, time_secs: f64) -> Self {
        Self {
            time_secs: Some(time_secs),
            ..self
        }
    }
}

/// What a contact estimator says about one observation: a contact probability per vertex and,
/// for estimators that estimate it, the force on every vertex.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactEstimate {
    /// Per-vertex contact probability.
    pub map: ContactMap,
    /// `vertex_force_n[f][v]`: force on vertex `v` of finger `f`, hand frame, newtons, for
    /// estimators that estimate force (`None` otherwise).
    pub vertex_force_n: Option<Vec<Vec<Vector3>>>,
}

impl ContactEstimate {
    /// A contact map without forces.
    pub fn from_map(map: ContactMap) -> Self {
        Self {
            map,
            vertex_force_n: None,
        }
    }

    /// Per finger, the sum of its vertices' forces, hand frame, newtons (`None` without
    /// forces).
    pub fn finger_forces_n(&self) -> Option<Vec<Vector3>> {
        self.vertex_force_n.as_ref().map(|fingers| {
            fingers
                .iter()
                .map(|f| f.iter().fold(Vector3::zeros(), |sum, v| sum + v))
                .collect()
        })
    }
}

/// Something that says, for every vertex of a deformed hand, how likely it is to touch the world
/// (the DGCNN and the KNN baseline of `moe-contact`, and physical estimators).
pub trait ContactEstimator {
    /// What can go wrong.
    type Error: std::error::Error + Send + Sync + 'static;

    /// The estimate of one observation. Stateful estimators (a memory of the stream) keep their
    /// state between calls, hence `&mut self`.
    ///
    /// # Errors
    /// An observation that does not fit the estimator's hand, non-finite input, what the
    /// estimator needs and was not given (keypoints for a keypoint-based estimator, pulls for a
    /// model that takes them), or a failed estimate.
    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, Self::Error>;

    /// Forgets what was carried from frame to frame, so that the next observation is estimated
    /// as a first one. Stateless estimators keep the default, which does nothing.
    fn reset(&mut self) {}
}

/// A mutably borrowed estimator estimates as the estimator does (so that a caller lends its
/// estimator to a pipeline and keeps it).
impl<T: ContactEstimator + ?Sized> ContactEstimator for &mut T {
    type Error = T::Error;

    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, Self::Error> {
        (**self).estimate(input)
    }

    fn reset(&mut self) {
        (**self).reset();
    }
}

/// A boxed estimator estimates as the estimator does (so that the estimator can be chosen at
/// run time).
impl<T: ContactEstimator + ?Sized> ContactEstimator for Box<T> {
    type Error = T::Error;

    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, Self::Error> {
        (**self).estimate(input)
    }

    fn reset(&mut self) {
        (**self).reset();
    }
}

/// A vertex estimated to be in contact.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ContactPoint {
    /// Finger index.
    pub finger: usize,
    /// Vertex index within the finger's mesh.
    pub vertex: u32,
    /// The vertex's position in the frame of the shape it was taken from (the hand frame for a
    /// [`HandShape`]).
    pub point: Point3,
    /// Contact probability of the vertex.
    pub probability: Real,
}

/// Per-vertex contact probability of every finger.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactMap {
    /// `fingers[f][v]`: probability in `[0, 1]` that vertex `v` of finger `f` touches the world.
    pub fingers: Vec<Vec<Real>>,
}

impl ContactMap {
    /// A map of hard labels (1 for contact, 0 otherwise), as a data set stores them.
    pub fn from_labels(labels: &[Vec<bool>]) -> Self {
        Self {
            fingers: labels
                .iter()
                .map(|f| f.iter().map(|&c| if c { 1.0 } else { 0.0 }).collect())
                .collect(),
        }
    }

    /// Total vertex count over all fingers.
    pub fn num_vertices(&self) -> usize {
        self.fingers.iter().map(Vec::len).sum()
    }
    /// Per finger and vertex, whether its probability is at or above `threshold`: the
    /// predicted labels the contact metrics score.
    pub fn labels_at(&self, threshold: Real) -> Vec<Vec<bool>> {
        self.fingers
            .iter()
            .map(|f| f.iter().map(|&p| p >= threshold).collect())
            .collect()
    }

    /// Per finger, the vertices whose probability is at least `threshold`, in increasing order.
    pub fn vertices_above(&self, threshold: Real) -> Vec<Vec<u32>> {
        self.fingers
            .iter()
            .map(|f| {
                f.iter()
                    .enumerate()
                    .filter(|&(_, &p)| p >= threshold)
                    .map(|(v, _)| v as u32)
                    .collect()
            })
            .collect()
    }

    /// The vertices whose probability is at least `threshold`, with their positions in `shape`,
    /// finger by finger and vertex by vertex in increasing order.
    ///
    /// # Errors
    /// [`GeomError::LengthMismatch`] or [`GeomError::FingerLengthMismatch`] when `shape` does not
    /// have the map's fingers and vertices.
    pub fn contacts_above(
        &self,
        threshold: Real,
        shape: &HandShape,
    ) -> Result<Vec<ContactPoint>, GeomError> {
        self.check_shape(shape)?;
        let mut out = Vec::new();
        for (finger, (probs, vertices)) in self.fingers.iter().zip(&shape.fingers).enumerate() {
            for (v, (&probability, point)) in probs.iter().zip(vertices).enumerate() {
                if probability >= threshold {
                    out.push(ContactPoint {
                        finger,
                        vertex: v as u32,
                        point: *point,
                        probability,
                    });
                }
            }
        }
        Ok(out)
    }

    /// Checks that `shape` has one vertex per probability, finger by finger.
    ///
    /// # Errors
    /// [`GeomError::LengthMismatch`] or [`GeomError::FingerLengthMismatch`].
    pub fn check_shape(&self, shape: &HandShape) -> Result<(), GeomError> {
        if self.fingers.len() != shape.fingers.len() {
            return Err(GeomError::LengthMismatch {
                what: "fingers of the contact map",
                expected: shape.fingers.len(),
                got: self.fingers.len(),
            });
        }
        for (finger, (probs, vertices)) in self.fingers.iter().zip(&shape.fingers).enumerate() {
            if probs.len() != vertices.len() {
                return Err(GeomError::FingerLengthMismatch {
                    what: "contact probabilities",
                    finger,
                    expected: vertices.len(),
                    got: probs.len(),
                });
            }
        }
        Ok(())
    }
}

/// A simulated instant of a hand with its ground truth: what a data set stores per frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledFrame {
    /// Trajectory the frame belongs to.
    pub trajectory_id: u64,
    /// Frame number within the trajectory.
    pub frame_index: u32,
    /// The deformed surface of every finger, hand frame.
    pub shape: HandShape,
    /// `contact[f][v]`: whether vertex `v` of finger `f` is in contact.
    pub contact: Vec<Vec<bool>>,
    /// Marker positions of every finger, hand frame (all present: this is the ground truth).
    pub markers: HandKeypoints,
    /// Wrist pose.
    pub world_from_hand: WorldFromHand,
    /// `tendon_pull_m[f][t]`: pulled length of tendon `t` of finger `f`, metres (what the robot
    /// commanded; negative pays the tendon out).
    pub tendon_pull_m: Vec<Vec<f64>>,
}

impl LabelledFrame {
    /// Number of vertices labelled as in contact.
    pub fn contact_count(&self) -> usize {
        self.contact.iter().flatten().filter(|&&c| c).count()
    }

    /// The ground-truth contact points (vertex ids and positions on the true surface).
    pub fn true_contacts(&self) -> Vec<ContactPoint> {
        let mut out = Vec::new();
        for (finger, (labels, vertices)) in self.contact.iter().zip(&self.shape.fingers).enumerate()
        {
            for (v, (&c, point)) in labels.iter().zip(vertices).enumerate() {
                if c {
                    out.push(ContactPoint {
                        finger,
                        vertex: v as u32,
                        point: *point,
                        probability: 1.0,
                    });
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::finger::FingerParams;
    use crate::hand::HandPreset;

    fn small_hand() -> HandModel {
        let params = FingerParams {
            vertex_budget: 128,
            ..FingerParams::default()
        };
        HandModel::preset(HandPreset::TwoFinger, &params).unwrap()
    }

    #[test]
    fn contacts_above_pick_the_vertices_at_or_over_the_threshold() {
        let hand = small_hand();
        let shape = HandShape::rest(&hand);
        let mut map = ContactMap {
            fingers: shape.fingers.iter().map(|f| vec![0.0; f.len()]).collect(),
        };
        map.fingers[0][3] = 0.5;
        map.fingers[1][7] = 0.9;
        map.fingers[1][8] = 0.49;
        let contacts = map.contacts_above(0.5, &shape).unwrap();
        assert_eq!(contacts.len(), 2);
        assert_eq!((contacts[0].finger, contacts[0].vertex), (0, 3));
        assert_eq!(contacts[0].point, shape.fingers[0][3]);
        assert_eq!((contacts[1].finger, contacts[1].vertex), (1, 7));
        assert_eq!(map.vertices_above(0.5), vec![vec![3], vec![7]]);
    }

    #[test]
    fn a_shape_of_another_hand_is_refused_by_finger() {
        let hand = small_hand();
        let mut shape = HandShape::rest(&hand);
        shape.check_against(&hand).unwrap();
        shape.fingers[1].pop();
        let err = shape.check_against(&hand).unwrap_err();
        assert!(matches!(
            err,
            GeomError::FingerLengthMismatch { finger: 1, .. }
        ));
        let map = ContactMap {
            fingers: vec![vec![0.0; 3]],
        };
        assert!(matches!(
            map.contacts_above(0.5, &shape),
            Err(GeomError::LengthMismatch { .. })
        ));
        let mut shape = HandShape::rest(&hand);
        shape.fingers[0][5].y = Real::NAN;
        assert!(matches!(
            shape.check_against(&hand),
            Err(GeomError::NonFiniteFingerPoint {
                finger: 0,
                index: 5,
                ..
            })
        ));
    }

    #[test]
    fn finger_forces_are_the_sums_of_their_vertices_forces() {
        let map = ContactMap {
            fingers: vec![vec![0.0; 2], vec![0.0; 3], Vec::new()],
        };
        assert_eq!(
            ContactEstimate::from_map(map.clone()).finger_forces_n(),
            None
        );
        let estimate = ContactEstimate {
            map,
            vertex_force_n: Some(vec![
                vec![Vector3::new(1.0, 0.0, -2.0), Vector3::new(0.5, 3.0, 0.0)],
                vec![
                    Vector3::new(0.0, 0.0, 1.0),
                    Vector3::new(0.0, 0.0, 2.0),
                    Vector3::new(-1.0, 0.0, 4.0),
                ],
                Vec::new(),
            ]),
        };
        assert_eq!(
            estimate.finger_forces_n(),
            Some(vec![
                Vector3::new(1.5, 3.0, -2.0),
                Vector3::new(-1.0, 0.0, 7.0),
                Vector3::zeros(),
            ])
        );
    }

    /// Counts its estimates and resets, and answers with the observation's time as every
    /// vertex's probability (so that a test sees which observation it was given).
    #[derive(Debug, Default)]
    struct Counting {
        estimates: usize,
        resets: usize,
    }

    impl ContactEstimator for Counting {
        type Error = GeomError;

        fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, GeomError> {
            self.estimates += 1;
            let p = input.time_secs.unwrap_or(-1.0);
            Ok(ContactEstimate::from_map(ContactMap {
                fingers: input
                    .shape
                    .fingers
                    .iter()
                    .map(|f| vec![p; f.len()])
                    .collect(),
            }))
        }

        fn reset(&mut self) {
            self.resets += 1;
        }
    }

    /// Runs `estimator` on one observation at 0.25 s and resets it, as a pipeline would.
    fn run_once<C: ContactEstimator>(mut estimator: C, shape: &HandShape) -> ContactEstimate {
        let estimate = estimator
            .estimate(&ContactInput::shape(shape).with_time(0.25))
            .map_err(|_| "the test estimator does not fail")
            .unwrap();
        estimator.reset();
        estimate
    }

    #[test]
    fn borrowed_and_boxed_contact_estimators_forward_estimates_and_resets() {
        let shape = HandShape {
            fingers: vec![vec![Point3::origin(); 3], vec![Point3::origin(); 2]],
        };
        let mut counting = Counting::default();
        let estimate = run_once(&mut counting, &shape);
        assert_eq!(estimate.map.fingers, vec![vec![0.25; 3], vec![0.25; 2]]);
        assert_eq!(estimate.vertex_force_n, None);
        assert_eq!((counting.estimates, counting.resets), (1, 1));
        {
            // An unsized box chosen at run time, lent and then given away.
            let mut boxed: Box<dyn ContactEstimator<Error = GeomError> + '_> =
                Box::new(&mut counting);
            run_once(&mut boxed, &shape);
            let estimate = run_once(boxed, &shape);
            assert_eq!(estimate.map.fingers[1], vec![0.25; 2]);
        }
        assert_eq!((counting.estimates, counting.resets), (3, 3));
    }

    #[test]
    fn contact_inputs_are_built_from_a_frame_and_builders() {
        let hand = small_hand();
        let shape = HandShape::rest(&hand);
        let frame = LabelledFrame {
            trajectory_id: 3,
            frame_index: 1,
            shape: shape.clone(),
            contact: shape.fingers.iter().map(|f| vec![false; f.len()]).collect(),
            markers: hand.rest_keypoints(),
            world_from_hand: WorldFromHand::identity(),
            tendon_pull_m: vec![vec![0.001; 4]; 2],
        };
        let input = ContactInput::of_frame(&frame, &shape);
        assert!(std::ptr::eq(input.shape, &shape));
        assert_eq!(input.keypoints, Some(&frame.markers));
        assert_eq!(input.tendon_pull_m, Some(frame.tendon_pull_m.as_slice()));
        assert!(input.world_from_hand.is_some());
        assert_eq!(input.time_secs, None);
        let built = ContactInput::shape(&shape)
            .with_keypoints(&frame.markers)
            .with_tendon_pulls(&frame.tendon_pull_m)
            .with_world_from_hand(&frame.world_from_hand)
            .with_time(1.5);
        assert_eq!(built.keypoints, input.keypoints);
        assert_eq!(built.tendon_pull_m, input.tendon_pull_m);
        assert_eq!(built.time_secs, Some(1.5));
        assert_eq!(ContactInput::shape(&shape).keypoints, None);
    }

    /// Returns a rest shape and counts which entry point was called.
    struct RestShape {
        rest: HandShape,
        calls: usize,
    }

    impl ShapeEstimator for RestShape {
        type Error = GeomError;

        fn estimate_shape(&mut self, keypoints: &HandKeypoints) -> Result<HandShape, GeomError> {
            self.calls += 1;
            if keypoints.fingers.len() == self.rest.fingers.len() {
                Ok(self.rest.clone())
            } else {
                Err(GeomError::LengthMismatch {
                    what: "fingers of the keypoints",
                    expected: self.rest.fingers.len(),
                    got: keypoints.fingers.len(),
                })
            }
        }
    }

    #[test]
    fn a_shape_estimate_with_the_whole_observation_is_by_default_one_of_its_keypoints() {
        let hand = small_hand();
        let mut estimator = RestShape {
            rest: HandShape::rest(&hand),
            calls: 0,
        };
        let keypoints = hand.rest_keypoints();
        let pulls = vec![vec![0.002; 4]; 2];
        let pose = WorldFromHand::identity();
        let input = ShapeInput::keypoints(&keypoints)
            .with_tendon_pulls(&pulls)
            .with_world_from_hand(&pose)
            .with_time(0.5);
        assert_eq!(input.time_secs, Some(0.5));
        let shape = estimator.estimate_shape_with(&input).unwrap();
        assert_eq!(shape, HandShape::rest(&hand));
        assert_eq!(estimator.calls, 1);
        let one_finger = HandKeypoints {
            fingers: keypoints.fingers[..1].to_vec(),
        };
        crate::assert_err!(
            estimator.estimate_shape_with(&ShapeInput::keypoints(&one_finger)),
            GeomError::LengthMismatch { got: 1, .. }
        );
        assert_eq!(estimator.calls, 2);
    }

    #[test]
    fn labels_become_a_map_of_zeros_and_ones() {
        let map = ContactMap::from_labels(&[vec![false, true], vec![true]]);
        assert_eq!(map.fingers, vec![vec![0.0, 1.0], vec![1.0]]);
        assert_eq!(map.num_vertices(), 3);
    }
}
