//! Randomised contact scenes for training data (paper §4.3.1): a hand carried by the wrist onto
//! a rigid object of a random family, size and orientation, pressing a random region (tip,
//! middle or base) of a random finger from a random direction, with random tendon actuation.
//!
//! Families cover the variety of the YCB objects the paper uses: boxes, spheres, cylinders,
//! capsules, thin plates, superquadrics, random convex hulls and a head-like shape. Every
//! choice is drawn from a [`SeededRng`](moe_geom::SeededRng) split by trajectory id, so a trajectory is a pure
//! function of `(seed, trajectory id)`.
//!
//! Placement: the contact target is a point of the chosen finger's rest surface (hand frame) with
//! its outward normal `n`. The object, in its random orientation, is translated so that its
//! extreme point toward the finger (its support point in direction `−n`) sits a small gap away
//! from the target along `n`. The object stays fixed in the world; the wrist moves the hand along
//! `n` by the gap plus a random press depth, holds, and retracts. Placements that would start in
//! contact with any finger are redrawn.
//!
//! The silicone ([`RandomSceneParams::material`](crate::randomize::RandomSceneParams::material))
//! and the tet-mesh resolution
//! ([`RandomSceneParams::voxel`](crate::randomize::RandomSceneParams::voxel)) are parameters,
//! not draws: a data set of a stiffer finger or a finer mesh draws exactly the scenes of the
//! default one.

use std::f64::consts::{PI, TAU};

use moe_geom::bodies::HeadParams;
use moe_geom::rng::SeededRng;
use moe_geom::shapes::Superquadric;
use moe_geom::{FingerParams, HandModel, HandPreset, Iso3, Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::contact::ContactParams;
use crate::error::{SimError, require_positive};
use crate::material::Material;
use crate::obstacle::{Obstacle, ObstacleConfig, ObstacleShape};
use crate::run::run_saving;
use crate::scene::{HandBodies, PresetHandConfig, Scene, SceneConfig, SimFrame};
use crate::surface::obstacle_surface;
use crate::trajectory::{ActuationKeyframe, ActuationSchedule, PoseKeyframe, PoseTrajectory};
use crate::voxelize::VoxelParams;

/// Object families of the randomised scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObjectFamily {
    /// Boxes (half extents 1–4 cm).
    Box,
    /// Spheres (radius 1–5 cm).
    Sphere,
    /// Cylinders (radius 1–4 cm, half height 2–6 cm).
    Cylinder,
    /// Capsules (radius 0.8–3 cm, half height 1–5 cm).
    Capsule,
    /// Thin plates (1–3 mm thick, 3–8 cm wide), faced toward the finger.
    ThinPlate,
    /// Superquadrics (half axes 1.5–4 cm, exponents 0.3–1.8).
    Superquadric,
    /// Convex hulls of 8–24 random points in a 2–5 cm box.
    ConvexHull,
    /// A head-like shape (a member of `moe_geom::bodies::HeadParams`).
    Head,
}

impl ObjectFamily {
    /// Every family, in the order of their dataset codes.
    pub const ALL: [ObjectFamily; 8] = [
        Self::Box,
        Self::Sphere,
        Self::Cylinder,
        Self::Capsule,
        Self::ThinPlate,
        Self::Superquadric,
        Self::ConvexHull,
        Self::Head,
    ];

    /// Stable name (the data set card's family names).
    pub fn name(self) -> &'static str {
        match self {
            Self::Box => "box",
            Self::Sphere => "sphere",
            Self::Cylinder => "cylinder",
            Self::Capsule => "capsule",
            Self::ThinPlate => "thin_plate",
            Self::Superquadric => "superquadric",
            Self::ConvexHull => "convex_hull",
            Self::Head => "head",
        }
    }

    /// Index in [`ObjectFamily::ALL`].
    pub fn code(self) -> u8 {
        Self::ALL.iter().position(|f| *f == self).unwrap_or(0) as u8
    }
}

/// Region of the finger that the object presses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FingerRegion {
    /// The last 20 % of the length, the rounded tip included.
    Tip,
    /// 40–70 % of the length.
    Middle,
    /// 12–35 % of the length.
    Base,
    /// The end of the rounded tip, pressed along the finger's axis or nearly (cap points 45–90°
    /// from the radial direction): what patting a surface or pressing a plate with the
    /// fingertips loads. [`FingerRegion::Tip`] stops at 44°.
    Apex,
}

