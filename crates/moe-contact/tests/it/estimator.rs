//! The DGCNN behind the `moe_geom::ContactEstimator` trait, on hands.

use moe_contact::candle_core::{DType, Device};
use moe_contact::{
    ContactError, DgcnnEstimator, FeatureBuilder, FeatureFrame, InputFeature, InputSpec, ModelCard,
    ModelWeights, PointSet,
};
use moe_geom::{
    ContactEstimator, ContactInput, FingerParams, GeomError, HandModel, HandPreset, HandShape,
    Observation, Vector3,
};

use crate::common::small_config;

fn hand(preset: HandPreset) -> HandModel {
    let params = FingerParams {
        vertex_budget: 160,
        ..FingerParams::default()
    };
    HandModel::preset(preset, &params).unwrap()
}

fn estimator(
    hand: &HandModel,
    point_set: PointSet,
    frame: FeatureFrame,
    rest: bool,
) -> DgcnnEstimator {
    let mut config = small_config(Default::default());
    config.input.point_set = point_set;
    config.input.frame = frame;
    if rest {
        config.input.features.push(InputFeature::RestXyz);
    }
    let c = config.input.channels();
    let card = ModelCard::new(config.clone());
    let net = ModelWeights::seeded(&config, c, 31)
        .unwrap()
        .build(Some(&card), DType::F64, &Device::Cpu)
        .unwrap();
    DgcnnEstimator::new(net, card, hand).unwrap()
}

/// Every finger pushed in along its own x by a bump near the tip, and jittered by up to 20 µm
/// (the same jitter per vertex on every finger), so that no two neighbour distances tie: the
/// finger mesh is a surface of revolution, whose rings give many exactly equal distances that
/// rounding would break differently on each finger.
fn pressed(hand: &HandModel) -> HandShape {
    let jitter: Vec<Vector3> = {
        let mut rng = moe_geom::SeededRng::new(77);
        (0..hand.fingers()[0].model.mesh().num_vertices())
            .map(|_| {
                Vector3::new(
                    rng.uniform_range(-2e-5, 2e-5),
                    rng.uniform_range(-2e-5, 2e-5),
                    rng.uniform_range(-2e-5, 2e-5),
                )
            })
            .collect()
    };
    let mut shape = HandShape::rest(hand);
    for (f, finger) in hand.fingers().iter().enumerate() {
        for (v, p) in finger.model.mesh().vertices().iter().enumerate() {
            let bump = (-((p.z - 0.06).powi(2) + p.y.powi(2)) / 1e-4).exp();
            let moved = p - Vector3::x() * (0.002 * bump * p.x.max(0.0) / 0.01) + jitter[v];
            shape.fingers[f][v] = finger.hand_from_finger.transform_point(&moved);
        }
    }
    shape
}

#[test]
fn identical_fingers_in_their_own_frames_get_identical_maps() {
    let hand = hand(HandPreset::ThreeFinger);
    let est = estimator(&hand, PointSet::PerFinger, FeatureFrame::Finger, true);
    let map = est
        .estimate_map(&ContactInput::shape(&pressed(&hand)))
        .unwrap();
    for f in 1..3 {
        let diff = map.fingers[0]
            .iter()
            .zip(&map.fingers[f])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff < 1e-9, "finger {f}: {diff:e}");
    }
    assert!(
        map.fingers
            .iter()
            .flatten()
            .all(|p| (0.0..=1.0).contains(p))
    );
}

#[test]
fn a_batch_equals_one_estimate_at_a_time() {
    let hand = hand(HandPreset::TwoFinger);
    for (set, frame) in [
        (PointSet::WholeHand, FeatureFrame::Hand),
        (PointSet::PerFinger, FeatureFrame::Finger),
    ] {
        let mut est = estimator(&hand, set, frame, false);
        let a = HandShape::rest(&hand);
        let b = pressed(&hand);
        let batch = est
            .estimate_batch(&[ContactInput::shape(&a), ContactInput::shape(&b)])
            .unwrap();
        for (got, shape) in batch.iter().zip([&a, &b]) {
            // Through the trait: the map of `estimate_map`, and no forces.
            let input = ContactInput::shape(shape);
            let estimate = est.estimate(&input).unwrap();
            assert_eq!(estimate.vertex_force_n, None);
            assert_eq!(estimate.map, est.estimate_map(&input).unwrap());
            let one = estimate.map;
            for (x, y) in got
                .fingers
                .iter()
                .flatten()
                .zip(one.fingers.iter().flatten())
            {
                assert!((x - y).abs() < 1e-12, "{set:?}");
            }
        }
    }
}

