//! Writing ROS 2 recordings (rosbag2 with MCAP storage, CDR messages): an episode, on the topics
//! and frames of a [`RosConfig`] (what a robot would have recorded of the same frames), and a
//! run's results as `visualization_msgs` and `geometry_msgs` to replay beside the robot's own.

use std::fmt::Write as _;
use std::path::Path;

use moe_geom::{Iso3, Point3};

use super::RosConfig;
use super::cdr::CdrWriter;
use crate::episode::{add_channel, mcap_writer};
use crate::run_output::{
    CONTACT_COLOR, CONTACT_DIAMETER_M, FORCE_COLOR, MARKER_COLOR, MARKER_DIAMETER_M,
    probability_rgba,
};
use moe_io::AtomicFile;
use moe_io::IoError;

use crate::{Episode, RunFrame};

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

/// A rosbag2 directory being written: one MCAP file of CDR messages, then its `metadata.yaml`
/// (written last, so that a recording cut short by an error is not taken for a whole one).
struct BagWriter<'a> {
    dir: &'a Path,
    /// The MCAP file, `dir/NAME_0.mcap`.
    path: std::path::PathBuf,
    writer: mcap::Writer<AtomicFile>,
    /// Per declared channel: topic, message type, MCAP channel id, messages written.
    channels: Vec<(String, &'static str, u16, u64)>,
    sequence: u32,
    /// The first and last message times.
    span_ns: Option<(u64, u64)>,
}

impl<'a> BagWriter<'a> {
    /// Creates `dir` (it must not exist), writes the recording with `messages`, and finishes
    /// it; on an error, removes what it created, so that nothing half-written is left.
    fn write(
        dir: &'a Path,
        messages: impl FnOnce(&mut Self) -> Result<(), IoError>,
    ) -> Result<(), IoError> {
        let mut bag = Self::create(dir)?;
        let written = messages(&mut bag).and_then(|()| bag.finish());
        if written.is_err() {
            let _ = std::fs::remove_dir_all(dir);
        }
        written
    }

