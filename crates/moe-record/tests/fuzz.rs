//! Fuzz-style robustness of the episode reader: every prefix of a valid episode, byte-flipped
//! and spliced copies and random bytes must give a typed error or an episode whose images have
//! the camera's size — never a panic, never a huge allocation from a corrupt length.

#[allow(dead_code)]
#[path = "../../moe-io/tests/it/harness.rs"]
mod harness;

use std::path::Path;

use moe_geom::Point3;

use harness::{Outcome, from_result, fuzz_readers};

fn read_episode(b: &[u8]) -> Outcome {
    from_result(
        moe_record::parse_episode(Path::new("fuzz.mcap"), b),
        |e: &moe_record::Episode| {
            let pixels = (e.info.camera.width * e.info.camera.height) as usize;
            e.frames
                .iter()
                .any(|f| f.color_rgb8.len() != 3 * pixels || f.depth_m.len() != pixels)
                .then(|| "a frame with images of another size was returned".into())
        },
    )
}

/// A valid episode of two frames of a 4 × 3 camera and a two-finger toy hand.
fn episode_sample() -> Vec<u8> {
    use moe_geom::Iso3;
    use moe_record::{CameraInfo, EpisodeFrame, EpisodeInfo, EpisodeWriter, ObstacleMesh};
    let info = EpisodeInfo {
        scene: "fuzz".into(),
        camera: CameraInfo {
            width: 4,
            height: 3,
            fx: 380.0,
            fy: 380.0,
            cx: 1.5,
            cy: 1.0,
        },
        hand_from_camera: Iso3::translation(0.0, 0.0, -0.02),
        hand_from_finger: vec![Iso3::identity(), Iso3::translation(0.05, 0.0, 0.0)],
        finger_faces: vec![vec![[0, 1, 2]], vec![[0, 2, 1]]],
        finger_num_vertices: vec![3, 3],
        tendons_per_finger: 1,
    };
    let frame = |k: u64| EpisodeFrame {
        time_ns: k * 100_000_000,
        color_rgb8: (0..36).map(|i| (i * 7 + k) as u8).collect(),
        depth_m: (0..12).map(|i| 0.05 + i as f32 * 1e-3).collect(),
        world_from_hand: Iso3::translation(0.0, 0.0, 0.1 * k as f64),
        tendon_pull_m: vec![vec![0.001 * k as f64], vec![0.0]],
        finger_vertices_in_hand: vec![
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(0.01, 0.0, 0.0),
                Point3::new(0.0, 0.01, 0.0),
            ],
            vec![
                Point3::new(0.05, 0.0, 0.0),
                Point3::new(0.06, 0.0, 0.0),
                Point3::new(0.05, 0.01, 0.0),
            ],
        ],
        contact_vertices: vec![vec![1], vec![]],
        markers_in_hand: vec![
            vec![Point3::new(0.0, 0.0, 0.0)],
            vec![Point3::new(0.05, 0.0, 0.0)],
        ],
        obstacles: vec![ObstacleMesh {
            name: "plate".into(),
            vertices_in_world: vec![
                Point3::new(0.0, 0.0, 0.5),
                Point3::new(1.0, 0.0, 0.5),
                Point3::new(0.0, 1.0, 0.5),
            ],
            faces: vec![[0, 1, 2]],
        }],
    };
    let mut w = EpisodeWriter::new(
        std::io::Cursor::new(Vec::new()),
        &info,
        Path::new("fuzz.mcap"),
    )
    .unwrap();
    for k in 0..2 {
        w.write_frame(&frame(k)).unwrap();
    }
    w.finish().unwrap().into_inner()
}

#[test]
fn the_episode_reader_survives_truncation_flips_and_garbage() {
    fuzz_readers(
        0x005E_ED0F_F023,
        vec![("episode", read_episode, episode_sample())],
    );
}

#[test]
fn an_episode_declaring_huge_lengths_is_a_typed_error() {
    let sample = episode_sample();
    // Every chunk record (opcode 0x06 after the 8-byte magic) gets a huge uncompressed size;
    // then every top-level record a huge length.
    let mut chunks = Vec::new();
    let mut records = Vec::new();
    let mut at = 8;
    while at + 9 <= sample.len() {
        let len = u64::from_le_bytes(sample[at + 1..at + 9].try_into().unwrap()) as usize;
        if at + 9 + len > sample.len() {
            break;
        }
        records.push(at);
        if sample[at] == 0x06 {
            chunks.push(at);
        }
        at += 9 + len;
    }
    assert!(chunks.len() >= 2, "the sample is chunked");
    for &c in &chunks {
        for huge in [1u64 << 40, u64::MAX] {
            let mut b = sample.clone();
            b[c + 9 + 16..c + 9 + 24].copy_from_slice(&huge.to_le_bytes());
            let err = moe_record::parse_episode(Path::new("huge.mcap"), &b).unwrap_err();
            assert!(err.to_string().contains("uncompressed"), "{err}");
        }
    }
    for &r in &records {
        for huge in [1u64 << 40, u64::MAX, (sample.len() as u64) * 2] {
            let mut b = sample.clone();
            b[r + 1..r + 9].copy_from_slice(&huge.to_le_bytes());
            assert!(
                matches!(read_episode(&b), Outcome::Error),
                "record at {r}, length {huge}"
            );
        }
    }
}
