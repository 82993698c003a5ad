//! Reading a rosbag2 recording into an episode (see the module documentation).

use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};

use moe_geom::nalgebra::{Quaternion, Translation3, UnitQuaternion};
use moe_geom::{HandModel, Iso3};
use serde::{Deserialize, Serialize};

use super::cdr::{self, CdrError, TransformStamped};
use crate::episode::check_declared_lengths;
use crate::{CameraInfo, Episode, EpisodeFrame, EpisodeInfo};
use moe_io::IoError;

/// Where a recording's data are: topics, frames, pairing and the tendons' joint names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RosConfig {
    /// Colour images (`rgb8` or `bgr8`).
    pub color_topic: String,
    /// Depth images aligned to colour (`16UC1` millimetres or `32FC1` metres).
    pub depth_topic: String,
    /// The colour camera's intrinsics.
    pub camera_info_topic: String,
    /// Time-stamped transforms.
    pub tf_topic: String,
    /// Static transforms.
    pub tf_static_topic: String,
    /// Tendon pulls (`position`, metres).
    pub joint_state_topic: String,
    /// The world frame of TF.
    pub world_frame: String,
    /// The hand's frame of TF (the palm; the hand model's frame).
    pub hand_frame: String,
    /// Largest time between a colour image and the depth image paired with it, seconds.
    pub pair_tolerance_s: f64,
    /// The joint name of every tendon, `[finger][tendon]`; empty: `finger{i}_tendon{j}`.
    pub tendon_joints: Vec<Vec<String>>,
}

impl Default for RosConfig {
    fn default() -> Self {
        Self {
            color_topic: "/camera/camera/color/image_raw".into(),
            depth_topic: "/camera/camera/aligned_depth_to_color/image_raw".into(),
            camera_info_topic: "/camera/camera/color/camera_info".into(),
            tf_topic: "/tf".into(),
            tf_static_topic: "/tf_static".into(),
            joint_state_topic: "/hand/tendons".into(),
            world_frame: "world".into(),
            hand_frame: "hand".into(),
            pair_tolerance_s: 0.02,
            tendon_joints: Vec::new(),
        }
    }
}

/// Largest image side accepted, pixels.
const MAX_SIDE: u32 = 8192;

/// One decoded image: stamp, size, and its pixels (RGB8, or depth in metres).
struct Stamped<T> {
    stamp_ns: i64,
    frame_id: String,
    width: u32,
    height: u32,
    pixels: Vec<T>,
}

impl<T> Stamped<T> {
    /// `im`'s stamp, frame and size with its decoded `pixels`.
    fn of(im: &cdr::Image<'_>, pixels: Vec<T>) -> Self {
        Self {
            stamp_ns: im.header.stamp_ns,
            frame_id: im.header.frame_id.clone(),
            width: im.width,
            height: im.height,
            pixels,
        }
    }
}

/// What the messages of a recording hold, before frames are assembled.
#[derive(Default)]
struct Messages {
    color: Vec<Stamped<u8>>,
    depth: Vec<Stamped<f32>>,
    camera: Option<cdr::CameraInfo>,
    tf: Tf,
    joints: Vec<cdr::JointState>,
}

/// One edge's transforms, `parent_from_child`: a static one (`None`), or time-stamped ones in
/// time order.
type EdgeTransforms = Vec<(Option<i64>, Iso3)>;

/// Transforms by edge, `(parent, child)`.
#[derive(Default)]
struct Tf {
    edges: BTreeMap<(String, String), EdgeTransforms>,
}

impl Tf {
    fn add(&mut self, t: &TransformStamped, is_static: bool) -> Result<(), String> {
        let [x, y, z, w] = t.rotation_xyzw;
        let q = Quaternion::new(w, x, y, z);
        let norm = q.norm();
        if !(norm.is_finite() && norm > 1e-9 && t.translation.iter().all(|v| v.is_finite())) {
            return Err(format!(
                "transform {} → {}: not a rigid transform",
                t.header.frame_id, t.child_frame_id
            ));
        }
        let [tx, ty, tz] = t.translation;
        let iso = Iso3::from_parts(
            Translation3::new(tx, ty, tz),
            UnitQuaternion::from_quaternion(q),
        );
        let stamp = (!is_static).then_some(t.header.stamp_ns);
        let edge = (t.header.frame_id.clone(), t.child_frame_id.clone());
        let list = self.edges.entry(edge).or_default();
        // Messages come in time order as a rule: sort only when one does not (sorting on
        // every push made reading a long recording quadratic).
        let in_order = list.last().is_none_or(|(last, _)| *last <= stamp);
        list.push((stamp, iso));
        if !in_order {
            list.sort_by_key(|(s, _)| *s);
        }
        Ok(())
    }

