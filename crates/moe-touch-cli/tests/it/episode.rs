//! `moe-touch sim --out EPISODE.mcap` and the committed example episode.

use std::path::Path;

use crate::common::{assert_one_line_error, fixtures, run, run_json, scratch};

fn small_scene() -> String {
    fixtures()
        .join("scenes/episode_small.toml")
        .to_string_lossy()
        .into_owned()
}

#[test]
fn the_committed_episode_reads_back_with_its_ground_truth() {
    let path = fixtures().join("episodes/plate_tip_front_small.mcap");
    assert!(
        std::fs::metadata(&path).unwrap().len() < 5_000_000,
        "fixture stays small"
    );
    let episode = moe_record::read_episode(&path).unwrap();
    assert_eq!(
        (episode.info.camera.width, episode.info.camera.height),
        (320, 240)
    );
    assert_eq!(episode.frames.len(), 7);
    assert!(
        episode
            .frames
            .iter()
            .any(|f| !f.contact_vertices[0].is_empty()),
        "the plate touches finger 0"
    );
    let hand = moe_geom::HandModel::preset(
        moe_geom::HandPreset::TwoFinger,
        &moe_geom::FingerParams::default(),
    )
    .unwrap();
    for frame in &episode.frames {
        for (i, f) in hand.fingers().iter().enumerate() {
            // Ground-truth markers are the marker vertices of the ground-truth mesh.
            for (m, &v) in f.model.marker_vertices().iter().enumerate() {
                assert_eq!(
                    frame.markers_in_hand[i][m],
                    frame.finger_vertices_in_hand[i][v as usize]
                );
            }
            // The ground-truth mesh has the finger's topology and is a valid closed surface.
            let mesh = f
                .model
                .mesh()
                .with_vertices(frame.finger_vertices_in_hand[i].clone())
                .unwrap();
            assert!(mesh.signed_volume() > 0.0);
        }
        assert!(frame.time_ns <= 1_200_000_000);
        assert!(frame.depth_m.iter().all(|d| d.is_finite() && *d >= 0.0));
    }
}

#[test]
fn episodes_are_deterministic_and_keep_complete_frames_when_cut() {
    let dir = scratch("episode");
    let a = dir.join("a.mcap");
    let b = dir.join("b.mcap");
    for out in [&a, &b] {
        let summary = run_json(&[
            "sim",
            "--scene",
            &small_scene(),
            "--out",
            out.to_str().unwrap(),
            "--steps",
            "40",
            "--json",
        ]);
        assert_eq!(summary["frames"], 3);
    }
    let bytes = std::fs::read(&a).unwrap();
    assert_eq!(bytes, std::fs::read(&b).unwrap(), "same scene, same bytes");
    let full = moe_record::parse_episode(Path::new("a.mcap"), &bytes).unwrap();
    assert_eq!(full.frames.len(), 3);
    // Cut in the last frame: the first two frames survive exactly.
    let cut = bytes.len() - bytes.len() / 5;
    let (prefix, err) = moe_record::parse_episode_prefix(Path::new("a.mcap"), &bytes[..cut]);
    assert!(err.is_some());
    let prefix = prefix.unwrap();
    assert!(!prefix.frames.is_empty() && prefix.frames.len() < 3);
    assert_eq!(prefix.frames[..], full.frames[..prefix.frames.len()]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_bad_scene_writes_no_episode() {
    let dir = scratch("episode-bad");
    let scene = dir.join("bad.toml");
    std::fs::write(&scene, "[solver]\ndt_secs = -0.01\n").unwrap();
    let out = dir.join("e.mcap");
    let res = run(&[
        "sim",
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let msg = assert_one_line_error(&res);
    assert!(msg.contains("dt_secs"), "{msg}");
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        1,
        "only the scene file remains"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
