//! Writing an episode as a ROS 2 recording (rosbag2 with MCAP storage, CDR messages), on the
//! topics and frames of a [`RosConfig`]: what a robot would have recorded of the same frames.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use moe_geom::Iso3;

use super::RosConfig;
use super::cdr::CdrWriter;
use crate::episode::{add_channel, mcap_writer};
use crate::error::IoError;
use crate::{AtomicFile, Episode};

/// How depth is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthEncoding {
    /// `16UC1`, millimetres (what `realsense2_camera` publishes; quantised to 1 mm).
    Millimetres16,
    /// `32FC1`, metres (exact).
    Metres32,
}

/// The colour camera's optical frame in the written TF tree.
pub const CAMERA_FRAME: &str = "camera_color_optical_frame";

fn stamp(w: &mut CdrWriter, time_ns: u64, frame: &str) {
    w.header(time_ns as i64, frame);
}

fn transform(w: &mut CdrWriter, time_ns: u64, parent: &str, child: &str, iso: &Iso3) {
    stamp(w, time_ns, parent);
    w.string(child);
    let t = iso.translation.vector;
    let q = iso.rotation.quaternion();
    for v in [t.x, t.y, t.z, q.i, q.j, q.k, q.w] {
        w.f64(v);
    }
}

/// Writes `episode` into the directory `dir` (created; it must not exist yet) as a rosbag2
/// recording: `metadata.yaml` and `NAME_0.mcap`. Colour as `rgb8`, depth as `encoding`, the
/// intrinsics with every frame, the camera's mounting on `/tf_static` (hand → the camera's
/// optical frame), the hand's pose on `/tf` (world → hand) and the tendon pulls as joint
/// positions (the names of `config.tendon_joints`, or `finger{i}_tendon{j}`).
///
/// # Errors
/// A directory that exists or cannot be created, a file that cannot be written.
pub fn write_ros2_bag(
    dir: &Path,
    episode: &Episode,
    config: &RosConfig,
    encoding: DepthEncoding,
) -> Result<(), IoError> {
    if dir.exists() {
        return Err(IoError::invalid(
            dir,
            "output",
            "already exists; give a new directory",
        ));
    }
    std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
    let name = dir
        .file_name()
        .map_or_else(|| "bag".into(), |n| n.to_string_lossy().into_owned());
    let file_name = format!("{name}_0.mcap");
    let path = dir.join(&file_name);
    let file = AtomicFile::create(&path)?;
    let mut counts: BTreeMap<&str, (&str, u64)> = BTreeMap::new();
    let file = {
        let mut w = mcap_writer(file, &path)?;
        let mut channels: BTreeMap<&str, u16> = BTreeMap::new();
        let topics = [
            (config.tf_static_topic.as_str(), "tf2_msgs/msg/TFMessage"),
            (
                config.camera_info_topic.as_str(),
                "sensor_msgs/msg/CameraInfo",
            ),
            (config.color_topic.as_str(), "sensor_msgs/msg/Image"),
            (config.depth_topic.as_str(), "sensor_msgs/msg/Image"),
            (config.tf_topic.as_str(), "tf2_msgs/msg/TFMessage"),
            (
                config.joint_state_topic.as_str(),
                "sensor_msgs/msg/JointState",
            ),
        ];
        for (topic, ty) in topics {
            let schema = (ty.to_owned(), "ros2msg".to_owned(), Vec::new());
            channels.insert(topic, add_channel(&mut w, &path, topic, schema, "cdr")?);
            counts.insert(topic, (ty, 0));
        }
        let mut sequence = 0u32;
        let mut put = |w: &mut mcap::Writer<_>, topic: &str, t: u64, data: Vec<u8>| {
            if let Some(c) = counts.get_mut(topic) {
                c.1 += 1;
            }
            crate::episode::write_message(w, &path, channels[topic], &mut sequence, t, &data)
        };
        let mut tf_static = CdrWriter::new();
        tf_static.u32(1);
        transform(
            &mut tf_static,
            0,
            &config.hand_frame,
            CAMERA_FRAME,
            &episode.info.hand_from_camera,
        );
        put(&mut w, &config.tf_static_topic, 0, tf_static.finish())?;
        let names = joint_names(config, episode);
        for frame in &episode.frames {
            let t = frame.time_ns;
            put(
                &mut w,
                &config.camera_info_topic,
                t,
                camera_info(episode, t),
            )?;
            put(&mut w, &config.color_topic, t, color(episode, frame, t))?;
            put(
                &mut w,
                &config.depth_topic,
                t,
                depth(episode, frame, t, encoding),
            )?;
            let mut tf = CdrWriter::new();
            tf.u32(1);
            transform(
                &mut tf,
                t,
                &config.world_frame,
                &config.hand_frame,
                &frame.world_from_hand,
            );
            put(&mut w, &config.tf_topic, t, tf.finish())?;
            let mut js = CdrWriter::new();
            stamp(&mut js, t, "");
            js.u32(names.len() as u32);
            for n in &names {
                js.string(n);
            }
            let positions: Vec<f64> = frame.tendon_pull_m.iter().flatten().copied().collect();
            js.f64_seq(&positions).f64_seq(&[]).f64_seq(&[]);
            put(&mut w, &config.joint_state_topic, t, js.finish())?;
        }
        w.finish().map_err(|e| crate::episode::mcap_err(&path, e))?;
        w.into_inner()
    };
    file.commit()?;
    let duration = episode.frames.last().map_or(0, |f| f.time_ns);
    let mut meta =
        String::from("rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n");
    let _ = writeln!(meta, "  duration:\n    nanoseconds: {duration}");
    let _ = writeln!(meta, "  starting_time:\n    nanoseconds_since_epoch: 0");
    let total: u64 = counts.values().map(|c| c.1).sum();
    let _ = writeln!(
        meta,
        "  message_count: {total}\n  topics_with_message_count:"
    );
    for (topic, (ty, n)) in &counts {
        let _ = writeln!(
            meta,
            "    - topic_metadata:\n        name: {topic}\n        type: {ty}\n        serialization_format: cdr\n      message_count: {n}"
        );
    }
    let _ = writeln!(
        meta,
        "  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n    - {file_name}"
    );
    crate::write_atomic(&dir.join("metadata.yaml"), meta.as_bytes())
}

