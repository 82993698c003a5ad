//! The estimator's settings and the hand's material.

pub use moe_geom::depth::DepthNoise;
use moe_geom::{HandSignature, Real};
use moe_tendon_sim::{Material, TendonParams, VoxelParams};
use serde::{Deserialize, Serialize};

use crate::error::PhysicsError;

/// What the hand is made of, as the estimator models it: the silicone's elasticity, the
/// damping that dynamic observations are corrected for, and the tendons' stiffness. Calibration
/// (`moe-touch calibrate`) fits it from contact-free frames; the defaults are the nominal
/// values of the hand's design (the paper's E = 100 kPa, ν = 0.1).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HandMaterial {
    /// Silicone body.
    pub material: Material,
    /// Tendons.
    pub tendon: TendonParams,
    /// The hand the material was fitted to (calibration records it; a material without it
    /// fits any hand).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hand: Option<HandSignature>,
}

impl HandMaterial {
    /// Checks every value.
    ///
    /// # Errors
    /// [`PhysicsError::InvalidParameter`] naming the first non-physical one (E ≤ 0, Poisson's
    /// ratio outside (−1, 0.5), density ≤ 0, negative damping, tendon stiffness ≤ 0).
    pub fn validate(&self) -> Result<(), PhysicsError> {
        let sim = |e: moe_tendon_sim::SimError| match e {
            moe_tendon_sim::SimError::InvalidParameter {
                name,
                value,
                reason,
            } => PhysicsError::InvalidParameter {
                name,
                value,
                reason,
            },
            _ => PhysicsError::InvalidParameter {
                name: "material",
                value: Real::NAN,
                reason: "rejected by the simulator",
            },
        };
        self.material.validate().map_err(sim)?;
        self.tendon.validate().map_err(sim)?;
        Ok(())
    }

    /// Checks that the material describes `hand` (when it records a hand).
    ///
    /// # Errors
    /// [`PhysicsError::MaterialOfAnotherHand`] with the first difference.
    pub fn check_hand(&self, hand: &moe_geom::HandModel) -> Result<(), PhysicsError> {
        match self
            .hand
            .as_ref()
            .and_then(|recorded| hand.differs_from(recorded))
        {
            Some(difference) => Err(PhysicsError::MaterialOfAnotherHand { difference }),
            None => Ok(()),
        }
    }
}

