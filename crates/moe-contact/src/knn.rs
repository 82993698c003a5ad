//! The KNN baselines of the paper (§5.1): the training frame whose keypoints are nearest to the
//! observed ones gives its contact vertices (and its shape).
//!
//! The distance is the Euclidean distance between the stacked marker positions of the whole hand
//! in the hand frame, over the markers observed in the query (an occluded marker is left out).
//! KNN\[All\] searches every training frame; KNN\[Sub\] a seeded random subset.

use std::collections::HashMap;

use moe_geom::{
    ContactEstimate, ContactEstimator, ContactInput, ContactMap, HandKeypoints, HandShape,
    LabelledFrame, Observation, Point3, SeededRng,
};
use safetensors::tensor::Dtype;

use crate::error::ContactError;
use crate::tensor_file::{self, Entry};

/// The training frames' keypoints, contact vertices and (optionally) shapes.
#[derive(Debug, Clone, PartialEq)]
pub struct KnnIndex {
    markers_per_finger: Vec<usize>,
    vertices_per_finger: Vec<usize>,
    /// `[frame][marker]` stacked over the fingers, xyz, f64.
    keypoints: Vec<f64>,
    /// Contact vertex ids per frame per finger.
    contacts: Vec<Vec<Vec<u32>>>,
    /// The frames' shapes, when kept (`[frame][vertex]` stacked over the fingers).
    shapes: Option<Vec<f32>>,
}

/// What a query found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KnnMatch {
    /// Index of the training frame in the index.
    pub frame: usize,
    /// Keypoint distance, metres (over the observed markers).
    pub distance_m: f64,
}

impl KnnIndex {
    /// An index of `frames`, keeping their shapes when `keep_shapes`.
    ///
    /// # Errors
    /// No frames, or frames whose finger, marker or vertex counts differ from the first's, or a
    /// frame with a missing ground-truth marker.
    pub fn new(frames: &[LabelledFrame], keep_shapes: bool) -> Result<Self, ContactError> {
        let first = frames.first().ok_or_else(|| ContactError::InvalidBatch {
            message: "a KNN index needs at least one frame".into(),
        })?;
        let markers_per_finger: Vec<usize> = first.markers.fingers.iter().map(Vec::len).collect();
        let vertices_per_finger: Vec<usize> = first.shape.fingers.iter().map(Vec::len).collect();
        let total_markers: usize = markers_per_finger.iter().sum();
        let mut keypoints = Vec::with_capacity(frames.len() * total_markers * 3);
        let mut contacts = Vec::with_capacity(frames.len());
        let mut shapes = keep_shapes.then(Vec::new);
        for (i, f) in frames.iter().enumerate() {
            let m: Vec<usize> = f.markers.fingers.iter().map(Vec::len).collect();
            let v: Vec<usize> = f.shape.fingers.iter().map(Vec::len).collect();
            if m != markers_per_finger || v != vertices_per_finger {
                return Err(ContactError::InvalidBatch {
                    message: format!(
                        "frame {i} (trajectory {}) has another hand layout than the first frame",
                        f.trajectory_id
                    ),
                });
            }
            for p in f.markers.fingers.iter().flatten() {
                let p = p.ok_or_else(|| ContactError::InvalidBatch {
                    message: format!("frame {i} misses a ground-truth marker"),
                })?;
                keypoints.extend([p.x, p.y, p.z]);
            }
            contacts.push(
                f.contact
                    .iter()
                    .map(|labels| {
                        labels
                            .iter()
                            .enumerate()
                            .filter(|(_, c)| **c)
                            .map(|(v, _)| v as u32)
                            .collect()
                    })
                    .collect(),
            );
            if let Some(s) = shapes.as_mut() {
                for p in f.shape.fingers.iter().flatten() {
                    s.extend([p.x as f32, p.y as f32, p.z as f32]);
                }
            }
        }
        Ok(Self {
            markers_per_finger,
            vertices_per_finger,
            keypoints,
            contacts,
            shapes,
        })
    }