    /// `parent_from_child` of one edge at time `t`: the static transform; between two stamped
    /// transforms, their interpolation (translation linear, rotation spherical), as tf2 looks
    /// transforms up; before the first or after the last, the nearest one.
    fn edge_at(list: &[(Option<i64>, Iso3)], t: i64) -> Iso3 {
        if let Some((None, iso)) = list.first() {
            return *iso;
        }
        let after = list.partition_point(|(s, _)| s.is_some_and(|s| s <= t));
        match (after.checked_sub(1).map(|i| &list[i]), list.get(after)) {
            (Some((Some(s0), a)), Some((Some(s1), b))) if s1 > s0 => {
                let f = (t - s0) as f64 / (s1 - s0) as f64;
                let translation = a.translation.vector.lerp(&b.translation.vector, f);
                // q and −q are one rotation: interpolate towards the nearer sign. Rotations half
                // a turn apart have no unique arc; the nearer stamp's is kept.
                let to = if a.rotation.coords.dot(&b.rotation.coords) < 0.0 {
                    UnitQuaternion::new_unchecked(-b.rotation.into_inner())
                } else {
                    b.rotation
                };
                let nearer = if f < 0.5 { a.rotation } else { b.rotation };
                let rotation = a.rotation.try_slerp(&to, f, 1e-9).unwrap_or(nearer);
                Iso3::from_parts(translation.into(), rotation)
            }
            (Some((_, a)), _) => *a,
            (None, Some((_, b))) => *b,
            (None, None) => Iso3::identity(),
        }
    }

    /// `to_from_from` at time `t` through the tree, edges used either way.
    fn lookup(&self, to: &str, from: &str, t: i64) -> Option<Iso3> {
        let mut seen: BTreeMap<&str, Iso3> = BTreeMap::new();
        seen.insert(from, Iso3::identity());
        let mut queue = VecDeque::from([from]);
        while let Some(frame) = queue.pop_front() {
            let frame_from_start = seen[frame];
            if frame == to {
                return Some(frame_from_start);
            }
            for ((parent, child), list) in &self.edges {
                let step = Self::edge_at(list, t);
                let (next, next_from_frame) = if child == frame {
                    (parent.as_str(), step)
                } else if parent == frame {
                    (child.as_str(), step.inverse())
                } else {
                    continue;
                };
                if !seen.contains_key(next) {
                    seen.insert(next, next_from_frame * frame_from_start);
                    queue.push_back(next);
                }
            }
        }
        None
    }

    fn frames(&self) -> Vec<String> {
        let mut all: Vec<String> = self
            .edges
            .keys()
            .flat_map(|(p, c)| [p.clone(), c.clone()])
            .collect();
        all.sort();
        all.dedup();
        all
    }
}

/// The MCAP files of a recording: a rosbag2 directory's (from its `metadata.yaml`), or the file
/// itself.
fn storage_files(path: &Path) -> Result<Vec<PathBuf>, IoError> {
    if !path.is_dir() {
        return Ok(vec![path.to_path_buf()]);
    }
    let meta = path.join("metadata.yaml");
    let text = std::fs::read_to_string(&meta).map_err(|e| IoError::io(&meta, e))?;
    let value = |key: &str| {
        text.lines()
            .find_map(|l| l.trim().strip_prefix(key).map(|v| v.trim().to_owned()))
    };
    match value("storage_identifier:").as_deref() {
        Some("mcap") => {}
        Some(other) => {
            return Err(IoError::invalid(
                &meta,
                "storage_identifier",
                format!(
                    "'{other}' storage is not read: convert the bag to MCAP (`ros2 bag convert`)"
                ),
            ));
        }
        None => return Err(IoError::invalid(&meta, "storage_identifier", "missing")),
    }
    let mut files = Vec::new();
    let mut in_list = false;
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with("relative_file_paths:") {
            in_list = true;
            continue;
        }
        if in_list {
            match t.strip_prefix("- ") {
                Some(name) => files.push(path.join(name.trim_matches(|c| c == '"' || c == '\''))),
                None => in_list = false,
            }
        }
    }
    if files.is_empty() {
        return Err(IoError::invalid(
            &meta,
            "relative_file_paths",
            "no storage file listed",
        ));
    }
    Ok(files)
}