/// How the physics estimator models a finger and decides what it sees.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PhysicsConfig {
    /// The estimator's own volume discretisation. Default 4 mm cells: not the data generator's
    /// 3.5 mm (a model is never the data's own mesh), and cheaper.
    pub voxel: VoxelParams,
    /// Static solves stop when the largest nodal update is below this, metres. Default 1e-6.
    pub static_tolerance_m: Real,
    /// Newton iterations of a static solve. Default 60.
    pub static_max_iterations: usize,
    /// Newton iterations of a static solve within the load search (the free shape keeps
    /// [`Self::static_max_iterations`]). From the warm start the search gives it, a load the
    /// model can carry converges in a few; a load it cannot (an axial press on the apex past
    /// the point where the finger buckles) stalls, and is given up sooner. Default 15, chosen
    /// on the validation streams, where it changes no figure and cuts the most solves of a
    /// finger-frame from 171 to 95.
    pub search_max_iterations: usize,
    /// Linear solves (Newton iterations) a finger's load search may spend in one frame of a
    /// stream, after its free shape; 0 for no limit. A search that reaches it keeps the best
    /// loads found so far and reports the finger degraded ([`crate::FingerReport::degraded`]),
    /// so a frame's time has a bound. A lone frame, and the first of a stream, search in full:
    /// they have no previous press to start from. Default 100, chosen on the validation streams (with
    /// `search_max_iterations` 15) as the smallest of 40, 60, 80 and 100 that changes no figure
    /// there: their median finger-frame makes 5 solves, the 99th percentile 46 and the most 95.
    pub frame_solve_budget: usize,
    /// Standard deviation of an observed marker coordinate about the model's prediction,
    /// metres: marker noise and model error together. Default 3e-4, for markers detected by
    /// the perception stage (0.16 mm per coordinate, heavier tails at the tip) on a model of
    /// 0.1 mm error; with exact (simulated) markers 1e-4 (`fixtures/physics/exact-markers.toml`).
    pub marker_sigma_m: Real,
    /// A finger is pressed when one load explains the markers better than none by at least
    /// this many units of χ² (the likelihood-ratio statistic). Default 25.
    pub detection_chi2: Real,
    /// Smallest force reported as a contact, newtons. Default 0.02.
    pub min_force_n: Real,
    /// Largest force of one load, newtons: a fit asking for more is capped. Default 10.
    pub max_force_n: Real,
    /// Friction coefficient of the loads' admissible cone: 0 admits only forces along the
    /// inward surface normal (frictionless contact). Default 0.
    pub friction: Real,
    /// Whether a load turns with the surface it presses in the static solves (a follower load,
    /// as an object's push stays normal to the surface it touches), rather than keeping the
    /// direction it was proposed with (a dead load). Default false: on the held-out presses
    /// (exact markers) following costs 5 → 42 degraded finger-frames of 1,356 and moves BCD
    /// 3.91 → 4.28 mm and missed frames 4.9 → 7.7 %; it places large presses of an
    /// independent code better (docs/results.md, "Large presses").
    pub follow_surface: bool,
    /// Most loads per finger. Default 1: a finger pressed in two places is representable
    /// (2), but with a model that is not the hand's own mesh a pair of loads often explains a
    /// single press's markers better than the press itself (measured in docs/results.md), so the
    /// second load is opt-in.
    pub max_loads_per_finger: usize,
    /// A second load is kept when it lowers χ² by at least this much. Default 25.
    pub second_load_chi2: Real,
    /// Two loads of one finger are at least this far apart on the rest surface, metres.
    /// Default 0.015.
    pub min_load_separation_m: Real,
    /// Radius of a load's patch on the rest surface, metres. Default 0.004.
    pub patch_radius_m: Real,
    /// Radius of the contact region a load reports (per-vertex probability) on the rest
    /// surface, metres (on the load's side of the surface). Default 0.006: on held-out
    /// validation trajectories 4 mm gave contact BCD 5.38 mm and F1 0.327, 6 mm 4.89 mm and
    /// 0.366, 8 mm 4.67 mm and 0.309.
    pub contact_radius_m: Real,
    /// How a load's place is reported: the posterior mean of the place over the candidates
    /// within this radius of its best patch's centre vertex, on its side of the surface (each
    /// candidate weighted by its area and the likelihood of its best single load), which is not
    /// tied to the rest mesh's vertices; it also centres the contact region. 0: the centre
    /// vertex itself. Metres; default 0.008, chosen on validation trajectories (markers
    /// detected in rendered frames: contact BCD 9.66 → 9.47 mm; with 0.2 mm noise, 0.2–0.5 N
    /// presses placed 0.9 mm closer; docs/results.md).
    pub place_radius_m: Real,
    /// Memory of a press's place across a stream: how far a press may move on the rest
    /// surface between two observations (the standard deviation of a Gaussian step), metres.
    /// While a finger stays pressed, the previous observation's posterior over the place,
    /// spread by this step, is the prior of the next one's search and posterior (with a small
    /// chance of a press anywhere), so a held press's place averages the frames' noise. 0 (the
    /// default) forgets: each observation is placed on its own. Measured in docs/results.md: it
    /// helps markers with independent noise, not markers detected in camera frames.
    pub place_memory_m: Real,
    /// Memory of whether a finger is pressed across a stream, seconds: the time over which a
    /// press's belief fades to even odds. With it, a finger pressed in the previous
    /// observation keeps a prior belief of being pressed (`exp(−Δt/τ)` of it), so a held press
    /// whose evidence dips below the threshold for a frame is still reported (no flicker),
    /// while a free finger's prior stays at even odds (onsets are found as without memory).
    /// 0 (the default) decides each observation on its own. Measured in docs/results.md.
    pub press_hold_secs: Real,
    /// How much more likely a press is near a marker the camera has lost — seen earlier in the
    /// stream, hidden now (most often by the object pressing there): places within
    /// `hidden_marker_radius_m` of a lost marker get `1 +` this times the prior of the others.
    /// 0 leaves the prior uniform over the surface. Measured in docs/results.md.
    pub hidden_marker_prior: Real,
    /// Reach of a hidden marker's evidence on the rest surface (a Gaussian's standard
    /// deviation), metres. Default 0.008.
    pub hidden_marker_radius_m: Real,
    /// A marker that the best fit leaves more than this many `marker_sigma_m` from its
    /// observation is taken for a misidentified one (a blob assigned to the wrong marker, the
    /// rest of a marker hidden by the object) and left out of the frame's fit, which is then
    /// searched again; one per observation. 0 turns it off. Default 8 (2.4 mm with the default
    /// noise; measured in docs/results.md).
    pub outlier_sigma: Real,
    /// Most Gauss–Newton iterations (search, loaded solve, re-linearisation) per frame.
    /// Default 4.
    pub gauss_newton_iterations: usize,
    /// Gauss–Newton stops when the loads stay in place and their forces change by less than
    /// this fraction. Default 0.02.
    pub force_tolerance: Real,
    /// Fewest observed markers of a finger the estimator works with. Default 3.
    pub min_markers: usize,
    /// Gravity in the world frame, m/s². Default (0, 0, −9.81).
    pub gravity_m_s2: [Real; 3],
    /// Observations at most this far apart in time form a stream: the free finger is simulated
    /// from one to the next (its lag behind the pulls is taken out of the markers). A longer
    /// gap starts the stream again. Seconds; default 0.2.
    pub stream_horizon_secs: Real,
    /// How much of the contact response's lag is taken out of the markers and the depth
    /// patches in a stream (0: none, 1: all, as a first-order lag with the body's damping
    /// time). With it, whether a finger is pressed and how hard are read from the corrected
    /// observation, so an onset is weighed at its force and a release is seen in its frame,
    /// while the place and the shape come from the observation as measured (the lag scales a
    /// dent but does not move it, and the correction amplifies the noise 2.5–3 times at 20
    /// frames/s). Default 0; 1 for exact markers and with the depth image
    /// (`fixtures/physics/depth.toml`; measured in docs/results.md).
    pub contact_lag_gain: Real,
    /// Largest time step of the free finger's simulation between observations, seconds; 0
    /// turns the simulation off (the markers are then compared with the static free shape).
    /// Default 0.01.
    pub dynamic_step_secs: Real,
    /// Most steps of that simulation between two observations: frames further apart take
    /// longer steps (backward Euler is stable at any step). Default 25, more than a stream's
    /// horizon needs (every step stays `dynamic_step_secs`). Lower it to trade accuracy for
    /// speed on sparse streams: with 5, the demo's frames 0.2 s apart cost half as much with
    /// the same contacts, but the committed held-out frames (exact markers, further apart than
    /// 50 ms) lose accuracy (contact BCD 1.75 → 3.71 mm on 12 frames).
    pub max_dynamic_steps: usize,
    /// How the wrist camera's depth image is used, when an observation carries one.
    pub depth: DepthSettings,
}

