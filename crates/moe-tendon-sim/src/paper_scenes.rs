//! The scenes of the paper's experiments, built in code so that the committed scene files under
//! `fixtures/scenes/` are reproducible (`cargo xtask fixtures --update` writes them, `--check`
//! compares them):
//!
//! - [`head_patting`](crate::paper_scenes::head_patting): a two-finger hand pats a head-like surface at 30 poses over the top, back
//!   and sides of the scalp (paper §5.3, where 30 contact conditions on a head are evaluated);
//! - [`arm_patting`](crate::paper_scenes::arm_patting): the same hand pats a long arm at 15 poses along its top and outer
//!   side (the paper's arm under a gown, §6.1);
//! - [`inclined_plate`](crate::paper_scenes::inclined_plate): a three-finger hand presses a flat plate inclined at 0°, 30° or 45°
//!   (paper §6.2, grasping paper on an inclined surface).
//!
//! The paper's plate-at-tip/middle/base scenes (Fig. 5) are hand-written TOML files beside them.

use std::f64::consts::PI;

use moe_geom::bodies::{ArmParams, HeadParams};
use moe_geom::math::UnitQuat;
use moe_geom::{FingerParams, HandPreset, Point3, Real, Vector3};

use crate::error::SimError;
use crate::obstacle::{ObstacleConfig, ObstacleShape};
use crate::scene::{PresetHandConfig, SceneConfig};
use crate::trajectory::{PoseKeyframe, PoseTrajectory};

/// Seed of the head used by [`head_patting`].
pub const HEAD_SEED: u64 = 2024;
/// Number of pats in [`head_patting`].
pub const HEAD_PATS: usize = 30;
/// Seed of the arm used by [`arm_patting`].
pub const ARM_SEED: u64 = 2025;
/// Number of pats in [`arm_patting`].
pub const ARM_PATS: usize = 15;
/// Icosphere level of the patted arm's mesh (level 3 would leave 5 cm facets along its length).
pub const ARM_MESH_LEVEL: u32 = 4;
/// Icosphere level of the patted head's mesh.
pub const HEAD_MESH_LEVEL: u32 = 3;
/// Seconds from one pat to the next.
pub const PAT_PERIOD_SECS: Real = 0.9;
/// Seconds from the start of a pat to the end of its hold at full press.
pub const PAT_HOLD_END_SECS: Real = 0.6;

/// The time of pat `k`'s deepest press (the end of its hold), seconds from the scene's start.
pub fn pat_press_time(k: usize) -> Real {
    k as Real * PAT_PERIOD_SECS + PAT_HOLD_END_SECS
}

/// A wrist keyframe that puts the fingertips (hand z = finger length) at `point`, the hand's z
/// axis along `-normal` (fingers pointing into the surface) with a roll about it.
fn pose_facing(
    time_secs: Real,
    point: &Point3,
    normal: &Vector3,
    standoff_m: Real,
    roll: Real,
) -> PoseKeyframe {
    let fingertips = FingerParams::default().length_m;
    let align = UnitQuat::rotation_between(&Vector3::z(), &(-normal))
        .unwrap_or_else(|| UnitQuat::from_axis_angle(&Vector3::x_axis(), PI));
    let rotation = align * UnitQuat::from_axis_angle(&Vector3::z_axis(), roll);
    let origin = point + normal * (fingertips + standoff_m);
    PoseKeyframe {
        time_secs,
        translation_m: origin.coords.into(),
        rotation_rad: rotation.scaled_axis().into(),
    }
}

/// A wrist keyframe as [`pose_facing`], with the roll chosen so that the hand's x axis (the
/// line through the two fingers of the two-finger hand) is as close to `x_hint` as the facing
/// allows.
fn pose_facing_along(
    time_secs: Real,
    point: &Point3,
    normal: &Vector3,
    standoff_m: Real,
    x_hint: &Vector3,
) -> PoseKeyframe {
    let z = -normal.normalize();
    let x = (x_hint - z * x_hint.dot(&z)).normalize();
    let y = z.cross(&x);
    let rotation = UnitQuat::from_matrix(&moe_geom::Matrix3::from_columns(&[x, y, z]));
    let fingertips = FingerParams::default().length_m;
    let origin = point + normal * (fingertips + standoff_m);
    PoseKeyframe {
        time_secs,
        translation_m: origin.coords.into(),
        rotation_rad: rotation.scaled_axis().into(),
    }
}

