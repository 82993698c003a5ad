//! Grasping paper on an unknown incline (paper §6.2, Table 4): the three-finger hand presses an
//! inclined plate from a misaligned start, the pipeline estimates the contacts, a plane is fitted,
//! the hand turns its axis onto the plane's normal and presses again. The simulator judges the
//! last press.
//!
//! **The plane.** From a press's hold, RANSAC through the estimated contact points (the paper's
//! fit) — unless three or more fingers are *loaded*, in which case the plane goes through their
//! seen tips ([`PlaneSource`](crate::grasp::PlaneSource)). The hand is not actuated during the
//! grasp, so a finger whose estimated shape has moved from rest is one the plate pushes: which
//! fingers touch comes from their deformation, not from the contact classifier, and the plane
//! is spanned by points tens of millimetres apart instead of by one fingertip's patch. A level
//! hand touches a slope with one finger, so the first plane there is a patch's; with
//! [`GraspOptions::refinements`](crate::grasp::GraspOptions::refinements) the hand turns onto
//! the latest plane, presses again (now with more fingers down; deeper when fewer than three
//! are loaded) and fits again before the judged press. `refinements = 0` without the
//! fingertip plane is the paper's protocol.
//!
//! **Success** is the state from which the paper's hand folds the sheet: at the deepest point of
//! the judged press every finger touches the plate (at least
//! [`GraspOptions::min_contact_vertices`](crate::grasp::GraspOptions::min_contact_vertices)
//! labelled vertices each) and the hand's axis is within
//! [`GraspOptions::max_axis_error_deg`](crate::grasp::GraspOptions::max_axis_error_deg) of the
//! plate's normal, so the palm faces the sheet squarely. Without MOE-Touch the hand keeps its
//! initial orientation: the judged press is its first.

use moe_geom::math::UnitQuat;
use moe_geom::{
    ContactEstimator, ContactPoint, HandEstimator, HandModel, HandShape, Point3, RansacConfig,
    Real, SeededRng, Staged, Vector3, fit_plane_ransac,
};
use moe_tendon_sim::paper_scenes::{PLATE_PRESS_TIMES_SECS, inclined_plate_press};
use moe_tendon_sim::{Scene, SimFrame, run_saving};
use serde::Serialize;

use crate::LabError;
use crate::episode::{EpisodeRecorder, saved_frame_at};
use moe_arap::{MultiShapeEstimator, ShapeConfig};
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::pipeline::{PhysicsPipeline, Pipeline};

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
    /// The plane fit through the contact points.
    pub ransac: RansacConfig,
    /// Presses that refine the plane before the judged one: each turns the hand onto the
    /// latest fitted normal, presses and fits again. 0 is the paper's protocol (one fit, one
    /// reorientation, the judged press). Default 2.
    pub refinements: usize,
    /// A finger is *loaded* when some vertex of its estimated shape lies farther than this from
    /// its rest position, metres. The hand is not actuated during the grasp, so a loaded finger
    /// is one the plate pushes (free fingers move 0.1–1.3 mm under the camera's noise, pressed
    /// ones 4.6–22 mm). Default 3 mm.
    pub loaded_finger_m: Real,
    /// A refining press that loads fewer than three fingers is repeated this far past first
    /// touch, so that more fingers reach the plate and their tips give the plane (a robot's
    /// guarded move pressing on until more of the hand touches); at most
    /// [`GraspOptions::press_m`] disables it. The judged press keeps `press_m`. Default 16 mm.
    pub deeper_press_m: Real,
    /// When at least [`GraspOptions::min_loaded_fingers`] fingers are loaded, fit the plane
    /// through their tips (see [`PlaneSource::LoadedFingertips`]) instead of through the
    /// contact points. Default true.
    pub fingertip_plane: bool,
    /// Loaded fingers the fingertip plane needs (fewer, and a refining press goes
    /// [`GraspOptions::deeper_press_m`] deep; fewer still there, and the plane goes through the
    /// contact points). Default 3: three tips span a plane.
    pub min_loaded_fingers: usize,
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
            refinements: 2,
            deeper_press_m: 0.016,
            loaded_finger_m: 0.003,
            fingertip_plane: true,
            min_loaded_fingers: 3,
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

