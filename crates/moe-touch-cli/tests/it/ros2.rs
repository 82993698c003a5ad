//! ROS 2 recordings in: an episode written as a rosbag2 recording reads back as the same
//! frames, and `moe-touch run` on the recording finds what it finds on the episode.

use std::path::Path;

use moe_geom::{FingerParams, HandModel, HandPreset, Point3};
use moe_record::ros2::{DepthEncoding, RosConfig, read_ros2_bag, write_ros2_bag};

use crate::common::{fixtures, run, scratch};

fn hand() -> HandModel {
    HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap()
}

fn episode_path() -> std::path::PathBuf {
    fixtures().join("episodes/plate_tip_front_small.mcap")
}

/// `back`, read from a recording, holds `episode`'s frames: the same camera, colour bit for bit,
/// depth within `16UC1`'s half millimetre, poses to rounding (through quaternions), the same
/// pulls, and the same times (a recording's frames keep their stamps).
fn assert_decodes_to(back: &moe_record::Episode, episode: &moe_record::Episode) {
    assert_eq!(back.frames.len(), episode.frames.len());
    assert_eq!(back.info.camera, episode.info.camera);
    let p = Point3::new(0.01, -0.02, 0.03);
    let close = |a: Point3, b: Point3| (a - b).norm() < 1e-12;
    assert!(close(
        back.info.hand_from_camera * p,
        episode.info.hand_from_camera * p
    ));
    for (a, b) in back.frames.iter().zip(&episode.frames) {
        assert_eq!(a.time_ns, b.time_ns);
        assert_eq!(a.color_rgb8, b.color_rgb8);
        assert_eq!(a.tendon_pull_m, b.tendon_pull_m);
        assert!(close(a.world_from_hand * p, b.world_from_hand * p));
        assert_eq!(a.depth_m.len(), b.depth_m.len());
        for (x, y) in a.depth_m.iter().zip(&b.depth_m) {
            assert!((x - y).abs() <= 0.0005 + 1e-6, "{x} vs {y}");
        }
    }
}

/// `16UC1` depth comes back within its millimetre quantisation, everything else exactly (poses
/// to rounding, through quaternions).
#[test]
fn an_episode_written_as_a_bag_reads_back_as_its_frames() {
    let episode = moe_record::read_episode(&episode_path()).unwrap();
    let dir = scratch("ros2-roundtrip").join("bag");
    let config = RosConfig::default();
    write_ros2_bag(&dir, &episode, &config, DepthEncoding::Millimetres16).unwrap();
    assert!(moe_record::ros2::is_ros2_recording(&dir));
    let back = read_ros2_bag(&dir, &config, &hand()).unwrap();
    assert_decodes_to(&back, &episode);
    // Writing into an existing directory is refused and changes nothing.
    let err = write_ros2_bag(&dir, &episode, &config, DepthEncoding::Metres32).unwrap_err();
    assert!(err.to_string().contains("already exists"), "{err}");
    assert_decodes_to(&read_ros2_bag(&dir, &config, &hand()).unwrap(), &episode);
}

/// The arguments of `moe-touch run --episode episode --out out` and `extra`.
fn run_args<'a>(episode: &'a Path, out: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "run",
        "--episode",
        episode.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    args
}

/// `moe-touch run` on `episode` (with `extra` options), writing `out` and its report beside it:
/// the report, and per frame the markers found and the contact points.
fn run_report(episode: &Path, out: &Path, extra: &[&str]) -> (serde_json::Value, Vec<(u64, u64)>) {
    let report = out.with_extension("json");
    let mut args = run_args(episode, out, extra);
    args.extend_from_slice(&["--report", report.to_str().unwrap()]);
    let o = run(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let frames = v["per_frame"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["markers_found"].as_u64().unwrap(),
                f["contact_points"].as_u64().unwrap(),
            )
        })
        .collect();
    (v, frames)
}