/// How the physics estimator uses a depth image: which pixels it keeps, how it aggregates them
/// into observations of the surface, and how much it trusts them.
///
/// Each finger's pixels are predicted from the model (the estimated meshes drawn through the
/// camera), gated, and pooled over patches of the surface about `patch_spacing_m` across: a
/// patch gives one observation, the mean distance of its pixels from the model's surface along
/// the surface normal, with the variance of that mean under the noise model plus
/// `model_sigma_m²` for what the model gets wrong.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DepthSettings {
    /// Use the observation's depth image when it carries one. Default false.
    pub enabled: bool,
    /// Every `stride_px`-th pixel in both directions is sampled. Default 4.
    pub stride_px: u32,
    /// Pixels this close to a predicted silhouette (flying pixels) are left out. Default 2.
    pub edge_band_px: u32,
    /// Pixels that see further than this behind the predicted surface (along the optical axis)
    /// are not the finger's, metres. Default 0.003.
    pub gate_m: Real,
    /// Pixels that see further than this in front of the predicted surface are not the
    /// finger's (an object near it), metres. Default 0.003.
    pub front_gate_m: Real,
    /// Spacing of the patches pixels are pooled over, metres. Default 0.005.
    pub patch_spacing_m: Real,
    /// Fewest pixels of a patch's observation. Default 8.
    pub min_pixels: usize,
    /// The camera's noise.
    pub noise: DepthNoise,
    /// Standard deviation of the model's surface about the true one at a patch, metres.
    /// Default 1e-4.
    pub model_sigma_m: Real,
    /// Scale, in standard deviations, beyond which a patch whose pixels lie in front of the
    /// model's surface counts less and less (a Cauchy loss: they may see an object, such as the
    /// one pressing the finger); behind the surface the loss stays quadratic. 0: quadratic on
    /// both sides. Default 1.
    pub front_loss_sigma: Real,
    /// A lost marker is covered when the depth image sees something in front of its predicted
    /// place, by more than `front_gate_m` (not the finger's own surface) and at most this much,
    /// metres. Default 0.01.
    pub reach_m: Real,
    /// How much more likely a press is near a marker the stream has lost when the depth image
    /// shows it covered (something just in front of it, within `reach_m`, as an object
    /// touching the finger is about the contact): the weight of
    /// [`PhysicsConfig::hidden_marker_prior`]'s evidence for such a marker (a marker lost behind
    /// an object further off keeps `hidden_marker_prior`). 0 turns it off. Default 20.
    pub covered_marker_prior: Real,
    /// How likely a press is at a candidate place where the depth image sees through the space
    /// an object touching the finger there would fill, relative to a place where it does not:
    /// the chance that the camera reports a surface behind a point inside an opaque object (a
    /// gross depth error). A candidate is seen through when, [`SEEN_THROUGH_PROBE_M`] outside
    /// the predicted surface along its normal, every valid pixel of the 3 × 3 about the probe's
    /// projection sees more than `seen_through_margin_m` (plus three standard deviations of the
    /// depth noise) behind the probe, unless the pixels about the place itself all see behind
    /// it, some within `reach_m` (the finger pushed away from its predicted place). The place
    /// the search finds is probed again on the surface its load makes, without that exception;
    /// seen through there, the places seen through on that surface are made less likely too
    /// and the search runs again. 1 turns it off. Default 0.02, an assumed rate of gross errors, not fitted (docs/results.md, "The
    /// space seen empty").
    pub seen_through_prior: Real,
    /// How far behind the probe a pixel must see for the probe's place to count as empty,
    /// metres (before the noise allowance). Default 0.004.
    pub seen_through_margin_m: Real,
}