/// Reads a ROS 2 recording (a rosbag2 directory with MCAP storage, or one MCAP file of CDR
/// messages) for `hand`.
///
/// # Errors
/// Unreadable or damaged files; no colour, depth or camera-info message; an image encoding
/// other than `rgb8`/`bgr8` (colour) or `16UC1`/`32FC1` (depth), named; depth of another size
/// than colour; colour stamps out of order; no TF path from the world to the hand or from the
/// hand to the camera; joint states without a tendon's joint name; no colour image with a
/// depth image within the tolerance.
pub fn read_ros2_bag(
    path: &Path,
    config: &RosConfig,
    hand: &HandModel,
) -> Result<Episode, IoError> {
    let mut messages = Messages::default();
    for file in storage_files(path)? {
        let bytes = moe_io::read_bytes(&file)?;
        let readable = check_declared_lengths(&file, &bytes)?;
        let bytes = &bytes[..readable];
        moe_io::guarded(&file, "mcap", || {
            read_messages(&file, bytes, config, &mut messages)
        })?;
    }
    // A second line of defence, as for the third-party parsers: a panic becomes an error.
    moe_io::guarded(path, "ros2", || assemble(path, config, hand, messages))
}

fn read_messages(
    path: &Path,
    bytes: &[u8],
    config: &RosConfig,
    out: &mut Messages,
) -> Result<(), IoError> {
    let stream = mcap::MessageStream::new(bytes)
        .map_err(|e| IoError::parse(path, None, format!("MCAP: {e}")))?;
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    for message in stream {
        let message = message.map_err(|e| IoError::parse(path, None, format!("MCAP: {e}")))?;
        let topic = message.channel.topic.as_str();
        let k = counts.entry(topic.to_owned()).or_default();
        *k += 1;
        let bad = |e: CdrError| {
            IoError::invalid(path, format!("{topic} message {}", *k - 1), e.to_string())
        };
        let data = &message.data[..];
        if topic == config.color_topic {
            out.color.push(
                color_image(&cdr::image(data).map_err(bad)?).map_err(|m| {
                    IoError::invalid(path, format!("{topic} message {}", *k - 1), m)
                })?,
            );
        } else if topic == config.depth_topic {
            out.depth.push(
                depth_image(&cdr::image(data).map_err(bad)?).map_err(|m| {
                    IoError::invalid(path, format!("{topic} message {}", *k - 1), m)
                })?,
            );
        } else if topic == config.camera_info_topic {
            let info = cdr::camera_info(data).map_err(bad)?;
            out.camera.get_or_insert(info);
        } else if topic == config.tf_topic || topic == config.tf_static_topic {
            let is_static = topic == config.tf_static_topic;
            for t in cdr::tf_message(data).map_err(bad)? {
                out.tf.add(&t, is_static).map_err(|m| {
                    IoError::invalid(path, format!("{topic} message {}", *k - 1), m)
                })?;
            }
        } else if topic == config.joint_state_topic {
            out.joints.push(cdr::joint_state(data).map_err(bad)?);
        }
    }
    Ok(())
}

fn check_size(im: &cdr::Image<'_>, bytes_per_pixel: u32) -> Result<(), String> {
    if im.width == 0 || im.height == 0 || im.width > MAX_SIDE || im.height > MAX_SIDE {
        return Err(format!(
            "{} × {} pixels is not an image size",
            im.width, im.height
        ));
    }
    if im.step < im.width * bytes_per_pixel {
        return Err(format!(
            "rows of {} bytes for {} pixels of {bytes_per_pixel} bytes",
            im.step, im.width
        ));
    }
    Ok(())
}

/// Rows of `im` without their padding.
fn rows<'a>(im: &'a cdr::Image<'a>, bytes_per_pixel: u32) -> impl Iterator<Item = &'a [u8]> {
    let used = (im.width * bytes_per_pixel) as usize;
    im.data
        .chunks_exact(im.step as usize)
        .map(move |r| &r[..used])
}

fn color_image(im: &cdr::Image<'_>) -> Result<Stamped<u8>, String> {
    let swap = match im.encoding.as_str() {
        "rgb8" => false,
        "bgr8" => true,
        other => {
            return Err(format!(
                "colour encoding '{other}' is not read (expected rgb8 or bgr8)"
            ));
        }
    };
    check_size(im, 3)?;
    let mut pixels = Vec::with_capacity((im.width * im.height * 3) as usize);
    for row in rows(im, 3) {
        for px in row.chunks_exact(3) {
            if swap {
                pixels.extend_from_slice(&[px[2], px[1], px[0]]);
            } else {
                pixels.extend_from_slice(px);
            }
        }
    }
    Ok(Stamped::of(im, pixels))
}

