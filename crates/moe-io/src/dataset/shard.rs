//! Safetensors shards: frames stacked tensor by tensor, written atomically, parsed and checked
//! against their layout.

use std::collections::HashMap;
use std::path::Path;

use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use super::frame::{DatasetFrame, DatasetLayout};
use crate::error::IoError;

/// Metadata key under which a shard stores its layout.
pub const LAYOUT_KEY: &str = "moe_touch_layout";

/// Name of the optional tensor of the fingers' net contact forces (format version 2).
const FINGER_FORCE: &str = "finger_force_n";

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
    if let Some(forces) = &f.finger_force_n {
        let fingers = layout.finger_num_vertices.len();
        if forces.len() != fingers {
            return Err(IoError::invalid(
                path,
                item(),
                format!(
                    "{} finger forces, the layout has {fingers} fingers",
                    forces.len()
                ),
            ));
        }
    }
    if f.contact.iter().any(|&c| c > 1) {
        return Err(IoError::invalid(
            path,
            item(),
            "contact labels must be 0 or 1",
        ));
    }
    let finite3 = |v: &[[f32; 3]]| v.iter().position(|p| !p.iter().all(|c| c.is_finite()));
    let finite = |v: &[f32]| v.iter().position(|c| !c.is_finite());
    let non_finite = finite3(&f.vertices)
        .map(|i| format!("vertex {i}"))
        .or_else(|| finite3(&f.markers).map(|i| format!("marker {i}")))
        .or_else(|| finite(&f.tendon_pull_m).map(|i| format!("tendon pull {i}")))
        .or_else(|| finite(&f.object_params).map(|i| format!("object parameter {i}")))
        .or_else(|| {
            (f.finger_force_n.as_deref())
                .and_then(finite3)
                .map(|i| format!("finger force {i}"))
        })
        .or_else(|| {
            (f.world_from_hand.iter().position(|c| !c.is_finite()))
                .map(|i| format!("wrist pose component {i}"))
        });
    if let Some(what) = non_finite {
        return Err(IoError::invalid(
            path,
            item(),
            format!("non-finite value in {what}"),
        ));
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

/// A tensor to serialise: name, element type, shape and little-endian bytes.
type Tensor = (&'static str, Dtype, Vec<usize>, Vec<u8>);

/// Serialises frames into shard bytes.
///
/// # Errors
/// A frame that does not fit the layout (naming the frame), or an empty frame list.
pub fn shard_bytes(
    path: &Path,
    layout: &DatasetLayout,
    frames: &[DatasetFrame],
) -> Result<Vec<u8>, IoError> {
    let with_forces = check_frames(path, layout, frames)?;
    let mut tensors = frame_tensors(layout, frames);
    if with_forces {
        tensors.push((
            FINGER_FORCE,
            Dtype::F32,
            vec![frames.len(), layout.finger_num_vertices.len(), 3],
            bytes_of(
                frames
                    .iter()
                    .flat_map(|f| f.finger_force_n.iter().flatten().flatten().copied()),
                f32::to_le_bytes,
            ),
        ));
    }
    serialize_tensors(path, layout, &tensors)
}

/// Checks that there are frames, that each fits the layout and that all or none carry finger
/// forces; returns whether they do.
fn check_frames(
    path: &Path,
    layout: &DatasetLayout,
    frames: &[DatasetFrame],
) -> Result<bool, IoError> {
    if frames.is_empty() {
        return Err(IoError::invalid(
            path,
            "shard",
            "a shard needs at least one frame",
        ));
    }
    let with_forces = frames[0].finger_force_n.is_some();
    for (k, f) in frames.iter().enumerate() {
        check_frame(path, layout, k, f)?;
        if f.finger_force_n.is_some() != with_forces {
            return Err(IoError::invalid(
                path,
                format!(
                    "frame {k} (trajectory {}, frame {})",
                    f.trajectory_id, f.frame_index
                ),
                "finger forces must be given for every frame of a shard or for none",
            ));
        }
    }
    Ok(with_forces)
}

/// The frames' fixed tensors (all but the finger forces), stacked frame by frame.
fn frame_tensors(layout: &DatasetLayout, frames: &[DatasetFrame]) -> Vec<Tensor> {
    let n = frames.len();
    let (m, t, p) = (
        layout.total_markers(),
        layout.total_tendons(),
        layout.object_param_len,
    );
    let mut tensors: Vec<Tensor> = vec![
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
    ];
    tensors.extend(vertex_tensors(layout, frames));
    tensors.extend([
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
    ]);
    tensors
}

/// The frames' per-vertex tensors: vertices, contact labels, forces and obstacle distances.
fn vertex_tensors(layout: &DatasetLayout, frames: &[DatasetFrame]) -> [Tensor; 4] {
    let (n, v) = (frames.len(), layout.total_vertices());
    [
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
    ]
}

/// Serialises the tensors with the layout as metadata.
fn serialize_tensors(
    path: &Path,
    layout: &DatasetLayout,
    tensors: &[Tensor],
) -> Result<Vec<u8>, IoError> {
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
    // Absent from shards of format version 1: their frames carry no finger forces.
    let fingers = layout.finger_num_vertices.len();
    let forces = if st.names().contains(&FINGER_FORCE) {
        Some(f32s(tensor(
            path,
            &st,
            FINGER_FORCE,
            Dtype::F32,
            &[n, fingers, 3],
        )?))
    } else {
        None
    };
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
            finger_force_n: forces
                .as_ref()
                .map(|all| triples(&all[3 * fingers * k..3 * fingers * (k + 1)])),
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