    /// A seeded random subset of about `fraction` of the frames (KNN\[Sub\]; at least one frame).
    ///
    /// # Errors
    /// A fraction outside (0, 1].
    pub fn subset(&self, fraction: f64, seed: u64) -> Result<Self, ContactError> {
        if !(fraction > 0.0 && fraction <= 1.0) {
            return Err(ContactError::InvalidConfig {
                field: "fraction",
                message: format!("{fraction} is not in (0, 1]"),
            });
        }
        let n = self.len();
        let want = ((n as f64 * fraction).round() as usize).clamp(1, n);
        let mut order: Vec<usize> = (0..n).collect();
        let mut rng = SeededRng::new(seed);
        for i in (1..n).rev() {
            order.swap(i, rng.below(i as u64 + 1) as usize);
        }
        let mut keep = order[..want].to_vec();
        keep.sort_unstable();
        let km = self.total_markers() * 3;
        let kv = self.total_vertices() * 3;
        Ok(Self {
            markers_per_finger: self.markers_per_finger.clone(),
            vertices_per_finger: self.vertices_per_finger.clone(),
            keypoints: keep
                .iter()
                .flat_map(|&i| self.keypoints[i * km..(i + 1) * km].iter().copied())
                .collect(),
            contacts: keep.iter().map(|&i| self.contacts[i].clone()).collect(),
            shapes: self.shapes.as_ref().map(|s| {
                keep.iter()
                    .flat_map(|&i| s[i * kv..(i + 1) * kv].iter().copied())
                    .collect()
            }),
        })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.contacts.len()
    }

    /// Whether the index has no frames.
    pub fn is_empty(&self) -> bool {
        self.contacts.is_empty()
    }

    fn total_markers(&self) -> usize {
        self.markers_per_finger.iter().sum()
    }

    /// Surface vertices of every finger of the indexed hand.
    pub fn vertices_per_finger(&self) -> &[usize] {
        &self.vertices_per_finger
    }

    fn total_vertices(&self) -> usize {
        self.vertices_per_finger.iter().sum()
    }

    /// The training frame nearest to `keypoints` over its observed markers (the lowest index on
    /// ties). An exhaustive search: the keypoint space has 3 × markers dimensions (42 for the
    /// two-finger hand), where a k-d tree visits most leaves anyway, and a missing marker only
    /// drops terms from the sum.
    ///
    /// # Errors
    /// Keypoints of another hand layout, non-finite keypoints, or no observed marker.
    pub fn nearest(&self, keypoints: &HandKeypoints) -> Result<KnnMatch, ContactError> {
        let m: Vec<usize> = keypoints.fingers.iter().map(Vec::len).collect();
        if m != self.markers_per_finger {
            return Err(ContactError::InvalidBatch {
                message: format!(
                    "keypoints with {m:?} markers per finger; the index has {:?}",
                    self.markers_per_finger
                ),
            });
        }
        let observed: Vec<(usize, Point3)> = keypoints
            .fingers
            .iter()
            .flatten()
            .enumerate()
            .filter_map(|(i, p)| p.map(|p| (i, p)))
            .collect();
        if observed.is_empty() {
            return Err(ContactError::InvalidBatch {
                message: "no marker is observed".into(),
            });
        }
        if let Some((i, _)) = observed
            .iter()
            .find(|(_, p)| !moe_geom::math::is_finite_point(p))
        {
            return Err(ContactError::NonFinitePoint { set: 0, index: *i });
        }
        let km = self.total_markers() * 3;
        let mut best = KnnMatch {
            frame: 0,
            distance_m: f64::INFINITY,
        };
        for (frame, row) in self.keypoints.chunks_exact(km).enumerate() {
            let d2: f64 = observed
                .iter()
                .map(|(i, p)| {
                    let q = &row[3 * i..3 * i + 3];
                    (p.x - q[0]).powi(2) + (p.y - q[1]).powi(2) + (p.z - q[2]).powi(2)
                })
                .sum();
            if d2 < best.distance_m {
                best = KnnMatch {
                    frame,
                    distance_m: d2,
                };
            }
        }
        best.distance_m = best.distance_m.sqrt();
        Ok(best)
    }

    /// The contact vertex ids of frame `frame`, per finger.
    pub fn contacts_of(&self, frame: usize) -> Option<&[Vec<u32>]> {
        self.contacts.get(frame).map(Vec::as_slice)
    }

