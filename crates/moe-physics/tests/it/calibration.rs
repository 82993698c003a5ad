//! Calibration recovers the material of a hand whose markers the data generator made.

use moe_geom::{HandKeypoints, OwnedObservation, Real};
use moe_physics::{CalibrationOptions, HandMaterial, PhysicsConfig, calibrate};
use moe_tendon_sim::{Material, SceneConfig, run_saving};

use crate::common::hand;

/// The calibration scene of `fixtures/scenes/calibration.toml` (moe-physics reads no files),
/// shortened, with the material `material`.
fn calibration_scene(material: Material) -> SceneConfig {
    let text = include_str!("../../../../fixtures/scenes/calibration.toml");
    let mut config: SceneConfig = toml::from_str(text).unwrap();
    config.material = material;
    config
}

/// The contact-free stream of a simulated calibration recording with exact markers.
fn recording(material: Material, seconds: Real) -> Vec<OwnedObservation> {
    let mut config = calibration_scene(material);
    config.duration_secs = seconds;
    let hand = hand();
    let mut scene = moe_tendon_sim::Scene::with_hand(config, hand.clone()).unwrap();
    let steps = scene.num_steps();
    run_saving(&mut scene, steps)
        .unwrap()
        .iter()
        .map(|f| {
            OwnedObservation::new()
                .with_time(f.time_secs)
                .with_keypoints(
                    hand.keypoints_on(
                        &f.fingers
                            .iter()
                            .map(|g| &g.vertices_in_hand)
                            .collect::<Vec<_>>(),
                    ),
                )
                .with_tendon_pulls(f.tendon_pulls_m().unwrap())
                .with_world_from_hand(moe_geom::WorldFromHand::new(f.world_from_hand))
        })
        .collect()
}

#[test]
fn calibration_recovers_a_stiffer_hand_within_five_percent() {
    let truth = Material {
        youngs_modulus_pa: 1.25e5,
        ..Material::default()
    };
    let stream = recording(truth, 1.6);
    let report = calibrate(
        &hand(),
        &[stream],
        &HandMaterial::default(),
        &PhysicsConfig::default(),
        &CalibrationOptions {
            fit_damping: false,
            max_evaluations: 30,
            ..CalibrationOptions::default()
        },
    )
    .unwrap();
    let e = report.material.material.youngs_modulus_pa;
    eprintln!("{report:?}");
    assert!(
        (e - 1.25e5).abs() <= 0.05 * 1.25e5,
        "fitted E {e} Pa for a hand of 125 kPa"
    );
    assert!(report.rms_fitted_m < report.rms_initial_m);
    // Not fitted, the damping is the initial material's, exactly.
    assert_eq!(
        report.material.material.rayleigh_stiffness,
        HandMaterial::default().material.rayleigh_stiffness
    );
}

#[test]
fn calibration_refuses_what_it_cannot_use() {
    let hand = hand();
    let config = PhysicsConfig::default();
    let options = CalibrationOptions::default();
    moe_geom::assert_err!(
        calibrate(&hand, &[], &HandMaterial::default(), &config, &options),
        moe_physics::PhysicsError::Missing { .. }
    );
    let mut bad = HandMaterial::default();
    bad.material.youngs_modulus_pa = -1.0;
    let frame = OwnedObservation::new()
        .with_time(0.0)
        .with_keypoints(HandKeypoints {
            fingers: vec![vec![None; 7]; 2],
        })
        .with_tendon_pulls(vec![vec![0.0; 4]; 2])
        .with_world_from_hand(moe_geom::WorldFromHand::identity());
    moe_geom::assert_err!(
        calibrate(&hand, &[vec![frame.clone()]], &bad, &config, &options),
        moe_physics::PhysicsError::InvalidParameter {
            name: "youngs_modulus_pa",
            ..
        }
    );
    let mut short = frame.clone();
    short.tendon_pull_m.as_mut().unwrap()[1].pop();
    moe_geom::assert_err!(
        calibrate(
            &hand,
            &[vec![short]],
            &HandMaterial::default(),
            &config,
            &options
        ),
        moe_physics::PhysicsError::FingerLengthMismatch { finger: 1, .. }
    );
    let mut nan = frame.clone();
    nan.keypoints.as_mut().unwrap().fingers[0][3] =
        Some(moe_geom::Point3::new(Real::NAN, 0.0, 0.0));
    moe_geom::assert_err!(
        calibrate(
            &hand,
            &[vec![nan]],
            &HandMaterial::default(),
            &config,
            &options
        ),
        moe_physics::PhysicsError::NonFinite {
            finger: 0,
            index: 3,
            ..
        }
    );
    // A calibration frame is part of a stream: it needs its time.
    let mut untimed = frame;
    untimed.time_secs = None;
    moe_geom::assert_err!(
        calibrate(
            &hand,
            &[vec![untimed]],
            &HandMaterial::default(),
            &config,
            &options
        ),
        moe_physics::PhysicsError::Missing { what } if what.contains("time")
    );
}