impl FingerRegion {
    /// The regions the randomisation draws from unless told otherwise.
    pub const DEFAULT: [FingerRegion; 3] = [Self::Tip, Self::Middle, Self::Base];
}

impl FingerRegion {
    /// Fraction of the press depth range used in this region (1 at the tip and the apex, 0.35 at
    /// the base).
    pub fn press_scale(self) -> Real {
        match self {
            Self::Tip | Self::Apex => 1.0,
            Self::Middle => 0.7,
            Self::Base => 0.35,
        }
    }
}

/// Number of object parameters stored per frame (zero-padded).
pub const OBJECT_PARAM_LEN: usize = 8;

/// Ranges of the randomisation. SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RandomSceneParams {
    /// Hand layout.
    pub preset: HandPreset,
    /// Finger geometry.
    pub finger: FingerParams,
    /// Families to draw from (uniformly).
    pub families: Vec<ObjectFamily>,
    /// Finger regions to press (uniformly). Default [`FingerRegion::DEFAULT`].
    pub regions: Vec<FingerRegion>,
    /// Gap between the object and the target at the start, metres. Default 0.003.
    pub gap_m: Real,
    /// Press depth range beyond first touch at the tip, metres (scaled by
    /// [`FingerRegion::press_scale`] elsewhere). Default 2–8 mm.
    pub press_depth_m: [Real; 2],
    /// Largest tendon pull, metres. Default 0.006.
    pub max_pull_m: Real,
    /// Time to reach full press, seconds. Default 0.5.
    pub press_secs: Real,
    /// Hold time, seconds. Default 0.2.
    pub hold_secs: Real,
    /// Retract time, seconds. Default 0.3.
    pub retract_secs: Real,
    /// Time step, seconds. Default 0.01.
    pub dt_secs: Real,
    /// A frame is kept every this many steps. Default 5.
    pub save_every_steps: u64,
    /// Contact model and label rule of the scenes. Default [`ContactParams::default`]
    /// (the press rule).
    pub contact: ContactParams,
    /// Silicone of every finger (`[material]` in a parameter file, e.g.
    /// `youngs_modulus_pa = 125000.0` for a stiffer finger). Default [`Material::default`],
    /// the paper's 100 kPa.
    pub material: Material,
    /// Tet-mesh resolution of every finger (`[voxel]`, e.g. `cell_size_m = 0.0025` for a finer
    /// mesh). Default [`VoxelParams::default`], 3.5 mm cells.
    pub voxel: VoxelParams,
    /// How the hand is held: the rotation from the hand frame to the world at rest, as an
    /// axis-angle vector (axis × angle), radians. Gravity stays along the world's −z, so this
    /// turns the hand relative to gravity; the object and the press turn with the hand. Default
    /// zero: fingers up, gravity along the hand's −z. `[1.5707963267948966, 0.0, 0.0]` holds
    /// the hand horizontal with gravity across the fingers' sides, `[0.0, 1.5707963267948966,
    /// 0.0]` horizontal with gravity from one finger toward the other (two-finger preset), and
    /// `[3.141592653589793, 0.0, 0.0]` upside down.
    #[serde(skip_serializing_if = "is_zero_rotation")]
    pub hand_rotation_rad: [Real; 3],
}

fn is_zero_rotation(r: &[Real; 3]) -> bool {
    r.iter().all(crate::is_zero)
}

impl Default for RandomSceneParams {
    fn default() -> Self {
        Self {
            preset: HandPreset::TwoFinger,
            finger: FingerParams::default(),
            families: ObjectFamily::ALL.to_vec(),
            regions: FingerRegion::DEFAULT.to_vec(),
            gap_m: 0.003,
            press_depth_m: [0.002, 0.008],
            max_pull_m: 0.006,
            press_secs: 0.5,
            hold_secs: 0.2,
            retract_secs: 0.3,
            dt_secs: 0.01,
            save_every_steps: 5,
            contact: ContactParams::default(),
            material: Material::default(),
            voxel: VoxelParams::default(),
            hand_rotation_rad: [0.0; 3],
        }
    }
}

