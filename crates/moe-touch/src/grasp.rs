//! Grasping paper on an unknown incline (paper §6.2, Table 4): the three-finger hand presses an
//! inclined plate from a misaligned start, the pipeline estimates the contacts, RANSAC fits the
//! plane through them, the hand turns its axis onto the plane's normal and presses again. The
//! simulator judges the second press.
//!
//! **Success** is the state from which the paper's hand folds the sheet: at the deepest point of
//! the second press every finger touches the plate (at least
//! [`GraspOptions::min_contact_vertices`](crate::grasp::GraspOptions::min_contact_vertices)
//! labelled vertices each) and the hand's axis is within
//! [`GraspOptions::max_axis_error_deg`](crate::grasp::GraspOptions::max_axis_error_deg) of the
//! plate's normal, so the palm faces the sheet squarely. Without MOE-Touch the hand keeps its
//! initial orientation: its second press is its first.

use moe_geom::math::UnitQuat;
use moe_geom::{
    ContactPoint, HandModel, Point3, RansacConfig, Real, SeededRng, Vector3, fit_plane_ransac,
};
use moe_tendon_sim::paper_scenes::{PLATE_PRESS_TIMES_SECS, inclined_plate_press};
use moe_tendon_sim::{Scene, SimFrame, run_saving};
use serde::Serialize;

use crate::TouchError;
use crate::episode::{EpisodeRecorder, saved_frame_at};
use crate::perception::{DetectorConfig, MarkerDetector};
use crate::pipeline::Pipeline;
use moe_arap::ShapeConfig;
use moe_contact::ContactEstimator;

/// Settings of a grasp trial.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GraspOptions {
    /// Press past first touch along the hand's axis, metres. Default 8 mm.
    pub press_m: Real,
    /// Largest tilt of the initial hand orientation away from level, degrees (uniform in a
    /// cone; the yaw about the axis is uniform too). Default 3°.
    pub start_tilt_deg: Real,
    /// Largest offset of the aim point from the plate's centre, metres (uniform in a square).
    /// Default 5 mm.
    pub aim_offset_m: Real,
    /// Success: every finger has at least this many labelled vertices. Default 3.
    pub min_contact_vertices: usize,
    /// Success: the hand's axis is within this of the plate's normal, degrees. Default 10°.
    pub max_axis_error_deg: Real,
    /// The plane fit.
    pub ransac: RansacConfig,
}

impl Default for GraspOptions {
    fn default() -> Self {
        Self {
            press_m: 0.008,
            start_tilt_deg: 3.0,
            aim_offset_m: 0.005,
            min_contact_vertices: 3,
            max_axis_error_deg: 10.0,
            ransac: RansacConfig::default(),
        }
    }
}

/// How one press ended, as the simulator saw it at its deepest point.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PressOutcome {
    /// Labelled vertices per finger.
    pub contact_vertices: Vec<usize>,
    /// Angle between the hand's axis and the plate's inward normal, degrees.
    pub axis_error_deg: Real,
    /// Whether this is the state the grasp needs (see the module documentation).
    pub success: bool,
}

/// One trial on one incline.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GraspTrial {
    /// The plate's incline, degrees.
    pub incline_deg: Real,
    /// Trial number (its seed).
    pub trial: u64,
    /// The first press (also the whole trial without MOE-Touch).
    pub first_press: PressOutcome,
    /// Points the plane was fitted to: the contact source's over the first press's hold (the
    /// pipeline's estimates, or the simulator's labels).
    pub estimated_contacts: usize,
    /// The fitted plane's unit normal (toward the hand), world frame; `None` when the fit
    /// failed.
    pub estimated_normal: Option<[Real; 3]>,
    /// The incline of the fitted plane, degrees (angle of its normal from vertical).
    pub estimated_incline_deg: Option<Real>,
    /// Angle between the fitted and the true normal, degrees.
    pub normal_error_deg: Option<Real>,
    /// RANSAC inliers of the fit.
    pub inliers: usize,
    /// Why the plane fit failed, if it did.
    pub fit_error: Option<String>,
    /// The second press, reoriented to the fitted normal (`None` when the fit failed: the
    /// trial fails).
    pub second_press: Option<PressOutcome>,
    /// Success with MOE-Touch: the second press succeeded.
    pub success_with: bool,
    /// Success without: the first press succeeded.
    pub success_without: bool,
    /// The points the plane was fitted to, world frame (probability 1 for the simulator's
    /// labels); for display, not serialised.
    #[serde(skip)]
    pub plane_points: Vec<ContactPoint>,
    /// Indices into `plane_points` of the fit's inliers (empty when the fit failed).
    #[serde(skip)]
    pub inlier_indices: Vec<usize>,
    /// The simulator's contact vertices over the same hold frames, world frame.
    #[serde(skip)]
    pub true_points: Vec<ContactPoint>,
}

