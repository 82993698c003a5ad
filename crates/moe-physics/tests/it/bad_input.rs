//! Bad input: refused with the item named, or reported for one finger while the rest goes on.

use moe_geom::{HandEstimator as _, Observation};
use moe_geom::{Point3, Real, WorldFromHand, assert_err};
use moe_physics::{HandMaterial, HandSignature, PhysicsConfig, PhysicsError, PhysicsEstimator};

use crate::common::{hand, no_pulls, press, simulate, vertex_near};

fn observe<'a>(
    keypoints: &'a moe_geom::HandKeypoints,
    pulls: &'a [Vec<Real>],
    pose: &'a WorldFromHand,
) -> Observation<'a> {
    Observation::from_keypoints(keypoints)
        .with_tendon_pulls(pulls)
        .with_world_from_hand(*pose)
}

#[test]
fn a_finger_with_too_few_markers_is_reported_and_the_others_estimated() {
    let hand = hand();
    let pulls = no_pulls(&hand);
    let v = vertex_near(&hand, 0, Point3::new(-0.0095, 0.0, 0.045));
    let mut keypoints = simulate(&hand, &pulls, &[press(&hand, v, 0.2)]);
    // Finger 1 keeps two of its seven markers.
    for m in 2..7 {
        keypoints.fingers[1][m] = None;
    }
    let pose = WorldFromHand::identity();
    let mut est =
        PhysicsEstimator::new(&hand, &HandMaterial::default(), &PhysicsConfig::default()).unwrap();
    let e = est.estimate(&observe(&keypoints, &pulls, &pose)).unwrap();
    let message = e.details.fingers[1].error.as_deref().unwrap();
    assert!(
        message.contains("finger 1") && message.contains("2 observed markers"),
        "{message}"
    );
    assert!(e.details.fingers[0].error.is_none());
    assert_eq!(e.details.loads.len(), 1);
    assert_eq!(e.details.loads[0].finger, 0);
    // Its shape is the rest shape, its map zero.
    assert_eq!(e.shape.fingers[1], hand.rest_vertices_in_hand(1));
    assert!(e.contact.fingers[1].iter().all(|&p| p == 0.0));
}

#[test]
fn observations_that_do_not_fit_the_hand_are_refused_naming_the_item() {
    let hand = hand();
    let pulls = no_pulls(&hand);
    let keypoints = simulate(&hand, &pulls, &[]);
    let pose = WorldFromHand::identity();
    let mut est =
        PhysicsEstimator::new(&hand, &HandMaterial::default(), &PhysicsConfig::default()).unwrap();
    let mut nan = keypoints.clone();
    nan.fingers[1][4] = Some(Point3::new(0.0, Real::NAN, 0.0));
    assert_err!(
        est.estimate(&observe(&nan, &pulls, &pose)),
        PhysicsError::NonFinite {
            what: "marker",
            finger: 1,
            index: 4
        }
    );
    let mut short = pulls.clone();
    short[0].pop();
    assert_err!(
        est.estimate(&observe(&keypoints, &short, &pose)),
        PhysicsError::FingerLengthMismatch {
            what: "tendon pulls",
            finger: 0,
            expected: 4,
            got: 3
        }
    );
    let mut missing = keypoints.clone();
    missing.fingers.pop();
    assert_err!(
        est.estimate(&observe(&missing, &pulls, &pose)),
        PhysicsError::LengthMismatch { .. }
    );
    let mut bad_pull = pulls.clone();
    bad_pull[1][2] = Real::INFINITY;
    assert_err!(
        est.estimate(&observe(&keypoints, &bad_pull, &pose)),
        PhysicsError::NonFinite {
            what: "tendon pull",
            finger: 1,
            index: 2
        }
    );
    // A pull no tendon takes (a quarter of its length, 20 mm here): refused, not solved for
    // seconds. The generator's ±6 mm are taken.
    let limit =
        moe_physics::MAX_PULL_FRACTION * hand.fingers()[0].model.tendon_routes()[3].length();
    let mut far = pulls.clone();
    far[0][3] = -1.01 * limit;
    assert_err!(
        est.estimate(&observe(&keypoints, &far, &pose)),
        PhysicsError::PullOutOfRange {
            finger: 0,
            tendon: 3,
            ..
        }
    );
    far[0][3] = 0.006;
    assert!(est.estimate(&observe(&keypoints, &far, &pose)).is_ok());
    // A pose that is not rigid (its quaternion twice unit length).
    let scaled = WorldFromHand::new(moe_geom::Iso3::from_parts(
        moe_geom::nalgebra::Translation3::identity(),
        moe_geom::nalgebra::UnitQuaternion::new_unchecked(moe_geom::nalgebra::Quaternion::new(
            2.0, 0.0, 0.0, 0.0,
        )),
    ));
    assert_err!(
        est.estimate(&observe(&keypoints, &pulls, &scaled)),
        PhysicsError::InvalidParameter {
            name: "world_from_hand",
            value: 2.0,
            ..
        }
    );
}

