//! Tests of `write`.

use super::*;
use crate::ros2::cdr::{marker_array, wrench_stamped};
use crate::{RunForces, RunLoad};
use moe_geom::Vector3;

fn frame(time_ns: u64, pressed: bool) -> RunFrame {
    let p = |x: f64| Point3::new(x, 0.0, 0.01);
    RunFrame {
        time_ns,
        color_rgb8: Vec::new(),
        world_from_hand: Iso3::translation(1.0, 0.0, 0.0),
        markers_in_hand: vec![vec![Some(p(0.0)), None], vec![Some(p(1.0))]],
        vertices_in_hand: vec![vec![p(0.0), p(0.1), p(0.2)], vec![p(1.0), p(1.1), p(1.2)]],
        contact_probability: vec![vec![0.0, 0.5, 1.0], vec![0.0; 3]],
        contacts_in_world: if pressed { vec![p(1.2)] } else { Vec::new() },
        truth: None,
        forces: Some(RunForces {
            finger_force_n: vec![Vector3::new(0.0, 0.0, -0.05), Vector3::zeros()],
            pressed_probability: None,
            loads: if pressed {
                vec![RunLoad {
                    finger: 0,
                    location_in_hand: p(0.2),
                    force_n: Vector3::new(0.0, 0.0, -0.05),
                }]
            } else {
                Vec::new()
            },
        }),
    }
}

/// The written messages decode to the frames: a marker array per frame (the previous
/// deleted, a surface per finger coloured by contact, the markers seen, the contacts in the
/// world, an arrow per load ending at its place) and a wrench per finger.
#[test]
fn results_decode_to_the_frames() {
    let dir = std::env::temp_dir().join(format!("moe-io-ros2-results-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let frames = [frame(100, true), frame(200, false)];
    let config = RosConfig::default();
    write_ros2_results(&dir, &frames, &config, 0.2).unwrap();
    assert!(crate::ros2::is_ros2_recording(&dir));
    let meta = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    // Every field rosbag2's version-8 reader requires, and the frames' time span.
    for key in [
        "version: 8",
        "message_count: 6",
        "offered_qos_profiles:",
        "type_description_hash:",
        "files:",
        "custom_data:",
        "ros_distro: jazzy",
        "nanoseconds_since_epoch: 100",
        "nanoseconds: 100",
    ] {
        assert!(meta.contains(key), "{key} in {meta}");
    }
    let bytes = std::fs::read(dir.join(format!(
        "{}_0.mcap",
        dir.file_name().unwrap().to_string_lossy()
    )))
    .unwrap();
    // The header record's profile: rosbag2's, which ROS 2 readers require.
    assert_eq!(bytes[8], 0x01);
    assert_eq!(&bytes[17..25], b"\x04\0\0\0ros2");
    // A chunk per frame (records: opcode, u64 length, content; 0x06 a chunk).
    let (mut at, mut chunks) = (8, 0);
    while at + 9 <= bytes.len() - 8 {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        chunks += usize::from(bytes[at] == 0x06);
        at += 9 + len;
    }
    assert_eq!(chunks, frames.len());
    let mut arrays = Vec::new();
    let mut wrenches = Vec::new();
    let mut raw = Vec::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "ros2msg");
        assert!(
            !schema.data.is_empty(),
            "the definition travels with the file"
        );
        if m.channel.topic == RESULT_MARKERS_TOPIC {
            raw.push(m.data.to_vec());
            arrays.push((m.log_time, marker_array(&m.data).unwrap()));
        } else {
            let w = wrench_stamped(&m.data).unwrap();
            wrenches.push((m.channel.topic.clone(), m.log_time, w));
        }
    }
    assert_eq!(arrays.len(), 2);
    let (t, a) = &arrays[0];
    assert_eq!(*t, 100);
    let kinds: Vec<(&str, i32, i32)> = a
        .iter()
        .map(|m| (m.ns.as_str(), m.kind, m.action))
        .collect();
    assert_eq!(
        kinds,
        [
            ("", ARROW, DELETE_ALL),
            ("surface", POINTS, ADD),
            ("surface", POINTS, ADD),
            ("markers", SPHERE_LIST, ADD),
            ("contacts", SPHERE_LIST, ADD),
            ("loads", ARROW, ADD),
        ]
    );
    assert_eq!(a[1].points[2], [0.2, 0.0, 0.01]);
    assert_eq!(a[1].colors[0][0], 0.0);
    assert_eq!(a[1].colors[2][0], 1.0, "probability 1 is full red");
    assert_eq!(a[3].points.len(), 2, "the two markers seen");
    assert_eq!(a[4].header.frame_id, "world");
    assert_eq!(a[4].points, [[1.2, 0.0, 0.01]]);
    let arrow = &a[5].points;
    assert_eq!(arrow[1], [0.2, 0.0, 0.01]);
    assert!((arrow[0][2] - (0.01 + 0.2 * 0.05)).abs() < 1e-15);
    assert_eq!(arrays[1].1.len(), 5, "no load, no arrow");
    assert_eq!(wrenches.len(), 4);
    let (topic, t, w) = &wrenches[0];
    assert_eq!((topic.as_str(), *t), ("/moe_touch/finger0/wrench", 100));
    assert_eq!(w.header.frame_id, "hand");
    assert_eq!(w.force, [0.0, 0.0, -0.05]);
    assert_eq!(w.torque, [0.0; 3]);
    // Damaged result messages are errors, never panics: every truncation, flipped bytes.
    let (markers, wrench) = (&raw[0], {
        let mut w = CdrWriter::new();
        w.header(100, "hand");
        for v in [0.0, 0.0, -0.05, 0.0, 0.0, 0.0] {
            w.f64(v);
        }
        w.finish()
    });
    assert_eq!(wrench_stamped(&wrench).unwrap(), wrenches[0].2);
    for cut in 0..markers.len() {
        assert!(marker_array(&markers[..cut]).is_err(), "cut at {cut}");
    }
    for cut in 0..wrench.len() {
        assert!(wrench_stamped(&wrench[..cut]).is_err(), "cut at {cut}");
    }
    for bytes in [markers, &wrench] {
        for at in 0..bytes.len() {
            for flip in [0x01, 0x80, 0xff] {
                let mut b = bytes.clone();
                b[at] ^= flip;
                let _ = marker_array(&b);
                let _ = wrench_stamped(&b);
            }
        }
    }
    let err = write_ros2_results(&dir, &frames, &config, 0.2).unwrap_err();
    assert!(err.to_string().contains("already exists"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