/// The labelled vertices of a simulated frame, placed at `positions(finger)` transformed into
/// the world frame (a vertex `positions` does not have is skipped).
fn labelled_points<'a>(
    frame: &SimFrame,
    positions: impl Fn(usize) -> &'a [Point3],
    transform: impl Fn(&Point3) -> Point3,
) -> Vec<ContactPoint> {
    frame
        .fingers
        .iter()
        .enumerate()
        .flat_map(|(finger, f)| {
            let at = positions(finger);
            f.labels
                .iter()
                .zip(at)
                .enumerate()
                .filter(|(_, (l, _))| **l)
                .map(|(v, (_, p))| ContactPoint {
                    finger,
                    vertex: v as u32,
                    point: transform(p),
                    probability: 1.0,
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

fn angle_deg(a: &Vector3, b: &Vector3) -> Real {
    (a.dot(b) / (a.norm() * b.norm()))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// The plate's top-surface unit normal.
pub fn plate_normal(incline_deg: Real) -> Vector3 {
    let a = incline_deg.to_radians();
    Vector3::new(0.0, -a.sin(), a.cos())
}

/// A level hand (fingers down) tilted by up to `max_tilt_deg` in a random direction, with a
/// random yaw.
fn start_rotation(rng: &mut SeededRng, max_tilt_deg: Real) -> UnitQuat {
    let down = UnitQuat::from_scaled_axis(Vector3::x() * std::f64::consts::PI);
    let yaw = UnitQuat::from_axis_angle(
        &Vector3::z_axis(),
        rng.uniform_range(0.0, std::f64::consts::TAU),
    );
    // Uniform in the cap of the cone: cos θ uniform in [cos max, 1].
    let cos_max = max_tilt_deg.to_radians().cos();
    let tilt = (1.0 - rng.uniform() * (1.0 - cos_max)).acos();
    let phi = rng.uniform_range(0.0, std::f64::consts::TAU);
    let axis = moe_geom::nalgebra::Unit::new_normalize(Vector3::new(phi.cos(), phi.sin(), 0.0));
    UnitQuat::from_axis_angle(&axis, tilt) * down * yaw
}

/// Simulates one press and returns its saved frames and the scene.
fn simulate_press(
    incline_deg: Real,
    rotation: UnitQuat,
    aim: Point3,
    press_m: Real,
) -> Result<(Scene, Vec<SimFrame>), TouchError> {
    let config = inclined_plate_press(incline_deg, rotation, aim, press_m)?;
    let mut scene = Scene::new(config)?;
    let steps = scene.num_steps();
    let frames = run_saving(&mut scene, steps)?;
    Ok((scene, frames))
}

fn outcome(
    frames: &[SimFrame],
    rotation: &UnitQuat,
    normal: &Vector3,
    options: &GraspOptions,
) -> Result<PressOutcome, TouchError> {
    let (_, deepest) = saved_frame_at(frames, PLATE_PRESS_TIMES_SECS[2]).ok_or_else(|| {
        TouchError::InvalidEvaluation {
            reason: "the press saved no frame".into(),
        }
    })?;
    let contact_vertices: Vec<usize> = deepest
        .fingers
        .iter()
        .map(|f| f.labels.iter().filter(|&&l| l).count())
        .collect();
    let axis_error_deg = angle_deg(&(rotation * Vector3::z()), &(-normal));
    let success = contact_vertices
        .iter()
        .all(|&n| n >= options.min_contact_vertices)
        && axis_error_deg <= options.max_axis_error_deg;
    Ok(PressOutcome {
        contact_vertices,
        axis_error_deg,
        success,
    })
}

/// Where a trial's contacts come from.
#[derive(Debug)]
pub enum GraspContacts<C> {
    /// The pipeline on the wrist camera's frames, with this contact estimator and threshold.
    Pipeline {
        /// The contact stage.
        contact: C,
        /// Its contact threshold.
        threshold: Real,
    },
    /// The simulator's contact vertices placed where the pipeline's estimated shape puts them
    /// (the pipeline runs with this contact estimator, whose own output is not used): a perfect
    /// contact classifier on the shape the markers give, which separates the error of the shape
    /// estimate from that of the contact classification.
    SimulatorLabelsOnEstimatedShape {
        /// The pipeline's contact stage (needed to run it; its probabilities are not used).
        contact: C,
    },
    /// The simulator's own contact vertices (the upper bound a perfect estimator reaches).
    Simulator,
}

/// Runs trial `trial` on the plate inclined by `incline_deg`: the first press from a perturbed
/// level start, the contacts of the press's hold (from the pipeline on the wrist camera's
/// frames, `camera_seed` seeding the noise, or from the simulator), the plane fit, and the
/// second press reoriented to the fitted normal.
///
/// # Errors
/// An incline outside `[0°, 60°]`, a diverging simulation, a failing pipeline stage (a plane
/// that cannot be fitted is reported in the trial, not as an error).
pub fn run_grasp_trial<C: ContactEstimator>(
    hand: &HandModel,
    contacts: GraspContacts<C>,
    incline_deg: Real,
    trial: u64,
    camera_seed: u64,
    options: &GraspOptions,
) -> Result<GraspTrial, TouchError> {
    let normal = plate_normal(incline_deg);
    let mut rng = SeededRng::new(trial).split((incline_deg * 1000.0).round() as u64);
    let rotation = start_rotation(&mut rng, options.start_tilt_deg);
    let u = Vector3::x();
    let v = normal.cross(&u);
    let aim = Point3::from(
        u * rng.uniform_range(-options.aim_offset_m, options.aim_offset_m)
            + v * rng.uniform_range(-options.aim_offset_m, options.aim_offset_m),
    );
    let (scene, frames) = simulate_press(incline_deg, rotation, aim, options.press_m)?;
    let first_press = outcome(&frames, &rotation, &normal, options)?;

    // Contacts over the hold.
    let [_, hold_start, hold_end, _] = PLATE_PRESS_TIMES_SECS;
    let hold: Vec<(usize, &SimFrame)> = frames
        .iter()
        .enumerate()
        .filter(|(_, f)| {
            let t = f.time_secs;
            t >= hold_start - 1e-9 && t <= hold_end + 1e-9
        })
        .collect();
    let wrist = hold.last().map_or_else(Point3::origin, |(_, f)| {
        Point3::from(f.world_from_hand.translation.vector)
    });
    let mut plane_points: Vec<ContactPoint> = Vec::new();
    let mut true_points: Vec<ContactPoint> = Vec::new();
    for (_, f) in &hold {
        true_points.extend(labelled_points(
            f,
            |finger| &f.fingers[finger].vertices_in_world,
            |p| *p,
        ));
    }
    let (contact, threshold, labels_only) = match contacts {
        GraspContacts::Pipeline { contact, threshold } => (Some(contact), threshold, false),
        GraspContacts::SimulatorLabelsOnEstimatedShape { contact } => (Some(contact), 1.0, true),
        GraspContacts::Simulator => (None, 1.0, false),
    };
    match contact {
        Some(contact) => {
            let recorder = EpisodeRecorder::new(&scene, "grasp", camera_seed)?;
            let detector =
                MarkerDetector::for_episode(recorder.info(), hand, DetectorConfig::default())?;
            let shape = crate::contact_eval::study_shape_estimator(hand, &ShapeConfig::default())?;
            let mut pipeline = Pipeline::new(hand.clone(), detector, shape, contact, threshold)?;
            for (k, f) in hold {
                let episode_frame = recorder.frame(&scene, f, k as u64)?;
                pipeline.reset();
                let estimate = pipeline.process_episode_frame(&episode_frame)?;
                if labels_only {
                    plane_points.extend(labelled_points(
                        f,
                        |finger| {
                            estimate
                                .shape
                                .fingers
                                .get(finger)
                                .map_or(&[], Vec::as_slice)
                        },
                        |p| estimate.world_from_hand.transform_point(p),
                    ));
                } else {
                    plane_points.extend_from_slice(&estimate.contacts_in_world);
                }
            }
        }
        None => plane_points.clone_from(&true_points),
    }
    let points: Vec<Point3> = plane_points.iter().map(|c| c.point).collect();
    let mut trial_report = GraspTrial {
        incline_deg,
        trial,
        first_press: first_press.clone(),
        estimated_contacts: points.len(),
        estimated_normal: None,
        estimated_incline_deg: None,
        normal_error_deg: None,
        inliers: 0,
        fit_error: None,
        second_press: None,
        success_with: false,
        success_without: first_press.success,
        plane_points,
        inlier_indices: Vec::new(),
        true_points,
    };
    let fit = match fit_plane_ransac(&points, &options.ransac) {
        Ok(fit) => fit.oriented_toward(&wrist),
        Err(e) => {
            trial_report.fit_error = Some(e.to_string());
            return Ok(trial_report);
        }
    };
    let n_est = fit.normal;
    trial_report.estimated_normal = Some([n_est.x, n_est.y, n_est.z]);
    trial_report.estimated_incline_deg = Some(angle_deg(&n_est, &Vector3::z()));
    trial_report.normal_error_deg = Some(angle_deg(&n_est, &normal));
    trial_report.inliers = fit.inliers.len();
    trial_report.inlier_indices.clone_from(&fit.inliers);

    // Turn the hand's axis onto −n̂ by the smallest rotation, and press again.
    let axis = rotation * Vector3::z();
    let turn = UnitQuat::rotation_between(&axis, &(-n_est)).unwrap_or_else(UnitQuat::identity);
    let reoriented = turn * rotation;
    match simulate_press(incline_deg, reoriented, aim, options.press_m) {
        Ok((_, frames)) => {
            let second = outcome(&frames, &reoriented, &normal, options)?;
            trial_report.success_with = second.success;
            trial_report.second_press = Some(second);
        }
        // A fitted normal too far from the plate's to press along: the trial fails.
        Err(TouchError::Simulation(e)) => trial_report.fit_error = Some(e.to_string()),
        Err(e) => return Err(e),
    }
    Ok(trial_report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simulators_contacts_of_a_tilted_press_give_the_plate_within_a_degree() {
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
        // The level hand's own first press on the same plate is not a grasp: its axis is 30° off.
        let level = simulate_press(30.0, rotation, Point3::origin(), options.press_m).unwrap();
        assert!(
            !outcome(&level.1, &rotation, &normal, &options)
                .unwrap()
                .success
        );
    }
}
