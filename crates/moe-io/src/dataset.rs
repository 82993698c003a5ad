//! Training data sets: safetensors shards of labelled frames plus a JSON data set card.
//!
//! A data set is a directory:
//!
//! ```text
//! DIR/card.json                 the DatasetCard: layout, counts, contact ratios, per-family statistics
//! DIR/shard-00000-of-00008.safetensors
//! ...
//! ```
//!
//! Each shard stacks its frames along the first axis of these tensors (`F` frames, `V` surface
//! vertices of the whole hand, `M` markers, `T` tendons, `P` object parameters):
//!
//! | tensor | dtype | shape | content |
//! |---|---|---|---|
//! | `trajectory_id` | U64 | `[F]` | trajectory the frame belongs to |
//! | `frame_index` | U32 | `[F]` | frame number within its trajectory |
//! | `vertices` | F32 | `[F, V, 3]` | deformed surface vertices, hand frame, metres, fingers concatenated |
//! | `contact` | U8 | `[F, V]` | 1 where the vertex is in contact, by the card's label rule |
//! | `contact_force_n` | F32 | `[F, V]` | normal magnitude of the obstacles' penalty force on the vertex, newtons |
//! | `obstacle_distance_m` | F32 | `[F, V]` | smallest signed distance to an obstacle, metres (+∞ without one) |
//! | `markers` | F32 | `[F, M, 3]` | ground-truth marker centres, hand frame |
//! | `world_from_hand` | F64 | `[F, 7]` | wrist pose: translation xyz, quaternion xyzw |
//! | `tendon_pull_m` | F32 | `[F, T]` | pulled length of every tendon, fingers concatenated |
//! | `object_family` | U8 | `[F]` | index into the layout's `object_families` |
//! | `object_params` | F32 | `[F, P]` | the object's family parameters (zero-padded) |
//!
//! The shard's safetensors metadata holds the layout as JSON under `moe_touch_layout`. In Python:
//!
//! ```python
//! from safetensors.numpy import load_file
//! shard = load_file("DIR/shard-00000-of-00008.safetensors")
//! shard["vertices"].shape   # (F, V, 3), float32
//! ```
//!
//! Shards are written atomically (temporary file, then rename), so an interrupted generator
//! loses at most the shard in progress. A shard is one safetensors document, stored tensor by
//! tensor, so a damaged shard is rejected whole with an error naming the file. Splits into
//! training, validation and test sets are by trajectory, never by frame ([`split_of`]).

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde::{Deserialize, Serialize};

use moe_geom::math::{Translation3, UnitQuat};
use moe_geom::nalgebra::Quaternion;
use moe_geom::{GeomError, HandKeypoints, HandShape, Iso3, LabelledFrame, Point3, WorldFromHand};

use crate::error::IoError;

/// Metadata key under which a shard stores its layout.
pub const LAYOUT_KEY: &str = "moe_touch_layout";
/// File name of the data set card.
pub const CARD_FILE: &str = "card.json";

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
        })
    }
}