/// A sampled scene and what was drawn for it.
#[derive(Debug, Clone, PartialEq)]
pub struct SampledScene {
    /// The runnable scene description.
    pub config: SceneConfig,
    /// Object family.
    pub family: ObjectFamily,
    /// The family's parameters, zero-padded to [`OBJECT_PARAM_LEN`].
    pub object_params: [Real; OBJECT_PARAM_LEN],
    /// The pressed finger.
    pub finger: usize,
    /// The pressed region.
    pub region: FingerRegion,
    /// Target point on the rest surface, hand frame.
    pub target_in_hand: Point3,
    /// Outward surface normal at the target, hand frame (the object comes from this side).
    pub normal_in_hand: Vector3,
}

/// Attempts at a placement that starts clear of every finger before giving up.
const MAX_ATTEMPTS: usize = 64;

/// Draws the scene of trajectory `trajectory_id` of a data set with `seed`.
///
/// # Errors
/// Invalid parameters, or no clear placement found in 64 draws (reported as
/// [`SimError::InvalidObstacle`]).
pub fn sample_scene(
    params: &RandomSceneParams,
    seed: u64,
    trajectory_id: u64,
) -> Result<SampledScene, SimError> {
    validate(params)?;
    let hand = HandModel::preset(params.preset, &params.finger)?;
    let rest: Vec<Vec<Point3>> = (0..hand.num_fingers())
        .map(|i| hand.rest_vertices_in_hand(i))
        .collect();
    let mut rng = SeededRng::new(seed).split(trajectory_id);
    for _ in 0..MAX_ATTEMPTS {
        let family = params.families[rng.below(params.families.len() as u64) as usize];
        let finger = rng.below(hand.num_fingers() as u64) as usize;
        let region = params.regions[rng.below(params.regions.len() as u64) as usize];
        let (target_f, normal_f) = target_on_finger(&params.finger, region, &mut rng);
        let hff = hand.fingers()[finger].hand_from_finger;
        let target = hff.transform_point(&target_f);
        let normal = hff.transform_vector(&normal_f);
        let (shape, object_params) = sample_object(family, &normal, &mut rng)?;
        let rotation = if family == ObjectFamily::ThinPlate {
            plate_rotation(&normal, &mut rng)
        } else {
            random_rotation(&mut rng)
        };
        // Support point of the rotated object toward the finger.
        let (surface, _) = obstacle_surface(&shape)?;
        let support = surface
            .iter()
            .map(|p| rotation * p.coords)
            .min_by(|a, b| a.dot(&normal).total_cmp(&b.dot(&normal)))
            .ok_or_else(|| SimError::InvalidObstacle {
                obstacle: 0,
                reason: "empty surface".into(),
            })?;
        let translation = target.coords + normal * params.gap_m - support;
        let world_from_object = Iso3::from_parts(translation.into(), rotation);
        // The object is placed in the hand frame and turned with the hand into the world.
        let world_from_hand = hand_rotation(params);
        let placement = PoseTrajectory::fixed(
            (world_from_hand * translation).into(),
            (world_from_hand * rotation).scaled_axis().into(),
        );
        let obstacle_config = ObstacleConfig {
            shape,
            trajectory: placement,
        };
        // Start clear of every finger.
        let obstacle = Obstacle::new(0, &obstacle_config)?;
        let clear = rest.iter().flatten().all(|p| {
            obstacle
                .signed_distance(&world_from_object, p)
                .is_some_and(|s| s.distance_m > 0.5 * params.gap_m)
        });
        if !clear {
            continue;
        }
        // The finger is stiffer toward its fixed base, where a deep press would only push the
        // rigid object into the silicone: presses scale down from the tip to the base.
        let depth = region.press_scale()
            * rng.uniform_range(params.press_depth_m[0], params.press_depth_m[1]);
        let config = build_config(
            params,
            &hand,
            normal * (params.gap_m + depth),
            obstacle_config,
            &mut rng,
        );
        return Ok(SampledScene {
            config,
            family,
            object_params,
            finger,
            region,
            target_in_hand: target,
            normal_in_hand: normal,
        });
    }
    Err(SimError::InvalidObstacle {
        obstacle: 0,
        reason: format!(
            "no placement clear of the hand in {MAX_ATTEMPTS} draws (trajectory {trajectory_id})"
        ),
    })
}

impl RandomSceneParams {
    /// Checks the parameters ([`sample_scene`] does too, on every draw).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the first bad one: no family or region, an invalid
    /// contact model or material (e.g. `youngs_modulus_pa` ≤ 0), a non-positive
    /// `voxel cell_size_m`, a bad press-depth range, or a non-positive or non-finite time,
    /// gap or pull.
    pub fn validate(&self) -> Result<(), SimError> {
        validate(self)
    }
}

