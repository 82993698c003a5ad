//! "Is this the same hand?": the one answer behind every file made for a hand (an episode, a
//! fitted material, a data set) and every pair of hands.
//!
//! A [`HandSignature`] is what a file records of the hand it was made for: per finger its
//! surface vertex count and, where recorded, its marker and tendon counts and its rest mesh's
//! digest ([`crate::TriMesh::digest`]). [`HandModel::differs_from`] compares a hand with a
//! signature, field by field where the signature has the field; [`HandModel::difference`]
//! compares two hands (their full signatures, their marker vertices and where their fingers
//! sit). Both give the first [`HandDifference`], which names the finger.

use serde::{Deserialize, Serialize};

use crate::hand::HandModel;
use crate::math::Real;

/// What a file records of the hand it was made for.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandSignature {
    /// Surface vertices of each finger.
    pub vertices_per_finger: Vec<usize>,
    /// Markers of each finger, where recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub markers_per_finger: Option<Vec<usize>>,
    /// Tendons of each finger, where recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tendons_per_finger: Option<Vec<usize>>,
    /// [`crate::TriMesh::digest`] of each finger's rest mesh (finger frame), where recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh_digests: Option<Vec<String>>,
}

impl HandSignature {
    /// A signature of vertex counts alone (what an episode records).
    pub fn of_vertex_counts(vertices_per_finger: Vec<usize>) -> Self {
        Self {
            vertices_per_finger,
            markers_per_finger: None,
            tendons_per_finger: None,
            mesh_digests: None,
        }
    }

    /// The vertex, marker and tendon counts of `hand` (what a fitted material records).
    pub fn counts_of(hand: &HandModel) -> Self {
        let f = hand.fingers();
        Self {
            vertices_per_finger: f.iter().map(|f| f.model.mesh().num_vertices()).collect(),
            markers_per_finger: Some(f.iter().map(|f| f.model.marker_vertices().len()).collect()),
            tendons_per_finger: Some(f.iter().map(|f| f.model.tendon_routes().len()).collect()),
            mesh_digests: None,
        }
    }

    /// Everything of `hand`: its counts and its rest meshes' digests.
    pub fn of(hand: &HandModel) -> Self {
        Self {
            mesh_digests: Some(
                hand.fingers()
                    .iter()
                    .map(|f| f.model.mesh().digest())
                    .collect(),
            ),
            ..Self::counts_of(hand)
        }
    }
}

/// The first way two hands, or a hand and a signature, differ.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HandDifference {
    /// Another number of fingers.
    #[error("{hand} fingers against {recorded}")]
    Fingers {
        /// The hand's.
        hand: usize,
        /// The other's.
        recorded: usize,
    },
    /// A finger with another number of vertices, markers or tendons.
    #[error("finger {finger} has {hand} {what} against {recorded}")]
    Count {
        /// What was counted: "vertices", "markers" or "tendons".
        what: &'static str,
        /// The finger.
        finger: usize,
        /// The hand's count.
        hand: usize,
        /// The other's.
        recorded: usize,
    },
    /// A finger whose rest mesh is another (the same counts, another digest).
    #[error("finger {finger} has another rest mesh (digest {hand} against {recorded})")]
    Mesh {
        /// The finger.
        finger: usize,
        /// The hand's digest.
        hand: String,
        /// The other's.
        recorded: String,
    },
    /// A finger whose markers sit on other vertices.
    #[error("finger {finger} has other marker vertices")]
    MarkerVertices {
        /// The finger.
        finger: usize,
    },
    /// A finger that sits elsewhere on the palm.
    #[error("finger {finger} sits elsewhere on the palm (by up to {distance_mm:.3} mm)")]
    Placement {
        /// The finger.
        finger: usize,
        /// The largest distance between its rest vertices in the two hands, millimetres.
        distance_mm: Real,
    },
}

/// The first finger whose `ours` and `theirs` differ, as a count difference.
fn first_count(what: &'static str, ours: &[usize], theirs: &[usize]) -> Option<HandDifference> {
    ours.iter()
        .zip(theirs)
        .enumerate()
        .find(|(_, (a, b))| a != b)
        .map(|(finger, (&hand, &recorded))| HandDifference::Count {
            what,
            finger,
            hand,
            recorded,
        })
}

impl HandModel {
    /// The hand's full signature ([`HandSignature::of`]).
    pub fn signature(&self) -> HandSignature {
        HandSignature::of(self)
    }

