//! The simulated grasp: presses on the inclined plates, the planes fitted from their holds, and
//! a whole trial.

use moe_geom::math::UnitQuat;
use moe_geom::{HandModel, HandShape, Point3, Real, SeededRng, Vector3, fit_plane_ransac};
use moe_tendon_sim::SimFrame;
use moe_tendon_sim::paper_scenes::PLATE_PRESS_TIMES_SECS;

use super::plane::{FingerView, fingertip_plane, loaded_fingertips};
use super::press::{
    angle_deg, in_hold, outcome, simulate_press, simulated_hold_shape, start_rotation, trial_start,
};
use super::trial::Presses;
use super::*;
use crate::episode::saved_frame_at;

#[test]
fn a_tilted_press_gives_the_plate_through_its_contacts_and_through_its_loaded_fingertips() {
    let options = GraspOptions::default();
    let mut rng = SeededRng::new(4);
    let rotation = start_rotation(&mut rng, 3.0);
    let axis = rotation * Vector3::z();
    assert!(angle_deg(&axis, &-Vector3::z()) <= 3.0 + 1e-9);
    // A hand turned 25° toward the 30° plate's normal touches it with all three fingers.
    let normal = plate_normal(30.0);
    let turn = UnitQuat::rotation_between(&axis, &(-normal))
        .unwrap()
        .powf(25.0 / 30.0);
    let turned = turn * rotation;
    let (_, frames) = simulate_press(30.0, turned, Point3::origin(), options.press_m).unwrap();
    let press = outcome(&frames, &turned, &normal, &options).unwrap();
    assert!(press.contact_vertices.iter().all(|&n| n >= 3), "{press:?}");
    assert!(press.success, "within 10° of the normal: {press:?}");
    let (_, deepest) = saved_frame_at(&frames, PLATE_PRESS_TIMES_SECS[2]).unwrap();
    let points: Vec<Point3> = deepest
        .fingers
        .iter()
        .flat_map(|f| {
            f.labels
                .iter()
                .zip(&f.vertices_in_world)
                .filter(|(l, _)| **l)
                .map(|(_, p)| *p)
        })
        .collect();
    let wrist = Point3::from(deepest.world_from_hand.translation.vector);
    let fit = fit_plane_ransac(&points, &options.ransac)
        .unwrap()
        .oriented_toward(&wrist);
    assert!(
        angle_deg(&fit.normal, &normal) < 1.0,
        "{}",
        angle_deg(&fit.normal, &normal)
    );
    // All three fingers are loaded, and the plane through their tips is the plate's.
    let rest = HandShape::rest(&hand_model());
    let shapes: Vec<Vec<FingerView>> = hold_frames(&frames)
        .map(|f| simulated_hold_shape(f, &rest))
        .collect();
    let (loaded, tips) = loaded_fingertips(&shapes, &(turned * Vector3::z()), &options);
    assert_eq!(loaded, [0, 1, 2]);
    let (source, n) = fingertip_plane(
        loaded.len(),
        options.min_loaded_fingers,
        &tips,
        &-(turned * Vector3::z()),
        &options.ransac,
    )
    .unwrap();
    assert_eq!(source, PlaneSource::LoadedFingertips);
    let error = angle_deg(&n, &normal);
    assert!(error < 2.0, "{error}°");
    // The level hand's own first press on the same plate is not a grasp: its axis is 30° off.
    let level = simulate_press(30.0, rotation, Point3::origin(), options.press_m).unwrap();
    let press = outcome(&level.1, &rotation, &normal, &options).unwrap();
    assert!(!press.success);
    // It touches with fewer fingers than three, and exactly those are loaded.
    let shapes: Vec<Vec<FingerView>> = hold_frames(&level.1)
        .map(|f| simulated_hold_shape(f, &rest))
        .collect();
    let (loaded, _) = loaded_fingertips(&shapes, &(rotation * Vector3::z()), &options);
    let touching: Vec<usize> = (0..3).filter(|&f| press.contact_vertices[f] > 0).collect();
    assert!(!touching.is_empty() && touching.len() < 3, "{press:?}");
    assert_eq!(loaded, touching);
}

/// Pressing on loads more fingers: a hand 20° off the 45° plate's normal loads fewer than
/// three at the judged depth, more at the deeper press's, and each plane reports the depth
/// it came from.
#[test]
fn a_deeper_press_loads_more_fingers() {
    // Turned 25° of the 45° toward the normal: 20° off.
    const TURN_DEG: Real = 25.0;
    let options = GraspOptions::default();
    let hand = hand_model();
    let normal = plate_normal(45.0);
    let level = start_rotation(&mut SeededRng::new(4), 0.0);
    let axis = level * Vector3::z();
    let turn = UnitQuat::rotation_between(&axis, &(-normal))
        .unwrap()
        .powf(TURN_DEG / 45.0);
    let rotation = turn * level;
    let mut presses = Presses::new(
        &hand,
        GraspContacts::<moe_contact::DgcnnEstimator>::Simulator,
        45.0,
        Point3::origin(),
        0,
        &options,
    );
    let mut press = |press_m| presses.observe(&rotation, press_m).unwrap();
    let shallow = press(options.press_m);
    let deep = press(options.deeper_press_m);
    assert_eq!(shallow.step.press_depth_m, options.press_m);
    assert_eq!(deep.step.press_depth_m, options.deeper_press_m);
    let (a, b) = (shallow.step.loaded_fingers, deep.step.loaded_fingers);
    assert!(a.len() < 3 && b.len() > a.len(), "{a:?} -> {b:?}");
}

