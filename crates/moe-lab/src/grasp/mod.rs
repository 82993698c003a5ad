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
//! fingertip plane is the paper's protocol. The rule is
//! [`fit_grasp_plane`](crate::grasp::fit_grasp_plane), a pure function of the pipeline's frame
//! estimates ([`finger_views`](crate::grasp::finger_views)) that a robot calls with its own; the
//! simulated trials call the same function.
//!
//! **Success** is the state from which the paper's hand folds the sheet: at the deepest point of
//! the judged press every finger touches the plate (at least
//! [`GraspOptions::min_contact_vertices`](crate::grasp::GraspOptions::min_contact_vertices)
//! labelled vertices each) and the hand's axis is within
//! [`GraspOptions::max_axis_error_deg`](crate::grasp::GraspOptions::max_axis_error_deg) of the
//! plate's normal, so the palm faces the sheet squarely. Without MOE-Touch the hand keeps its
//! initial orientation: the judged press is its first.
//!
//! [`run_grasp_trial`](crate::grasp::run_grasp_trial) runs one trial;
//! [`run_grasp_study`](crate::grasp::run_grasp_study) the paper's study (seeded trials on each
//! incline, tallied beside Table 4).

mod plane;
mod press;
mod study;
mod trial;

pub use plane::{
    FingerView, GraspPlane, GraspPlaneFit, PlaneSource, distal_markers, finger_views,
    fit_grasp_plane,
};
pub use press::plate_normal;
pub use study::{
    GraspInclineRow, GraspStudyOptions, GraspStudyReport, GraspStudySource, PAPER_INCLINES,
    SkippedTrial, run_grasp_study, trial_point_clouds,
};
pub use trial::run_grasp_trial;

use moe_geom::{ContactPoint, RansacConfig, Real};
use serde::Serialize;

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
    /// Hold frames the pipeline could not estimate: they gave no contact points and no finger
    /// states, and the plane came from the others.
    pub failed_frames: Vec<FailedHoldFrame>,
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

/// A hold frame the pipeline could not estimate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FailedHoldFrame {
    /// Its index among the press's simulated frames.
    pub frame: usize,
    /// Why (the failing stage and its error).
    pub error: String,
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
        /// SR-ARAP's settings.
        shape: moe_arap::ShapeConfig,
    },
    /// The simulator's contact vertices placed where the pipeline's estimated shape puts them
    /// (the pipeline runs with this contact estimator, whose own output is not used): a perfect
    /// contact classifier on the shape the markers give, which separates the error of the shape
    /// estimate from that of the contact classification.
    SimulatorLabelsOnEstimatedShape {
        /// The pipeline's contact stage (needed to run it; its probabilities are not used).
        contact: C,
        /// SR-ARAP's settings.
        shape: moe_arap::ShapeConfig,
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

#[cfg(test)]
mod tests;