/// How far outside the predicted surface, along its outward normal, the place a toucher would
/// fill is probed in the depth image, metres: inside any object touching the finger there that
/// is thicker than this (allowing for a dent of the same depth under the model's free surface).
pub const SEEN_THROUGH_PROBE_M: Real = 0.0015;

impl Default for DepthSettings {
    fn default() -> Self {
        Self {
            enabled: false,
            stride_px: 4,
            edge_band_px: 2,
            gate_m: 0.003,
            front_gate_m: 0.003,
            patch_spacing_m: 0.005,
            min_pixels: 8,
            noise: DepthNoise::default(),
            model_sigma_m: 1e-4,
            front_loss_sigma: 1.0,
            reach_m: 0.01,
            covered_marker_prior: 20.0,
            seen_through_prior: 0.02,
            seen_through_margin_m: 0.004,
        }
    }
}

impl DepthSettings {
    /// Checks every setting.
    ///
    /// # Errors
    /// [`PhysicsError::InvalidParameter`] naming the first bad one.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        moe_geom::depth::check_depth_settings(
            &self.noise,
            &self.association(),
            self.patch_spacing_m,
            self.min_pixels,
        )
        .map_err(PhysicsError::from_parameter)?;
        for (name, v) in [
            ("depth.model_sigma_m", self.model_sigma_m),
            ("depth.front_loss_sigma", self.front_loss_sigma),
            ("depth.reach_m", self.reach_m),
            ("depth.covered_marker_prior", self.covered_marker_prior),
            ("depth.seen_through_margin_m", self.seen_through_margin_m),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(PhysicsError::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be finite and non-negative",
                });
            }
        }
        if !(self.seen_through_prior > 0.0 && self.seen_through_prior <= 1.0) {
            return Err(PhysicsError::InvalidParameter {
                name: "depth.seen_through_prior",
                value: self.seen_through_prior,
                reason: "must be in (0, 1]",
            });
        }
        let floor = self.model_sigma_m + self.noise.correlated_sigma_m;
        if floor <= 0.0 {
            return Err(PhysicsError::InvalidParameter {
                name: "depth.model_sigma_m",
                value: self.model_sigma_m,
                reason: "with no correlated noise either, a patch of many pixels would be trusted \
                         without limit",
            });
        }
        Ok(())
    }

    /// The association of pixels with fingers these settings ask for.
    pub fn association(&self) -> moe_geom::depth::AssociationOptions {
        moe_geom::depth::AssociationOptions {
            stride_px: self.stride_px,
            edge_band_px: self.edge_band_px,
            gate_m: self.gate_m,
            front_gate_m: self.front_gate_m,
        }
    }
}