fn check_frame(
    path: &Path,
    layout: &DatasetLayout,
    k: usize,
    f: &DatasetFrame,
) -> Result<(), IoError> {
    let item = || {
        format!(
            "frame {k} (trajectory {}, frame {})",
            f.trajectory_id, f.frame_index
        )
    };
    let sizes = [
        ("vertices", f.vertices.len(), layout.total_vertices()),
        ("contact labels", f.contact.len(), layout.total_vertices()),
        (
            "contact forces",
            f.contact_force_n.len(),
            layout.total_vertices(),
        ),
        (
            "obstacle distances",
            f.obstacle_distance_m.len(),
            layout.total_vertices(),
        ),
        ("markers", f.markers.len(), layout.total_markers()),
        (
            "tendon pulls",
            f.tendon_pull_m.len(),
            layout.total_tendons(),
        ),
        (
            "object parameters",
            f.object_params.len(),
            layout.object_param_len,
        ),
    ];
    for (what, got, expected) in sizes {
        if got != expected {
            return Err(IoError::invalid(
                path,
                item(),
                format!("{got} {what}, the layout has {expected}"),
            ));
        }
    }
    if usize::from(f.object_family) >= layout.object_families.len() {
        return Err(IoError::invalid(
            path,
            item(),
            format!("object family {} is not in the layout", f.object_family),
        ));
    }
    if f.contact.iter().any(|&c| c > 1) {
        return Err(IoError::invalid(
            path,
            item(),
            "contact labels must be 0 or 1",
        ));
    }
    let finite = f
        .vertices
        .iter()
        .chain(&f.markers)
        .flatten()
        .all(|v| v.is_finite())
        && f.tendon_pull_m
            .iter()
            .chain(&f.object_params)
            .all(|v| v.is_finite())
        && f.world_from_hand.iter().all(|v| v.is_finite());
    if !finite {
        return Err(IoError::invalid(path, item(), "non-finite value"));
    }
    if let Some(i) = f
        .contact_force_n
        .iter()
        .position(|v| !(v.is_finite() && *v >= 0.0))
    {
        return Err(IoError::invalid(
            path,
            item(),
            format!(
                "contact force of vertex {i} is {}, must be finite and ≥ 0",
                f.contact_force_n[i]
            ),
        ));
    }
    if let Some(i) = f
        .obstacle_distance_m
        .iter()
        .position(|v| v.is_nan() || *v == f32::NEG_INFINITY)
    {
        return Err(IoError::invalid(
            path,
            item(),
            format!(
                "obstacle distance of vertex {i} is {}, must be a number or +∞",
                f.obstacle_distance_m[i]
            ),
        ));
    }
    Ok(())
}

fn bytes_of<T: Copy, const N: usize>(
    values: impl Iterator<Item = T>,
    to_le: impl Fn(T) -> [u8; N],
) -> Vec<u8> {
    values.flat_map(to_le).collect()
}