fn depth_image(im: &cdr::Image<'_>) -> Result<Stamped<f32>, String> {
    let (bytes, millimetres) = match im.encoding.as_str() {
        "16UC1" | "mono16" => (2, true),
        "32FC1" => (4, false),
        other => {
            return Err(format!(
                "depth encoding '{other}' is not read (expected 16UC1 in millimetres or 32FC1 in metres)"
            ));
        }
    };
    check_size(im, bytes)?;
    let mut pixels = Vec::with_capacity((im.width * im.height) as usize);
    for row in rows(im, bytes) {
        for px in row.chunks_exact(bytes as usize) {
            let v = if millimetres {
                let raw = [px[0], px[1]];
                let mm = if im.is_bigendian {
                    u16::from_be_bytes(raw)
                } else {
                    u16::from_le_bytes(raw)
                };
                f32::from(mm) * 1e-3
            } else {
                let raw = [px[0], px[1], px[2], px[3]];
                let m = if im.is_bigendian {
                    f32::from_be_bytes(raw)
                } else {
                    f32::from_le_bytes(raw)
                };
                // No depth is 0 in an episode; NaN and infinities are no depth too.
                if m.is_finite() { m } else { 0.0 }
            };
            pixels.push(v);
        }
    }
    Ok(Stamped::of(im, pixels))
}

/// The joint names of every tendon.
fn tendon_joints(config: &RosConfig, hand: &HandModel) -> Result<Vec<Vec<String>>, String> {
    let tendons = hand.tendons_per_finger().map_err(|e| e.to_string())?;
    if config.tendon_joints.is_empty() {
        return Ok((0..hand.num_fingers())
            .map(|i| {
                (0..tendons)
                    .map(|j| format!("finger{i}_tendon{j}"))
                    .collect()
            })
            .collect());
    }
    let shape: Vec<usize> = config.tendon_joints.iter().map(Vec::len).collect();
    if shape != vec![tendons; hand.num_fingers()] {
        return Err(format!(
            "tendon_joints has {shape:?} names per finger; the hand has {} fingers of {tendons} tendons",
            hand.num_fingers()
        ));
    }
    Ok(config.tendon_joints.clone())
}

/// The tendon pulls of the latest joint state at or before `t` (zeros before the first).
fn pulls_at(
    joints: &[cdr::JointState],
    names: &[Vec<String>],
    t: i64,
) -> Result<Vec<Vec<f64>>, String> {
    let Some(state) = joints.iter().rev().find(|j| j.header.stamp_ns <= t) else {
        return Ok(names.iter().map(|f| vec![0.0; f.len()]).collect());
    };
    names
        .iter()
        .map(|finger| {
            finger
                .iter()
                .map(|name| {
                    let i = state.name.iter().position(|n| n == name).ok_or_else(|| {
                        format!(
                            "joint state at {} ns has no joint '{name}' (it has {:?}); map the \
                             tendons to joints with tendon_joints",
                            state.header.stamp_ns, state.name
                        )
                    })?;
                    state
                        .position
                        .get(i)
                        .copied()
                        .filter(|p| p.is_finite())
                        .ok_or_else(|| format!("joint '{name}' has no finite position"))
                })
                .collect()
        })
        .collect()
}

