//! A grasp trial: presses seen through the contact source, the plane fitted from each press's
//! hold with [`fit_grasp_plane`], and the hand turned onto it.

use moe_arap::{MultiShapeEstimator, ShapeConfig};
use moe_geom::math::UnitQuat;
use moe_geom::{
    ContactEstimator, ContactPoint, HandEstimator, HandModel, HandShape, Point3, Real, Staged,
    Vector3,
};
use moe_tendon_sim::{Scene, SimFrame};
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::pipeline::{PhysicsPipeline, Pipeline};

use super::plane::{FingerView, GraspPlane, distal_markers, finger_views, fit_grasp_plane};
use super::press::{
    angle_deg, in_hold, labelled_points, outcome, plate_normal, simulate_press,
    simulated_hold_shape, trial_start,
};
use super::{FailedHoldFrame, GraspContacts, GraspOptions, GraspTrial, PlaneStep, PressOutcome};
use crate::LabError;
use crate::episode::EpisodeRecorder;

/// One press seen through the contact source: how it ended, and the plane fitted from its hold.
pub(super) struct ObservedPress {
    pub(super) outcome: PressOutcome,
    pub(super) step: PlaneStep,
    normal: Option<Vector3>,
    plane_points: Vec<ContactPoint>,
    inlier_indices: Vec<usize>,
    true_points: Vec<ContactPoint>,
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

    /// [`HoldView::estimate`] with the paper's pipeline: SR-ARAP with `shape` and `contact` at
    /// `threshold`.
    fn chain<C: ContactEstimator>(
        &self,
        shape: &ShapeConfig,
        contact: C,
        threshold: Real,
        labels_only: bool,
        views: &mut HoldEstimates,
    ) -> Result<(), LabError> {
        let (recorder, detector) = self.camera()?;
        let shape = MultiShapeEstimator::new(self.hand.clone(), shape.clone())?;
        let mut pipeline = Pipeline::new(
            self.hand.clone(),
            detector,
            Staged::new(shape, contact),
            threshold,
        )?;
        self.estimate(&mut pipeline, &recorder, labels_only, views)
    }

    /// Runs `pipeline` on every hold frame (each from a fresh stream, as the paper estimates
    /// each frame), appending each frame's finger states to `shapes` and its contact points
    /// (world frame) to `plane_points`: the pipeline's own, or with `labels_only` the
    /// simulator's contact vertices placed on the estimated shape. A frame the pipeline cannot
    /// estimate gives neither and is named in `failed` (the plane comes from the others).
    fn estimate<E: HandEstimator>(
        &self,
        pipeline: &mut Pipeline<E>,
        recorder: &EpisodeRecorder,
        labels_only: bool,
        views: &mut HoldEstimates,
    ) -> Result<(), LabError> {
        let HoldEstimates {
            shapes,
            plane_points,
            failed,
        } = views;
        for (k, f) in self.hold {
            let episode_frame = recorder.frame(self.scene, f, *k as u64)?;
            pipeline.reset();
            let estimate =
                match pipeline.process(episode_frame.rgbd(), &episode_frame.observation()) {
                    Ok(estimate) => estimate,
                    Err(failure) => {
                        failed.push(FailedHoldFrame {
                            frame: *k,
                            error: failure.to_string(),
                        });
                        continue;
                    }
                };
            let to_world = |p: &Point3| estimate.world_from_hand.transform_point(p);
            shapes.push(finger_views(&estimate, self.rest, self.distal));
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

/// What the contact source made of a press's hold: per estimated frame its finger states, the
/// contact points of all of them (world frame), and the frames it could not estimate.
#[derive(Default)]
struct HoldEstimates {
    shapes: Vec<Vec<FingerView>>,
    plane_points: Vec<ContactPoint>,
    failed: Vec<FailedHoldFrame>,
}

/// What every press of one trial shares: the hand and its rest shape, the contact source, the
/// plate, the aim point, the camera's seed and the options.
pub(super) struct Presses<'a, C> {
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
    pub(super) fn new(
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
    pub(super) fn observe(
        &mut self,
        rotation: &UnitQuat,
        press_m: Real,
    ) -> Result<ObservedPress, LabError> {
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
        let mut views = HoldEstimates::default();
        let mut true_points: Vec<ContactPoint> = Vec::new();
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
            GraspContacts::Pipeline {
                contact,
                threshold,
                shape,
            } => {
                hold_view.chain(shape, contact, *threshold, false, &mut views)?;
            }
            GraspContacts::SimulatorLabelsOnEstimatedShape { contact, shape } => {
                hold_view.chain(shape, contact, 1.0, true, &mut views)?;
            }
            GraspContacts::Physics { material, config } => {
                let (recorder, detector) = hold_view.camera()?;
                let mut pipeline =
                    PhysicsPipeline::physics((*hand).clone(), detector, material, config)?;
                hold_view.estimate(&mut pipeline, &recorder, false, &mut views)?;
            }
            GraspContacts::Simulator => {
                views.plane_points.clone_from(&true_points);
                views
                    .shapes
                    .extend(hold.iter().map(|(_, f)| simulated_hold_shape(f, rest)));
            }
        }
        let HoldEstimates {
            shapes,
            plane_points,
            failed,
        } = views;

        let axis = rotation * Vector3::z();
        let fit = fit_grasp_plane(&plane_points, &shapes, &axis, &wrist, options);
        let mut step = PlaneStep {
            press_depth_m: press_m,
            source: None,
            loaded_fingers: fit.loaded_fingers,
            tips: fit.tips.iter().map(|p| [p.x, p.y, p.z]).collect(),
            estimated_contacts: plane_points.len(),
            failed_frames: failed,
            inliers: 0,
            estimated_normal: None,
            estimated_incline_deg: None,
            normal_error_deg: None,
            fit_error: None,
            press: None,
        };
        let mut inlier_indices = Vec::new();
        let normal_est = match fit.plane {
            Ok(GraspPlane {
                source,
                normal: n,
                inliers,
            }) => {
                step.source = Some(source);
                step.inliers = inliers.len();
                inlier_indices = inliers;
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

/// Runs trial `trial` on the plate inclined by `incline_deg`: the first press from a perturbed
/// level start, the plane fitted from its hold (from the pipeline on the wrist camera's frames,
/// `camera_seed` seeding the noise, or from the simulator), then
/// [`GraspOptions::refinements`] presses that each turn the hand onto the latest plane and fit
/// again, and the judged press onto the last plane.
///
/// # Errors
/// An incline outside `[0°, 60°]`, a diverging simulation of the first press, or a camera,
/// marker detector or pipeline that cannot be made for a press. A hold frame the pipeline
/// cannot estimate is named in its plane's step ([`PlaneStep::failed_frames`]) and left out of
/// the fit; a plane that cannot be fitted or pressed along is reported in the trial, and a
/// deeper press that fails is passed over (the shallow press's plane stands), not returned as
/// errors.
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