/// What a plane was fitted through.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PlaneSource {
    /// RANSAC through the contact points of the press's hold (the paper's fit).
    ContactPoints,
    /// The plane through the tips of the loaded fingers, when three or more are loaded and the
    /// tips of at least three of them were seen: per such finger the vertex of its estimated
    /// shape farthest along the press, averaged over the hold frames in which it is loaded and
    /// its most distal marker seen. Which fingers touch comes from their deformation, not from
    /// the contact classifier, so a finger whose contacts the classifier misses still counts,
    /// and contacts placed up a finger do not tilt the plane.
    LoadedFingertips,
    /// Three or more fingers loaded but only two tips seen (a finger pressed along its axis
    /// hides its distal markers from the wrist camera, and its estimated tip is then
    /// extrapolated): the plane through the two seen tips whose normal is nearest the hand's
    /// axis. All fingers touching says the axis is near the normal; the seen tips fix the rest.
    TwoFingertipsAndAxis,
    /// Three or more fingers loaded and fewer than two tips seen: the hand's own axis (all
    /// fingers touching says the palm already faces the plate; no tips say better).
    LoadedFingersAxis,
}

/// One plane fitted from one press, and the press that turned onto it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlaneStep {
    /// How far past first touch the press this plane was fitted from went, metres.
    pub press_depth_m: Real,
    /// What the plane was fitted through (`None` when the fit failed).
    pub source: Option<PlaneSource>,
    /// Fingers whose estimated shape shows a load ([`GraspOptions::loaded_finger_m`]).
    pub loaded_fingers: Vec<usize>,
    /// Contact points of the press's hold (the pipeline's estimates, or the simulator's
    /// labels).
    pub estimated_contacts: usize,
    /// RANSAC inliers among them (0 when the plane went through the fingertips).
    pub inliers: usize,
    /// The seen tips of the loaded fingers, world frame, in finger order (what a fingertip
    /// plane goes through).
    pub tips: Vec<[Real; 3]>,
    /// The fitted plane's unit normal (toward the hand), world frame.
    pub estimated_normal: Option<[Real; 3]>,
    /// The incline of the fitted plane, degrees (angle of its normal from vertical).
    pub estimated_incline_deg: Option<Real>,
    /// Angle between the fitted and the true normal, degrees.
    pub normal_error_deg: Option<Real>,
    /// Why the fit (or the press onto it) failed, if it did.
    pub fit_error: Option<String>,
    /// The press with the hand's axis turned onto this plane's normal, at
    /// [`GraspOptions::press_m`] (the judged depth).
    pub press: Option<PressOutcome>,
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
    /// Every plane fitted, in order: from the first press's hold, then from each refining
    /// press's. A failed fit ends the list (the hand stays on the plane before it).
    pub fits: Vec<PlaneStep>,
    /// The estimated incline: the last fitted plane's, degrees.
    pub estimated_incline_deg: Option<Real>,
    /// Angle between the last fitted plane's normal and the true one, degrees.
    pub normal_error_deg: Option<Real>,
    /// The judged press, onto the last fitted plane; `None` when the first fit failed or the
    /// press could not be simulated (the trial fails).
    pub final_press: Option<PressOutcome>,
    /// Success with MOE-Touch: the judged press succeeded.
    pub success_with: bool,
    /// Success without: the first press succeeded.
    pub success_without: bool,
    /// The contact points of the last observed press's hold (the one the last entry of `fits`
    /// came from), world frame (probability 1 for the simulator's labels); for display, not
    /// serialised.
    #[serde(skip)]
    pub plane_points: Vec<ContactPoint>,
    /// Indices into `plane_points` of the RANSAC inliers (empty when the plane went through
    /// the fingertips, or the fit failed).
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
) -> Result<(Scene, Vec<SimFrame>), LabError> {
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

/// Where a trial's contacts come from.
// One value per trial: the physics settings' size is of no consequence.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
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
    /// The pipeline on the wrist camera's frames with the physics estimator as its shape and
    /// contact stages (the default of `moe-touch run`).
    Physics {
        /// The hand's material.
        material: moe_physics::HandMaterial,
        /// The estimator's settings.
        config: moe_physics::PhysicsConfig,
    },
    /// The simulator's own contact vertices and shapes (the upper bound a perfect estimator
    /// reaches).
    Simulator,
}