    /// The shape of frame `frame`, if the index keeps shapes.
    pub fn shape_of(&self, frame: usize) -> Option<HandShape> {
        let s = self.shapes.as_ref()?;
        let kv = self.total_vertices() * 3;
        let row = s.get(frame * kv..(frame + 1) * kv)?;
        let mut fingers = Vec::with_capacity(self.vertices_per_finger.len());
        let mut start = 0;
        for &n in &self.vertices_per_finger {
            fingers.push(
                row[start * 3..(start + n) * 3]
                    .chunks_exact(3)
                    .map(|p| Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
                    .collect(),
            );
            start += n;
        }
        Some(HandShape { fingers })
    }

    /// The contact map a match gives: 1 on the matched frame's contact vertices, 0 elsewhere.
    pub fn contact_map(&self, m: KnnMatch) -> ContactMap {
        let mut fingers: Vec<Vec<f64>> = self
            .vertices_per_finger
            .iter()
            .map(|&n| vec![0.0; n])
            .collect();
        for (f, ids) in self.contacts[m.frame].iter().enumerate() {
            for &v in ids {
                fingers[f][v as usize] = 1.0;
            }
        }
        ContactMap { fingers }
    }

    /// The contact map of one observation: the contact vertices of the training frame whose
    /// keypoints are nearest to the observation's (its shape only has to fit the index's hand;
    /// its pulls, pose and time are not used).
    ///
    /// # Errors
    /// [`ContactError::UnavailableFeatures`] for an observation without keypoints,
    /// [`ContactError::InvalidBatch`] for a shape of another hand, and as
    /// [`KnnIndex::nearest`].
    pub fn estimate_map(&self, input: &ContactInput<'_>) -> Result<ContactMap, ContactError> {
        let keypoints = input
            .observation
            .keypoints
            .ok_or(ContactError::UnavailableFeatures {
                features: "keypoints".into(),
                given: "a hand shape without keypoints",
            })?;
        let v: Vec<usize> = input.shape.fingers.iter().map(Vec::len).collect();
        if v != self.vertices_per_finger {
            return Err(ContactError::InvalidBatch {
                message: format!(
                    "a shape with {v:?} vertices per finger; the index has {:?}",
                    self.vertices_per_finger
                ),
            });
        }
        Ok(self.contact_map(self.nearest(keypoints)?))
    }

    /// The index as safetensors bytes (f64 keypoints, u32 contact ids with per-frame-finger
    /// offsets, f32 shapes if kept; the layout in the metadata).
    ///
    /// # Errors
    /// The serialiser's refusal (not for valid indexes).
    pub fn to_bytes(&self) -> Result<Vec<u8>, ContactError> {
        let mut offsets = vec![0u32];
        let mut ids = Vec::new();
        for frame in &self.contacts {
            for finger in frame {
                ids.extend_from_slice(finger);
                offsets.push(ids.len() as u32);
            }
        }
        let km = self.total_markers() * 3;
        let kv = self.total_vertices() * 3;
        let mut entries = vec![
            Entry::f64("keypoints", vec![self.len(), km], &self.keypoints),
            Entry::u32("contact_ids", vec![ids.len()], &ids),
            Entry::u32("contact_offsets", vec![offsets.len()], &offsets),
        ];
        if let Some(s) = &self.shapes {
            entries.push(Entry::f32("shapes", vec![self.len(), kv], s));
        }
        let mut meta = HashMap::new();
        meta.insert(
            "markers_per_finger".to_string(),
            serde_json::to_string(&self.markers_per_finger).unwrap_or_default(),
        );
        meta.insert(
            "vertices_per_finger".to_string(),
            serde_json::to_string(&self.vertices_per_finger).unwrap_or_default(),
        );
        tensor_file::serialize(&entries, Some(meta))
    }

    /// Reads an index written by [`KnnIndex::to_bytes`].
    ///
    /// # Errors
    /// [`ContactError::MalformedWeights`] naming what is wrong.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ContactError> {
        let bad = |message: String| ContactError::MalformedWeights { message };
        let (st, meta) = tensor_file::parse(bytes, "KNN index")?;
        let layout = |key: &str| -> Result<Vec<usize>, ContactError> {
            let text = meta
                .get(key)
                .ok_or_else(|| bad(format!("KNN index: no '{key}' in the metadata")))?;
            serde_json::from_str(text).map_err(|e| bad(format!("KNN index: '{key}': {e}")))
        };
        let markers_per_finger = layout("markers_per_finger")?;
        let vertices_per_finger = layout("vertices_per_finger")?;
        let km = 3 * markers_per_finger.iter().sum::<usize>();
        let kv = 3 * vertices_per_finger.iter().sum::<usize>();
        let tensor = |name: &str, dtype: Dtype| -> Result<(Vec<usize>, Vec<u8>), ContactError> {
            let v = st
                .tensor(name)
                .map_err(|_| bad(format!("KNN index: no tensor '{name}'")))?;
            if v.dtype() != dtype {
                return Err(bad(format!("KNN index: '{name}' is {:?}", v.dtype())));
            }
            Ok((v.shape().to_vec(), v.data().to_vec()))
        };
        let (kshape, kbytes) = tensor("keypoints", Dtype::F64)?;
        if kshape.len() != 2 || kshape[1] != km {
            return Err(bad(format!("KNN index: keypoints of shape {kshape:?}")));
        }
        let frames = kshape[0];
        let keypoints = tensor_file::f64s(&kbytes);
        if keypoints.iter().any(|v| !v.is_finite()) {
            return Err(bad("KNN index: non-finite keypoint".into()));
        }
        let ids = tensor_file::u32s(&tensor("contact_ids", Dtype::U32)?.1);
        let offsets = tensor_file::u32s(&tensor("contact_offsets", Dtype::U32)?.1);
        let fingers = vertices_per_finger.len();
        if offsets.len() != frames * fingers + 1
            || offsets.first() != Some(&0)
            || offsets.windows(2).any(|w| w[1] < w[0])
            || offsets.last().map(|&o| o as usize) != Some(ids.len())
        {
            return Err(bad("KNN index: contact offsets do not fit the ids".into()));
        }
        let mut contacts = Vec::with_capacity(frames);
        for f in 0..frames {
            let mut per = Vec::with_capacity(fingers);
            for (k, &n) in vertices_per_finger.iter().enumerate() {
                let (a, b) = (
                    offsets[f * fingers + k] as usize,
                    offsets[f * fingers + k + 1] as usize,
                );
                let slice = &ids[a..b];
                if let Some(v) = slice.iter().find(|&&v| v as usize >= n) {
                    return Err(bad(format!(
                        "KNN index: frame {f}, finger {k}: vertex {v} of {n}"
                    )));
                }
                per.push(slice.to_vec());
            }
            contacts.push(per);
        }
        let shapes = match st.tensor("shapes") {
            Ok(_) => {
                let (shape, b) = tensor("shapes", Dtype::F32)?;
                if shape != [frames, kv] {
                    return Err(bad(format!("KNN index: shapes of shape {shape:?}")));
                }
                Some(tensor_file::f32s(&b))
            }
            Err(_) => None,
        };
        Ok(Self {
            markers_per_finger,
            vertices_per_finger,
            keypoints,
            contacts,
            shapes,
        })
    }
}