#[test]
fn a_shape_of_another_hand_is_refused_naming_the_finger() {
    let hand = hand(HandPreset::TwoFinger);
    let est = estimator(&hand, PointSet::WholeHand, FeatureFrame::Hand, false);
    let mut shape = HandShape::rest(&hand);
    shape.fingers[1].truncate(100);
    match est.estimate_map(&ContactInput::shape(&shape)) {
        Err(ContactError::Geometry(GeomError::FingerLengthMismatch {
            finger: 1,
            got: 100,
            ..
        })) => {}
        other => panic!("{other:?}"),
    }
    let mut shape = HandShape::rest(&hand);
    shape.fingers[0][12].z = f64::INFINITY;
    match est.estimate_map(&ContactInput::shape(&shape)) {
        Err(ContactError::Geometry(GeomError::NonFiniteFingerPoint {
            finger: 0,
            index: 12,
            ..
        })) => {}
        other => panic!("{other:?}"),
    }
    let three = HandShape::rest(&self::hand(HandPreset::ThreeFinger));
    assert!(matches!(
        est.estimate_map(&ContactInput::shape(&three)),
        Err(ContactError::Geometry(GeomError::LengthMismatch {
            expected: 2,
            got: 3,
            ..
        }))
    ));
}

#[test]
fn a_card_whose_features_do_not_fit_the_network_is_refused() {
    let hand = hand(HandPreset::TwoFinger);
    let config = small_config(Default::default());
    let net = ModelWeights::seeded(&config, 3, 1)
        .unwrap()
        .build(None, DType::F64, &Device::Cpu)
        .unwrap();
    let mut card = ModelCard::new(config);
    card.architecture.input.features.push(InputFeature::RestXyz);
    assert!(matches!(
        DgcnnEstimator::new(net, card, &hand),
        Err(ContactError::CardMismatch {
            field: "architecture.input.features",
            ..
        })
    ));
}

#[test]
fn per_finger_undoes_arrange_for_every_point_set_layout() {
    let hand = hand(HandPreset::ThreeFinger);
    let values: Vec<Vec<u32>> = hand
        .fingers()
        .iter()
        .enumerate()
        .map(|(f, hf)| {
            (0..hf.model.mesh().num_vertices() as u32)
                .map(|v| 100_000 * f as u32 + v)
                .collect()
        })
        .collect();
    for point_set in [PointSet::PerFinger, PointSet::WholeHand] {
        let spec = InputSpec {
            point_set,
            ..InputSpec::default()
        };
        let builder = FeatureBuilder::new(&spec, &hand).unwrap();
        let flat: Vec<u32> = builder.arrange(&values).into_iter().flatten().collect();
        assert_eq!(builder.per_finger(&flat).unwrap(), values, "{point_set:?}");
        assert!(matches!(
            builder.per_finger(&flat[1..]),
            Err(moe_contact::ContactError::InvalidBatch { .. })
        ));
    }
}

#[test]
fn a_card_s_hand_decides_which_hands_the_model_runs_on() {
    let two = hand(HandPreset::TwoFinger);
    let three = hand(HandPreset::ThreeFinger);
    let other = HandModel::preset(
        HandPreset::TwoFinger,
        &FingerParams {
            vertex_budget: 200,
            ..FingerParams::default()
        },
    )
    .unwrap();
    let build = |point_set: PointSet, on: &HandModel| {
        let mut config = small_config(Default::default());
        config.input.point_set = point_set;
        let c = config.input.channels();
        let mut card = ModelCard::new(config.clone());
        card.hand = Some(moe_contact::CardHand {
            name: "two-finger".into(),
            finger_num_vertices: two
                .fingers()
                .iter()
                .map(|f| f.model.mesh().num_vertices())
                .collect(),
            // A card written before digests were recorded: vertex counts are checked.
            finger_digests: Vec::new(),
        });
        let net = ModelWeights::seeded(&config, c, 31)
            .unwrap()
            .build(Some(&card), DType::F32, &Device::Cpu)
            .unwrap();
        DgcnnEstimator::new(net, card, on)
    };
    // A per-finger model runs on any number of the trained fingers; a whole-hand one does not.
    assert!(build(PointSet::PerFinger, &two).is_ok());
    assert!(build(PointSet::PerFinger, &three).is_ok());
    assert!(build(PointSet::WholeHand, &two).is_ok());
    for (set, on) in [(PointSet::WholeHand, &three), (PointSet::PerFinger, &other)] {
        let err = build(set, on).unwrap_err();
        assert!(
            matches!(err, ContactError::HandMismatch { .. }),
            "{set:?}: {err}"
        );
        assert!(err.to_string().contains("two-finger"), "{err}");
    }
}