/// One press seen through the contact source: how it ended, and the plane fitted from its hold.
struct ObservedPress {
    outcome: PressOutcome,
    step: PlaneStep,
    normal: Option<Vector3>,
    plane_points: Vec<ContactPoint>,
    inlier_indices: Vec<usize>,
    true_points: Vec<ContactPoint>,
}

/// One finger in one hold frame, world frame.
struct FingerState {
    /// Its vertices.
    at: Vec<Point3>,
    /// The largest distance of a vertex from its rest position, metres.
    displacement: Real,
    /// Whether its most distal marker was seen: without it the shape estimate extrapolates the
    /// tip (a hidden tip of a finger pressed along its axis was placed 5.8–7.8 mm past the plate,
    /// at the uncompressed length, where the seen ones were within 2.3 mm).
    tip_seen: bool,
}

impl FingerState {
    /// The finite vertex farthest along `axis`.
    fn tip(&self, axis: &Vector3) -> Option<Point3> {
        self.at
            .iter()
            .filter(|p| moe_geom::math::is_finite_point(p))
            .max_by(|a, b| axis.dot(&a.coords).total_cmp(&axis.dot(&b.coords)))
            .copied()
    }
}

/// The largest distance of a vertex from its rest position (vertices in the same frame as the
/// rest positions; non-finite distances skipped).
fn largest_displacement(at: &[Point3], rest: &[Point3]) -> Real {
    at.iter()
        .zip(rest)
        .map(|(a, r)| (a - r).norm())
        .filter(|d| d.is_finite())
        .fold(0.0, Real::max)
}

/// The loaded fingers of a hold (a finger is loaded when it is loaded in any hold frame) and the tips
/// of those whose tip was seen while loaded: per such finger, its vertex farthest along `axis`
/// averaged over the hold frames in which it is loaded and its tip seen.
fn loaded_fingertips(
    shapes: &[Vec<FingerState>],
    axis: &Vector3,
    options: &GraspOptions,
) -> (Vec<usize>, Vec<Point3>) {
    let fingers = shapes.first().map_or(0, Vec::len);
    let mut loaded = Vec::new();
    let mut tips = Vec::new();
    for finger in 0..fingers {
        let states = shapes
            .iter()
            .filter_map(|s| s.get(finger))
            .filter(|f| f.displacement > options.loaded_finger_m);
        let mut any = false;
        let seen: Vec<Point3> = states
            .inspect(|_| any = true)
            .filter(|f| f.tip_seen)
            .filter_map(|f| f.tip(axis))
            .collect();
        if any {
            loaded.push(finger);
        }
        if !seen.is_empty() {
            let mean = seen.iter().map(|p| p.coords).sum::<Vector3>() / seen.len() as Real;
            tips.push(Point3::from(mean));
        }
    }
    (loaded, tips)
}

/// Per finger, the index of its most distal marker
/// ([`moe_geom::FingerModel::distal_marker_order`]).
fn distal_markers(hand: &HandModel) -> Vec<usize> {
    hand.fingers()
        .iter()
        .map(|f| f.model.distal_marker_order().first().copied().unwrap_or(0))
        .collect()
}

/// Whether a press's frame is in its hold (the stretch at full depth).
fn in_hold(frame: &SimFrame) -> bool {
    let [_, hold_start, hold_end, _] = PLATE_PRESS_TIMES_SECS;
    let t = frame.time_secs;
    t >= hold_start - 1e-9 && t <= hold_end + 1e-9
}

/// The simulator's shape of a frame (every tip seen).
fn simulated_hold_shape(frame: &SimFrame, rest: &HandShape) -> Vec<FingerState> {
    frame
        .fingers
        .iter()
        .zip(&rest.fingers)
        .map(|(f, r)| {
            let at_rest: Vec<Point3> = r.iter().map(|p| frame.world_from_hand * p).collect();
            FingerState {
                displacement: largest_displacement(&f.vertices_in_world, &at_rest),
                at: f.vertices_in_world.clone(),
                tip_seen: true,
            }
        })
        .collect()
}