fn validate(params: &RandomSceneParams) -> Result<(), SimError> {
    let bad = |name, value, reason| {
        Err(SimError::InvalidParameter {
            name,
            value,
            reason,
        })
    };
    if params.families.is_empty() {
        return bad("families", 0.0, "at least one object family is needed");
    }
    if params.regions.is_empty() {
        return bad("regions", 0.0, "at least one finger region is needed");
    }
    params.contact.validate()?;
    params.material.validate()?;
    require_positive("voxel cell_size_m", params.voxel.cell_size_m)?;
    let [lo, hi] = params.press_depth_m;
    if !(lo >= 0.0 && hi >= lo && hi.is_finite()) {
        return bad("press_depth_m", hi, "must be a non-negative range [lo, hi]");
    }
    for (name, v) in [
        ("gap_m", params.gap_m),
        ("press_secs", params.press_secs),
        ("retract_secs", params.retract_secs),
        ("dt_secs", params.dt_secs),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return bad(name, v, "must be finite and positive");
        }
    }
    for (name, v) in [
        ("hold_secs", params.hold_secs),
        ("max_pull_m", params.max_pull_m),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return bad(name, v, "must be finite and non-negative");
        }
    }
    if params.save_every_steps == 0 {
        return bad("save_every_steps", 0.0, "must be positive");
    }
    if let Some(&r) = params.hand_rotation_rad.iter().find(|r| !r.is_finite()) {
        return bad("hand_rotation_rad", r, "must be finite");
    }
    Ok(())
}

/// The hand's orientation in the world ([`RandomSceneParams::hand_rotation_rad`]).
fn hand_rotation(params: &RandomSceneParams) -> moe_geom::math::UnitQuat {
    moe_geom::math::UnitQuat::from_scaled_axis(Vector3::from(params.hand_rotation_rad))
}

/// A point of the finger's rest surface in `region` and its outward normal, finger frame.
fn target_on_finger(
    f: &FingerParams,
    region: FingerRegion,
    rng: &mut SeededRng,
) -> (Point3, Vector3) {
    let (lo, hi): (Real, Real) = match region {
        FingerRegion::Tip => (0.8, 1.0),
        FingerRegion::Middle => (0.4, 0.7),
        FingerRegion::Base => (0.12, 0.35),
        FingerRegion::Apex => {
            // Elevation above the cap's equator uniform in [45°, 90°).
            let phi = rng.uniform_range(0.0, TAU);
            let theta = rng.uniform_range(0.25 * PI, 0.5 * PI);
            let n = Vector3::new(
                theta.cos() * phi.cos(),
                theta.cos() * phi.sin(),
                theta.sin(),
            );
            return (
                Point3::new(0.0, 0.0, f.cap_start_z()) + n * f.tip_radius_m,
                n,
            );
        }
    };
    let phi = rng.uniform_range(0.0, TAU);
    let zc = f.cap_start_z();
    let z = f.length_m * rng.uniform_range(lo, hi.min(0.97));
    if z <= zc {
        let r = f.radius_at(z);
        // The body is a cone frustum: its normal tilts by the taper angle.
        let slope = (f.base_radius_m - f.tip_radius_m) / zc;
        let n = Vector3::new(phi.cos(), phi.sin(), slope).normalize();
        (Point3::new(r * phi.cos(), r * phi.sin(), z), n)
    } else {
        let theta = ((z - zc) / f.tip_radius_m).clamp(-1.0, 1.0).asin();
        let n = Vector3::new(
            theta.cos() * phi.cos(),
            theta.cos() * phi.sin(),
            theta.sin(),
        );
        (Point3::new(0.0, 0.0, zc) + n * f.tip_radius_m, n)
    }
}

fn random_rotation(rng: &mut SeededRng) -> moe_geom::math::UnitQuat {
    // Uniform on SO(3): a normalised 4-D Gaussian.
    let q = nalgebra_quat(rng.normal(), rng.normal(), rng.normal(), rng.normal());
    moe_geom::math::UnitQuat::from_quaternion(q)
}

fn nalgebra_quat(w: Real, i: Real, j: Real, k: Real) -> moe_geom::nalgebra::Quaternion<Real> {
    moe_geom::nalgebra::Quaternion::new(w, i, j, k)
}

