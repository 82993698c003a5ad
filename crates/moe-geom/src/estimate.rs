//! The estimator seams: what turns an [`Observation`] into the hand's shape and contact.
//!
//! - A [`HandEstimator`] is the one seam a pipeline runs: an observation in, a
//!   [`HandEstimate`] out — the hand's shape, contact per vertex, per-vertex force where the
//!   estimator estimates it, and the estimator's own [`HandEstimator::Details`] (the physics
//!   estimator's loads with their force, place and uncertainty; nothing for the paper's chain).
//!   Contact from physics implements it directly: it makes shape and contact together.
//! - The paper's chain is two stages: a [`ShapeEstimator`] (SR-ARAP, or the shape of the nearest
//!   training frame) and a [`ContactEstimator`] that scores the vertices of that shape (the DGCNN,
//!   the KNN baseline). [`Staged`] composes the two into a [`HandEstimator`].
//!
//! The seams live in `moe-geom`, beside the values they exchange, so that an estimator's crate
//! needs nothing of the others' (no candle for the physics estimator, no FEM for the network).

use crate::instant::{ContactMap, HandShape, LabelledFrame};
use crate::math::Vector3;
use crate::observation::Observation;

/// An error of one stage of a [`Staged`] estimator, boxed with the stage it came from.
#[derive(Debug, thiserror::Error)]
pub enum StageError {
    /// The shape stage failed.
    #[error("shape estimation: {0}")]
    Shape(#[source] Box<dyn std::error::Error + Send + Sync>),
    /// The contact stage failed.
    #[error("contact estimation: {0}")]
    Contact(#[source] Box<dyn std::error::Error + Send + Sync>),
}

/// Something that estimates a hand's deformed shape from an observation (SR-ARAP from the
/// markers, or the shape of the nearest training frame).
pub trait ShapeEstimator {
    /// What can go wrong.
    type Error: std::error::Error + Send + Sync + 'static;

    /// The shape of one observation. Estimators that track (warm starts, marker identities)
    /// keep their state between calls, hence `&mut self`.
    ///
    /// # Errors
    /// An observation that lacks what the estimator needs (the markers, for SR-ARAP) or does not
    /// fit its hand, or a failed estimate.
    fn estimate_shape(&mut self, observation: &Observation<'_>) -> Result<HandShape, Self::Error>;

    /// Forgets what was carried from frame to frame (a warm start, for example), so that the
    /// next frame is estimated as a first one. Stateless estimators keep the default, which
    /// does nothing.
    fn reset(&mut self) {}
}

/// What a contact estimator scores: a hand's (estimated) deformed shape and the observation it
/// was estimated from.
#[derive(Debug, Clone, Copy)]
pub struct ContactInput<'a> {
    /// The (estimated) deformed surface of every finger, hand frame.
    pub shape: &'a HandShape,
    /// What was observed (the markers for a keypoint-based estimator, the tendon pulls for a
    /// model that takes them).
    pub observation: Observation<'a>,
}

impl<'a> ContactInput<'a> {
    /// A shape and its observation.
    pub fn new(shape: &'a HandShape, observation: Observation<'a>) -> Self {
        Self { shape, observation }
    }

    /// A shape alone.
    pub fn shape(shape: &'a HandShape) -> Self {
        Self::new(shape, Observation::new())
    }

    /// A labelled frame's observation ([`LabelledFrame::observation`]) with `shape` in place of
    /// its own (an estimate of it).
    pub fn of_frame(frame: &'a LabelledFrame, shape: &'a HandShape) -> Self {
        Self::new(shape, frame.observation())
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
        finger_sums(self.vertex_force_n.as_deref())
    }
}

/// Per finger, the sum of its vertices' forces.
fn finger_sums(vertex_force_n: Option<&[Vec<Vector3>]>) -> Option<Vec<Vector3>> {
    vertex_force_n.map(|fingers| {
        fingers
            .iter()
            .map(|f| f.iter().fold(Vector3::zeros(), |sum, v| sum + v))
            .collect()
    })
}

/// Something that says, for every vertex of a deformed hand, how likely it is to touch the world
/// (the DGCNN and the KNN baseline of `moe-contact`).
pub trait ContactEstimator {
    /// What can go wrong.
    type Error: std::error::Error + Send + Sync + 'static;

    /// The estimate of one shape and its observation. Stateful estimators (a memory of the
    /// stream) keep their state between calls, hence `&mut self`.
    ///
    /// # Errors
    /// An input that does not fit the estimator's hand, non-finite input, what the estimator
    /// needs and was not given (keypoints for a keypoint-based estimator, pulls for a model
    /// that takes them), or a failed estimate.
    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, Self::Error>;

    /// Forgets what was carried from frame to frame, so that the next observation is estimated
    /// as a first one. Stateless estimators keep the default, which does nothing.
    fn reset(&mut self) {}
}

/// What a [`HandEstimator`] says about one observation.
#[derive(Debug, Clone, PartialEq)]
pub struct HandEstimate<D = ()> {
    /// The estimated surface of every finger, hand frame.
    pub shape: HandShape,
    /// Per-vertex contact probability.
    pub contact: ContactMap,
    /// `vertex_force_n[f][v]`: the force on vertex `v` of finger `f`, hand frame, newtons, from
    /// an estimator that estimates force; `None` otherwise.
    pub vertex_force_n: Option<Vec<Vec<Vector3>>>,
    /// What the estimator says beyond shape and contact.
    pub details: D,
}

impl<D> HandEstimate<D> {
    /// Per finger, the sum of its vertices' forces, hand frame, newtons (`None` without
    /// forces).
    pub fn finger_forces_n(&self) -> Option<Vec<Vector3>> {
        finger_sums(self.vertex_force_n.as_deref())
    }
}

/// The seam a pipeline runs: an observation in, the hand's shape, contact and the estimator's
/// own details out.
pub trait HandEstimator {
    /// What the estimator says beyond shape and contact (`()` for none).
    type Details;
    /// What can go wrong.
    type Error: std::error::Error + Send + Sync + 'static;

    /// The estimate of one observation. Estimators that carry a stream's state (warm starts,
    /// the free finger simulated through the stream) keep it between calls, hence `&mut self`.
    ///
    /// # Errors
    /// An observation that lacks what the estimator needs or does not fit its hand, or a failed
    /// estimate.
    fn estimate(
        &mut self,
        observation: &Observation<'_>,
    ) -> Result<HandEstimate<Self::Details>, Self::Error>;

    /// Forgets what was carried from frame to frame, so that the next observation is estimated
    /// as a first one. Stateless estimators keep the default, which does nothing.
    fn reset(&mut self) {}
}

/// A shape estimator and a contact estimator run one after the other: the contact stage scores
/// the shape the shape stage made of the same observation (the paper's chain: SR-ARAP, then the
/// DGCNN).
#[derive(Debug, Clone)]
pub struct Staged<S, C> {
    shape: S,
    contact: C,
}

impl<S, C> Staged<S, C> {
    /// `shape`, then `contact` on its shape.
    pub fn new(shape: S, contact: C) -> Self {
        Self { shape, contact }
    }

    /// The shape stage.
    pub fn shape_estimator(&self) -> &S {
        &self.shape
    }

    /// The contact stage.
    pub fn contact_estimator(&self) -> &C {
        &self.contact
    }

    /// The two stages, given back.
    pub fn into_parts(self) -> (S, C) {
        (self.shape, self.contact)
    }
}

impl<S: ShapeEstimator, C: ContactEstimator> HandEstimator for Staged<S, C> {
    type Details = ();
    type Error = StageError;

    fn estimate(&mut self, observation: &Observation<'_>) -> Result<HandEstimate, StageError> {
        let shape = self
            .shape
            .estimate_shape(observation)
            .map_err(|e| StageError::Shape(Box::new(e)))?;
        let contact = self
            .contact
            .estimate(&ContactInput::new(&shape, *observation))
            .map_err(|e| StageError::Contact(Box::new(e)))?;
        Ok(HandEstimate {
            shape,
            contact: contact.map,
            vertex_force_n: contact.vertex_force_n,
            details: (),
        })
    }

    fn reset(&mut self) {
        self.shape.reset();
        self.contact.reset();
    }
}

/// Borrowed and boxed estimators estimate as the estimator does (so that a caller lends its
/// estimator to a pipeline and keeps it, or chooses one at run time).
macro_rules! forward_estimator {
    ($trait:ident $({ $($assoc:ident),* })?, $method:ident($($arg:ident: $ty:ty),*) -> $out:ty) => {
        forward_estimator!(@impl &mut T, $trait $({ $($assoc),* })?, $method($($arg: $ty),*) -> $out);
        forward_estimator!(@impl Box<T>, $trait $({ $($assoc),* })?, $method($($arg: $ty),*) -> $out);
    };
    (@impl $for:ty, $trait:ident $({ $($assoc:ident),* })?, $method:ident($($arg:ident: $ty:ty),*) -> $out:ty) => {
        impl<T: $trait + ?Sized> $trait for $for {
            $($(type $assoc = T::$assoc;)*)?
            type Error = T::Error;
            fn $method(&mut self, $($arg: $ty),*) -> Result<$out, Self::Error> {
                (**self).$method($($arg),*)
            }
            fn reset(&mut self) {
                (**self).reset();
            }
        }
    };
}

forward_estimator!(ShapeEstimator, estimate_shape(observation: &Observation<'_>) -> HandShape);
forward_estimator!(ContactEstimator, estimate(input: &ContactInput<'_>) -> ContactEstimate);
forward_estimator!(
    HandEstimator { Details },
    estimate(observation: &Observation<'_>) -> HandEstimate<Self::Details>
);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::GeomError;
    use crate::hand::HandKeypoints;
    use crate::math::Point3;
    use crate::transform::WorldFromHand;

    use crate::hand::tests::small_hand;

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
        let sums = Some(vec![
            Vector3::new(1.5, 3.0, -2.0),
            Vector3::new(-1.0, 0.0, 7.0),
            Vector3::zeros(),
        ]);
        assert_eq!(estimate.finger_forces_n(), sums);
        let hand = HandEstimate {
            shape: HandShape {
                fingers: Vec::new(),
            },
            contact: estimate.map.clone(),
            vertex_force_n: estimate.vertex_force_n.clone(),
            details: (),
        };
        assert_eq!(hand.finger_forces_n(), sums);
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
            let p = input.observation.time_secs.unwrap_or(-1.0);
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
            .estimate(&ContactInput::new(
                shape,
                Observation::new().with_time(0.25),
            ))
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
    fn a_frame_observation_carries_its_markers_pulls_and_pose() {
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
        let obs = input.observation;
        assert_eq!(obs.keypoints, Some(&frame.markers));
        assert_eq!(obs.tendon_pull_m, Some(frame.tendon_pull_m.as_slice()));
        assert_eq!(obs.world_from_hand, Some(frame.world_from_hand));
        assert_eq!(obs.time_secs, None);
        assert_eq!(ContactInput::shape(&shape).observation, Observation::new());
    }

    /// Returns a rest shape for the keypoints of its hand, and counts its estimates and resets.
    struct RestShape {
        rest: HandShape,
        calls: usize,
        resets: usize,
    }

    impl ShapeEstimator for RestShape {
        type Error = GeomError;

        fn estimate_shape(&mut self, obs: &Observation<'_>) -> Result<HandShape, GeomError> {
            self.calls += 1;
            let keypoints: &HandKeypoints = obs.keypoints.ok_or(GeomError::LengthMismatch {
                what: "fingers of the keypoints",
                expected: self.rest.fingers.len(),
                got: 0,
            })?;
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

        fn reset(&mut self) {
            self.resets += 1;
        }
    }

    #[test]
    fn staged_estimators_score_the_shape_of_the_same_observation_and_name_the_failing_stage() {
        let hand = small_hand();
        let mut shape = RestShape {
            rest: HandShape::rest(&hand),
            calls: 0,
            resets: 0,
        };
        let mut contact = Counting::default();
        let keypoints = hand.rest_keypoints();
        {
            let mut staged = Staged::new(&mut shape, &mut contact);
            let obs = Observation::from_keypoints(&keypoints).with_time(0.5);
            let estimate = staged.estimate(&obs).unwrap();
            assert_eq!(estimate.shape, HandShape::rest(&hand));
            // The contact stage saw the same observation (its time) on that shape.
            assert!(estimate.contact.fingers.iter().flatten().all(|&p| p == 0.5));
            assert_eq!(
                estimate.contact.num_vertices(),
                estimate.shape.num_vertices()
            );
            assert_eq!(estimate.vertex_force_n, None);
            // A shape stage that fails stops the estimate before the contact stage, named.
            let one_finger = HandKeypoints {
                fingers: keypoints.fingers[..1].to_vec(),
            };
            let err = staged
                .estimate(&Observation::from_keypoints(&one_finger))
                .unwrap_err();
            assert!(matches!(err, StageError::Shape(_)), "{err:?}");
            assert!(err.to_string().starts_with("shape estimation: "), "{err}");
            // Boxed behind the seam, chosen at run time, and reset through it.
            let mut boxed: Box<dyn HandEstimator<Details = (), Error = StageError> + '_> =
                Box::new(&mut staged);
            boxed.estimate(&obs).unwrap();
            boxed.reset();
        }
        assert_eq!((shape.calls, shape.resets), (3, 1));
        assert_eq!((contact.estimates, contact.resets), (2, 1));
    }
}
