//! What one instant of a hand is: its deformed shape, where it touches, its markers and its pose.
//!
//! These are the values that flow between the stages of the pipeline and that training and
//! evaluation consume in memory: a [`HandShape`] (from the simulator or from shape estimation), a
//! [`ContactMap`] (from a contact estimator), and a [`LabelledFrame`] (a simulated instant with its
//! ground truth, as a data set stores it).
//!
//! The estimators that make and consume them are in [`crate::estimate`].

use serde::{Deserialize, Serialize};

use crate::error::GeomError;
use crate::hand::{HandKeypoints, HandModel};
use crate::math::{Point3, Real, is_finite_point};
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
    /// What was observed of the frame: its markers, tendon pulls and wrist pose; no time (a
    /// data set's frames are not a stream).
    pub fn observation(&self) -> crate::observation::Observation<'_> {
        crate::observation::Observation::from_keypoints(&self.markers)
            .with_tendon_pulls(&self.tendon_pull_m)
            .with_world_from_hand(self.world_from_hand)
    }

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

    use crate::hand::tests::small_hand;

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
    fn labels_become_a_map_of_zeros_and_ones() {
        let map = ContactMap::from_labels(&[vec![false, true], vec![true]]);
        assert_eq!(map.fingers, vec![vec![0.0, 1.0], vec![1.0]]);
        assert_eq!(map.num_vertices(), 3);
    }
}
