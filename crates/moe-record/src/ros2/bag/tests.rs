//! Tests of `bag`.

use std::collections::BTreeMap;
use std::io::Cursor;

use moe_geom::{FingerParams, HandPreset, Point3};

use super::*;
use crate::ros2::cdr::CdrWriter;

const W: u32 = 4;
const H: u32 = 3;

fn hand() -> HandModel {
    HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap()
}

fn image(
    stamp: i64,
    frame: &str,
    encoding: &str,
    bpp: u32,
    fill: impl Fn(u32) -> Vec<u8>,
) -> Vec<u8> {
    let data: Vec<u8> = (0..W * H).flat_map(fill).collect();
    CdrWriter::new()
        .header(stamp, frame)
        .u32(H)
        .u32(W)
        .string(encoding)
        .u8(0)
        .u32(W * bpp)
        .bytes(&data)
        .finish()
}

fn camera_info(stamp: i64) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.header(stamp, "cam")
        .u32(H)
        .u32(W)
        .string("plumb_bob")
        .f64_seq(&[0.0; 5]);
    let k = [100.0, 0.0, 1.5, 0.0, 100.0, 1.0, 0.0, 0.0, 1.0];
    for v in k.iter().chain(&[0.0; 21]) {
        w.f64(*v);
    }
    w.u32(0).u32(0).u32(0).u32(0).u32(0).u32(0).u8(0);
    w.finish()
}

fn tf(transforms: &[(i64, &str, &str, [f64; 3])]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.u32(transforms.len() as u32);
    for &(stamp, parent, child, t) in transforms {
        w.header(stamp, parent).string(child);
        for v in [t[0], t[1], t[2], 0.0, 0.0, 0.0, 1.0] {
            w.f64(v);
        }
    }
    w.finish()
}

fn joints(stamp: i64, names: &[&str], positions: &[f64]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.header(stamp, "").u32(names.len() as u32);
    for n in names {
        w.string(n);
    }
    w.f64_seq(positions).f64_seq(&[]).f64_seq(&[]);
    w.finish()
}

/// An MCAP of `(topic, schema, log time, message)`.
fn bag(messages: &[(&str, &str, i64, Vec<u8>)]) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    {
        let mut w = mcap::Writer::new(&mut out).unwrap();
        let mut channels: BTreeMap<String, u16> = BTreeMap::new();
        for (seq, (topic, schema, t, data)) in messages.iter().enumerate() {
            let id = match channels.get(*topic) {
                Some(&id) => id,
                None => {
                    let s = w.add_schema(schema, "ros2msg", b"").unwrap();
                    let id = w.add_channel(s, topic, "cdr", &BTreeMap::new()).unwrap();
                    channels.insert((*topic).to_owned(), id);
                    id
                }
            };
            let header = mcap::records::MessageHeader {
                channel_id: id,
                sequence: seq as u32,
                log_time: *t as u64,
                publish_time: *t as u64,
            };
            w.write_to_known_channel(&header, data).unwrap();
        }
        w.finish().unwrap();
    }
    out.into_inner()
}

const COLOR: &str = "/camera/camera/color/image_raw";
const DEPTH: &str = "/camera/camera/aligned_depth_to_color/image_raw";
const INFO: &str = "/camera/camera/color/camera_info";

fn names() -> Vec<&'static str> {
    vec![
        "finger0_tendon0",
        "finger0_tendon1",
        "finger0_tendon2",
        "finger0_tendon3",
        "finger1_tendon0",
        "finger1_tendon1",
        "finger1_tendon2",
        "finger1_tendon3",
    ]
}