/// A card that records its finger's rest-mesh digest runs on that finger — in a hand, or alone
/// from its mesh without markers — and refuses another finger of the same vertex count, saying
/// how to get a model for it.
#[test]
fn a_card_with_finger_digests_refuses_another_finger_of_the_same_size() {
    let params = FingerParams {
        vertex_budget: 200,
        ..FingerParams::default()
    };
    let two = HandModel::preset(HandPreset::TwoFinger, &params).unwrap();
    let rest = two.fingers()[0].model.mesh();
    // The same finger 1 % larger: the same vertex count and ids, another geometry.
    let grown: Vec<moe_geom::Point3> = rest.vertices().iter().map(|p| p * 1.01).collect();
    let other = &moe_geom::TriMesh::new(grown, rest.faces().to_vec()).unwrap();
    let longer = HandModel::new(
        two.fingers()
            .iter()
            .map(|f| moe_geom::HandFinger {
                model: moe_geom::FingerModel::from_parts(
                    other.clone(),
                    f.model.marker_vertices().to_vec(),
                    f.model.base_vertices().to_vec(),
                    f.model.tendon_routes().to_vec(),
                )
                .unwrap(),
                ..f.clone()
            })
            .collect(),
    )
    .unwrap();
    assert_ne!(rest.digest(), other.digest());

    let mut config = small_config(Default::default());
    config.input.point_set = PointSet::PerFinger;
    config.input.frame = moe_contact::FeatureFrame::Finger;
    let c = config.input.channels();
    let mut card = ModelCard::new(config.clone());
    card.hand = Some(moe_contact::CardHand::of("two-finger", &two));
    let weights = ModelWeights::seeded(&config, c, 31)
        .unwrap()
        .to_bytes()
        .unwrap();
    let json = card.to_json().unwrap();

    assert!(DgcnnEstimator::from_bytes(&weights, &json, &two).is_ok());
    let err = DgcnnEstimator::from_bytes(&weights, &json, &longer).unwrap_err();
    assert!(
        matches!(err, ContactError::FingerMismatch { finger: 0, .. }),
        "{err}"
    );

    // One finger from its mesh alone: the same probabilities as in the hand (finger-frame
    // features).
    let alone = DgcnnEstimator::finger_from_bytes(&weights, &json, rest).unwrap();
    let p = alone.finger_map(rest.vertices()).unwrap();
    let in_hand = DgcnnEstimator::from_bytes(&weights, &json, &two).unwrap();
    let shape = HandShape {
        fingers: (0..2).map(|f| two.rest_vertices_in_hand(f)).collect(),
    };
    let map = in_hand
        .estimate_map(&moe_geom::ContactInput::shape(&shape))
        .unwrap();
    for (a, b) in p.iter().zip(&map.fingers[0]) {
        assert!((a - b).abs() < 1e-5, "{a} vs {b}");
    }
    let err = DgcnnEstimator::finger_from_bytes(&weights, &json, other).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, ContactError::FingerMismatch { .. }), "{text}");
    assert!(
        text.contains("moe-touch train") && text.contains(&other.digest()),
        "{text}"
    );
}