/// The frames and the episode info from everything read.
fn assemble(
    path: &Path,
    config: &RosConfig,
    hand: &HandModel,
    m: Messages,
) -> Result<Episode, IoError> {
    let refuse = |item: &str, message: String| Err(IoError::invalid(path, item, message));
    if m.color.is_empty() {
        return refuse(
            "colour",
            format!("no message on the colour topic {}", config.color_topic),
        );
    }
    if m.depth.is_empty() {
        return refuse(
            "depth",
            format!("no message on the depth topic {}", config.depth_topic),
        );
    }
    let Some(info) = m.camera else {
        return refuse(
            "camera info",
            format!("no message on {}", config.camera_info_topic),
        );
    };
    if let Some(k) = m
        .color
        .windows(2)
        .position(|w| w[1].stamp_ns <= w[0].stamp_ns)
    {
        return refuse(
            &format!("colour message {}", k + 1),
            format!(
                "stamp {} ns is not after the previous {} ns: timestamps out of order",
                m.color[k + 1].stamp_ns,
                m.color[k].stamp_ns
            ),
        );
    }
    // The first image's stamp, frame and size: where the camera's mounting is looked up, the
    // camera and its size.
    let (first_stamp, first_frame, size) = {
        let f = &m.color[0];
        (f.stamp_ns, f.frame_id.clone(), (f.width, f.height))
    };
    if first_stamp < 0 {
        return refuse(
            "colour message 0",
            format!("stamp {first_stamp} ns is before 1970: stamps must be times since the epoch"),
        );
    }
    if (info.width, info.height) != size {
        return refuse(
            "camera info",
            format!(
                "{} × {} pixels, the colour images {} × {}",
                info.width, info.height, size.0, size.1
            ),
        );
    }
    let names =
        tendon_joints(config, hand).map_err(|e| IoError::invalid(path, "tendon_joints", e))?;
    let no_path = |from: &str, to: &str| {
        IoError::invalid(
            path,
            "tf",
            format!(
                "no transform path from '{from}' to '{to}' (frames: {:?})",
                m.tf.frames()
            ),
        )
    };
    let hand_from_camera =
        m.tf.lookup(&config.hand_frame, &first_frame, first_stamp)
            .ok_or_else(|| no_path(&config.hand_frame, &first_frame))?;
    let tolerance_ns = (config.pair_tolerance_s * 1e9).round() as i64;
    let mut frames = Vec::new();
    // The colour images move into the frames; a depth image may serve two of them.
    for (k, color) in m.color.into_iter().enumerate() {
        if (color.width, color.height) != size {
            return refuse(
                &format!("colour message {k}"),
                "another size than the first".into(),
            );
        }
        let Some(depth) = m
            .depth
            .iter()
            .min_by_key(|d| (d.stamp_ns - color.stamp_ns).abs())
            .filter(|d| (d.stamp_ns - color.stamp_ns).abs() <= tolerance_ns)
        else {
            continue;
        };
        if (depth.width, depth.height) != (color.width, color.height) {
            return refuse(
                &format!("depth at {} ns", depth.stamp_ns),
                format!(
                    "{} × {} pixels, the colour image {} × {}: depth must be aligned to colour",
                    depth.width, depth.height, color.width, color.height
                ),
            );
        }
        let world_from_hand =
            m.tf.lookup(&config.world_frame, &config.hand_frame, color.stamp_ns)
                .ok_or_else(|| no_path(&config.world_frame, &config.hand_frame))?;
        let tendon_pull_m = pulls_at(&m.joints, &names, color.stamp_ns)
            .map_err(|e| IoError::invalid(path, config.joint_state_topic.clone(), e))?;
        frames.push(EpisodeFrame {
            // Stamps are ordered and the first is not negative.
            time_ns: color.stamp_ns.unsigned_abs(),
            color_rgb8: color.pixels,
            depth_m: depth.pixels.clone(),
            world_from_hand,
            tendon_pull_m,
            finger_vertices_in_hand: Vec::new(),
            contact_vertices: Vec::new(),
            markers_in_hand: Vec::new(),
            obstacles: Vec::new(),
        });
    }
    if frames.is_empty() {
        return refuse(
            "depth",
            format!(
                "no colour image has a depth image within {} s",
                config.pair_tolerance_s
            ),
        );
    }
    let scene = path
        .file_stem()
        .map_or_else(|| "ros2".into(), |s| s.to_string_lossy().into_owned());
    let camera = CameraInfo {
        width: info.width,
        height: info.height,
        fx: info.k[0],
        fy: info.k[4],
        cx: info.k[2],
        cy: info.k[5],
    };
    let info = EpisodeInfo::for_hand(scene, camera, hand_from_camera, hand)
        .map_err(|e| IoError::invalid(path, "hand", e.to_string()))?;
    Ok(Episode { info, frames })
}

/// Whether `path` is a ROS 2 recording: a rosbag2 directory (it has a `metadata.yaml`), or an
/// MCAP file whose first message is CDR.
pub fn is_ros2_recording(path: &Path) -> bool {
    if path.is_dir() {
        return path.join("metadata.yaml").is_file();
    }
    // The first message is in the file's head: read no more than that.
    const HEAD: u64 = 64 << 20;
    let mut bytes = Vec::new();
    let read = std::fs::File::open(path)
        .and_then(|f| std::io::Read::read_to_end(&mut std::io::Read::take(f, HEAD), &mut bytes));
    if read.is_err() {
        return false;
    }
    let Ok(n) = check_declared_lengths(path, &bytes) else {
        return false;
    };
    let first_encoding = || {
        let encoding = mcap::MessageStream::new(&bytes[..n])
            .ok()
            .and_then(|mut s| s.next())
            .and_then(Result::ok)
            .map(|m| m.channel.message_encoding.clone());
        Ok(encoding)
    };
    moe_io::guarded(path, "mcap", first_encoding)
        .ok()
        .flatten()
        .is_some_and(|e| e == "cdr")
}

#[cfg(test)]
mod tests;