    /// How the hand differs from what `recorded` says of a hand, comparing each field the
    /// signature records; `None` when it is that hand.
    pub fn differs_from(&self, recorded: &HandSignature) -> Option<HandDifference> {
        // The digests hash every rest vertex: made only when the record has some to compare.
        let ours = if recorded.mesh_digests.is_some() {
            HandSignature::of(self)
        } else {
            HandSignature::counts_of(self)
        };
        let n = ours.vertices_per_finger.len();
        if recorded.vertices_per_finger.len() != n {
            return Some(HandDifference::Fingers {
                hand: n,
                recorded: recorded.vertices_per_finger.len(),
            });
        }
        let counts = [
            (
                "vertices",
                Some(&ours.vertices_per_finger),
                Some(&recorded.vertices_per_finger),
            ),
            (
                "markers",
                ours.markers_per_finger.as_ref(),
                recorded.markers_per_finger.as_ref(),
            ),
            (
                "tendons",
                ours.tendons_per_finger.as_ref(),
                recorded.tendons_per_finger.as_ref(),
            ),
        ];
        for (what, a, b) in counts {
            if let (Some(a), Some(b)) = (a, b) {
                if a.len() != b.len() {
                    return Some(HandDifference::Fingers {
                        hand: a.len(),
                        recorded: b.len(),
                    });
                }
                if let Some(d) = first_count(what, a, b) {
                    return Some(d);
                }
            }
        }
        if let (Some(a), Some(b)) = (&ours.mesh_digests, &recorded.mesh_digests) {
            if a.len() != b.len() {
                return Some(HandDifference::Fingers {
                    hand: a.len(),
                    recorded: b.len(),
                });
            }
            if let Some((finger, (x, y))) = a.iter().zip(b).enumerate().find(|(_, (x, y))| x != y) {
                return Some(HandDifference::Mesh {
                    finger,
                    hand: x.clone(),
                    recorded: y.clone(),
                });
            }
        }
        None
    }

    /// How the hand differs from `other`: their full signatures, the vertices their markers sit
    /// on, and where their fingers sit on the palm (rest vertices in the hand frame, to the
    /// nanometre); `None` when they are the same hand.
    pub fn difference(&self, other: &HandModel) -> Option<HandDifference> {
        if let Some(d) = self.differs_from(&other.signature()) {
            return Some(d);
        }
        for (finger, (a, b)) in self.fingers().iter().zip(other.fingers()).enumerate() {
            if a.model.marker_vertices() != b.model.marker_vertices() {
                return Some(HandDifference::MarkerVertices { finger });
            }
            let far = self
                .rest_vertices_in_hand(finger)
                .iter()
                .zip(&other.rest_vertices_in_hand(finger))
                .map(|(p, q)| (p - q).norm())
                .fold(0.0, Real::max);
            if far > 1e-9 {
                return Some(HandDifference::Placement {
                    finger,
                    distance_mm: 1e3 * far,
                });
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::finger::FingerParams;
    use crate::hand::HandPreset;
    use crate::math::Iso3;
    use crate::transform::HandFromFinger;

    fn hand(preset: HandPreset, budget: usize) -> HandModel {
        let params = FingerParams {
            vertex_budget: budget,
            ..FingerParams::default()
        };
        HandModel::preset(preset, &params).unwrap()
    }

    #[test]
    fn a_hand_is_its_own_and_differs_from_others_by_finger() {
        let two = hand(HandPreset::TwoFinger, 128);
        assert_eq!(two.difference(&two.clone()), None);
        assert_eq!(two.differs_from(&two.signature()), None);
        assert_eq!(two.differs_from(&HandSignature::counts_of(&two)), None);
        let three = hand(HandPreset::ThreeFinger, 128);
        assert_eq!(
            two.difference(&three),
            Some(HandDifference::Fingers {
                hand: 2,
                recorded: 3
            })
        );
        // Vertex counts alone (an episode's record): a finer mesh differs on finger 0.
        let fine = hand(HandPreset::TwoFinger, 256);
        let recorded =
            HandSignature::of_vertex_counts(fine.signature().vertices_per_finger.clone());
        let d = two.differs_from(&recorded).unwrap();
        assert!(
            matches!(
                d,
                HandDifference::Count {
                    what: "vertices",
                    finger: 0,
                    ..
                }
            ),
            "{d}"
        );
        assert!(d.to_string().starts_with("finger 0 has "), "{d}");
        // Same counts, another mesh: only the digest sees it.
        let mut signature = two.signature();
        signature.mesh_digests.as_mut().unwrap()[1] = "0".repeat(16);
        assert!(matches!(
            two.differs_from(&signature),
            Some(HandDifference::Mesh { finger: 1, .. })
        ));
        // A signature without digests does not check them.
        signature.mesh_digests = None;
        assert_eq!(two.differs_from(&signature), None);
        // A finger moved on the palm: the same meshes, another placement.
        let mut fingers = two.fingers().to_vec();
        fingers[1].hand_from_finger = HandFromFinger::new(
            Iso3::translation(0.0, 0.001, 0.0) * fingers[1].hand_from_finger.iso(),
        );
        let moved = HandModel::new(fingers).unwrap();
        assert!(matches!(
            two.difference(&moved),
            Some(HandDifference::Placement { finger: 1, distance_mm }) if (distance_mm - 1.0).abs() < 1e-9
        ));
    }

    #[test]
    fn a_signature_without_the_optional_fields_reads_and_writes_as_before() {
        let text = r#"{"vertices_per_finger":[5,6],"markers_per_finger":[7,7],"tendons_per_finger":[2,2]}"#;
        let s: HandSignature = serde_json::from_str(text).unwrap();
        assert_eq!(s.mesh_digests, None);
        assert_eq!(serde_json::to_string(&s).unwrap(), text);
        assert!(
            serde_json::from_str::<HandSignature>(r#"{"vertices_per_finger":[1],"x":1}"#).is_err()
        );
    }
}