/// Serialises frames into shard bytes.
///
/// # Errors
/// A frame that does not fit the layout (naming the frame), or an empty frame list.
pub fn shard_bytes(
    path: &Path,
    layout: &DatasetLayout,
    frames: &[DatasetFrame],
) -> Result<Vec<u8>, IoError> {
    if frames.is_empty() {
        return Err(IoError::invalid(
            path,
            "shard",
            "a shard needs at least one frame",
        ));
    }
    for (k, f) in frames.iter().enumerate() {
        check_frame(path, layout, k, f)?;
    }
    let n = frames.len();
    let (v, m, t, p) = (
        layout.total_vertices(),
        layout.total_markers(),
        layout.total_tendons(),
        layout.object_param_len,
    );
    let tensors: Vec<(&str, Dtype, Vec<usize>, Vec<u8>)> = vec![
        (
            "trajectory_id",
            Dtype::U64,
            vec![n],
            bytes_of(frames.iter().map(|f| f.trajectory_id), u64::to_le_bytes),
        ),
        (
            "frame_index",
            Dtype::U32,
            vec![n],
            bytes_of(frames.iter().map(|f| f.frame_index), u32::to_le_bytes),
        ),
        (
            "vertices",
            Dtype::F32,
            vec![n, v, 3],
            bytes_of(
                frames
                    .iter()
                    .flat_map(|f| f.vertices.iter().flatten().copied()),
                f32::to_le_bytes,
            ),
        ),
        (
            "contact",
            Dtype::U8,
            vec![n, v],
            frames
                .iter()
                .flat_map(|f| f.contact.iter().copied())
                .collect(),
        ),
        (
            "contact_force_n",
            Dtype::F32,
            vec![n, v],
            bytes_of(
                frames
                    .iter()
                    .flat_map(|f| f.contact_force_n.iter().copied()),
                f32::to_le_bytes,
            ),
        ),
        (
            "obstacle_distance_m",
            Dtype::F32,
            vec![n, v],
            bytes_of(
                frames
                    .iter()
                    .flat_map(|f| f.obstacle_distance_m.iter().copied()),
                f32::to_le_bytes,
            ),
        ),
        (
            "markers",
            Dtype::F32,
            vec![n, m, 3],
            bytes_of(
                frames
                    .iter()
                    .flat_map(|f| f.markers.iter().flatten().copied()),
                f32::to_le_bytes,
            ),
        ),
        (
            "world_from_hand",
            Dtype::F64,
            vec![n, 7],
            bytes_of(
                frames.iter().flat_map(|f| f.world_from_hand),
                f64::to_le_bytes,
            ),
        ),
        (
            "tendon_pull_m",
            Dtype::F32,
            vec![n, t],
            bytes_of(
                frames.iter().flat_map(|f| f.tendon_pull_m.iter().copied()),
                f32::to_le_bytes,
            ),
        ),
        (
            "object_family",
            Dtype::U8,
            vec![n],
            frames.iter().map(|f| f.object_family).collect(),
        ),
        (
            "object_params",
            Dtype::F32,
            vec![n, p],
            bytes_of(
                frames.iter().flat_map(|f| f.object_params.iter().copied()),
                f32::to_le_bytes,
            ),
        ),
    ];
    let views = tensors
        .iter()
        .map(|(name, dtype, shape, data)| {
            TensorView::new(*dtype, shape.clone(), data)
                .map(|view| (*name, view))
                .map_err(|e| IoError::Serialize {
                    path: path.to_path_buf(),
                    message: format!("tensor {name}: {e}"),
                })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let layout_json = serde_json::to_string(layout).map_err(|e| IoError::Serialize {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let metadata = HashMap::from([(LAYOUT_KEY.to_owned(), layout_json)]);
    safetensors::serialize(views, Some(metadata)).map_err(|e| IoError::Serialize {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Writes a shard atomically.
///
/// # Errors
/// As [`shard_bytes`], and file-system errors.
pub fn write_shard(
    path: &Path,
    layout: &DatasetLayout,
    frames: &[DatasetFrame],
) -> Result<(), IoError> {
    let bytes = shard_bytes(path, layout, frames)?;
    crate::atomic::write_atomic(path, &bytes)
}

/// Reads a whole shard file.
///
/// # Errors
/// A missing, truncated or corrupt file, or tensors that disagree with the stored layout.
pub fn read_shard(path: &Path) -> Result<(DatasetLayout, Vec<DatasetFrame>), IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    parse_shard(path, &bytes)
}

fn tensor<'a>(
    path: &Path,
    st: &SafeTensors<'a>,
    name: &str,
    dtype: Dtype,
    shape: &[usize],
) -> Result<&'a [u8], IoError> {
    let view = st
        .tensor(name)
        .map_err(|e| IoError::parse(path, None, format!("tensor {name}: {e}")))?;
    if view.dtype() != dtype || view.shape() != shape {
        return Err(IoError::invalid(
            path,
            format!("tensor {name}"),
            format!(
                "is {:?} {:?}, expected {dtype:?} {shape:?}",
                view.dtype(),
                view.shape()
            ),
        ));
    }
    Ok(view.data())
}

fn f32s(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Parses shard bytes (`path` names the source in errors). The safetensors parser runs under
/// the same panic guard as the mesh readers.
///
/// # Errors
/// As [`read_shard`].
pub fn parse_shard(
    path: &Path,
    bytes: &[u8],
) -> Result<(DatasetLayout, Vec<DatasetFrame>), IoError> {
    crate::files::guarded(path, "safetensors", || parse_shard_unguarded(path, bytes))
}

fn parse_shard_unguarded(
    path: &Path,
    bytes: &[u8],
) -> Result<(DatasetLayout, Vec<DatasetFrame>), IoError> {
    let (_, metadata) = SafeTensors::read_metadata(bytes).map_err(|e| {
        IoError::parse(path, None, format!("not a complete safetensors shard: {e}"))
    })?;
    let layout_json = metadata
        .metadata()
        .as_ref()
        .and_then(|m| m.get(LAYOUT_KEY))
        .ok_or_else(|| IoError::invalid(path, "metadata", format!("no '{LAYOUT_KEY}' entry")))?;
    let layout: DatasetLayout = serde_json::from_str(layout_json)
        .map_err(|e| IoError::invalid(path, "metadata layout", e.to_string()))?;
    let st = SafeTensors::deserialize(bytes).map_err(|e| {
        IoError::parse(path, None, format!("not a complete safetensors shard: {e}"))
    })?;
    let ids = st
        .tensor("trajectory_id")
        .map_err(|e| IoError::parse(path, None, format!("tensor trajectory_id: {e}")))?;
    let n = ids.shape().first().copied().unwrap_or(0);
    let (v, m, t, p) = (
        layout.total_vertices(),
        layout.total_markers(),
        layout.total_tendons(),
        layout.object_param_len,
    );
    let traj = tensor(path, &st, "trajectory_id", Dtype::U64, &[n])?;
    let index = tensor(path, &st, "frame_index", Dtype::U32, &[n])?;
    let verts = f32s(tensor(path, &st, "vertices", Dtype::F32, &[n, v, 3])?);
    let contact = tensor(path, &st, "contact", Dtype::U8, &[n, v])?;
    let force = f32s(tensor(path, &st, "contact_force_n", Dtype::F32, &[n, v])?);
    let distance = f32s(tensor(
        path,
        &st,
        "obstacle_distance_m",
        Dtype::F32,
        &[n, v],
    )?);
    let markers = f32s(tensor(path, &st, "markers", Dtype::F32, &[n, m, 3])?);
    let pose = tensor(path, &st, "world_from_hand", Dtype::F64, &[n, 7])?;
    let tendons = f32s(tensor(path, &st, "tendon_pull_m", Dtype::F32, &[n, t])?);
    let family = tensor(path, &st, "object_family", Dtype::U8, &[n])?;
    let params = f32s(tensor(path, &st, "object_params", Dtype::F32, &[n, p])?);
    let triples = |flat: &[f32]| -> Vec<[f32; 3]> {
        flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    };
    let mut frames = Vec::with_capacity(n);
    for k in 0..n {
        let mut world_from_hand = [0.0; 7];
        for (j, w) in world_from_hand.iter_mut().enumerate() {
            let o = 8 * (7 * k + j);
            *w = f64::from_le_bytes(pose[o..o + 8].try_into().expect("8 bytes"));
        }
        let frame = DatasetFrame {
            trajectory_id: u64::from_le_bytes(traj[8 * k..8 * k + 8].try_into().expect("8 bytes")),
            frame_index: u32::from_le_bytes(index[4 * k..4 * k + 4].try_into().expect("4 bytes")),
            vertices: triples(&verts[3 * v * k..3 * v * (k + 1)]),
            contact: contact[v * k..v * (k + 1)].to_vec(),
            contact_force_n: force[v * k..v * (k + 1)].to_vec(),
            obstacle_distance_m: distance[v * k..v * (k + 1)].to_vec(),
            markers: triples(&markers[3 * m * k..3 * m * (k + 1)]),
            world_from_hand,
            tendon_pull_m: tendons[t * k..t * (k + 1)].to_vec(),
            object_family: family[k],
            object_params: params[p * k..p * (k + 1)].to_vec(),
        };
        check_frame(path, &layout, k, &frame)?;
        frames.push(frame);
    }
    Ok((layout, frames))
}

/// Name of shard `index` of `count`.
pub fn shard_file_name(index: usize, count: usize) -> String {
    format!("shard-{index:05}-of-{count:05}.safetensors")
}

/// Counts over a set of frames.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameStats {
    /// Frames.
    pub frames: u64,
    /// Distinct trajectories.
    pub trajectories: u64,
    /// Frames with at least one contact vertex.
    pub contact_frames: u64,
    /// Vertices labelled in contact, over all frames.
    pub contact_vertices: u64,
    /// Vertices, over all frames.
    pub vertices: u64,
}

impl FrameStats {
    /// Fraction of all vertices that are labelled in contact.
    pub fn contact_ratio(&self) -> f64 {
        if self.vertices == 0 {
            0.0
        } else {
            self.contact_vertices as f64 / self.vertices as f64
        }
    }

    fn add(&mut self, other: &FrameStats) {
        self.frames += other.frames;
        self.trajectories += other.trajectories;
        self.contact_frames += other.contact_frames;
        self.contact_vertices += other.contact_vertices;
        self.vertices += other.vertices;
    }
}

/// One shard as listed in the card.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardEntry {
    /// File name within the data set directory.
    pub file: String,
    /// Its statistics.
    pub stats: FrameStats,
}

/// The data set card: what a data set holds, written beside its shards.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatasetCard {
    /// Format version of the shards.
    pub format_version: u32,
    /// The frame layout.
    pub layout: DatasetLayout,
    /// Seed of the generator that produced the data.
    pub seed: u64,
    /// Free-form description of how the data were generated.
    pub generator: serde_json::Value,
    /// Every shard, in order.
    pub shards: Vec<ShardEntry>,
    /// Totals over all shards.
    pub totals: FrameStats,
    /// Totals per object family.
    pub families: BTreeMap<String, FrameStats>,
}

/// The shard format version this crate writes.
pub const FORMAT_VERSION: u32 = 1;

/// Statistics of a shard's frames, overall and per family.
pub fn shard_stats(
    layout: &DatasetLayout,
    frames: &[DatasetFrame],
) -> (FrameStats, BTreeMap<String, FrameStats>) {
    let mut total = FrameStats::default();
    let mut per_family: BTreeMap<String, FrameStats> = BTreeMap::new();
    let mut seen: BTreeMap<String, std::collections::BTreeSet<u64>> = BTreeMap::new();
    for f in frames {
        let name = layout
            .object_families
            .get(usize::from(f.object_family))
            .cloned()
            .unwrap_or_default();
        let contacts = f.contact_count() as u64;
        let one = FrameStats {
            frames: 1,
            trajectories: 0,
            contact_frames: u64::from(contacts > 0),
            contact_vertices: contacts,
            vertices: f.contact.len() as u64,
        };
        total.add(&one);
        per_family.entry(name.clone()).or_default().add(&one);
        seen.entry(name).or_default().insert(f.trajectory_id);
    }
    let all: std::collections::BTreeSet<u64> = frames.iter().map(|f| f.trajectory_id).collect();
    total.trajectories = all.len() as u64;
    for (name, ids) in seen {
        per_family.entry(name).or_default().trajectories = ids.len() as u64;
    }
    (total, per_family)
}

impl DatasetCard {
    /// A card for shards whose statistics are given (trajectories never span shards).
    pub fn new(
        layout: DatasetLayout,
        seed: u64,
        generator: serde_json::Value,
        shards: Vec<(ShardEntry, BTreeMap<String, FrameStats>)>,
    ) -> Self {
        let mut totals = FrameStats::default();
        let mut families: BTreeMap<String, FrameStats> = BTreeMap::new();
        for (entry, fam) in &shards {
            totals.add(&entry.stats);
            for (name, s) in fam {
                families.entry(name.clone()).or_default().add(s);
            }
        }
        Self {
            format_version: FORMAT_VERSION,
            layout,
            seed,
            generator,
            shards: shards.into_iter().map(|(e, _)| e).collect(),
            totals,
            families,
        }
    }
}

/// Which part of a data set a trajectory belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Split {
    /// Training set.
    Train,
    /// Validation set.
    Validation,
    /// Test set.
    Test,
}

/// Fractions of trajectories in the training and validation sets; the rest is the test set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SplitFractions {
    /// Fraction for training. Default 0.8.
    pub train: f64,
    /// Fraction for validation. Default 0.1 (the test set gets the remaining 0.1, as the paper
    /// evaluates on 10 % of unseen trajectories).
    pub validation: f64,
}