/// Two frames of a recording as `realsense2_camera` and a robot publish them.
fn recording() -> Vec<(&'static str, &'static str, i64, Vec<u8>)> {
    let ms = 1_000_000;
    let img = "sensor_msgs/msg/Image";
    let mut m = vec![
        (
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            0,
            tf(&[(0, "hand", "cam", [0.0, 0.0, 0.1])]),
        ),
        (INFO, "sensor_msgs/msg/CameraInfo", 0, camera_info(0)),
        (
            "/tf",
            "tf2_msgs/msg/TFMessage",
            0,
            tf(&[(0, "world", "hand", [1.0, 0.0, 0.0])]),
        ),
        (
            "/hand/tendons",
            "sensor_msgs/msg/JointState",
            0,
            joints(0, &names(), &[0.001; 8]),
        ),
    ];
    for (k, t) in [(0u8, 100 * ms), (1, 200 * ms)] {
        m.push((
            COLOR,
            img,
            t,
            image(t, "cam", "bgr8", 3, |i| vec![k, 10 + k, i as u8]),
        ));
        m.push((
            DEPTH,
            img,
            t + 5 * ms,
            image(t + 5 * ms, "cam", "16UC1", 2, |i| {
                (500 + i as u16).to_le_bytes().to_vec()
            }),
        ));
        m.push((
            "/tf",
            "tf2_msgs/msg/TFMessage",
            t,
            tf(&[(t, "world", "hand", [1.0, f64::from(k), 0.0])]),
        ));
    }
    m
}

