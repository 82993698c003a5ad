//! One simulated press on the inclined plate: the trial's start, the press, how it ended, and
//! the simulator's own view of its hold.

use moe_geom::math::UnitQuat;
use moe_geom::{ContactPoint, HandShape, Point3, Real, SeededRng, Vector3};
use moe_tendon_sim::paper_scenes::{PLATE_PRESS_TIMES_SECS, inclined_plate_press};
use moe_tendon_sim::{Scene, SimFrame, run_saving};

use super::plane::{FingerView, largest_displacement};
use super::{GraspOptions, PressOutcome};
use crate::LabError;
use crate::episode::saved_frame_at;

/// The labelled vertices of a simulated frame, placed at `positions(finger)` transformed into
/// the world frame (a vertex `positions` does not have is skipped).
pub(super) fn labelled_points<'a>(
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

pub(super) fn angle_deg(a: &Vector3, b: &Vector3) -> Real {
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
pub(super) fn start_rotation(rng: &mut SeededRng, max_tilt_deg: Real) -> UnitQuat {
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
pub(super) fn simulate_press(
    incline_deg: Real,
    rotation: UnitQuat,
    aim: Point3,
    press_m: Real,
) -> Result<(Scene, Vec<SimFrame>), LabError> {
    let config = inclined_plate_press(incline_deg, rotation, aim, press_m)?;
    let mut scene = Scene::new(config)?;
    let steps = scene.num_steps();
    let frames = run_saving(&mut scene, steps)?;
    Ok((scene, frames))
}

pub(super) fn outcome(
    frames: &[SimFrame],
    rotation: &UnitQuat,
    normal: &Vector3,
    options: &GraspOptions,
) -> Result<PressOutcome, LabError> {
    let (_, deepest) = saved_frame_at(frames, PLATE_PRESS_TIMES_SECS[2]).ok_or_else(|| {
        LabError::InvalidEvaluation {
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

/// Whether a press's frame is in its hold (the stretch at full depth).
pub(super) fn in_hold(frame: &SimFrame) -> bool {
    let [_, hold_start, hold_end, _] = PLATE_PRESS_TIMES_SECS;
    let t = frame.time_secs;
    t >= hold_start - 1e-9 && t <= hold_end + 1e-9
}

/// The simulator's shape of a frame (every tip seen).
pub(super) fn simulated_hold_shape(frame: &SimFrame, rest: &HandShape) -> Vec<FingerView> {
    frame
        .fingers
        .iter()
        .zip(&rest.fingers)
        .map(|(f, r)| {
            let at_rest: Vec<Point3> = r.iter().map(|p| frame.world_from_hand * p).collect();
            FingerView {
                displacement_m: largest_displacement(&f.vertices_in_world, &at_rest),
                vertices_in_world: f.vertices_in_world.clone(),
                tip_seen: true,
            }
        })
        .collect()
}

/// Trial `trial`'s start on the plate inclined by `incline_deg`: the hand's orientation and the
/// aim point on the plate (seeded by both).
pub(super) fn trial_start(
    incline_deg: Real,
    trial: u64,
    options: &GraspOptions,
) -> (UnitQuat, Point3) {
    let normal = plate_normal(incline_deg);
    let mut rng = SeededRng::new(trial).split((incline_deg * 1000.0).round() as u64);
    let rotation = start_rotation(&mut rng, options.start_tilt_deg);
    let u = Vector3::x();
    let v = normal.cross(&u);
    let aim = Point3::from(
        u * rng.uniform_range(-options.aim_offset_m, options.aim_offset_m)
            + v * rng.uniform_range(-options.aim_offset_m, options.aim_offset_m),
    );
    (rotation, aim)
}