/// The five keyframes of one pat starting at `t0`: above at 5 cm, approach to 3 cm, press 6 mm
/// past first touch, hold, retreat to 5 cm.
fn pat_keyframes(t0: Real, pose: impl Fn(Real, Real) -> PoseKeyframe) -> [PoseKeyframe; 5] {
    [
        pose(t0, 0.05),
        pose(t0 + 0.2, 0.03),
        pose(t0 + 0.5, -0.006),
        pose(t0 + PAT_HOLD_END_SECS, -0.006),
        pose(t0 + 0.8, 0.05),
    ]
}

/// The outward normal of a surface given as a map of the unit sphere, at direction `d`, by
/// central differences.
fn mapped_normal(map: impl Fn(&Vector3) -> Point3, d: &Vector3) -> (Point3, Vector3) {
    let a = if d.z.abs() < 0.9 {
        Vector3::z()
    } else {
        Vector3::x()
    };
    let t1 = d.cross(&a).normalize();
    let t2 = d.cross(&t1);
    let h = 1e-4;
    let s = |v: Vector3| map(&v.normalize()).coords;
    let du = s(d + t1 * h) - s(d - t1 * h);
    let dv = s(d + t2 * h) - s(d - t2 * h);
    let mut n = du.cross(&dv).normalize();
    let p = Point3::from(s(*d));
    if n.dot(&p.coords) < 0.0 {
        n = -n;
    }
    (p, n)
}

/// The outward normal of a star-shaped surface `r(d)·d` at direction `d`, by central differences.
fn star_normal(radius: impl Fn(&Vector3) -> Real, d: &Vector3) -> (Point3, Vector3) {
    mapped_normal(|u| Point3::from(u * radius(u)), d)
}

/// Pat directions over the scalp (head frame: x left–right, y toward the face, z up): rings of
/// constant elevation, the face sector left out, in snake order so that consecutive pats are
/// neighbours.
fn pat_directions() -> Vec<Vector3> {
    let rings: [(Real, usize); 3] = [(70.0, 6), (40.0, 10), (12.0, 14)];
    let mut out = Vec::with_capacity(HEAD_PATS);
    for (r, &(elevation_deg, count)) in rings.iter().enumerate() {
        let el = elevation_deg.to_radians();
        // Azimuth from the face direction (+y): keep 50°..310° (sides and back).
        let mut ring: Vec<Vector3> = (0..count)
            .map(|k| {
                let az = (50.0 + 260.0 * (k as Real + 0.5) / count as Real).to_radians();
                Vector3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin())
            })
            .collect();
        if r % 2 == 1 {
            ring.reverse();
        }
        out.extend(ring);
    }
    out
}

/// The head-patting scene: a two-finger hand pats the head of seed [`HEAD_SEED`] at
/// [`HEAD_PATS`] poses, each an approach from 3 cm, a 6 mm press past first touch, and a
/// retreat to 5 cm before moving to the next pose.
///
/// # Errors
/// Mesh errors from the head generator (none for the fixed seed).
pub fn head_patting() -> Result<SceneConfig, SimError> {
    head_patting_of(HEAD_SEED, HEAD_PATS)
}

/// [`head_patting`] on the head of `seed`, with the first `pats` poses (at most
/// [`HEAD_PATS`]).
///
/// # Errors
/// Mesh errors from the head generator; [`SimError::InvalidParameter`] for `pats` = 0.
pub fn head_patting_of(seed: u64, pats: usize) -> Result<SceneConfig, SimError> {
    check_pats(pats, HEAD_PATS)?;
    let head = HeadParams::sample(seed);
    let mesh = head.mesh(HEAD_MESH_LEVEL)?;
    let mut keyframes = Vec::new();
    for (k, d) in pat_directions().iter().take(pats).enumerate() {
        let (p, n) = star_normal(|u| head.radius(u), d);
        let roll = 0.5 * k as Real;
        keyframes.extend(pat_keyframes(k as Real * PAT_PERIOD_SECS, |t, standoff| {
            pose_facing(t, &p, &n, standoff, roll)
        }));
    }
    Ok(patting_scene(keyframes, &mesh))
}

/// The arm-patting scene (the paper's arm under a gown): a two-finger hand pats the arm of seed
/// [`ARM_SEED`] (y along the arm, x outward, z up) at [`ARM_PATS`] poses — five stations along
/// the arm, each patted from above, from the outer side and between the two — with the fingers
/// lined up along the arm so that both land on it.
///
/// # Errors
/// Mesh errors from the arm generator (none for the fixed seed).
pub fn arm_patting() -> Result<SceneConfig, SimError> {
    arm_patting_of(ARM_SEED, ARM_PATS)
}