/// The plane's normal from the loaded fingers (see [`PlaneSource`]), on `prior`'s side:
/// through three or more seen tips by least squares; through two, the plane containing them
/// whose normal is nearest `prior` (the hand's axis); with fewer, `prior`. `None` with fewer
/// than `min_loaded` loaded fingers, or when the tips do not span a plane.
fn fingertip_plane(
    loaded: usize,
    min_loaded: usize,
    tips: &[Point3],
    prior: &Vector3,
    ransac: &RansacConfig,
) -> Option<(PlaneSource, Vector3)> {
    if loaded < min_loaded {
        return None;
    }
    match tips {
        [a, b] => {
            let line = (b - a).try_normalize(1e-9)?;
            let n = (prior - line * line.dot(prior)).try_normalize(1e-6)?;
            n.iter()
                .all(|c| c.is_finite())
                .then_some((PlaneSource::TwoFingertipsAndAxis, n))
        }
        [] | [_] => Some((PlaneSource::LoadedFingersAxis, *prior)),
        _ => {
            let everything = RansacConfig {
                distance_threshold_m: Real::MAX.sqrt(),
                ..*ransac
            };
            let fit = fit_plane_ransac(tips, &everything).ok()?;
            let n = if fit.normal.dot(prior) < 0.0 {
                -fit.normal
            } else {
                fit.normal
            };
            Some((PlaneSource::LoadedFingertips, n))
        }
    }
}

/// A press's hold as the wrist camera sees it: the frames to estimate and what the plane fit
/// needs from each estimate.
struct HoldView<'a> {
    hand: &'a HandModel,
    rest: &'a HandShape,
    distal: &'a [usize],
    scene: &'a Scene,
    hold: &'a [(usize, &'a SimFrame)],
    camera_seed: u64,
}

impl HoldView<'_> {
    /// The hold's camera and a marker detector for it.
    fn camera(&self) -> Result<(EpisodeRecorder, MarkerDetector), LabError> {
        let recorder = EpisodeRecorder::new(self.scene, "grasp", self.camera_seed)?;
        let detector =
            MarkerDetector::for_episode(recorder.info(), self.hand, DetectorConfig::default())?;
        Ok((recorder, detector))
    }

    /// [`HoldView::estimate`] with the paper's pipeline: SR-ARAP and `contact` at `threshold`.
    fn chain<C: ContactEstimator>(
        &self,
        contact: C,
        threshold: Real,
        labels_only: bool,
        shapes: &mut Vec<Vec<FingerState>>,
        plane_points: &mut Vec<ContactPoint>,
    ) -> Result<(), LabError> {
        let (recorder, detector) = self.camera()?;
        let shape = MultiShapeEstimator::new(self.hand.clone(), ShapeConfig::default())?;
        let mut pipeline = Pipeline::new(
            self.hand.clone(),
            detector,
            Staged::new(shape, contact),
            threshold,
        )?;
        self.estimate(&mut pipeline, &recorder, labels_only, shapes, plane_points)
    }

    /// Runs `pipeline` on every hold frame (each from a fresh stream, as the paper estimates
    /// each frame), appending each frame's finger states to `shapes` and its contact points
    /// (world frame) to `plane_points`: the pipeline's own, or with `labels_only` the
    /// simulator's contact vertices placed on the estimated shape.
    fn estimate<E: HandEstimator>(
        &self,
        pipeline: &mut Pipeline<E>,
        recorder: &EpisodeRecorder,
        labels_only: bool,
        shapes: &mut Vec<Vec<FingerState>>,
        plane_points: &mut Vec<ContactPoint>,
    ) -> Result<(), LabError> {
        let (hand, rest, distal) = (self.hand, self.rest, self.distal);
        for (k, f) in self.hold {
            let episode_frame = recorder.frame(self.scene, f, *k as u64)?;
            pipeline.reset();
            let estimate = pipeline.process(episode_frame.rgbd(), &episode_frame.observation())?;
            let to_world = |p: &Point3| estimate.world_from_hand.transform_point(p);
            shapes.push(
                (0..hand.num_fingers())
                    .map(|finger| {
                        // Shape and rest compared in the hand frame (a rigid move
                        // keeps distances).
                        let at = estimate
                            .shape
                            .fingers
                            .get(finger)
                            .map_or(&[][..], Vec::as_slice);
                        FingerState {
                            at: at.iter().map(to_world).collect(),
                            displacement: largest_displacement(at, &rest.fingers[finger]),
                            tip_seen: estimate
                                .keypoints
                                .fingers
                                .get(finger)
                                .and_then(|m| m.get(distal[finger]))
                                .is_some_and(Option::is_some),
                        }
                    })
                    .collect(),
            );
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
                    to_world,
                ));
            } else {
                plane_points.extend_from_slice(&estimate.contacts_in_world);
            }
        }
        Ok(())
    }
}

