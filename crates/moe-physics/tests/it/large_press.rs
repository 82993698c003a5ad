//! Large presses from an independent FEM code: scikit-fem quadratic tetrahedra, compressible
//! Neo-Hookean, follower loads (`tools/fem_large_press.py`, fixture
//! `fixtures/mechanics/finger_large_presses.json`). Finger 0 of the default two-finger hand is
//! pressed at three heights on three sides with up to 1 N along its deformed normal; its markers
//! are given to the estimator as lone frames, finger 1's at its free shape.

use std::path::PathBuf;

use moe_geom::{HandEstimator as _, HandKeypoints, Observation, Point3, Real, Vector3};
use moe_physics::{HandMaterial, PhysicsConfig, PhysicsEstimator};
use serde::Deserialize;

use crate::common::{hand, no_pulls, simulate};

#[derive(Deserialize)]
struct Reference {
    youngs_modulus_pa: Real,
    poisson_ratio: Real,
    cable_stiffness_n_per_m: Real,
    marker_vertices: Vec<u32>,
    presses: Vec<Press>,
}

#[derive(Deserialize)]
struct Press {
    name: String,
    pressed_vertex: u32,
    states: Vec<State>,
}

#[derive(Deserialize)]
struct State {
    force_n: Real,
    /// The sum of the follower tractions at the solution, newtons (finger frame).
    resultant_n: [Real; 3],
    /// Per surface vertex of finger 0, finger frame.
    displacement_m: Vec<[Real; 3]>,
}