/// A rotation taking the plate's thin axis (x) onto the target normal, with a random roll.
fn plate_rotation(normal: &Vector3, rng: &mut SeededRng) -> moe_geom::math::UnitQuat {
    let align = moe_geom::math::UnitQuat::rotation_between(&Vector3::x(), normal)
        .unwrap_or_else(|| moe_geom::math::UnitQuat::from_axis_angle(&Vector3::z_axis(), PI));
    let roll =
        moe_geom::math::UnitQuat::from_axis_angle(&Vector3::x_axis(), rng.uniform_range(0.0, TAU));
    align * roll
}

fn sample_object(
    family: ObjectFamily,
    _normal: &Vector3,
    rng: &mut SeededRng,
) -> Result<(ObstacleShape, [Real; OBJECT_PARAM_LEN]), SimError> {
    let mut p = [0.0; OBJECT_PARAM_LEN];
    let mut u = |lo: Real, hi: Real| rng.uniform_range(lo, hi);
    let shape = match family {
        ObjectFamily::Box => {
            let h = [u(0.01, 0.04), u(0.01, 0.04), u(0.01, 0.04)];
            p[..3].copy_from_slice(&h);
            ObstacleShape::Cuboid { half_extents_m: h }
        }
        ObjectFamily::Sphere => {
            p[0] = u(0.01, 0.05);
            ObstacleShape::Ball { radius_m: p[0] }
        }
        ObjectFamily::Cylinder => {
            p[0] = u(0.01, 0.04);
            p[1] = u(0.02, 0.06);
            ObstacleShape::Cylinder {
                radius_m: p[0],
                half_height_m: p[1],
            }
        }
        ObjectFamily::Capsule => {
            p[0] = u(0.008, 0.03);
            p[1] = u(0.01, 0.05);
            ObstacleShape::Capsule {
                radius_m: p[0],
                half_height_m: p[1],
            }
        }
        ObjectFamily::ThinPlate => {
            let h = [u(0.0005, 0.0015), u(0.015, 0.04), u(0.015, 0.04)];
            p[..3].copy_from_slice(&h);
            ObstacleShape::Cuboid { half_extents_m: h }
        }
        ObjectFamily::Superquadric => {
            let q = Superquadric {
                half_axes_m: [u(0.015, 0.04), u(0.015, 0.04), u(0.015, 0.04)],
                e1: u(0.3, 1.8),
                e2: u(0.3, 1.8),
            };
            p[..3].copy_from_slice(&q.half_axes_m);
            p[3] = q.e1;
            p[4] = q.e2;
            mesh_shape(&q.mesh(3)?)
        }
        ObjectFamily::ConvexHull => {
            let n = 8 + rng.below(17) as usize;
            let half = [
                rng.uniform_range(0.01, 0.025),
                rng.uniform_range(0.01, 0.025),
                rng.uniform_range(0.01, 0.025),
            ];
            p[0] = n as Real;
            p[1..4].copy_from_slice(&half);
            let points_m = (0..n)
                .map(|_| [0, 1, 2].map(|k| rng.uniform_range(-half[k], half[k])))
                .collect();
            ObstacleShape::ConvexHull { points_m }
        }
        ObjectFamily::Head => {
            let head_seed = rng.next_u64();
            let head = HeadParams::sample(head_seed);
            p[0] = head.half_width;
            p[1] = head.half_length;
            p[2] = head.half_height;
            // The 53 low bits of the seed, exactly representable, identify the head.
            p[3] = (head_seed >> 11) as Real;
            mesh_shape(&head.mesh(3)?)
        }
    };
    Ok((shape, p))
}

fn mesh_shape(mesh: &moe_geom::TriMesh) -> ObstacleShape {
    ObstacleShape::TriangleMesh {
        vertices_m: mesh.vertices().iter().map(|p| [p.x, p.y, p.z]).collect(),
        faces: mesh.faces().to_vec(),
    }
}