/// The same frames as a ROS 2 recording (exact depth): the same markers and contacts, frame by
/// frame; a recording has no ground truth to score.
#[test]
fn run_on_a_recording_finds_what_it_finds_on_the_episode() {
    let episode = moe_record::read_episode(&episode_path()).unwrap();
    let root = scratch("ros2-run");
    let bag = root.join("bag");
    write_ros2_bag(
        &bag,
        &episode,
        &RosConfig::default(),
        DepthEncoding::Metres32,
    )
    .unwrap();
    let model = fixtures().join("../models/contact-two-finger.safetensors");
    let dgcnn = ["--contact", "dgcnn", "--model", model.to_str().unwrap()];
    let (from_episode, a) = run_report(&episode_path(), &root.join("a.mcap"), &dgcnn);
    let (from_bag, b) = run_report(&bag, &root.join("b.mcap"), &dgcnn);
    assert!(!a.is_empty());
    assert_eq!(a, b);
    assert!(from_bag["contact"].is_null() && !from_episode["contact"].is_null());
}

/// `moe-touch run --episode episode --out OUT` with `extra` options fails in one error line that
/// says `says`, and writes no result.
fn assert_run_refused(episode: &Path, extra: &[&str], says: &str) {
    let out = scratch("ros2-refused").join("r.mcap");
    let line = crate::common::assert_one_line_error(&run(&run_args(episode, &out, extra)));
    assert!(line.contains(says), "{line}");
    assert!(!out.exists());
}

/// A recording without its colour topic, or with a tendon joint the config names but the
/// recording lacks: one error line, nothing written.
#[test]
fn bad_recordings_give_one_error_line_and_no_output() {
    let episode = moe_record::read_episode(&episode_path()).unwrap();
    let root = scratch("ros2-bad");
    let bag = root.join("bag");
    let renamed = RosConfig {
        color_topic: "/elsewhere/image".into(),
        ..RosConfig::default()
    };
    write_ros2_bag(&bag, &episode, &renamed, DepthEncoding::Metres32).unwrap();
    assert_run_refused(
        &bag,
        &[],
        "no message on the colour topic /camera/camera/color/image_raw",
    );
    let config = root.join("ros.toml");
    std::fs::write(
        &config,
        "color_topic = \"/elsewhere/image\"\ntendon_joints = [[\"a\", \"b\", \"c\", \"d\"], [\"e\", \"f\", \"g\", \"h\"]]\n",
    )
    .unwrap();
    assert_run_refused(
        &bag,
        &["--ros", config.to_str().unwrap()],
        "has no joint 'a'",
    );
}

/// The recording `tools/episode_to_rosbag.py` made of the example episode with the `rosbags`
/// library (its CDR serialiser and MCAP writer, not ours): the same images (colour bit for bit,
/// depth within `16UC1`'s millimetre), poses and pulls as its source episode.
#[test]
fn a_recording_written_by_rosbags_decodes_to_its_source_episode() {
    let bag = fixtures().join("episodes/plate_tip_front_small_ros2");
    assert!(moe_record::ros2::is_ros2_recording(&bag));
    // Its MCAP file alone is recognised by its CDR messages; a Foxglove episode is not one.
    assert!(moe_record::ros2::is_ros2_recording(
        &bag.join("plate_tip_front_small_ros2.mcap")
    ));
    assert!(!moe_record::ros2::is_ros2_recording(&episode_path()));
    let episode = moe_record::read_episode(&episode_path()).unwrap();
    let back = read_ros2_bag(&bag, &RosConfig::default(), &hand()).unwrap();
    assert_decodes_to(&back, &episode);
}

/// `run` (the default physics pipeline) on the rosbags recording: the frames with contact are the
/// episode's, and depth rounded to the millimetre moves at most one marker per frame.
#[test]
fn run_on_the_rosbags_recording_finds_the_episodes_contact_frames() {
    let root = scratch("ros2-rosbags-run");
    let (_, a) = run_report(&episode_path(), &root.join("episode.mcap"), &[]);
    let bag = fixtures().join("episodes/plate_tip_front_small_ros2");
    let (_, b) = run_report(&bag, &root.join("bag.mcap"), &[]);
    assert_eq!(a.len(), b.len());
    for (k, ((ma, ca), (mb, cb))) in a.iter().zip(&b).enumerate() {
        assert!(ma.abs_diff(*mb) <= 1, "frame {k}: {a:?} vs {b:?}");
        assert_eq!(*ca > 0, *cb > 0, "frame {k}: {a:?} vs {b:?}");
    }
}