/// What every press of one trial shares: the hand and its rest shape, the contact source, the
/// plate, the aim point, the camera's seed and the options.
struct Presses<'a, C> {
    hand: &'a HandModel,
    /// The rest shape, hand frame.
    rest: HandShape,
    /// Per finger, its most distal marker.
    distal: Vec<usize>,
    contacts: GraspContacts<C>,
    incline_deg: Real,
    aim: Point3,
    camera_seed: u64,
    options: &'a GraspOptions,
}

impl<'a, C: ContactEstimator> Presses<'a, C> {
    fn new(
        hand: &'a HandModel,
        contacts: GraspContacts<C>,
        incline_deg: Real,
        aim: Point3,
        camera_seed: u64,
        options: &'a GraspOptions,
    ) -> Self {
        Self {
            hand,
            rest: HandShape::rest(hand),
            distal: distal_markers(hand),
            contacts,
            incline_deg,
            aim,
            camera_seed,
            options,
        }
    }

    /// Presses `press_m` past first touch with the hand at `rotation`, judges the press, and
    /// fits the plane from the contact source's view of its hold (a pipeline lent the contact
    /// estimator, reset before every hold frame).
    fn observe(&mut self, rotation: &UnitQuat, press_m: Real) -> Result<ObservedPress, LabError> {
        let Self {
            hand,
            rest,
            distal,
            contacts,
            incline_deg,
            aim,
            camera_seed,
            options,
        } = self;
        let (incline_deg, aim, camera_seed) = (*incline_deg, *aim, *camera_seed);
        let normal = plate_normal(incline_deg);

        let (scene, frames) = simulate_press(incline_deg, *rotation, aim, press_m)?;
        let outcome = outcome(&frames, rotation, &normal, options)?;

        // Contacts and shapes over the hold.
        let hold: Vec<(usize, &SimFrame)> = frames
            .iter()
            .enumerate()
            .filter(|(_, f)| in_hold(f))
            .collect();
        let wrist = hold.last().map_or_else(Point3::origin, |(_, f)| {
            Point3::from(f.world_from_hand.translation.vector)
        });
        let mut plane_points: Vec<ContactPoint> = Vec::new();
        let mut true_points: Vec<ContactPoint> = Vec::new();
        let mut shapes: Vec<Vec<FingerState>> = Vec::new();
        for (_, f) in &hold {
            true_points.extend(labelled_points(
                f,
                |finger| &f.fingers[finger].vertices_in_world,
                |p| *p,
            ));
        }
        let hold_view = HoldView {
            hand,
            rest,
            distal,
            scene: &scene,
            hold: &hold,
            camera_seed,
        };
        match contacts {
            GraspContacts::Pipeline { contact, threshold } => {
                hold_view.chain(contact, *threshold, false, &mut shapes, &mut plane_points)?;
            }
            GraspContacts::SimulatorLabelsOnEstimatedShape { contact } => {
                hold_view.chain(contact, 1.0, true, &mut shapes, &mut plane_points)?;
            }
            GraspContacts::Physics { material, config } => {
                let (recorder, detector) = hold_view.camera()?;
                let mut pipeline =
                    PhysicsPipeline::physics((*hand).clone(), detector, material, config)?;
                hold_view.estimate(
                    &mut pipeline,
                    &recorder,
                    false,
                    &mut shapes,
                    &mut plane_points,
                )?;
            }
            GraspContacts::Simulator => {
                plane_points.clone_from(&true_points);
                shapes.extend(hold.iter().map(|(_, f)| simulated_hold_shape(f, rest)));
            }
        }

        let axis = rotation * Vector3::z();
        let (loaded_fingers, tips) = loaded_fingertips(&shapes, &axis, options);
        let mut step = PlaneStep {
            press_depth_m: press_m,
            source: None,
            loaded_fingers,
            tips: tips.iter().map(|p| [p.x, p.y, p.z]).collect(),
            estimated_contacts: plane_points.len(),
            inliers: 0,
            estimated_normal: None,
            estimated_incline_deg: None,
            normal_error_deg: None,
            fit_error: None,
            press: None,
        };
        let mut inlier_indices = Vec::new();
        // Through the loaded fingertips when three or more are loaded, else (or when their tips do
        // not give a plane) RANSAC through the contact points.
        let through_tips = if options.fingertip_plane {
            fingertip_plane(
                step.loaded_fingers.len(),
                options.min_loaded_fingers,
                &tips,
                &-axis,
                &options.ransac,
            )
        } else {
            None
        };
        let fit = match through_tips {
            Some(plane) => Ok(plane),
            None => {
                let points: Vec<Point3> = plane_points.iter().map(|c| c.point).collect();
                fit_plane_ransac(&points, &options.ransac).map(|fit| {
                    step.inliers = fit.inliers.len();
                    inlier_indices.clone_from(&fit.inliers);
                    (
                        PlaneSource::ContactPoints,
                        fit.oriented_toward(&wrist).normal,
                    )
                })
            }
        };
        let normal_est = match fit {
            Ok((source, n)) => {
                step.source = Some(source);
                step.estimated_normal = Some([n.x, n.y, n.z]);
                step.estimated_incline_deg = Some(angle_deg(&n, &Vector3::z()));
                step.normal_error_deg = Some(angle_deg(&n, &normal));
                Some(n)
            }
            Err(e) => {
                step.fit_error = Some(e.to_string());
                None
            }
        };
        Ok(ObservedPress {
            outcome,
            step,
            normal: normal_est,
            plane_points,
            inlier_indices,
            true_points,
        })
    }
}

