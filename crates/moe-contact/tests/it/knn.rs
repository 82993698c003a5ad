//! The KNN baselines: a training frame queried against its own index is found at distance 0
//! with its exact labels; occluded markers drop out of the distance; the index survives a file.

use moe_contact::{ContactError, KnnIndex};
use moe_geom::{
    ContactEstimator, ContactInput, FingerParams, HandModel, HandPreset, HandShape, LabelledFrame,
    Observation, SeededRng, ShapeEstimator, Vector3, WorldFromHand,
};

/// Frames of a small two-finger hand: every vertex moved by a random bend, markers at their
/// marker vertices, a few random vertices labelled.
fn frames(count: usize, seed: u64) -> Vec<LabelledFrame> {
    let params = FingerParams {
        vertex_budget: 120,
        ..FingerParams::default()
    };
    let hand = HandModel::preset(HandPreset::TwoFinger, &params).unwrap();
    let mut rng = SeededRng::new(seed);
    (0..count)
        .map(|t| {
            let mut shape = HandShape::rest(&hand);
            let bend = rng.uniform_range(-0.01, 0.01);
            for (f, finger) in hand.fingers().iter().enumerate() {
                let along = finger.hand_from_finger.transform_vector(&Vector3::x());
                for (v, p) in finger.model.mesh().vertices().iter().enumerate() {
                    shape.fingers[f][v] += along * (bend * (p.z / 0.08).powi(2));
                }
            }
            let contact: Vec<Vec<bool>> = shape
                .fingers
                .iter()
                .map(|f| (0..f.len()).map(|_| rng.uniform() < 0.05).collect())
                .collect();
            let markers = hand.keypoints_on(&shape.fingers);
            LabelledFrame {
                trajectory_id: t as u64,
                frame_index: 0,
                shape,
                contact,
                markers,
                world_from_hand: WorldFromHand::identity(),
                tendon_pull_m: vec![vec![0.0; 4]; hand.num_fingers()],
            }
        })
        .collect()
}

#[test]
fn a_training_frame_finds_itself_with_its_exact_labels() {
    let train = frames(40, 1);
    let mut index = KnnIndex::new(&train, true).unwrap();
    for (i, f) in train.iter().enumerate() {
        let m = index.nearest(&f.markers).unwrap();
        assert_eq!((m.frame, m.distance_m), (i, 0.0), "frame {i}");
        let estimate = index
            .estimate(&ContactInput::new(
                &f.shape,
                Observation::from_keypoints(&f.markers),
            ))
            .unwrap();
        assert_eq!(estimate.vertex_force_n, None);
        let map = estimate.map;
        for (labels, probs) in f.contact.iter().zip(&map.fingers) {
            for (&l, &p) in labels.iter().zip(probs) {
                assert_eq!(p, if l { 1.0 } else { 0.0 });
            }
        }
        let shape = index
            .estimate_shape(&moe_geom::Observation::from_keypoints(&f.markers))
            .unwrap();
        for (a, b) in shape
            .fingers
            .iter()
            .flatten()
            .zip(f.shape.fingers.iter().flatten())
        {
            assert!((a - b).norm() < 1e-7, "f32 storage of the shape");
        }
    }
}

#[test]
fn occluded_markers_are_left_out_of_the_distance() {
    let train = frames(30, 2);
    let index = KnnIndex::new(&train, false).unwrap();
    let mut query = train[17].markers.clone();
    // Move two markers far away and hide them: the match is unchanged and exact.
    query.fingers[0][1] = None;
    query.fingers[1][4] = None;
    let m = index.nearest(&query).unwrap();
    assert_eq!((m.frame, m.distance_m), (17, 0.0));
    // Hiding every marker is an error, not a guess.
    let none = moe_geom::HandKeypoints {
        fingers: query.fingers.iter().map(|f| vec![None; f.len()]).collect(),
    };
    assert!(matches!(
        index.nearest(&none),
        Err(ContactError::InvalidBatch { .. })
    ));
    assert!(matches!(
        index.estimate_map(&ContactInput::shape(&train[0].shape)),
        Err(ContactError::UnavailableFeatures { .. })
    ));
}

#[test]
fn a_subset_is_seeded_and_a_file_round_trips() {
    let train = frames(50, 3);
    let index = KnnIndex::new(&train, true).unwrap();
    let sub = index.subset(0.1, 7).unwrap();
    assert_eq!(sub.len(), 5);
    assert_eq!(sub, index.subset(0.1, 7).unwrap());
    assert_ne!(sub, index.subset(0.1, 8).unwrap());
    for i in 0..sub.len() {
        // Every frame of the subset is a frame of the whole index.
        let shape = sub.shape_of(i).unwrap();
        let probe = train
            .iter()
            .position(|f| {
                f.shape
                    .fingers
                    .iter()
                    .flatten()
                    .zip(shape.fingers.iter().flatten())
                    .all(|(a, b)| (a - b).norm() < 1e-7)
            })
            .unwrap();
        assert_eq!(sub.contacts_of(i), index.contacts_of(probe));
    }
    let bytes = index.to_bytes().unwrap();
    assert_eq!(KnnIndex::from_bytes(&bytes).unwrap(), index);
    let lean = KnnIndex::new(&train, false).unwrap();
    assert_eq!(
        KnnIndex::from_bytes(&lean.to_bytes().unwrap()).unwrap(),
        lean
    );
    for cut in (0..bytes.len()).step_by(bytes.len() / 50) {
        moe_geom::assert_err!(
            KnnIndex::from_bytes(&bytes[..cut]),
            ContactError::MalformedWeights { message } if message.starts_with("KNN index: "),
            "cut at {cut}"
        );
    }
    moe_geom::assert_err!(
        index.subset(0.0, 1),
        ContactError::InvalidConfig {
            field: "fraction",
            ..
        }
    );
}
