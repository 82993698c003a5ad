//! The frame layout a data set shares and one frame as a shard stores it.

use serde::{Deserialize, Serialize};

use moe_geom::math::{Translation3, UnitQuat};
use moe_geom::nalgebra::Quaternion;
use moe_geom::{GeomError, HandKeypoints, HandShape, Iso3, LabelledFrame, Point3, WorldFromHand};

/// The shapes every frame of a data set shares.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatasetLayout {
    /// Surface vertices of each finger (the hand's vertices are these, concatenated).
    pub finger_num_vertices: Vec<usize>,
    /// Markers of each finger.
    pub markers_per_finger: Vec<usize>,
    /// Tendons per finger.
    pub tendons_per_finger: usize,
    /// Length of every frame's `object_params`.
    pub object_param_len: usize,
    /// Names of the object families; `object_family` indexes this list.
    pub object_families: Vec<String>,
}

impl DatasetLayout {
    /// Vertices of the whole hand.
    pub fn total_vertices(&self) -> usize {
        self.finger_num_vertices.iter().sum()
    }

    /// Markers of the whole hand.
    pub fn total_markers(&self) -> usize {
        self.markers_per_finger.iter().sum()
    }

    /// Per-vertex values of the whole hand (fingers concatenated, as a shard stores them) split
    /// per finger, each value mapped by `f`. `values` must hold [`DatasetLayout::total_vertices`]
    /// entries; a shorter list gives shorter (possibly empty) fingers.
    pub fn per_finger<T, U>(&self, values: &[T], f: impl Fn(&T) -> U) -> Vec<Vec<U>> {
        let mut out = Vec::with_capacity(self.finger_num_vertices.len());
        let mut start = 0;
        for &n in &self.finger_num_vertices {
            let end = (start + n).min(values.len());
            out.push(values[start.min(end)..end].iter().map(&f).collect());
            start += n;
        }
        out
    }

    /// Tendons of the whole hand.
    pub fn total_tendons(&self) -> usize {
        self.tendons_per_finger * self.finger_num_vertices.len()
    }
}

/// One labelled frame, stored as it is in a shard.
#[derive(Debug, Clone, PartialEq)]
pub struct DatasetFrame {
    /// Trajectory the frame belongs to.
    pub trajectory_id: u64,
    /// Frame number within the trajectory.
    pub frame_index: u32,
    /// Deformed surface vertices of the whole hand, hand frame, metres.
    pub vertices: Vec<[f32; 3]>,
    /// Contact label per vertex (0 or 1).
    pub contact: Vec<u8>,
    /// Penalty force per vertex (normal magnitude, summed over obstacles), newtons.
    pub contact_force_n: Vec<f32>,
    /// Smallest signed distance per vertex to any obstacle, metres (`+∞` without obstacles).
    pub obstacle_distance_m: Vec<f32>,
    /// Net contact force on each finger, hand frame, newtons: the vector sum of the penalty
    /// forces on its vertices (smaller than the finger's sum of `contact_force_n` where its
    /// vertices are pushed different ways). `None` for a frame of a shard without the
    /// `finger_force_n` tensor (format version 1); whether a whole data set has it:
    /// [`DatasetCard::has_finger_force`](super::DatasetCard::has_finger_force).
    pub finger_force_n: Option<Vec<[f32; 3]>>,
    /// Ground-truth marker centres, hand frame, metres.
    pub markers: Vec<[f32; 3]>,
    /// Wrist pose: translation xyz (metres), then quaternion xyzw.
    pub world_from_hand: [f64; 7],
    /// Pulled length of every tendon, metres.
    pub tendon_pull_m: Vec<f32>,
    /// Index into the layout's object families.
    pub object_family: u8,
    /// The object's parameters.
    pub object_params: Vec<f32>,
}

impl DatasetFrame {
    /// Number of vertices labelled as in contact.
    pub fn contact_count(&self) -> usize {
        self.contact.iter().filter(|&&c| c != 0).count()
    }

    /// The frame as the in-memory vocabulary speaks it: vertices, labels and markers split per
    /// finger (in `f64`), the wrist pose as a typed transform.
    ///
    /// # Errors
    /// [`GeomError::LengthMismatch`] when the frame does not fit `layout`, and
    /// [`GeomError::NonFinitePoint`] for a wrist pose whose quaternion is not a unit quaternion
    /// (norm off by more than 1e-3) or not finite.
    pub fn to_labelled(&self, layout: &DatasetLayout) -> Result<LabelledFrame, GeomError> {
        let sizes = [
            (
                "frame vertices",
                self.vertices.len(),
                layout.total_vertices(),
            ),
            (
                "frame contact labels",
                self.contact.len(),
                layout.total_vertices(),
            ),
            ("frame markers", self.markers.len(), layout.total_markers()),
            (
                "frame tendon pulls",
                self.tendon_pull_m.len(),
                layout.total_tendons(),
            ),
        ];
        for (what, got, expected) in sizes {
            if got != expected {
                return Err(GeomError::LengthMismatch {
                    what,
                    expected,
                    got,
                });
            }
        }
        let point = |p: &[f32; 3]| Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        let fingers = layout.per_finger(&self.vertices, point);
        let contact = layout.per_finger(&self.contact, |&c| c != 0);
        let mut markers = Vec::with_capacity(layout.markers_per_finger.len());
        let mut start = 0;
        for &m in &layout.markers_per_finger {
            markers.push(
                self.markers[start..start + m]
                    .iter()
                    .map(|p| Some(point(p)))
                    .collect(),
            );
            start += m;
        }
        let [x, y, z, qx, qy, qz, qw] = self.world_from_hand;
        let q = Quaternion::new(qw, qx, qy, qz);
        if !(q.norm() - 1.0).abs().le(&1e-3) || ![x, y, z].iter().all(|v| v.is_finite()) {
            return Err(GeomError::NonFinitePoint {
                what: "wrist pose (translation, unit quaternion)",
                index: 0,
            });
        }
        let world_from_hand = WorldFromHand::new(Iso3::from_parts(
            Translation3::new(x, y, z),
            UnitQuat::new_normalize(q),
        ));
        Ok(LabelledFrame {
            trajectory_id: self.trajectory_id,
            frame_index: self.frame_index,
            shape: HandShape { fingers },
            contact,
            markers: HandKeypoints { fingers: markers },
            world_from_hand,
            tendon_pull_m: (0..layout.finger_num_vertices.len())
                .map(|f| {
                    let t = layout.tendons_per_finger;
                    self.tendon_pull_m[f * t..(f + 1) * t]
                        .iter()
                        .map(|&p| f64::from(p))
                        .collect()
                })
                .collect(),
        })
    }
}