/// Trial `trial`'s start on the plate inclined by `incline_deg`: the hand's orientation and the
/// aim point on the plate (seeded by both).
fn trial_start(incline_deg: Real, trial: u64, options: &GraspOptions) -> (UnitQuat, Point3) {
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

/// Runs trial `trial` on the plate inclined by `incline_deg`: the first press from a perturbed
/// level start, the plane fitted from its hold (from the pipeline on the wrist camera's frames,
/// `camera_seed` seeding the noise, or from the simulator), then
/// [`GraspOptions::refinements`] presses that each turn the hand onto the latest plane and fit
/// again, and the judged press onto the last plane.
///
/// # Errors
/// An incline outside `[0°, 60°]`, a diverging simulation of the first press, a failing
/// pipeline stage on the first or a refining press. A plane that cannot be fitted or pressed
/// along is reported in the trial, and a deeper press that fails is passed over (the shallow
/// press's plane stands), not returned as errors.
pub fn run_grasp_trial<C: ContactEstimator>(
    hand: &HandModel,
    contacts: GraspContacts<C>,
    incline_deg: Real,
    trial: u64,
    camera_seed: u64,
    options: &GraspOptions,
) -> Result<GraspTrial, LabError> {
    let normal = plate_normal(incline_deg);
    let (mut rotation, aim) = trial_start(incline_deg, trial, options);
    let mut presses = Presses::new(hand, contacts, incline_deg, aim, camera_seed, options);
    let mut observed = presses.observe(&rotation, options.press_m)?;
    let first_press = observed.outcome.clone();
    let mut fits: Vec<PlaneStep> = Vec::new();
    let mut final_press = None;
    for press in 0..=options.refinements {
        let Some(n_est) = observed.normal else {
            // The hand stays on the last plane that was fitted; the press onto it, already made
            // at the judged depth, is the judged one (none when the first fit failed).
            final_press = fits.last().and_then(|s| s.press.clone());
            fits.push(observed.step);
            break;
        };
        // Turn the hand's axis onto −n̂ by the smallest rotation, and press again.
        let axis = rotation * Vector3::z();
        let turn = UnitQuat::rotation_between(&axis, &(-n_est)).unwrap_or_else(UnitQuat::identity);
        rotation = turn * rotation;
        let next = if press < options.refinements {
            presses.observe(&rotation, options.press_m).map(|shallow| {
                let turned = shallow.outcome.clone();
                if shallow.step.loaded_fingers.len() >= options.min_loaded_fingers
                    || options.deeper_press_m <= options.press_m
                {
                    return Some((turned, shallow));
                }
                // Press on: the plane comes from the deeper press, the turn's outcome from the
                // shallow one (the depth every press is judged at). The deeper press is optional:
                // if it cannot be made or seen, the shallow one's plane stands.
                let deep = presses
                    .observe(&rotation, options.deeper_press_m)
                    .unwrap_or(shallow);
                Some((turned, deep))
            })
        } else {
            // The judged press needs no plane.
            simulate_press(incline_deg, rotation, aim, options.press_m)
                .and_then(|(_, frames)| outcome(&frames, &rotation, &normal, options))
                .map(|o| {
                    final_press = Some(o);
                    None
                })
        };
        match next {
            Ok(Some((turned, next))) => {
                let mut step = std::mem::replace(&mut observed, next).step;
                step.press = Some(turned);
                fits.push(step);
            }
            Ok(None) => {
                observed.step.press.clone_from(&final_press);
                fits.push(observed.step);
                break;
            }
            // A fitted normal too far from the plate's to press along: the trial fails.
            Err(LabError::Simulation(e)) => {
                observed.step.fit_error = Some(e.to_string());
                fits.push(observed.step);
                break;
            }
            Err(e) => return Err(e),
        }
    }
    let last = fits.iter().rev().find(|s| s.estimated_normal.is_some());
    Ok(GraspTrial {
        incline_deg,
        trial,
        success_without: first_press.success,
        first_press,
        estimated_incline_deg: last.and_then(|s| s.estimated_incline_deg),
        normal_error_deg: last.and_then(|s| s.normal_error_deg),
        success_with: final_press.as_ref().is_some_and(|p| p.success),
        final_press,
        fits,
        plane_points: observed.plane_points,
        inlier_indices: observed.inlier_indices,
        true_points: observed.true_points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let shapes: Vec<Vec<FingerState>> = hold_frames(&frames)
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
        let shapes: Vec<Vec<FingerState>> = hold_frames(&level.1)
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

    /// A finger is loaded when it has moved more than the threshold from rest in some hold
    /// frame, and its tip (the vertex farthest along the press) is averaged over exactly the
    /// frames in which it is loaded and its tip seen.
    #[test]
    fn loaded_fingers_are_the_deformed_ones_and_their_tips_average_the_seen_loaded_frames() {
        let options = GraspOptions::default();
        let axis = Vector3::new(0.0, 0.0, -1.0);
        let rest = [Point3::new(0.0, 0.0, 0.0), Point3::new(0.0, 0.0, -0.05)];
        let finger = |moved: [Real; 2], tip_seen: bool| {
            let at: Vec<Point3> = rest
                .iter()
                .zip(moved)
                .map(|(p, dx)| Point3::new(p.x + dx, p.y, p.z))
                .collect();
            FingerState {
                displacement: largest_displacement(&at, &rest),
                at,
                tip_seen,
            }
        };
        let m = options.loaded_finger_m;
        let frames = [
            // Finger 0 loaded (its tip moved 2 thresholds), 1 just below the threshold, 2 at
            // rest, 3 loaded with its tip hidden.
            vec![
                finger([0.0, 2.0 * m], true),
                finger([0.0, 0.9 * m], true),
                finger([0.0; 2], true),
                finger([0.0, 2.0 * m], false),
            ],
            // Finger 0 loaded again (tip 4 thresholds), 2 loaded at its base only.
            vec![
                finger([0.0, 4.0 * m], true),
                finger([0.0, 0.5 * m], true),
                finger([1.5 * m, 0.0], true),
                finger([0.0, 2.0 * m], false),
            ],
            // Finger 0 loaded with its tip hidden: not in its average.
            vec![
                finger([0.0, 9.0 * m], false),
                finger([0.0; 2], true),
                finger([0.0; 2], true),
                finger([0.0; 2], true),
            ],
        ];
        let (loaded, tips) = loaded_fingertips(&frames, &axis, &options);
        assert_eq!(loaded, [0, 2, 3]);
        // A non-finite vertex is neither a displacement nor a tip.
        let mut broken = finger([0.0, 2.0 * m], true);
        broken.at.push(Point3::new(Real::NAN, 0.0, 1.0));
        let mut at_rest = rest.to_vec();
        at_rest.push(Point3::origin());
        assert_eq!(largest_displacement(&broken.at, &at_rest), 2.0 * m);
        assert_eq!(broken.tip(&axis), Some(Point3::new(2.0 * m, 0.0, -0.05)));
        assert_eq!(tips.len(), 2, "finger 3's tip was never seen");
        // Finger 0: the tip (z = −0.05) of frames 0 and 1, x averaged; finger 2: frame 1's.
        let close = |a: Point3, b: Point3| (a - b).norm() < 1e-12;
        assert!(
            close(tips[0], Point3::new(3.0 * m, 0.0, -0.05)),
            "{}",
            tips[0]
        );
        assert!(close(tips[1], Point3::new(0.0, 0.0, -0.05)), "{}", tips[1]);
    }

    /// Through three seen tips the plane is theirs; through two, it contains them with the
    /// normal nearest the prior; with fewer the prior itself; fewer than three loaded fingers
    /// give none.
    #[test]
    fn the_fingertip_plane_is_through_three_tips_or_two_and_the_axis() {
        let ransac = RansacConfig::default();
        let prior = Vector3::z();
        let tips = [
            Point3::new(0.03, 0.0, 0.0),
            Point3::new(-0.015, 0.026, 0.0),
            Point3::new(-0.015, -0.026, 0.01),
        ];
        let plane_normal = (tips[1] - tips[0]).cross(&(tips[2] - tips[0])).normalize();
        let (source, n) = fingertip_plane(3, 3, &tips, &prior, &ransac).unwrap();
        assert_eq!(source, PlaneSource::LoadedFingertips);
        assert!(n.dot(&prior) > 0.0);
        assert!(n.dot(&plane_normal).abs() > 1.0 - 1e-12, "{n}");
        // Two tips: the normal is perpendicular to their line, in the plane of the line's normal
        // and the prior, and tilted away from the prior only as far as the line demands.
        let two = [Point3::new(0.0, 0.0, 0.0), Point3::new(0.03, 0.0, 0.01)];
        let (source, n) = fingertip_plane(3, 3, &two, &prior, &ransac).unwrap();
        assert_eq!(source, PlaneSource::TwoFingertipsAndAxis);
        let line = (two[1] - two[0]).normalize();
        assert!(n.dot(&line).abs() < 1e-12);
        assert!(n.y.abs() < 1e-12);
        assert!((angle_deg(&n, &prior) - (0.01_f64 / 0.03).atan().to_degrees()).abs() < 1e-9);
        assert!(fingertip_plane(2, 3, &tips, &prior, &ransac).is_none());
        for seen in [&tips[..1], &[]] {
            let (source, n) = fingertip_plane(3, 3, seen, &prior, &ransac).unwrap();
            assert_eq!(source, PlaneSource::LoadedFingersAxis);
            assert_eq!(n, prior);
        }
        // A non-finite tip gives no plane, never a non-finite normal.
        let nan = Point3::new(Real::NAN, 0.0, 0.0);
        assert!(fingertip_plane(3, 3, &[two[0], nan], &prior, &ransac).is_none());
        assert!(fingertip_plane(3, 3, &[tips[0], tips[1], nan], &prior, &ransac).is_none());
    }
}