fn joint_names(config: &RosConfig, episode: &Episode) -> Vec<String> {
    if !config.tendon_joints.is_empty() {
        return config.tendon_joints.iter().flatten().cloned().collect();
    }
    let fingers = episode.info.finger_num_vertices.len();
    (0..fingers)
        .flat_map(|i| {
            (0..episode.info.tendons_per_finger).map(move |j| format!("finger{i}_tendon{j}"))
        })
        .collect()
}

fn camera_info(episode: &Episode, t: u64) -> Vec<u8> {
    let c = episode.info.camera;
    let mut w = CdrWriter::new();
    stamp(&mut w, t, CAMERA_FRAME);
    w.u32(c.height)
        .u32(c.width)
        .string("plumb_bob")
        .f64_seq(&[0.0; 5]);
    let k = [c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0];
    let r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let p = [
        c.fx, 0.0, c.cx, 0.0, 0.0, c.fy, c.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
    ];
    for v in k.iter().chain(&r).chain(&p) {
        w.f64(*v);
    }
    w.u32(0).u32(0).u32(0).u32(0).u32(0).u32(0).u8(0);
    w.finish()
}

fn color(episode: &Episode, frame: &crate::EpisodeFrame, t: u64) -> Vec<u8> {
    let c = episode.info.camera;
    let mut w = CdrWriter::new();
    stamp(&mut w, t, CAMERA_FRAME);
    w.u32(c.height)
        .u32(c.width)
        .string("rgb8")
        .u8(0)
        .u32(3 * c.width);
    w.bytes(&frame.color_rgb8);
    w.finish()
}

fn depth(
    episode: &Episode,
    frame: &crate::EpisodeFrame,
    t: u64,
    encoding: DepthEncoding,
) -> Vec<u8> {
    let c = episode.info.camera;
    let mut w = CdrWriter::new();
    stamp(&mut w, t, CAMERA_FRAME);
    let (name, bytes): (&str, Vec<u8>) = match encoding {
        DepthEncoding::Millimetres16 => (
            "16UC1",
            frame
                .depth_m
                .iter()
                .flat_map(|&d| ((d * 1e3).round().clamp(0.0, 65535.0) as u16).to_le_bytes())
                .collect(),
        ),
        DepthEncoding::Metres32 => (
            "32FC1",
            frame.depth_m.iter().flat_map(|d| d.to_le_bytes()).collect(),
        ),
    };
    let bpp = if encoding == DepthEncoding::Millimetres16 {
        2
    } else {
        4
    };
    w.u32(c.height)
        .u32(c.width)
        .string(name)
        .u8(0)
        .u32(bpp * c.width);
    w.bytes(&bytes);
    w.finish()
}