fn reference() -> Reference {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/mechanics/finger_large_presses.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// One press as the estimator saw it.
#[derive(Debug)]
struct Recovered {
    name: String,
    force_n: Real,
    /// Distance on the rest surface from the pressed vertex to the estimated load, metres
    /// (`None`: no load found on finger 0).
    place_error_m: Option<Real>,
    /// |estimated magnitude − reference resultant| / reference resultant.
    force_error: Option<Real>,
    /// Angle between the estimated force and the reference resultant, degrees.
    angle_deg: Option<Real>,
    degraded: bool,
    /// RMS of the markers about the free shape and about the estimate, metres.
    rms_m: [Real; 2],
    /// Where the press was and where the load was placed, rest surface, finger frame.
    places: [Point3; 2],
}

/// Every state of every press with at least `min_force_n`, given to the default estimator (with
/// `config`) as lone frames.
fn recover(config: &PhysicsConfig, min_force_n: Real) -> Vec<Recovered> {
    let reference = reference();
    let hand = hand();
    let finger = &hand.fingers()[0];
    let rest = finger.model.mesh().vertices();
    assert_eq!(
        reference.marker_vertices,
        finger.model.marker_vertices(),
        "the fixture is not the default finger"
    );
    // The reference's material and cables are the default hand's (cables held at their rest
    // length at zero pull).
    let material = HandMaterial::default();
    assert_eq!(
        (
            reference.youngs_modulus_pa,
            reference.poisson_ratio,
            reference.cable_stiffness_n_per_m
        ),
        (
            material.material.youngs_modulus_pa,
            material.material.poisson_ratio,
            material.tendon.stiffness_n_per_m
        )
    );
    assert_eq!(material.tendon.slack_m, 0.0);
    let pulls = no_pulls(&hand);
    let free = simulate(&hand, &pulls, &[]);
    let mut est = PhysicsEstimator::new(&hand, &material, config).unwrap();
    let mut out = Vec::new();
    for press in &reference.presses {
        for state in press.states.iter().filter(|s| s.force_n >= min_force_n) {
            assert_eq!(state.displacement_m.len(), rest.len());
            let markers: Vec<Option<Point3>> = reference
                .marker_vertices
                .iter()
                .map(|&v| {
                    let p = rest[v as usize] + Vector3::from(state.displacement_m[v as usize]);
                    Some(finger.hand_from_finger.transform_point(&p))
                })
                .collect();
            let keypoints = HandKeypoints {
                fingers: vec![markers, free.fingers[1].clone()],
            };
            est.reset();
            let e = est
                .estimate(
                    &Observation::from_keypoints(&keypoints)
                        .with_tendon_pulls(&pulls)
                        .with_world_from_hand(moe_geom::WorldFromHand::identity()),
                )
                .unwrap();
            let resultant = finger
                .hand_from_finger
                .transform_vector(&Vector3::from(state.resultant_n));
            let pressed = finger
                .hand_from_finger
                .transform_point(&rest[press.pressed_vertex as usize]);
            let load = e
                .details
                .loads
                .iter()
                .filter(|l| l.finger == 0)
                .max_by(|a, b| a.magnitude_n.total_cmp(&b.magnitude_n));
            let total: Vector3 = e
                .details
                .loads
                .iter()
                .filter(|l| l.finger == 0)
                .map(|l| l.force_n)
                .sum();
            out.push(Recovered {
                name: press.name.clone(),
                force_n: state.force_n,
                place_error_m: load.map(|l| (l.location_rest - pressed).norm()),
                force_error: load
                    .map(|_| (total.norm() - resultant.norm()).abs() / resultant.norm()),
                angle_deg: load.map(|_| total.angle(&resultant).to_degrees()),
                degraded: e.details.fingers[0].degraded,
                rms_m: [
                    e.details.fingers[0].free_rms_m,
                    e.details.fingers[0].fit_rms_m,
                ],
                places: [pressed, load.map_or(Point3::origin(), |l| l.location_rest)],
            });
        }
    }
    out
}

fn print(rows: &[Recovered]) {
    println!(
        "press                      force  place mm  force err  angle deg  degraded  free/fit rms mm  pressed / placed mm"
    );
    for r in rows {
        let f = |v: Option<Real>, s: Real| v.map_or("missed".into(), |v| format!("{:.1}", v * s));
        println!(
            "{:26} {:5.2} {:>9} {:>10} {:>10} {:>9}  {:6.2}/{:5.2}  {:?} / {:?}",
            r.name,
            r.force_n,
            f(r.place_error_m, 1e3),
            f(r.force_error, 100.0),
            f(r.angle_deg, 1.0),
            r.degraded,
            r.rms_m[0] * 1e3,
            r.rms_m[1] * 1e3,
            (r.places[0].coords * 1e3).map(|c| c.round()).as_slice(),
            (r.places[1].coords * 1e3).map(|c| c.round()).as_slice(),
        );
    }
}

/// A press the estimator cannot explain is never reported as no press in silence: at 1 N, with
/// the default settings, with friction (where every loaded solve from the free shape fails for
/// the tip and middle presses) and with loads that follow the surface, finger 0 either carries a
/// load or says its estimate is degraded.
#[test]
fn no_large_press_is_missed_in_silence() {
    for (friction, follow_surface) in [(0.0, false), (1.0, false), (0.0, true)] {
        let config = PhysicsConfig {
            friction,
            follow_surface,
            ..PhysicsConfig::default()
        };
        let rows = recover(&config, 1.0);
        print(&rows);
        assert_eq!(rows.len(), 9);
        for r in &rows {
            assert!(
                r.place_error_m.is_some() || r.degraded,
                "friction {friction}, following {follow_surface}, {}: no load and not degraded",
                r.name
            );
        }
    }
}

/// Every force of the fixture (0.25–1 N), with the default settings, with loads that follow the
/// surface and with friction: the table of docs/results.md.
#[test]
#[ignore = "report: cargo test -p moe-physics --test it large_press -- --ignored --nocapture"]
fn large_presses_per_force() {
    for (friction, follow_surface) in [(0.0, false), (0.0, true), (1.0, false)] {
        println!("friction {friction}, loads follow the surface: {follow_surface}");
        let config = PhysicsConfig {
            friction,
            follow_surface,
            ..PhysicsConfig::default()
        };
        print(&recover(&config, 0.0));
    }
}
