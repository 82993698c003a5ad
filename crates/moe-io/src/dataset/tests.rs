//! Round trips and failure modes of shards, cards, splits and the reader.

use std::path::Path;

use moe_geom::{GeomError, LabelledFrame, Point3};

use super::*;
use crate::IoError;

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
        finger_force_n: Some(vec![[0.0, 0.1 * s, -0.25], [-1.5, 0.0, 0.0]]),
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
        tendon_pull_m: vec![0.001 * k as f32, -0.0005, 0.0007, 0.002],
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
    // The hand's tendons, fingers concatenated, become each finger's own list.
    assert_eq!(
        l.tendon_pull_m,
        vec![
            vec![f64::from(0.002f32), f64::from(-0.0005f32)],
            vec![f64::from(0.0007f32), f64::from(0.002f32)]
        ]
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
    let mut few = f.clone();
    few.tendon_pull_m.pop();
    assert!(matches!(
        few.to_labelled(&layout()),
        Err(GeomError::LengthMismatch {
            what: "frame tendon pulls",
            expected: 4,
            got: 3,
        })
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

/// Frames as a shard of format version 1 held them: no finger forces.
fn frames_without_forces() -> Vec<DatasetFrame> {
    (0..2)
        .flat_map(|t| (0..3).map(move |k| frame(t, k)))
        .map(|f| DatasetFrame {
            finger_force_n: None,
            ..f
        })
        .collect()
}

#[test]
fn finger_forces_are_optional_per_shard() {
    let path = Path::new("s.safetensors");
    let with: Vec<DatasetFrame> = (0..2).map(|k| frame(4, k)).collect();
    let bytes = shard_bytes(path, &layout(), &with).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let forces = st.tensor("finger_force_n").unwrap();
    assert_eq!(forces.dtype(), safetensors::Dtype::F32);
    assert_eq!(forces.shape(), &[2, 2, 3]);
    // Without forces the tensor is left out (the shard of format version 1) and reads as None.
    let without = frames_without_forces();
    let bytes = shard_bytes(path, &layout(), &without).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    assert!(st.tensor("finger_force_n").is_err());
    assert_eq!(st.names().len(), 11);
    let (_, back) = parse_shard(path, &bytes).unwrap();
    assert_eq!(back, without);
    assert!(back.iter().all(|f| f.finger_force_n.is_none()));
    // A shard has them for every frame or for none.
    let mut mixed = with.clone();
    mixed[1].finger_force_n = None;
    moe_geom::assert_err!(
        shard_bytes(path, &layout(), &mixed),
        IoError::InvalidData { item, message, .. }
            if item == "frame 1 (trajectory 4, frame 1)" && message.contains("every frame")
    );
    // One force per finger, finite.
    let mut f = frame(4, 0);
    f.finger_force_n = Some(vec![[0.0; 3]]);
    moe_geom::assert_err!(
        shard_bytes(path, &layout(), &[f]),
        IoError::InvalidData { message, .. }
            if message == "1 finger forces, the layout has 2 fingers"
    );
    let mut f = frame(4, 0);
    f.finger_force_n.as_mut().unwrap()[1][2] = f32::NAN;
    moe_geom::assert_err!(
        shard_bytes(path, &layout(), &[f]),
        IoError::InvalidData { message, .. } if message == "non-finite value in finger force 1"
    );
}

/// `bytes` (a valid shard) with its `finger_force_n` tensor replaced by `dtype`, `shape`, `data`.
fn with_force_tensor(
    bytes: &[u8],
    dtype: safetensors::Dtype,
    shape: Vec<usize>,
    data: &[u8],
) -> Vec<u8> {
    let (_, metadata) = safetensors::SafeTensors::read_metadata(bytes).unwrap();
    let st = safetensors::SafeTensors::deserialize(bytes).unwrap();
    let mut views: Vec<(String, safetensors::tensor::TensorView<'_>)> = st
        .tensors()
        .into_iter()
        .filter(|(name, _)| name != "finger_force_n")
        .collect();
    views.push((
        "finger_force_n".into(),
        safetensors::tensor::TensorView::new(dtype, shape, data).unwrap(),
    ));
    safetensors::serialize(views, metadata.metadata().clone()).unwrap()
}

#[test]
fn finger_forces_of_the_wrong_kind_are_named() {
    let path = Path::new("s.safetensors");
    let frames: Vec<DatasetFrame> = (0..2).map(|k| frame(4, k)).collect();
    let bytes = shard_bytes(path, &layout(), &frames).unwrap();
    // The same values re-serialised read back exactly.
    let good = safetensors::SafeTensors::deserialize(&bytes)
        .unwrap()
        .tensor("finger_force_n")
        .unwrap()
        .data()
        .to_vec();
    let (_, back) = parse_shard(
        path,
        &with_force_tensor(&bytes, safetensors::Dtype::F32, vec![2, 2, 3], &good),
    )
    .unwrap();
    assert_eq!(back, frames);
    let wrong = [
        (safetensors::Dtype::F64, vec![2, 2, 3], vec![0u8; 96]),
        (safetensors::Dtype::F32, vec![2, 3, 3], vec![0u8; 72]),
        (safetensors::Dtype::F32, vec![2, 6], vec![0u8; 48]),
    ];
    for (dtype, shape, data) in wrong {
        moe_geom::assert_err!(
            parse_shard(path, &with_force_tensor(&bytes, dtype, shape.clone(), &data)),
            IoError::InvalidData { item, .. } if item == "tensor finger_force_n"
        );
    }
    let mut nan = good.clone();
    nan[4 * 10..4 * 11].copy_from_slice(&f32::NAN.to_le_bytes());
    moe_geom::assert_err!(
        parse_shard(path, &with_force_tensor(&bytes, safetensors::Dtype::F32, vec![2, 2, 3], &nan)),
        IoError::InvalidData { item, message, .. }
            if item == "frame 1 (trajectory 4, frame 1)"
                && message == "non-finite value in finger force 1"
    );
}

#[test]
fn a_data_set_of_format_version_1_reads_without_finger_forces() {
    // The committed held-out shard was written before finger forces existed.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/contact/heldout");
    let reader = DatasetReader::open(&dir).unwrap();
    assert_eq!(reader.card().format_version, 1);
    assert_eq!(reader.card().totals.force_frames, 0);
    assert!(!reader.card().has_finger_force());
    let frames: Vec<DatasetFrame> = reader
        .frames(None, SplitFractions::default())
        .map(Result::unwrap)
        .collect();
    assert_eq!(frames.len() as u64, reader.card().totals.frames);
    assert!(frames.iter().all(|f| f.finger_force_n.is_none()));
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
    moe_geom::assert_err!(
        shard_bytes(path, &layout(), &[f]),
        IoError::InvalidData { item, message, .. }
            if item == "frame 0 (trajectory 1, frame 2)" && message.contains("object family 9")
    );
    let mut f = frame(1, 2);
    f.vertices[0][1] = f32::NAN;
    moe_geom::assert_err!(
        shard_bytes(path, &layout(), &[f]),
        IoError::InvalidData { item, message, .. }
            if item == "frame 0 (trajectory 1, frame 2)" && message == "non-finite value in vertex 0"
    );
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
    moe_geom::assert_err!(
        shard_bytes(path, &layout(), &[]),
        IoError::InvalidData { item, message, .. }
            if item == "shard" && message.contains("at least one frame")
    );
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
    assert_eq!(card.format_version, FORMAT_VERSION);
    assert_eq!(card.totals.frames, 36);
    assert_eq!(card.totals.force_frames, 36);
    assert!(card.has_finger_force());
    assert_eq!(card.totals.trajectories, 12);
    assert_eq!(
        card.families["sphere"].frames + card.families["plate"].frames,
        36
    );
    let expected_ratio = all.iter().map(|f| f.contact_count()).sum::<usize>() as f64 / (36.0 * 5.0);
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
    // The owning iterator gives the borrowing one's frames; a shard is its frames; a shard past
    // the last is named.
    let owned: Vec<DatasetFrame> = reader
        .clone()
        .into_frames(Some(Split::Test), SplitFractions::default())
        .map(Result::unwrap)
        .collect();
    let borrowed: Vec<DatasetFrame> = reader
        .frames(Some(Split::Test), SplitFractions::default())
        .map(Result::unwrap)
        .collect();
    assert_eq!(owned, borrowed);
    assert_eq!(reader.num_shards(), 3);
    assert_eq!(reader.shard(1).unwrap(), all[12..24]);
    let err = reader.shard(3).unwrap_err().to_string();
    assert!(
        err.contains("index 3 is past the last of 3 shards"),
        "{err}"
    );
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