fn read(messages: &[(&str, &str, i64, Vec<u8>)], config: &RosConfig) -> Result<Episode, IoError> {
    let dir = std::env::temp_dir().join(format!(
        "moe-io-ros2-{}-{}",
        std::process::id(),
        messages.len()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("rec_0.mcap"), bag(messages)).unwrap();
    std::fs::write(
        dir.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  relative_file_paths:\n    - rec_0.mcap\n  duration:\n    nanoseconds: 1\n",
    )
    .unwrap();
    assert!(is_ros2_recording(&dir));
    let out = read_ros2_bag(&dir, config, &hand());
    let _ = std::fs::remove_dir_all(&dir);
    out
}

#[test]
fn a_recording_becomes_frames_with_poses_pulls_and_aligned_depth() {
    let ep = read(&recording(), &RosConfig::default()).unwrap();
    assert_eq!(ep.frames.len(), 2);
    assert_eq!((ep.info.camera.width, ep.info.camera.height), (W, H));
    assert_eq!(
        (ep.info.camera.fx, ep.info.camera.cx, ep.info.camera.cy),
        (100.0, 1.5, 1.0)
    );
    assert_eq!(ep.info.hand_from_camera.translation.vector.z, 0.1);
    assert_eq!(ep.info.finger_num_vertices.len(), 2);
    let f = &ep.frames[1];
    assert_eq!(f.time_ns, 200_000_000, "the colour image's stamp");
    // bgr8 became rgb8.
    assert_eq!(&f.color_rgb8[..3], &[0, 11, 1]);
    // 16UC1 millimetres became metres.
    assert!((f.depth_m[2] - 0.502).abs() < 1e-6);
    // The hand's pose at the frame's stamp, and the latest joint state.
    assert_eq!(
        f.world_from_hand * Point3::origin(),
        Point3::new(1.0, 1.0, 0.0)
    );
    assert_eq!(f.tendon_pull_m, vec![vec![0.001; 4]; 2]);
    assert!(f.finger_vertices_in_hand.is_empty());
}

#[test]
fn bad_recordings_are_refused_in_one_line_naming_what() {
    let config = RosConfig::default();
    let err = |m: &[(&str, &str, i64, Vec<u8>)], c: &RosConfig| read(m, c).unwrap_err().to_string();
    let without =
        |topic: &str| -> Vec<_> { recording().into_iter().filter(|m| m.0 != topic).collect() };
    assert!(err(&without(COLOR), &config).contains("no message on the colour topic"));
    let mut other = recording();
    other.retain(|m| m.0 != DEPTH);
    other.push((DEPTH, "sensor_msgs/msg/Image", 100_000_000, {
        let data = vec![0u8; 2 * 2 * 2];
        CdrWriter::new()
            .header(100_000_000, "cam")
            .u32(2)
            .u32(2)
            .string("16UC1")
            .u8(0)
            .u32(4)
            .bytes(&data)
            .finish()
    }));
    assert!(err(&other, &config).contains("depth must be aligned to colour"));
    let mut enc = recording();
    enc[4].3 = image(100_000_000, "cam", "yuv422", 2, |_| vec![0, 0]);
    assert!(err(&enc, &config).contains("colour encoding 'yuv422' is not read"));
    let e = err(&without("/tf_static"), &config);
    assert!(e.contains("no transform path from 'hand' to 'cam'"), "{e}");
    let mut renamed = config.clone();
    renamed.tendon_joints = vec![vec!["a".into(); 4], vec!["b".into(); 4]];
    assert!(err(&recording(), &renamed).contains("has no joint 'a'"));
    let mut late = recording();
    let t = late[7].2;
    late[7].3 = image(50_000_000, "cam", "rgb8", 3, |_| vec![0, 0, 0]);
    late[7].2 = t;
    assert!(err(&late, &config).contains("timestamps out of order"));
}

/// Between two stamped transforms the pose is interpolated (translation linearly, rotation
/// along the arc); outside them it is the nearest; a static transform holds at any time.
#[test]
fn transforms_are_interpolated_between_stamps() {
    let at = |stamp: i64, x: f64, yaw_deg: f64| {
        let half = yaw_deg.to_radians() / 2.0;
        TransformStamped {
            header: cdr::Header {
                stamp_ns: stamp,
                frame_id: "world".into(),
            },
            child_frame_id: "hand".into(),
            translation: [x, 0.0, 0.0],
            rotation_xyzw: [0.0, 0.0, half.sin(), half.cos()],
        }
    };
    let mut tf = Tf::default();
    tf.add(&at(100, 1.0, 90.0), false).unwrap();
    tf.add(&at(0, 0.0, 0.0), false).unwrap();
    let pose = |t| tf.lookup("world", "hand", t).unwrap();
    let p = pose(25);
    assert!((p.translation.vector.x - 0.25).abs() < 1e-12);
    assert!((p.rotation.angle() - 22.5f64.to_radians()).abs() < 1e-12);
    assert!((pose(-5).translation.vector.x).abs() < 1e-12);
    assert!((pose(500).translation.vector.x - 1.0).abs() < 1e-12);
    // A sign flip of the quaternion (the same rotation) interpolates without a turn.
    let mut flipped = Tf::default();
    flipped.add(&at(0, 0.0, 10.0), false).unwrap();
    let mut minus = at(100, 0.0, 10.0);
    minus.rotation_xyzw = minus.rotation_xyzw.map(|c| -c);
    flipped.add(&minus, false).unwrap();
    let mid = flipped.lookup("world", "hand", 50).unwrap();
    assert!((mid.rotation.angle() - 10f64.to_radians()).abs() < 1e-9);
    // The inverse direction composes the same edge backwards.
    let back = tf.lookup("hand", "world", 50).unwrap();
    assert!((back * pose(50)).translation.vector.norm() < 1e-12);
}

#[test]
fn damaged_bags_are_errors_never_panics() {
    let bytes = bag(&recording());
    let dir = std::env::temp_dir().join(format!("moe-io-ros2-damaged-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("b.mcap");
    for cut in (0..bytes.len()).step_by(97) {
        std::fs::write(&file, &bytes[..cut]).unwrap();
        assert!(
            read_ros2_bag(&file, &RosConfig::default(), &hand()).is_err(),
            "cut {cut}"
        );
    }
    // Splices: the head of one recording on the tail of another, at many cuts.
    let other = bag(&recording()[..6]);
    for cut in (0..bytes.len().min(other.len())).step_by(101) {
        let mut b = bytes[..cut].to_vec();
        b.extend_from_slice(&other[cut..]);
        std::fs::write(&file, &b).unwrap();
        let r = read_ros2_bag(&file, &RosConfig::default(), &hand());
        assert!(
            !matches!(r, Err(IoError::ParserPanic { .. })),
            "splice at {cut}"
        );
    }
    for at in (0..bytes.len()).step_by(13) {
        let mut b = bytes.clone();
        b[at] ^= 0xa5;
        std::fs::write(&file, &b).unwrap();
        let r = read_ros2_bag(&file, &RosConfig::default(), &hand());
        assert!(
            !matches!(r, Err(IoError::ParserPanic { .. })),
            "flip at {at}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