/// A marker further from its finger's base than twice the finger's length (markers given in
/// the wrong frame, a blob taken for one) fails that finger alone, at once.
#[test]
fn a_marker_off_its_finger_fails_that_finger_alone() {
    let hand = hand();
    let pulls = no_pulls(&hand);
    let mut keypoints = simulate(&hand, &pulls, &[]);
    let far = keypoints.fingers[1][2].unwrap() + moe_geom::Vector3::new(0.0, 0.5, 0.0);
    keypoints.fingers[1][2] = Some(far);
    let pose = WorldFromHand::identity();
    let mut est =
        PhysicsEstimator::new(&hand, &HandMaterial::default(), &PhysicsConfig::default()).unwrap();
    let e = est.estimate(&observe(&keypoints, &pulls, &pose)).unwrap();
    let message = e.details.fingers[1].error.as_deref().unwrap();
    assert!(
        message.contains("finger 1: marker 2 is") && message.contains("further than it can reach"),
        "{message}"
    );
    assert!(e.details.fingers[0].error.is_none());
    assert_eq!(e.shape.fingers[1], hand.rest_vertices_in_hand(1));
}

#[test]
fn non_physical_materials_and_materials_of_another_hand_are_refused() {
    let hand = hand();
    let config = PhysicsConfig::default();
    for (material, name) in [
        (
            HandMaterial {
                material: moe_tendon_sim::Material {
                    youngs_modulus_pa: 0.0,
                    ..Default::default()
                },
                ..HandMaterial::default()
            },
            "youngs_modulus_pa",
        ),
        (
            HandMaterial {
                material: moe_tendon_sim::Material {
                    poisson_ratio: 0.5,
                    ..Default::default()
                },
                ..HandMaterial::default()
            },
            "poisson_ratio",
        ),
        (
            HandMaterial {
                material: moe_tendon_sim::Material {
                    poisson_ratio: -1.2,
                    ..Default::default()
                },
                ..HandMaterial::default()
            },
            "poisson_ratio",
        ),
    ] {
        assert_err!(
            PhysicsEstimator::new(&hand, &material, &config),
            PhysicsError::InvalidParameter { name: got, .. } if *got == name
        );
    }
    let three = moe_geom::HandModel::preset(
        moe_geom::HandPreset::ThreeFinger,
        &moe_geom::FingerParams::default(),
    )
    .unwrap();
    let fitted = HandMaterial {
        hand: Some(HandSignature::counts_of(&three)),
        ..HandMaterial::default()
    };
    let e = assert_err!(
        PhysicsEstimator::new(&hand, &fitted, &config),
        PhysicsError::MaterialOfAnotherHand { .. }
    );
    assert!(e.to_string().contains("moe-touch calibrate"), "{e}");
    PhysicsEstimator::new(&three, &fitted, &config).unwrap();
}

#[test]
fn a_static_solve_that_does_not_converge_is_reported_and_the_stream_goes_on() {
    let hand = hand();
    let pulls = vec![vec![0.004, -0.004, 0.0, 0.0], vec![0.0; 4]];
    let keypoints = simulate(&hand, &pulls, &[]);
    let pose = WorldFromHand::identity();
    // One Newton iteration to a micrometre cannot bend a finger by its pulls from rest.
    let mut est = PhysicsEstimator::new(
        &hand,
        &HandMaterial::default(),
        &PhysicsConfig {
            static_max_iterations: 1,
            ..PhysicsConfig::default()
        },
    )
    .unwrap();
    let e = est.estimate(&observe(&keypoints, &pulls, &pose)).unwrap();
    let message = e.details.fingers[0].error.as_deref().unwrap();
    assert!(
        message.contains("finger 0") && message.contains("did not converge"),
        "{message}"
    );
    // The same estimator goes on with the next observation.
    est.estimate(&observe(&keypoints, &pulls, &pose)).unwrap();
}