impl Default for SplitFractions {
    fn default() -> Self {
        Self {
            train: 0.8,
            validation: 0.1,
        }
    }
}

/// The split of a trajectory: a hash of `(trajectory_id, seed)` mapped to `[0, 1)` and cut at
/// the fractions, so every frame of a trajectory lands in the same split, whatever shard it is in.
pub fn split_of(trajectory_id: u64, seed: u64, fractions: SplitFractions) -> Split {
    let mut rng = moe_geom::SeededRng::new(seed).split(trajectory_id);
    let u = rng.uniform();
    if u < fractions.train {
        Split::Train
    } else if u < fractions.train + fractions.validation {
        Split::Validation
    } else {
        Split::Test
    }
}

/// Reads a data set directory lazily: the card at once, shards one at a time while iterating.
#[derive(Debug, Clone)]
pub struct DatasetReader {
    dir: PathBuf,
    card: DatasetCard,
}

impl DatasetReader {
    /// Opens a data set directory by reading its card.
    ///
    /// # Errors
    /// A missing or malformed card.
    pub fn open(dir: &Path) -> Result<Self, IoError> {
        let card: DatasetCard = crate::config::read_json(&dir.join(CARD_FILE))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            card,
        })
    }

    /// The card.
    pub fn card(&self) -> &DatasetCard {
        &self.card
    }

    /// Like [`DatasetReader::frames`], as the in-memory vocabulary ([`LabelledFrame`]: per-finger
    /// vertices, labels and markers, typed wrist pose).
    pub fn labelled_frames(
        &self,
        split: Option<Split>,
        fractions: SplitFractions,
    ) -> LabelledFrames<'_> {
        LabelledFrames {
            frames: self.frames(split, fractions),
        }
    }

    /// Frames of `split` (all frames for `None`), shard by shard in card order; each item is a
    /// frame or the error that stopped reading a shard.
    pub fn frames(&self, split: Option<Split>, fractions: SplitFractions) -> DatasetFrames<'_> {
        DatasetFrames {
            reader: self,
            split,
            fractions,
            shard: 0,
            buffer: Vec::new().into_iter(),
            failed: false,
        }
    }
}