impl ContactEstimator for KnnIndex {
    type Error = ContactError;

    /// [`KnnIndex::estimate_map`], without forces.
    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, ContactError> {
        self.estimate_map(input).map(ContactEstimate::from_map)
    }
}

/// A shared index estimates as the index does: a search keeps no state between observations
/// (so that one large index serves several pipelines or threads without a copy).
impl ContactEstimator for &KnnIndex {
    type Error = ContactError;

    /// [`KnnIndex::estimate_map`], without forces.
    fn estimate(&mut self, input: &ContactInput<'_>) -> Result<ContactEstimate, ContactError> {
        self.estimate_map(input).map(ContactEstimate::from_map)
    }
}

impl moe_geom::ShapeEstimator for KnnIndex {
    type Error = ContactError;

    /// The shape of the nearest training frame.
    /// The shape of the training frame whose keypoints are nearest to the observation's.
    fn estimate_shape(&mut self, observation: &Observation<'_>) -> Result<HandShape, ContactError> {
        let keypoints = observation
            .keypoints
            .ok_or(ContactError::UnavailableFeatures {
                features: "keypoints".into(),
                given: "an observation without keypoints",
            })?;
        let m = self.nearest(keypoints)?;
        self.shape_of(m.frame)
            .ok_or_else(|| ContactError::InvalidConfig {
                field: "KNN index",
                message: "built without shapes; build it with keep_shapes to estimate shapes"
                    .into(),
            })
    }
}