/// The deformation channels are zero on the rest hand, the same for every finger of a pressed
/// hand whatever its place on the palm (frame-free), and negative where the bump dents a finger.
#[test]
fn deformation_features_are_frame_free_and_mark_the_dent() {
    let hand = hand(HandPreset::ThreeFinger);
    let spec = InputSpec {
        features: vec![InputFeature::Xyz, InputFeature::Deformation],
        frame: FeatureFrame::Finger,
        point_set: PointSet::PerFinger,
        normalisation: None,
    };
    let builder = FeatureBuilder::new(&spec, &hand).unwrap();
    assert_eq!(builder.channels(), 6);
    let deformation = |sets: &[Vec<f64>], f: usize| -> Vec<[f64; 3]> {
        sets[f]
            .chunks_exact(6)
            .map(|row| [row[3], row[4], row[5]])
            .collect()
    };
    let rest = builder.input_sets(&HandShape::rest(&hand)).unwrap();
    for f in 0..3 {
        let worst = deformation(&rest, f)
            .iter()
            .flatten()
            .fold(0.0f64, |m, c| m.max(c.abs()));
        assert!(worst < 1e-9, "finger {f} at rest: {worst:e}");
    }
    let sets = builder.input_sets(&pressed(&hand)).unwrap();
    let first = deformation(&sets, 0);
    for f in 1..3 {
        let diff = deformation(&sets, f)
            .iter()
            .zip(&first)
            .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
            .fold(0.0, f64::max);
        assert!(diff < 1e-9, "finger {f}: {diff:e}");
    }
    // The bump pushes the +x side in around z = 60 mm: the most negative curvature change is
    // there, and clearly below the jitter's.
    let mesh = hand.fingers()[0].model.mesh();
    let (v, m) = first
        .iter()
        .enumerate()
        .min_by(|a, b| a.1[0].total_cmp(&b.1[0]))
        .unwrap();
    let p = mesh.vertices()[v];
    assert!(m[0] < -0.05, "{m:?}");
    assert!(
        p.x > 0.0 && (p.z - 0.06).abs() < 0.01,
        "vertex {v} at {p:?}"
    );
}

/// The largest difference between two maps' probabilities, vertex by vertex.
fn largest_difference(a: &moe_geom::ContactMap, b: &moe_geom::ContactMap) -> f64 {
    a.fingers
        .iter()
        .flatten()
        .zip(b.fingers.iter().flatten())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The two-finger hand's pulls `[+x, −x, +y, −y]` per finger (the preset's route order).
fn pulls(a: [f64; 4], b: [f64; 4]) -> Vec<Vec<f64>> {
    vec![a.to_vec(), b.to_vec()]
}

fn pull_spec(frame: FeatureFrame, point_set: PointSet) -> InputSpec {
    InputSpec {
        features: vec![InputFeature::Xyz, InputFeature::TendonPull],
        frame,
        point_set,
        normalisation: None,
    }
}

/// A pair pulled one way and paid out the other is a bending along that pair's axis (twice the
/// pull, no co-contraction); two tendons pulled together add to the third channel. The channels
/// are the same on every vertex of the finger, in whatever frame and grouping.
#[test]
fn tendon_pull_channels_are_the_bending_the_pulls_ask_for() {
    let hand = hand(HandPreset::TwoFinger);
    let d = 0.003;
    let p = pulls([d, -d, 0.0, 0.0], [0.0, 0.0, 0.002, 0.001]);
    let want = [[2.0 * d, 0.0, 0.0], [0.0, 0.001, 0.003]];
    for (frame, set) in [
        (FeatureFrame::Finger, PointSet::PerFinger),
        (FeatureFrame::Hand, PointSet::WholeHand),
    ] {
        let builder = FeatureBuilder::new(&pull_spec(frame, set), &hand).unwrap();
        assert!(builder.needs_tendon_pulls());
        let sets = builder.input_sets_with(&pressed(&hand), Some(&p)).unwrap();
        let rows: Vec<&[f64]> = sets.iter().flat_map(|s| s.chunks_exact(6)).collect();
        let n = hand.fingers()[0].model.mesh().num_vertices();
        assert_eq!(rows.len(), 2 * n);
        for (i, row) in rows.iter().enumerate() {
            let w = want[i / n];
            for c in 0..3 {
                assert!(
                    (row[3 + c] - w[c]).abs() < 1e-15,
                    "{frame:?} row {i}: {row:?}"
                );
            }
        }
    }
}

/// A model that takes pulls refuses an observation without them, or with pulls that do not fit
/// the hand, naming what is wrong; a model that does not take them ignores them.
#[test]
fn pulls_that_are_missing_or_do_not_fit_are_named() {
    let hand = hand(HandPreset::TwoFinger);
    let shape = pressed(&hand);
    let builder =
        FeatureBuilder::new(&pull_spec(FeatureFrame::Finger, PointSet::PerFinger), &hand).unwrap();
    assert!(matches!(
        builder.input_sets(&shape),
        Err(ContactError::UnavailableFeatures { .. })
    ));
    let three = vec![vec![0.0; 4], vec![0.0; 3]];
    assert!(matches!(
        builder.input_sets_with(&shape, Some(&three)),
        Err(ContactError::Geometry(GeomError::FingerLengthMismatch {
            what: "tendon pulls",
            finger: 1,
            expected: 4,
            got: 3,
        }))
    ));
    let one = vec![vec![0.0; 4]];
    assert!(matches!(
        builder.input_sets_with(&shape, Some(&one)),
        Err(ContactError::Geometry(GeomError::LengthMismatch { .. }))
    ));
    let nan = pulls([0.0; 4], [0.0, f64::NAN, 0.0, 0.0]);
    assert!(matches!(
        builder.input_sets_with(&shape, Some(&nan)),
        Err(ContactError::Geometry(GeomError::NonFinitePoint {
            index: 1,
            ..
        }))
    ));
    let plain = FeatureBuilder::new(&InputSpec::default(), &hand).unwrap();
    assert!(!plain.needs_tendon_pulls());
    assert_eq!(
        plain.input_sets_with(&shape, Some(&nan)).unwrap(),
        plain.input_sets(&shape).unwrap()
    );
}