/// Iterator over a data set's frames as [`LabelledFrame`]s; see
/// [`DatasetReader::labelled_frames`].
#[derive(Debug)]
pub struct LabelledFrames<'a> {
    frames: DatasetFrames<'a>,
}

impl Iterator for LabelledFrames<'_> {
    type Item = Result<LabelledFrame, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        let frame = match self.frames.next()? {
            Ok(frame) => frame,
            Err(e) => return Some(Err(e)),
        };
        let reader = self.frames.reader;
        Some(frame.to_labelled(&reader.card.layout).map_err(|e| {
            self.frames.failed = true;
            IoError::invalid(
                &reader.dir,
                format!(
                    "trajectory {}, frame {}",
                    frame.trajectory_id, frame.frame_index
                ),
                e.to_string(),
            )
        }))
    }
}

/// Iterator over a data set's frames; see [`DatasetReader::frames`].
#[derive(Debug)]
pub struct DatasetFrames<'a> {
    reader: &'a DatasetReader,
    split: Option<Split>,
    fractions: SplitFractions,
    shard: usize,
    buffer: std::vec::IntoIter<DatasetFrame>,
    failed: bool,
}

impl Iterator for DatasetFrames<'_> {
    type Item = Result<DatasetFrame, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if self.failed {
                return None;
            }
            if let Some(frame) = self.buffer.next() {
                let keep = self.split.is_none_or(|s| {
                    split_of(frame.trajectory_id, self.reader.card.seed, self.fractions) == s
                });
                if keep {
                    return Some(Ok(frame));
                }
                continue;
            }
            let entry = self.reader.card.shards.get(self.shard)?;
            self.shard += 1;
            let path = self.reader.dir.join(&entry.file);
            match read_shard(&path) {
                Ok((layout, frames)) if layout == self.reader.card.layout => {
                    self.buffer = frames.into_iter()
                }
                Ok(_) => {
                    self.failed = true;
                    return Some(Err(IoError::invalid(
                        &path,
                        "layout",
                        "differs from the data set card",
                    )));
                }
                Err(e) => {
                    self.failed = true;
                    return Some(Err(e));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout() -> DatasetLayout {
        DatasetLayout {
            finger_num_vertices: vec![3, 2],
            markers_per_finger: vec![1, 1],
            tendons_per_finger: 2,
            object_param_len: 3,
            object_families: vec!["sphere".into(), "plate".into()],
        }
    }

    fn frame(traj: u64, k: u32) -> DatasetFrame {
        let s = traj as f32 + k as f32 * 0.1;
        DatasetFrame {
            trajectory_id: traj,
            frame_index: k,
            vertices: (0..5).map(|i| [i as f32, s, -0.5 * s]).collect(),
            contact: vec![0, 1, u8::from(k.is_multiple_of(2)), 0, 1],
            contact_force_n: vec![0.0, 0.25, 0.01 * s, 0.0, 1.5],
            obstacle_distance_m: vec![0.01, -1e-5, -1e-6 * s, f32::INFINITY, -2e-4],
            markers: vec![[0.1, 0.2, s], [0.3, 0.4, s]],
            world_from_hand: [
                0.1,
                0.2,
                0.3,
                0.0,
                0.0,
                (0.1 * traj as f64).sin(),
                (0.1 * traj as f64).cos(),
            ],
            tendon_pull_m: vec![0.001 * k as f32, 0.0, 0.0, 0.002],
            object_family: (traj % 2) as u8,
            object_params: vec![0.02, s, 1.0 / 3.0],
        }
    }

    #[test]
    fn frames_split_per_finger_as_labelled_frames() {
        let f = frame(3, 2);
        let l = f.to_labelled(&layout()).unwrap();
        assert_eq!((l.trajectory_id, l.frame_index), (3, 2));
        assert_eq!(l.shape.fingers.len(), 2);
        assert_eq!(l.shape.fingers[0].len(), 3);
        assert_eq!(
            l.shape.fingers[1][1],
            Point3::new(4.0, 3.2f32 as f64, -1.6f32 as f64)
        );
        assert_eq!(l.contact, vec![vec![false, true, true], vec![false, true]]);
        assert_eq!(l.contact_count(), f.contact_count());
        assert_eq!(
            l.markers.fingers[1],
            vec![Some(Point3::new(
                0.3f32 as f64,
                0.4f32 as f64,
                3.2f32 as f64
            ))]
        );
        let t = l.world_from_hand.iso().translation.vector;
        assert_eq!([t.x, t.y, t.z], [0.1, 0.2, 0.3]);
        let q = l.world_from_hand.iso().rotation.quaternion();
        assert!((q.k - 0.3f64.sin()).abs() < 1e-12 && (q.w - 0.3f64.cos()).abs() < 1e-12);
        let mut bad = f.clone();
        bad.world_from_hand[6] = 0.0;
        bad.world_from_hand[5] = 0.0;
        assert!(matches!(
            bad.to_labelled(&layout()),
            Err(GeomError::NonFinitePoint { .. })
        ));
        let mut short = f;
        short.markers.pop();
        assert!(matches!(
            short.to_labelled(&layout()),
            Err(GeomError::LengthMismatch {
                what: "frame markers",
                ..
            })
        ));
    }

    #[test]
    fn shards_round_trip_exactly() {
        let frames: Vec<DatasetFrame> = (0..3)
            .flat_map(|t| (0..4).map(move |k| frame(t, k)))
            .collect();
        let path = Path::new("s.safetensors");
        let bytes = shard_bytes(path, &layout(), &frames).unwrap();
        let (l, back) = parse_shard(path, &bytes).unwrap();
        assert_eq!(l, layout());
        assert_eq!(back, frames);
        // Deterministic bytes.
        assert_eq!(bytes, shard_bytes(path, &layout(), &frames).unwrap());
    }

    #[test]
    fn truncated_or_garbled_shards_are_clear_errors() {
        let frames: Vec<DatasetFrame> = (0..2).map(|k| frame(7, k)).collect();
        let path = Path::new("s.safetensors");
        let bytes = shard_bytes(path, &layout(), &frames).unwrap();
        for cut in 0..bytes.len() {
            let err = parse_shard(path, &bytes[..cut]).expect_err("a cut shard is an error");
            assert!(err.to_string().starts_with("s.safetensors"), "{err}");
        }
        let mut rng = moe_geom::SeededRng::new(3);
        for _ in 0..300 {
            let mut b = bytes.clone();
            let k = rng.below(b.len() as u64) as usize;
            b[k] = rng.below(256) as u8;
            let _ = parse_shard(path, &b);
        }
    }

    #[test]
    fn frames_that_do_not_fit_the_layout_are_named() {
        let path = Path::new("s.safetensors");
        let mut f = frame(1, 2);
        f.contact.pop();
        let err = shard_bytes(path, &layout(), &[frame(1, 1), f])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("frame 1 (trajectory 1, frame 2)") && err.contains("contact labels"),
            "{err}"
        );
        let mut f = frame(1, 2);
        f.object_family = 9;
        assert!(shard_bytes(path, &layout(), &[f]).is_err());
        let mut f = frame(1, 2);
        f.vertices[0][1] = f32::NAN;
        assert!(shard_bytes(path, &layout(), &[f]).is_err());
        let mut f = frame(1, 2);
        f.contact_force_n[3] = -0.5;
        let err = shard_bytes(path, &layout(), &[f]).unwrap_err().to_string();
        assert!(err.contains("contact force of vertex 3"), "{err}");
        let mut f = frame(1, 2);
        f.obstacle_distance_m[2] = f32::NAN;
        let err = shard_bytes(path, &layout(), &[f]).unwrap_err().to_string();
        assert!(err.contains("obstacle distance of vertex 2"), "{err}");
        let mut f = frame(1, 2);
        f.contact_force_n.pop();
        let err = shard_bytes(path, &layout(), &[f]).unwrap_err().to_string();
        assert!(err.contains("contact forces"), "{err}");
        assert!(shard_bytes(path, &layout(), &[]).is_err());
    }

    #[test]
    fn splits_are_by_trajectory_and_near_the_fractions() {
        let fractions = SplitFractions::default();
        let mut counts = [0usize; 3];
        for t in 0..10_000u64 {
            let s = split_of(t, 42, fractions);
            assert_eq!(s, split_of(t, 42, fractions), "deterministic");
            counts[s as usize] += 1;
        }
        assert!(
            (counts[0] as f64 / 10_000.0 - 0.8).abs() < 0.02,
            "{counts:?}"
        );
        assert!(
            (counts[1] as f64 / 10_000.0 - 0.1).abs() < 0.02,
            "{counts:?}"
        );
    }

    #[test]
    fn reader_iterates_shards_lazily_and_splits_by_trajectory() {
        let dir = std::env::temp_dir().join(format!("moe-dataset-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut entries = Vec::new();
        let mut all = Vec::new();
        for s in 0..3usize {
            let frames: Vec<DatasetFrame> = (0..4u64)
                .flat_map(|t| (0..3).map(move |k| frame(10 * s as u64 + t, k)))
                .collect();
            let file = shard_file_name(s, 3);
            write_shard(&dir.join(&file), &layout(), &frames).unwrap();
            let (stats, fam) = shard_stats(&layout(), &frames);
            entries.push((ShardEntry { file, stats }, fam));
            all.extend(frames);
        }
        let card = DatasetCard::new(layout(), 42, serde_json::json!({"test": true}), entries);
        assert_eq!(card.totals.frames, 36);
        assert_eq!(card.totals.trajectories, 12);
        assert_eq!(
            card.families["sphere"].frames + card.families["plate"].frames,
            36
        );
        let expected_ratio =
            all.iter().map(|f| f.contact_count()).sum::<usize>() as f64 / (36.0 * 5.0);
        assert!((card.totals.contact_ratio() - expected_ratio).abs() < 1e-12);
        crate::write_json(&dir.join(CARD_FILE), &card).unwrap();
        let reader = DatasetReader::open(&dir).unwrap();
        let everything: Vec<DatasetFrame> = reader
            .frames(None, SplitFractions::default())
            .map(Result::unwrap)
            .collect();
        assert_eq!(everything, all);
        let mut union = 0;
        for split in [Split::Train, Split::Validation, Split::Test] {
            for f in reader.frames(Some(split), SplitFractions::default()) {
                let f = f.unwrap();
                assert_eq!(
                    split_of(f.trajectory_id, 42, SplitFractions::default()),
                    split
                );
                union += 1;
            }
        }
        assert_eq!(union, 36);
        // The same frames as the in-memory vocabulary, split for split.
        for split in [None, Some(Split::Validation)] {
            let labelled: Vec<LabelledFrame> = reader
                .labelled_frames(split, SplitFractions::default())
                .map(Result::unwrap)
                .collect();
            let plain: Vec<DatasetFrame> = reader
                .frames(split, SplitFractions::default())
                .map(Result::unwrap)
                .collect();
            assert_eq!(labelled.len(), plain.len());
            for (l, p) in labelled.iter().zip(&plain) {
                assert_eq!(l, &p.to_labelled(&layout()).unwrap());
            }
        }
        // A damaged shard stops the iteration with an error naming it.
        std::fs::write(dir.join(shard_file_name(1, 3)), b"garbage").unwrap();
        let results: Vec<_> = reader.frames(None, SplitFractions::default()).collect();
        assert_eq!(results.iter().filter(|r| r.is_ok()).count(), 12);
        let err = results.last().unwrap().as_ref().unwrap_err().to_string();
        assert!(err.contains("shard-00001-of-00003"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