    /// Creates `dir` (it must not exist) and its MCAP file.
    fn create(dir: &'a Path) -> Result<Self, IoError> {
        if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| IoError::io(parent, e))?;
        }
        // `create_dir`, not a check then a create: a directory that appears in between is
        // refused, never filled (nor removed after a failure).
        std::fs::create_dir(dir).map_err(|e| match e.kind() {
            std::io::ErrorKind::AlreadyExists => {
                IoError::invalid(dir, "output", "already exists; give a new directory")
            }
            _ => IoError::io(dir, e),
        })?;
        let name = dir
            .file_name()
            .map_or_else(|| "bag".into(), |n| n.to_string_lossy().into_owned());
        let path = dir.join(format!("{name}_0.mcap"));
        let writer = mcap_writer(AtomicFile::create(&path)?, &path, "ros2")?;
        Ok(Self {
            dir,
            path,
            writer,
            channels: Vec::new(),
            sequence: 0,
            span_ns: None,
        })
    }

    /// Declares `topic` of message type `ty` with its `ros2msg` definition; the handle to
    /// [`BagWriter::put`] its messages with.
    fn channel(
        &mut self,
        topic: &str,
        ty: &'static str,
        definition: &str,
    ) -> Result<usize, IoError> {
        let schema = (
            ty.to_owned(),
            "ros2msg".to_owned(),
            definition.as_bytes().to_vec(),
        );
        let id = add_channel(&mut self.writer, &self.path, topic, schema, "cdr")?;
        self.channels.push((topic.to_owned(), ty, id, 0));
        Ok(self.channels.len() - 1)
    }

    /// Writes one message on the declared `channel` at `time_ns`.
    fn put(&mut self, channel: usize, time_ns: u64, data: &[u8]) -> Result<(), IoError> {
        let channel = &mut self.channels[channel];
        channel.3 += 1;
        self.span_ns = Some(self.span_ns.map_or((time_ns, time_ns), |(a, b)| {
            (a.min(time_ns), b.max(time_ns))
        }));
        crate::episode::write_message(
            &mut self.writer,
            &self.path,
            channel.2,
            &mut self.sequence,
            time_ns,
            data,
        )
    }

    /// Ends a frame's messages: closes their chunk, so that no chunk grows with the recording
    /// (the reader refuses chunks over a gigabyte).
    fn end_frame(&mut self) -> Result<(), IoError> {
        self.writer
            .flush()
            .map_err(|e| crate::episode::mcap_err(&self.path, e))
    }

    /// Finishes the MCAP file and writes `metadata.yaml` in rosbag2's version 8 form (ROS 2
    /// Jazzy), with every field its reader requires.
    fn finish(mut self) -> Result<(), IoError> {
        self.writer
            .finish()
            .map_err(|e| crate::episode::mcap_err(&self.path, e))?;
        self.writer.into_inner().commit()?;
        let (start, end) = self.span_ns.unwrap_or((0, 0));
        let file_name = self
            .path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let total: u64 = self.channels.iter().map(|c| c.3).sum();
        let time = |m: &mut String, indent: &str| {
            let _ = writeln!(
                m,
                "{indent}starting_time:\n{indent}  nanoseconds_since_epoch: {start}\n{indent}duration:\n{indent}  nanoseconds: {}",
                end - start
            );
        };
        let mut meta = String::from(
            "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n",
        );
        time(&mut meta, "  ");
        let _ = writeln!(
            meta,
            "  message_count: {total}\n  topics_with_message_count:"
        );
        for (topic, ty, _, n) in &self.channels {
            let _ = writeln!(
                meta,
                "    - topic_metadata:\n        name: {topic}\n        type: {ty}\n        serialization_format: cdr\n        offered_qos_profiles: \"[]\"\n        type_description_hash: \"\"\n      message_count: {n}"
            );
        }
        let _ = writeln!(
            meta,
            "  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n    - {}\n  files:\n    - path: {}",
            file_name, file_name
        );
        time(&mut meta, "      ");
        let _ = writeln!(
            meta,
            "      message_count: {total}\n  custom_data: ~\n  ros_distro: jazzy"
        );
        moe_io::write_atomic(&self.dir.join("metadata.yaml"), meta.as_bytes())
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
    BagWriter::write(dir, |bag| write_episode(bag, episode, config, encoding))
}

fn write_episode(
    bag: &mut BagWriter<'_>,
    episode: &Episode,
    config: &RosConfig,
    encoding: DepthEncoding,
) -> Result<(), IoError> {
    let topics = [
        (&config.tf_static_topic, "tf2_msgs/msg/TFMessage"),
        (&config.camera_info_topic, "sensor_msgs/msg/CameraInfo"),
        (&config.color_topic, "sensor_msgs/msg/Image"),
        (&config.depth_topic, "sensor_msgs/msg/Image"),
        (&config.tf_topic, "tf2_msgs/msg/TFMessage"),
        (&config.joint_state_topic, "sensor_msgs/msg/JointState"),
    ];
    let [tf_static_ch, info_ch, color_ch, depth_ch, tf_ch, joints_ch] =
        topics.map(|(topic, ty)| bag.channel(topic, ty, ""));
    // The static transform at the first frame's time, so that the recording starts there.
    let start = episode.frames.first().map_or(0, |f| f.time_ns);
    let mut tf_static = CdrWriter::new();
    tf_static.u32(1);
    transform(
        &mut tf_static,
        start,
        &config.hand_frame,
        CAMERA_FRAME,
        &episode.info.hand_from_camera,
    );
    bag.put(tf_static_ch?, start, &tf_static.finish())?;
    let [info_ch, color_ch, depth_ch, tf_ch, joints_ch] =
        [info_ch?, color_ch?, depth_ch?, tf_ch?, joints_ch?];
    let names = joint_names(config, episode);
    for frame in &episode.frames {
        let t = frame.time_ns;
        bag.put(info_ch, t, &camera_info(episode, t))?;
        bag.put(color_ch, t, &color(episode, frame, t))?;
        bag.put(depth_ch, t, &depth(episode, frame, t, encoding))?;
        let mut tf = CdrWriter::new();
        tf.u32(1);
        transform(
            &mut tf,
            t,
            &config.world_frame,
            &config.hand_frame,
            &frame.world_from_hand,
        );
        bag.put(tf_ch, t, &tf.finish())?;
        let mut js = CdrWriter::new();
        stamp(&mut js, t, "");
        js.u32(names.len() as u32);
        for n in &names {
            js.string(n);
        }
        let positions: Vec<f64> = frame.tendon_pull_m.iter().flatten().copied().collect();
        js.f64_seq(&positions).f64_seq(&[]).f64_seq(&[]);
        bag.put(joints_ch, t, &js.finish())?;
        bag.end_frame()?;
    }
    Ok(())
}