/// Every message of a recording's MCAP files: topic, log time, CDR bytes.
fn bag_messages(dir: &Path) -> Vec<(String, u64, Vec<u8>)> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "mcap") {
            let bytes = std::fs::read(&path).unwrap();
            for m in mcap::MessageStream::new(&bytes).unwrap() {
                let m = m.unwrap();
                out.push((m.channel.topic.clone(), m.log_time, m.data.into_owned()));
            }
        }
    }
    out
}

/// `run --ros-out` writes the results as ROS 2 messages: per frame one `MarkerArray` (the previous
/// frame's deleted first, a surface per finger, the contact points of the report in the world
/// frame, an arrow per load) and per finger a `WrenchStamped` of the report's force in the hand
/// frame. A directory that exists is refused before anything runs.
#[test]
fn run_writes_its_results_as_ros_messages() {
    use moe_record::ros2::cdr::{marker_array, wrench_stamped};
    use moe_record::ros2::{RESULT_MARKERS_TOPIC, result_wrench_topic};
    let root = scratch("ros2-results");
    let results = root.join("results");
    let bag = fixtures().join("episodes/plate_tip_front_small_ros2");
    let (report, _) = run_report(
        &bag,
        &root.join("r.mcap"),
        &["--ros-out", results.to_str().unwrap()],
    );
    assert!(moe_record::ros2::is_ros2_recording(&results));
    let meta = std::fs::read_to_string(results.join("metadata.yaml")).unwrap();
    assert!(
        meta.contains("type: visualization_msgs/msg/MarkerArray"),
        "{meta}"
    );
    let messages = bag_messages(&results);
    let frames = report["per_frame"].as_array().unwrap();
    let arrays: Vec<_> = messages
        .iter()
        .filter(|m| m.0 == RESULT_MARKERS_TOPIC)
        .collect();
    assert_eq!(arrays.len(), frames.len());
    let mut pressed = 0;
    for (m, f) in arrays.iter().zip(frames) {
        assert_eq!(m.1, f["time_ns"].as_u64().unwrap());
        let array = marker_array(&m.2).unwrap();
        assert_eq!(array[0].action, 3, "DELETEALL first");
        let ns = |name: &'static str| array.iter().filter(move |x| x.ns == name);
        let contacts: Vec<_> = ns("contacts").collect();
        assert_eq!(contacts.len(), 1);
        assert_eq!(contacts[0].header.frame_id, "world");
        assert_eq!(contacts[0].header.stamp_ns as u64, m.1);
        let n = contacts[0].points.len() as u64;
        assert_eq!(n, f["contact_points"].as_u64().unwrap());
        pressed += usize::from(n > 0);
        let surfaces: Vec<_> = ns("surface").collect();
        assert_eq!(surfaces.len(), 2);
        for s in &surfaces {
            assert_eq!(s.points.len(), 1024);
            assert_eq!(s.colors.len(), 1024);
        }
        assert_eq!(
            ns("loads").count(),
            f["loads"].as_array().unwrap().len(),
            "an arrow per load"
        );
        assert_eq!(
            ns("markers").next().unwrap().points.len() as u64,
            f["markers_found"].as_u64().unwrap()
        );
        for finger in 0..2 {
            let topic = result_wrench_topic(finger);
            let w = messages
                .iter()
                .find(|x| x.0 == topic && x.1 == m.1)
                .unwrap();
            let w = wrench_stamped(&w.2).unwrap();
            assert_eq!(w.header.frame_id, "hand");
            let expected = &f["finger_forces"][finger]["force_n"];
            for k in 0..3 {
                assert!((w.force[k] - expected[k].as_f64().unwrap()).abs() < 1e-12);
                assert_eq!(w.torque[k], 0.0);
            }
        }
    }
    assert!(pressed > 0, "the episode presses finger 0");
    assert_run_refused(
        &bag,
        &["--ros-out", results.to_str().unwrap()],
        "already exists",
    );
}