/// [`arm_patting`] on the arm of `seed`, with the first `pats` poses (at most [`ARM_PATS`]).
///
/// # Errors
/// Mesh errors from the arm generator; [`SimError::InvalidParameter`] for `pats` = 0.
pub fn arm_patting_of(seed: u64, pats: usize) -> Result<SceneConfig, SimError> {
    check_pats(pats, ARM_PATS)?;
    let arm = ArmParams::sample(seed);
    let mesh = arm.mesh(ARM_MESH_LEVEL)?;
    let mut keyframes = Vec::new();
    let mut k = 0;
    'stations: for (station, s) in [-0.6, -0.3, 0.0, 0.3, 0.6_f64].into_iter().enumerate() {
        // Snake order: consecutive pats are neighbours.
        let mut angles = [90.0, 50.0, 12.0];
        if station % 2 == 1 {
            angles.reverse();
        }
        for phi_deg in angles {
            if k == pats {
                break 'stations;
            }
            let phi = Real::to_radians(phi_deg);
            let q: Real = (1.0 - s * s).sqrt();
            let d = Vector3::new(q * phi.cos(), s, q * phi.sin());
            let (p, n) = mapped_normal(|u| arm.point(u), &d);
            keyframes.extend(pat_keyframes(k as Real * PAT_PERIOD_SECS, |t, standoff| {
                pose_facing_along(t, &p, &n, standoff, &Vector3::y())
            }));
            k += 1;
        }
    }
    Ok(patting_scene(keyframes, &mesh))
}

fn check_pats(pats: usize, most: usize) -> Result<(), SimError> {
    if pats == 0 || pats > most {
        return Err(SimError::InvalidParameter {
            name: "pats",
            value: pats as Real,
            reason: "must be at least 1 and at most the scene's number of poses",
        });
    }
    Ok(())
}

/// A two-finger hand moved through `keyframes` against a fixed body `mesh` (world frame).
fn patting_scene(keyframes: Vec<PoseKeyframe>, mesh: &moe_geom::TriMesh) -> SceneConfig {
    let duration = keyframes.last().map_or(0.0, |k| k.time_secs);
    SceneConfig {
        hand: PresetHandConfig {
            preset: HandPreset::TwoFinger,
            finger: FingerParams::default(),
        },
        duration_secs: duration,
        save_every_steps: 10,
        wrist: PoseTrajectory { keyframes },
        obstacles: vec![ObstacleConfig {
            shape: ObstacleShape::TriangleMesh {
                vertices_m: mesh.vertices().iter().map(|p| [p.x, p.y, p.z]).collect(),
                faces: mesh.faces().to_vec(),
            },
            trajectory: PoseTrajectory::default(),
        }],
        ..SceneConfig::default()
    }
}

/// The inclined-plate scene: a 190 × 130 mm plate on a 5 mm acrylic-like slab, inclined by
/// `incline_deg` about the world x axis, pressed from above by a three-finger hand held level
/// (fingers pointing down): approach from 2 cm above first touch, press 8 mm, hold, retract.
///
/// # Errors
/// [`SimError::InvalidParameter`] for an incline outside `[0°, 60°]`.
pub fn inclined_plate(incline_deg: Real) -> Result<SceneConfig, SimError> {
    if !(0.0..=60.0).contains(&incline_deg) {
        return Err(SimError::InvalidParameter {
            name: "incline_deg",
            value: incline_deg,
            reason: "must be in [0, 60]",
        });
    }
    let incline = incline_deg.to_radians();
    let finger = FingerParams::default();
    let palm = HandPreset::ThreeFinger.palm_radius_m();
    // Hand level, fingers down: hand z = world −z (a half turn about x).
    let down = Vector3::x() * PI;
    // The plate's top surface passes through the world origin with normal n = (0, −sin, cos).
    // The fingertip that touches first is the lowest one on the slope.
    let n = Vector3::new(0.0, -incline.sin(), incline.cos());
    let hand_rotation = UnitQuat::from_scaled_axis(down);
    let first_touch = (0..3)
        .map(|k| {
            let th = 2.0 * PI * k as Real / 3.0;
            // Centre of the hemispherical tip; the tip touches when the centre is one tip radius
            // above the plane.
            let tip_centre = Vector3::new(palm * th.cos(), palm * th.sin(), finger.cap_start_z());
            finger.tip_radius_m - (hand_rotation * tip_centre).dot(&n)
        })
        .fold(Real::MIN, Real::max);
    let at = |t: Real, extra: Real| PoseKeyframe {
        time_secs: t,
        translation_m: (n * (first_touch + extra)).into(),
        rotation_rad: down.into(),
    };
    let half_thickness = 0.0025;
    let rotation = Vector3::x() * incline;
    let centre = -n * half_thickness;
    Ok(SceneConfig {
        hand: PresetHandConfig {
            preset: HandPreset::ThreeFinger,
            finger,
        },
        duration_secs: 1.4,
        save_every_steps: 10,
        wrist: PoseTrajectory {
            keyframes: vec![
                at(0.0, 0.02),
                at(0.7, -0.008),
                at(1.0, -0.008),
                at(1.4, 0.02),
            ],
        },
        obstacles: vec![ObstacleConfig {
            shape: ObstacleShape::Cuboid {
                half_extents_m: [0.095, 0.065, half_thickness],
            },
            trajectory: PoseTrajectory::fixed(centre.into(), rotation.into()),
        }],
        ..SceneConfig::default()
    })
}