/// The topic of the results' markers (`visualization_msgs/msg/MarkerArray`).
pub const RESULT_MARKERS_TOPIC: &str = "/moe_touch/markers";

/// The topic of finger `finger`'s estimated force (`geometry_msgs/msg/WrenchStamped`).
pub fn result_wrench_topic(finger: usize) -> String {
    format!("/moe_touch/finger{finger}/wrench")
}

/// `visualization_msgs/Marker` types and actions used here.
const POINTS: i32 = 8;
const SPHERE_LIST: i32 = 7;
const ARROW: i32 = 0;
const ADD: i32 = 0;
const DELETE_ALL: i32 = 3;

/// One `visualization_msgs/Marker` (the Jazzy definition, with the texture and mesh-file fields).
struct MarkerSpec<'a> {
    frame: &'a str,
    ns: &'a str,
    id: i32,
    kind: i32,
    action: i32,
    scale: [f64; 3],
    color: [f32; 4],
    points: &'a [Point3],
    colors: &'a [[f32; 4]],
}

fn marker(w: &mut CdrWriter, t: u64, m: &MarkerSpec<'_>) {
    stamp(w, t, m.frame);
    w.string(m.ns).i32(m.id).i32(m.kind).i32(m.action);
    for v in [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0] {
        w.f64(v); // pose: position, orientation (identity)
    }
    for v in m.scale {
        w.f64(v);
    }
    for c in m.color {
        w.f32(c);
    }
    w.i32(0).u32(0).u8(0); // lifetime 0 (forever), frame_locked false
    w.u32(m.points.len() as u32);
    for p in m.points {
        w.f64(p.x).f64(p.y).f64(p.z);
    }
    w.u32(m.colors.len() as u32);
    for c in m.colors {
        for v in c {
            w.f32(*v);
        }
    }
    w.string(""); // texture_resource
    stamp(w, 0, ""); // texture: sensor_msgs/CompressedImage, empty
    w.string("").bytes(&[]);
    w.u32(0); // uv_coordinates
    w.string("").string(""); // text, mesh_resource
    w.string("").bytes(&[]); // mesh_file
    w.u8(0); // mesh_use_embedded_materials
}

/// Writes the results of a run of `frames` into the directory `dir` (created; it must not exist
/// yet) as a rosbag2 recording to replay beside the robot's own topics:
///
/// - [`RESULT_MARKERS_TOPIC`] (`visualization_msgs/msg/MarkerArray`, stamped with each frame's
///   time): every finger's estimated surface as points coloured by contact probability and the
///   markers found, in `config.hand_frame`; the contact points in `config.world_frame`; with the
///   physics estimator each load as an arrow ending at its place, `arrow_m_per_n` metres long
///   per newton.
///   The first marker of every array deletes the previous frame's.
/// - [`result_wrench_topic`]`(f)` (`geometry_msgs/msg/WrenchStamped`, `config.hand_frame`): the
///   net force the world exerts on finger `f` (zero torque), for runs that estimate force.
///
/// Messages carry their `ros2msg` definitions (as ROS 2 Jazzy defines them), so viewers that
/// decode from the file (Foxglove) need no ROS installation.
///
/// # Errors
/// A directory that exists or cannot be created, a file that cannot be written.
pub fn write_ros2_results(
    dir: &Path,
    frames: &[RunFrame],
    config: &RosConfig,
    arrow_m_per_n: f64,
) -> Result<(), IoError> {
    BagWriter::write(dir, |bag| write_results(bag, frames, config, arrow_m_per_n))
}