/// Weights widened for added channels compute exactly what they computed, whatever the new
/// channels hold; the pulls reach the network once the new weights are not zero; and an
/// estimator of a pull model refuses a bare shape.
#[test]
fn widened_weights_compute_what_they_computed_and_pulls_reach_the_network() {
    let hand = hand(HandPreset::TwoFinger);
    let shape = pressed(&hand);
    let mut plain = small_config(Default::default());
    plain.input.point_set = PointSet::PerFinger;
    plain.input.frame = FeatureFrame::Finger;
    let mut with_pulls = plain.clone();
    with_pulls.input.features.push(InputFeature::TendonPull);
    let build = |config: &moe_contact::DgcnnConfig, weights: &ModelWeights| {
        let card = ModelCard::new(config.clone());
        let net = weights
            .build(Some(&card), DType::F64, &Device::Cpu)
            .unwrap();
        DgcnnEstimator::new(net, card, &hand).unwrap()
    };
    let base = ModelWeights::seeded(&plain, 3, 5).unwrap();
    let before = build(&plain, &base)
        .estimate_map(&ContactInput::shape(&shape))
        .unwrap();
    let widened = build(&with_pulls, &base.with_input_channels(6).unwrap());
    let p = pulls([0.004, -0.004, 0.0, 0.0], [0.0, 0.0, -0.005, 0.005]);
    let input = ContactInput::new(&shape, Observation::new().with_tendon_pulls(&p));
    let after = widened.estimate_map(&input).unwrap();
    let moved = largest_difference(&after, &before);
    assert!(moved < 1e-12, "{moved:e}");
    assert!(matches!(
        widened.estimate_map(&ContactInput::shape(&shape)),
        Err(ContactError::UnavailableFeatures { .. })
    ));
    assert!(matches!(
        base.with_input_channels(2),
        Err(ContactError::InvalidConfig { .. })
    ));
    // Seeded weights for all six channels: other pulls, other probabilities.
    let full = build(
        &with_pulls,
        &ModelWeights::seeded(&with_pulls, 6, 5).unwrap(),
    );
    let a = full.estimate_map(&input).unwrap();
    let none = pulls([0.0; 4], [0.0; 4]);
    let b = full
        .estimate_map(&ContactInput::new(
            &shape,
            Observation::new().with_tendon_pulls(&none),
        ))
        .unwrap();
    let diff = largest_difference(&a, &b);
    assert!(diff > 1e-6, "{diff:e}");
}

/// A tendon whose route starts on the finger axis has no bending direction: a model taking the
/// pulls refuses the hand, naming the finger and tendon; one that does not take them accepts it.
#[test]
fn a_tendon_on_the_axis_is_refused_by_a_pull_model() {
    let two = hand(HandPreset::TwoFinger);
    let mut fingers = two.fingers().to_vec();
    let model = &fingers[1].model;
    let mut routes = model.tendon_routes().to_vec();
    for p in &mut routes[2].points_in_finger {
        p.x = 0.0;
        p.y = 0.0;
    }
    fingers[1].model = moe_geom::FingerModel::from_parts(
        model.mesh().clone(),
        model.marker_vertices().to_vec(),
        model.base_vertices().to_vec(),
        routes,
    )
    .unwrap();
    let odd = HandModel::new(fingers).unwrap();
    let err = FeatureBuilder::new(&pull_spec(FeatureFrame::Finger, PointSet::PerFinger), &odd)
        .unwrap_err();
    assert!(
        matches!(&err, ContactError::InvalidConfig { message, .. }
            if message.contains("finger 1's tendon 2")),
        "{err}"
    );
    assert!(FeatureBuilder::new(&InputSpec::default(), &odd).is_ok());
}