/// A refining press that loads fewer than three fingers is followed at the same orientation
/// by the deeper press, whose plane the trial uses; the first press keeps the judged depth.
#[test]
fn a_refining_press_that_loads_too_few_fingers_is_pressed_deeper() {
    // 1 mm past first touch moves no finger by 3 mm: nothing is loaded at that depth.
    let options = GraspOptions {
        press_m: 0.001,
        refinements: 1,
        ..GraspOptions::default()
    };
    let trial = run_grasp_trial(
        &hand_model(),
        GraspContacts::<moe_contact::DgcnnEstimator>::Simulator,
        0.0,
        0,
        0,
        &options,
    )
    .unwrap();
    let [first, refined] = trial.fits.as_slice() else {
        panic!("{:?}", trial.fits);
    };
    assert_eq!(first.press_depth_m, options.press_m);
    assert!(first.loaded_fingers.is_empty(), "{first:?}");
    assert_eq!(first.source, Some(PlaneSource::ContactPoints));
    assert_eq!(refined.press_depth_m, options.deeper_press_m);
    assert_eq!(refined.loaded_fingers, [0, 1, 2]);
    assert_eq!(refined.source, Some(PlaneSource::LoadedFingertips));
    // The press after the first turn is the one at the judged depth, not the deeper one.
    let (start, aim) = trial_start(0.0, 0, &options);
    let [x, y, z] = first.estimated_normal.unwrap();
    let turned = UnitQuat::rotation_between(&(start * Vector3::z()), &-Vector3::new(x, y, z))
        .unwrap()
        * start;
    let (_, frames) = simulate_press(0.0, turned, aim, options.press_m).unwrap();
    let expected = outcome(&frames, &turned, &plate_normal(0.0), &options).unwrap();
    assert_eq!(first.press.as_ref(), Some(&expected));
    assert!(trial.final_press.is_some());
    assert!(refined.normal_error_deg.unwrap() < 2.0, "{refined:?}");
}

/// A contact stage whose every other estimate fails (when `failing`), with zero probability
/// everywhere otherwise: the labels-on-the-estimated-shape source does not use its output, so
/// only the failures matter.
struct EveryOtherFails {
    failing: bool,
    calls: usize,
}

impl moe_geom::ContactEstimator for EveryOtherFails {
    type Error = std::io::Error;
    fn estimate(
        &mut self,
        input: &moe_geom::ContactInput<'_>,
    ) -> Result<moe_geom::ContactEstimate, std::io::Error> {
        self.calls += 1;
        if self.failing && self.calls.is_multiple_of(2) {
            return Err(std::io::Error::other("the contact stage failed on purpose"));
        }
        Ok(moe_geom::ContactEstimate::from_map(moe_geom::ContactMap {
            fingers: input
                .shape
                .fingers
                .iter()
                .map(|f| vec![0.0; f.len()])
                .collect(),
        }))
    }
}

/// A hold frame the pipeline cannot estimate is named in its plane's step and left out of the
/// fit; the trial goes on (it used to end with the frame's error).
#[test]
fn a_failing_hold_frame_is_named_and_the_trial_goes_on() {
    let options = GraspOptions {
        refinements: 0,
        fingertip_plane: false,
        ..GraspOptions::default()
    };
    let trial = |failing| {
        run_grasp_trial(
            &hand_model(),
            GraspContacts::SimulatorLabelsOnEstimatedShape {
                contact: EveryOtherFails { failing, calls: 0 },
                shape: moe_arap::ShapeConfig::default(),
            },
            0.0,
            0,
            0,
            &options,
        )
    };
    let whole = trial(false).unwrap();
    let halved = trial(true).unwrap();
    let (all, half) = (&whole.fits[0], &halved.fits[0]);
    assert!(all.failed_frames.is_empty(), "{all:?}");
    // Every second frame failed, each named with its stage's error, and only the others'
    // contact points reached the fit.
    assert!(half.failed_frames.len() >= 2, "{half:?}");
    assert!(
        half.failed_frames
            .iter()
            .all(|f| f.error.contains("failed on purpose")),
        "{half:?}"
    );
    let frames: Vec<usize> = half.failed_frames.iter().map(|f| f.frame).collect();
    assert!(frames.windows(2).all(|w| w[0] < w[1]), "{frames:?}");
    assert!(
        half.estimated_contacts > 0 && half.estimated_contacts < all.estimated_contacts,
        "{} of {}",
        half.estimated_contacts,
        all.estimated_contacts
    );
    assert!(half.estimated_normal.is_some(), "{half:?}");
    assert_eq!(halved.first_press, whole.first_press);
}

fn hold_frames(frames: &[SimFrame]) -> impl Iterator<Item = &SimFrame> {
    frames.iter().filter(|f| in_hold(f))
}

fn hand_model() -> HandModel {
    HandModel::preset(
        moe_geom::HandPreset::ThreeFinger,
        &moe_geom::FingerParams::default(),
    )
    .unwrap()
}