fn write_results(
    bag: &mut BagWriter<'_>,
    frames: &[RunFrame],
    config: &RosConfig,
    arrow_m_per_n: f64,
) -> Result<(), IoError> {
    let markers_ch = bag.channel(
        RESULT_MARKERS_TOPIC,
        "visualization_msgs/msg/MarkerArray",
        MARKER_ARRAY_DEFINITION,
    )?;
    let fingers = frames
        .iter()
        .find_map(|f| f.forces.as_ref().map(|r| r.finger_force_n.len()))
        .unwrap_or(0);
    let wrench_ch = (0..fingers)
        .map(|f| {
            bag.channel(
                &result_wrench_topic(f),
                "geometry_msgs/msg/WrenchStamped",
                WRENCH_STAMPED_DEFINITION,
            )
        })
        .collect::<Result<Vec<_>, _>>()?;
    for frame in frames {
        let t = frame.time_ns;
        bag.put(
            markers_ch,
            t,
            &result_markers(frame, config, t, arrow_m_per_n),
        )?;
        for (force, &ch) in frame
            .forces
            .iter()
            .flat_map(|r| &r.finger_force_n)
            .zip(&wrench_ch)
        {
            let mut w = CdrWriter::new();
            stamp(&mut w, t, &config.hand_frame);
            for v in [force.x, force.y, force.z, 0.0, 0.0, 0.0] {
                w.f64(v);
            }
            bag.put(ch, t, &w.finish())?;
        }
        bag.end_frame()?;
    }
    Ok(())
}

/// A colour in a marker's `float32` form.
fn rgba(c: [f64; 4]) -> [f32; 4] {
    c.map(|v| v as f32)
}