impl Default for PhysicsConfig {
    fn default() -> Self {
        Self {
            voxel: VoxelParams { cell_size_m: 0.004 },
            static_tolerance_m: 1e-6,
            static_max_iterations: 60,
            search_max_iterations: 15,
            frame_solve_budget: 100,
            marker_sigma_m: 3e-4,
            detection_chi2: 25.0,
            min_force_n: 0.02,
            max_force_n: 10.0,
            friction: 0.0,
            follow_surface: false,
            max_loads_per_finger: 1,
            second_load_chi2: 25.0,
            min_load_separation_m: 0.015,
            patch_radius_m: 0.004,
            contact_radius_m: 0.006,
            place_radius_m: 0.008,
            place_memory_m: 0.0,
            press_hold_secs: 0.0,
            hidden_marker_prior: 0.0,
            hidden_marker_radius_m: 0.008,
            outlier_sigma: 8.0,
            gauss_newton_iterations: 4,
            force_tolerance: 0.02,
            min_markers: 3,
            gravity_m_s2: [0.0, 0.0, -9.81],
            stream_horizon_secs: 0.2,
            dynamic_step_secs: 0.01,
            max_dynamic_steps: 25,
            contact_lag_gain: 0.0,
            depth: DepthSettings::default(),
        }
    }
}

impl PhysicsConfig {
    /// How far apart two observations may be and still be one stream, seconds:
    /// [`Self::stream_horizon_secs`] with a microsecond's slack for clocks in floating point.
    /// Further apart, the estimator starts the stream again.
    pub fn stream_reach_secs(&self) -> Real {
        self.stream_horizon_secs + 1e-6
    }

    /// Checks every setting.
    ///
    /// # Errors
    /// [`PhysicsError::InvalidParameter`] naming the first bad one.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        let bad = |name, value, reason| {
            Err(PhysicsError::InvalidParameter {
                name,
                value,
                reason,
            })
        };
        for (name, v) in [
            ("voxel.cell_size_m", self.voxel.cell_size_m),
            ("static_tolerance_m", self.static_tolerance_m),
            ("marker_sigma_m", self.marker_sigma_m),
            ("patch_radius_m", self.patch_radius_m),
            ("hidden_marker_radius_m", self.hidden_marker_radius_m),
            ("contact_radius_m", self.contact_radius_m),
            ("max_force_n", self.max_force_n),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, v, "must be finite and positive");
            }
        }
        for (name, v) in [
            ("detection_chi2", self.detection_chi2),
            ("min_force_n", self.min_force_n),
            ("friction", self.friction),
            ("second_load_chi2", self.second_load_chi2),
            ("min_load_separation_m", self.min_load_separation_m),
            ("stream_horizon_secs", self.stream_horizon_secs),
            ("dynamic_step_secs", self.dynamic_step_secs),
            ("contact_lag_gain", self.contact_lag_gain),
            ("place_radius_m", self.place_radius_m),
            ("place_memory_m", self.place_memory_m),
            ("press_hold_secs", self.press_hold_secs),
            ("outlier_sigma", self.outlier_sigma),
            ("hidden_marker_prior", self.hidden_marker_prior),
            ("force_tolerance", self.force_tolerance),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, v, "must be finite and non-negative");
            }
        }
        if !(1..=10_000).contains(&self.static_max_iterations) {
            return bad(
                "static_max_iterations",
                self.static_max_iterations as Real,
                "must be in 1..=10000",
            );
        }
        if !(1..=10_000).contains(&self.search_max_iterations) {
            return bad(
                "search_max_iterations",
                self.search_max_iterations as Real,
                "must be in 1..=10000",
            );
        }
        if self.frame_solve_budget > 1_000_000 {
            return bad(
                "frame_solve_budget",
                self.frame_solve_budget as Real,
                "must be at most 1000000 (0 for no limit)",
            );
        }
        if !(1..=4).contains(&self.max_loads_per_finger) {
            return bad(
                "max_loads_per_finger",
                self.max_loads_per_finger as Real,
                "must be in 1..=4",
            );
        }
        if !(1..=1000).contains(&self.max_dynamic_steps) {
            return bad(
                "max_dynamic_steps",
                self.max_dynamic_steps as Real,
                "must be in 1..=1000",
            );
        }
        if !(1..=50).contains(&self.gauss_newton_iterations) {
            return bad(
                "gauss_newton_iterations",
                self.gauss_newton_iterations as Real,
                "must be in 1..=50",
            );
        }
        if let Some(&g) = self.gravity_m_s2.iter().find(|g| !g.is_finite()) {
            return bad("gravity_m_s2", g, "must be finite");
        }
        if self.min_markers == 0 {
            return bad("min_markers", 0.0, "must be at least 1");
        }
        self.depth.validate()
    }
}