#[test]
fn settings_out_of_range_are_named() {
    for (config, name) in [
        (
            PhysicsConfig {
                place_radius_m: -0.001,
                ..PhysicsConfig::default()
            },
            "place_radius_m",
        ),
        (
            PhysicsConfig {
                contact_radius_m: Real::NAN,
                ..PhysicsConfig::default()
            },
            "contact_radius_m",
        ),
        (
            PhysicsConfig {
                search_max_iterations: 0,
                ..PhysicsConfig::default()
            },
            "search_max_iterations",
        ),
        (
            PhysicsConfig {
                frame_solve_budget: usize::MAX,
                ..PhysicsConfig::default()
            },
            "frame_solve_budget",
        ),
    ] {
        assert_err!(
            config.validate(),
            PhysicsError::InvalidParameter { name: got, .. } if *got == name
        );
    }
    // The depth settings' own ranges: a prior in (0, 1], a finite margin.
    let depth = |prior: Real, margin: Real| PhysicsConfig {
        depth: moe_physics::DepthSettings {
            seen_through_prior: prior,
            seen_through_margin_m: margin,
            ..moe_physics::DepthSettings::default()
        },
        ..PhysicsConfig::default()
    };
    for (config, name) in [
        (depth(0.0, 0.004), "depth.seen_through_prior"),
        (depth(1.5, 0.004), "depth.seen_through_prior"),
        (depth(0.02, Real::NAN), "depth.seen_through_margin_m"),
    ] {
        assert_err!(
            config.validate(),
            PhysicsError::InvalidParameter { name: got, .. } if *got == name
        );
    }
    assert!(depth(1.0, 0.0).validate().is_ok());
}

#[test]
fn a_search_that_spends_its_frame_budget_keeps_its_best_loads_and_says_so() {
    let hand = hand();
    let pulls = no_pulls(&hand);
    let v = vertex_near(&hand, 0, Point3::new(-0.0095, 0.0, 0.045));
    let keypoints = simulate(&hand, &pulls, &[press(&hand, v, 0.15)]);
    let pose = WorldFromHand::identity();
    // The press held over two frames of a stream 50 ms apart: the budget bounds the second
    // (the first, from rest, searches in full).
    let run = |budget: usize| {
        let config = PhysicsConfig {
            frame_solve_budget: budget,
            ..PhysicsConfig::default()
        };
        let mut est = PhysicsEstimator::new(&hand, &HandMaterial::default(), &config).unwrap();
        let first = est
            .estimate(&observe(&keypoints, &pulls, &pose).with_time(0.0))
            .unwrap();
        assert!(!first.details.fingers[0].degraded, "{:?}", first.details);
        est.estimate(&observe(&keypoints, &pulls, &pose).with_time(0.05))
            .unwrap()
    };
    // Without a limit, and with the default one, the search converges on its own.
    let free = run(0);
    let default = run(PhysicsConfig::default().frame_solve_budget);
    for e in [&free, &default] {
        let f = &e.details.fingers[0];
        assert!(!f.degraded && f.error.is_none(), "{f:?}");
        assert_eq!(e.details.loads.iter().filter(|l| l.finger == 0).count(), 1);
    }
    assert_eq!(free.details.loads, default.details.loads);
    // One solve for the whole search: the frame is still an estimate (no error), with fewer
    // solves, and says that its search stopped at the budget.
    let tight = run(1);
    let f = &tight.details.fingers[0];
    assert!(f.degraded && f.error.is_none(), "{f:?}");
    assert!(
        f.solves < free.details.fingers[0].solves,
        "{} solves within a budget of 1, {} without",
        f.solves,
        free.details.fingers[0].solves
    );
    // The unpressed finger never searches, so its budget never bites.
    assert!(!tight.details.fingers[1].degraded);
}