/// One frame's `MarkerArray`: the colours and sizes of the Foxglove result file.
fn result_markers(frame: &RunFrame, config: &RosConfig, t: u64, arrow_m_per_n: f64) -> Vec<u8> {
    let hand = config.hand_frame.as_str();
    let seen: Vec<Point3> = frame
        .markers_in_hand
        .iter()
        .flatten()
        .flatten()
        .copied()
        .collect();
    let arrows: Vec<[Point3; 2]> = frame
        .forces
        .iter()
        .flat_map(|f| &f.loads)
        .map(|l| {
            [
                l.location_in_hand - arrow_m_per_n * l.force_n,
                l.location_in_hand,
            ]
        })
        .collect();
    let colours: Vec<Vec<[f32; 4]>> = frame
        .contact_probability
        .iter()
        .map(|p| p.iter().map(|&p| rgba(probability_rgba(p))).collect())
        .collect();
    let mut specs = vec![MarkerSpec {
        frame: hand,
        ns: "",
        id: 0,
        kind: ARROW,
        action: DELETE_ALL,
        scale: [0.0; 3],
        color: [0.0; 4],
        points: &[],
        colors: &[],
    }];
    for (f, (vertices, colors)) in frame.vertices_in_hand.iter().zip(&colours).enumerate() {
        specs.push(MarkerSpec {
            frame: hand,
            ns: "surface",
            id: f as i32,
            kind: POINTS,
            action: ADD,
            scale: [0.001, 0.001, 0.0],
            color: [1.0; 4],
            points: vertices,
            colors,
        });
    }
    specs.push(MarkerSpec {
        frame: hand,
        ns: "markers",
        id: 0,
        kind: SPHERE_LIST,
        action: ADD,
        scale: [MARKER_DIAMETER_M; 3],
        color: rgba(MARKER_COLOR),
        points: &seen,
        colors: &[],
    });
    specs.push(MarkerSpec {
        frame: &config.world_frame,
        ns: "contacts",
        id: 0,
        kind: SPHERE_LIST,
        action: ADD,
        scale: [CONTACT_DIAMETER_M; 3],
        color: rgba(CONTACT_COLOR),
        points: &frame.contacts_in_world,
        colors: &[],
    });
    for (k, arrow) in arrows.iter().enumerate() {
        specs.push(MarkerSpec {
            frame: hand,
            ns: "loads",
            id: k as i32,
            kind: ARROW,
            action: ADD,
            scale: [0.001, 0.002, 0.003],
            color: rgba(FORCE_COLOR),
            points: arrow,
            colors: &[],
        });
    }
    let mut w = CdrWriter::new();
    w.u32(specs.len() as u32);
    for m in &specs {
        marker(&mut w, t, m);
    }
    w.finish()
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

/// The `ros2msg` definitions of `std_msgs/Header` and `builtin_interfaces/Time`, which both
/// result messages use.
macro_rules! header_definitions {
    () => {
        "================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"
    };
}

/// The `ros2msg` definition of `geometry_msgs/Vector3`.
macro_rules! vector3_definition {
    () => {
        "================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
"
    };
}

/// `geometry_msgs/msg/WrenchStamped` and its dependencies, `ros2msg` form.
const WRENCH_STAMPED_DEFINITION: &str = concat!(
    "std_msgs/Header header
geometry_msgs/Wrench wrench
",
    header_definitions!(),
    "================================================================================
MSG: geometry_msgs/Wrench
Vector3 force
Vector3 torque
",
    vector3_definition!()
);

/// `visualization_msgs/msg/MarkerArray` and its dependencies (ROS 2 Jazzy), `ros2msg` form.
const MARKER_ARRAY_DEFINITION: &str = concat!(
    "Marker[] markers
================================================================================
MSG: visualization_msgs/Marker
int32 ARROW=0
int32 CUBE=1
int32 SPHERE=2
int32 CYLINDER=3
int32 LINE_STRIP=4
int32 LINE_LIST=5
int32 CUBE_LIST=6
int32 SPHERE_LIST=7
int32 POINTS=8
int32 TEXT_VIEW_FACING=9
int32 MESH_RESOURCE=10
int32 TRIANGLE_LIST=11
int32 ARROW_STRIP=12
int32 ADD=0
int32 MODIFY=0
int32 DELETE=2
int32 DELETEALL=3
std_msgs/Header header
string ns
int32 id
int32 type
int32 action
geometry_msgs/Pose pose
geometry_msgs/Vector3 scale
std_msgs/ColorRGBA color
builtin_interfaces/Duration lifetime
bool frame_locked
geometry_msgs/Point[] points
std_msgs/ColorRGBA[] colors
string texture_resource
sensor_msgs/CompressedImage texture
UVCoordinate[] uv_coordinates
string text
string mesh_resource
MeshFile mesh_file
bool mesh_use_embedded_materials
",
    header_definitions!(),
    "================================================================================
MSG: geometry_msgs/Pose
Point position
Quaternion orientation
================================================================================
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1
",
    vector3_definition!(),
    "================================================================================
MSG: std_msgs/ColorRGBA
float32 r
float32 g
float32 b
float32 a
================================================================================
MSG: builtin_interfaces/Duration
int32 sec
uint32 nanosec
================================================================================
MSG: sensor_msgs/CompressedImage
std_msgs/Header header
string format
uint8[] data
================================================================================
MSG: visualization_msgs/UVCoordinate
float32 u
float32 v
================================================================================
MSG: visualization_msgs/MeshFile
string filename
uint8[] data
"
);

#[cfg(test)]
mod tests;