/// Seconds of one press of [`inclined_plate_press`]: approach until 0.7 s, hold until 1.0 s,
/// retract until 1.4 s.
pub const PLATE_PRESS_TIMES_SECS: [Real; 4] = [0.0, 0.7, 1.0, 1.4];

/// The inclined plate of [`inclined_plate`] pressed by the three-finger hand held at
/// `hand_rotation` (world from hand; the fingers point along the hand's z axis), moving along
/// its own axis toward the plate point `aim` (metres, in the plate's top plane or off it: the
/// hand's axis passes through it): from 2 cm before the first fingertip touches, to `press_m`
/// past first touch, hold, and back — the guarded move of a robot that does not know where the
/// plate is. Times are [`PLATE_PRESS_TIMES_SECS`].
///
/// # Errors
/// [`SimError::InvalidParameter`] for an incline outside `[0°, 60°]`, a negative press, or a
/// hand whose axis does not point into the plate (less than 20° from parallel to it).
pub fn inclined_plate_press(
    incline_deg: Real,
    hand_rotation: UnitQuat,
    aim: Point3,
    press_m: Real,
) -> Result<SceneConfig, SimError> {
    let mut config = inclined_plate(incline_deg)?;
    if !(press_m.is_finite() && press_m >= 0.0) {
        return Err(SimError::InvalidParameter {
            name: "press_m",
            value: press_m,
            reason: "must be finite and non-negative",
        });
    }
    let incline = incline_deg.to_radians();
    let n = Vector3::new(0.0, -incline.sin(), incline.cos());
    let axis = hand_rotation * Vector3::z();
    let into = n.dot(&axis);
    if into > -(20.0_f64.to_radians().sin()) {
        return Err(SimError::InvalidParameter {
            name: "hand_rotation",
            value: into,
            reason: "the hand's axis must point into the plate (at least 20° from parallel)",
        });
    }
    let finger = FingerParams::default();
    let palm = HandPreset::ThreeFinger.palm_radius_m();
    // The wrist at `aim − λ·axis`: fingertip k's sphere (centre `aim − λ·axis + tip_k`) touches
    // the top surface n·x = 0 when its centre is one tip radius above it, at λ = λ_k; coming
    // from far, the first to touch has the largest λ.
    let lambda_touch = (0..3)
        .map(|k| {
            let th = 2.0 * PI * k as Real / 3.0;
            let tip = hand_rotation
                * Vector3::new(palm * th.cos(), palm * th.sin(), finger.cap_start_z());
            (finger.tip_radius_m - n.dot(&(aim.coords + tip))) / -into
        })
        .fold(Real::MIN, Real::max);
    let [t0, t1, t2, t3] = PLATE_PRESS_TIMES_SECS;
    let at = |t: Real, lambda: Real| PoseKeyframe {
        time_secs: t,
        translation_m: (aim.coords - axis * lambda).into(),
        rotation_rad: hand_rotation.scaled_axis().into(),
    };
    config.duration_secs = t3;
    config.wrist = PoseTrajectory {
        keyframes: vec![
            at(t0, lambda_touch + 0.02),
            at(t1, lambda_touch - press_m),
            at(t2, lambda_touch - press_m),
            at(t3, lambda_touch + 0.02),
        ],
    };
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obstacle::Obstacle;

    #[test]
    fn head_pats_approach_along_the_surface_normal() {
        let config = head_patting().unwrap();
        assert_eq!(config.wrist.keyframes.len(), 5 * HEAD_PATS);
        let head = Obstacle::new(0, &config.obstacles[0]).unwrap();
        let length = FingerParams::default().length_m;
        // At every press keyframe the point between the fingertips is 6 mm inside the head, and
        // at every retreat keyframe 5 cm outside.
        for (k, key) in config.wrist.keyframes.iter().enumerate() {
            let pose = config.wrist.pose_at(key.time_secs);
            let tip_centre = pose * Point3::new(0.0, 0.0, length);
            let d = head
                .signed_distance(&moe_geom::Iso3::identity(), &tip_centre)
                .unwrap()
                .distance_m;
            let expected = [0.05, 0.03, -0.006, -0.006, 0.05][k % 5];
            assert!(
                (d - expected).abs() < 2e-3,
                "keyframe {k}: {d} vs {expected}"
            );
        }
    }

    #[test]
    fn a_press_along_the_hand_axis_starts_2_cm_away_and_ends_past_first_touch() {
        // A hand tilted 10° about y, aimed 5 mm off the plate's centre, on the 30° plate.
        let rotation = UnitQuat::from_scaled_axis(Vector3::x() * PI)
            * UnitQuat::from_axis_angle(&Vector3::y_axis(), 10f64.to_radians());
        let aim = Point3::new(0.005, 0.0, 0.0);
        let press = 0.006;
        let config = inclined_plate_press(30.0, rotation, aim, press).unwrap();
        let hand =
            moe_geom::HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default()).unwrap();
        // The plate's top surface is the plane n·x = 0 (the slab is 5 mm thick, so its signed
        // distance folds over past 2.5 mm of penetration: measure against the plane).
        let n = Vector3::new(0.0, -30f64.to_radians().sin(), 30f64.to_radians().cos());
        let into = -n.dot(&(rotation * Vector3::z()));
        let closest_at = |t: Real| {
            let wrist = config.wrist.pose_at(t);
            (0..3)
                .flat_map(|i| hand.rest_vertices_in_hand(i))
                .map(|p| n.dot(&(wrist * p).coords))
                .fold(Real::INFINITY, Real::min)
        };
        // 2 cm along the axis before first touch, `press` along it past first touch (the
        // surface mesh approximates the round tip within 0.3 mm).
        let start = closest_at(0.0);
        assert!(
            (start - 0.02 * into).abs() < 3e-4,
            "{start} vs {}",
            0.02 * into
        );
        let pressed = closest_at(PLATE_PRESS_TIMES_SECS[1]);
        assert!((pressed + press * into).abs() < 3e-4, "{pressed}");
        let parallel = UnitQuat::from_axis_angle(&Vector3::y_axis(), PI / 2.0);
        moe_geom::assert_err!(
            inclined_plate_press(30.0, parallel, aim, press),
            SimError::InvalidParameter {
                name: "hand_rotation",
                ..
            }
        );
        moe_geom::assert_err!(
            inclined_plate_press(30.0, rotation, aim, -1.0),
            SimError::InvalidParameter {
                name: "press_m",
                value,
                ..
            } if *value == -1.0
        );
    }

    #[test]
    fn inclined_plate_is_first_touched_at_the_end_of_the_approach_gap() {
        for deg in [0.0, 30.0, 45.0] {
            let config = inclined_plate(deg).unwrap();
            let plate = Obstacle::new(0, &config.obstacles[0]).unwrap();
            let pose = config.obstacles[0].trajectory.pose_at(0.0);
            let hand =
                moe_geom::HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default())
                    .unwrap();
            let wrist = config.wrist.pose_at(0.0);
            let closest = (0..3)
                .flat_map(|i| hand.rest_vertices_in_hand(i))
                .map(|p| {
                    plate
                        .signed_distance(&pose, &(wrist * p))
                        .unwrap()
                        .distance_m
                })
                .fold(Real::INFINITY, Real::min);
            // 2 cm of approach (the surface mesh approximates the round tip within 0.3 mm).
            assert!((0.0197..0.0203).contains(&closest), "{deg}°: {closest}");
        }
        moe_geom::assert_err!(
            inclined_plate(75.0),
            SimError::InvalidParameter {
                name: "incline_deg",
                value,
                ..
            } if *value == 75.0
        );
    }
}