/// The scene: object fixed in the world, wrist pressing along `press` and back, tendons ramped
/// to random pulls during the approach.
fn build_config(
    params: &RandomSceneParams,
    hand: &HandModel,
    press: Vector3,
    obstacle: ObstacleConfig,
    rng: &mut SeededRng,
) -> SceneConfig {
    let t1 = params.press_secs;
    let t2 = t1 + params.hold_secs;
    let t3 = t2 + params.retract_secs;
    // The wrist holds the hand's orientation and moves along the press turned into the world.
    let world_from_hand = hand_rotation(params);
    let press = world_from_hand * press;
    let keyframe = |time_secs, translation: Vector3| PoseKeyframe {
        time_secs,
        translation_m: translation.into(),
        rotation_rad: world_from_hand.scaled_axis().into(),
    };
    let mut wrist = vec![keyframe(0.0, Vector3::zeros()), keyframe(t1, press)];
    if params.hold_secs > 0.0 {
        wrist.push(keyframe(t2, press));
    }
    wrist.push(keyframe(t3, Vector3::zeros()));
    let actuation = hand
        .fingers()
        .iter()
        .map(|f| {
            let n = f.model.tendon_routes().len();
            let mut values = vec![0.0; n];
            // Each antagonistic pair is driven like a pulley on one servo: one side pulled by
            // `d`, the other paid out by `d` (a slack cable), in 70 % of the pairs.
            for (j, route) in f.model.tendon_routes().iter().enumerate() {
                if j < route.antagonist && rng.uniform() < 0.7 {
                    let d = rng.uniform_range(-params.max_pull_m, params.max_pull_m);
                    values[j] = d;
                    values[route.antagonist] = -d;
                }
            }
            ActuationSchedule {
                keyframes: vec![
                    ActuationKeyframe {
                        time_secs: 0.0,
                        values: vec![0.0; n],
                    },
                    ActuationKeyframe {
                        time_secs: 0.6 * t1,
                        values,
                    },
                ],
                ..ActuationSchedule::default()
            }
        })
        .collect();
    let mut config = SceneConfig {
        hand: PresetHandConfig {
            preset: params.preset,
            finger: params.finger.clone(),
        },
        duration_secs: t3,
        save_every_steps: params.save_every_steps,
        wrist: PoseTrajectory { keyframes: wrist },
        actuation,
        obstacles: vec![obstacle],
        contact: params.contact.clone(),
        material: params.material.clone(),
        voxel: params.voxel.clone(),
        ..SceneConfig::default()
    };
    config.solver.dt_secs = params.dt_secs;
    // The hand has been held still before the press: its fingers start in their free
    // equilibrium under gravity, not in the unloaded rest shape (4.6 mm apart at a horizontal
    // fingertip).
    config.solver.settled_start = true;
    config
}

/// Samples and simulates trajectory `trajectory_id` of a data set with `seed`.
///
/// # Errors
/// As [`sample_scene`], [`Scene::new`] and [`run_saving`].
pub fn simulate_trajectory(
    params: &RandomSceneParams,
    seed: u64,
    trajectory_id: u64,
) -> Result<(SampledScene, Scene, Vec<SimFrame>), SimError> {
    let sampled = sample_scene(params, seed, trajectory_id)?;
    let mut scene = Scene::new(sampled.config.clone())?;
    let steps = scene.num_steps();
    let frames = run_saving(&mut scene, steps)?;
    Ok((sampled, scene, frames))
}

/// The finger bodies every trajectory of a data set with `params` shares (its hand, material
/// and resolution), for [`simulate_trajectory_with`].
///
/// # Errors
/// An invalid hand, material or resolution.
pub fn hand_bodies(params: &RandomSceneParams) -> Result<HandBodies, SimError> {
    let hand = HandModel::preset(params.preset, &params.finger)?;
    HandBodies::new(hand, &params.material, &params.voxel)
}

/// [`simulate_trajectory`] on finger bodies built once for the data set ([`hand_bodies`]):
/// the same frames, without voxelising the fingers again for every trajectory.
///
/// # Errors
/// As [`sample_scene`], [`Scene::with_bodies`] and [`run_saving`].
pub fn simulate_trajectory_with(
    params: &RandomSceneParams,
    bodies: &HandBodies,
    seed: u64,
    trajectory_id: u64,
) -> Result<(SampledScene, Scene, Vec<SimFrame>), SimError> {
    let sampled = sample_scene(params, seed, trajectory_id)?;
    let mut scene = Scene::with_bodies(sampled.config.clone(), bodies)?;
    let steps = scene.num_steps();
    let frames = run_saving(&mut scene, steps)?;
    Ok((sampled, scene, frames))
}

#[cfg(test)]
mod tests;
