//! Multi-finger shape estimation: one SR-ARAP solver per finger of a hand, solved in parallel.
//!
//! Each finger's base vertices are fixed at rest; each observed marker pulls one handle vertex
//! onto its keypoint. [`MultiShapeEstimator::new`] attaches every marker to the rest-mesh vertex
//! nearest its rest position (the marker's own vertex), so the first frame may be strongly bent.
//! [`MultiShapeEstimator::unattached`] keeps the paper's rule instead: when a marker is first
//! observed, its handle is the rest-mesh vertex nearest to the observed keypoint (skipping base
//! vertices and vertices already taken by another marker), kept from then on — the hand must
//! then be relaxed when a marker is first seen. Missing markers are dropped for the frame without
//! refactorising.

use moe_geom::depth::{
    DepthImage, FingerDepth, SurfacePatches, associate_depth, pool_pixels, surface_pixels,
};
use moe_geom::{
    HandFinger, HandKeypoints, HandModel, HandShape, Observation, Point3, PointIndex, Real,
};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::{ArapConfig, ArapEnergy};
use crate::depth::ShapeDepth;
use crate::error::ArapError;
use crate::solver::{ArapInfo, ArapWorkspace, PartSolver, Start, SurfaceRow};

/// Number of nearest rest vertices examined when the nearest one is unusable for a handle.
const HANDLE_CANDIDATES: usize = 32;

/// Settings of the multi-finger estimator (serde; every field defaulted).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShapeConfig {
    /// Local/global iterations per frame. Default 50 (paper).
    pub iterations: usize,
    /// Smoothing weight α. Default 0.01 (paper).
    pub alpha: Real,
    /// Energy variant. Default [`ArapEnergy::Smoothed`].
    pub energy: ArapEnergy,
    /// Start each frame from the previous frame's shape instead of the rest shape. Default
    /// `false` (the paper starts from rest).
    pub warm_start: bool,
    /// Registration to the wrist camera's depth image as well (off by default).
    pub depth: ShapeDepth,
}

impl Default for ShapeConfig {
    fn default() -> Self {
        Self {
            iterations: 50,
            alpha: 0.01,
            energy: ArapEnergy::Smoothed,
            warm_start: false,
            depth: ShapeDepth::default(),
        }
    }
}

impl ShapeConfig {
    /// Checks every setting.
    ///
    /// # Errors
    /// [`ArapError::InvalidConfig`] naming the first bad one.
    pub fn validate(&self) -> Result<(), ArapError> {
        ArapConfig {
            energy: self.energy,
            alpha: self.alpha,
            iterations: self.iterations,
            parallel: false,
        }
        .validate()?;
        self.depth.validate()
    }
}

/// How one finger was solved in one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FingerReport {
    /// Finger index.
    pub finger: usize,
    /// Iterations run, over the markers-only solve and every depth pass (0 when no marker was
    /// visible).
    pub iterations: usize,
    /// Energy per iteration of the last solve (see [`ArapInfo::energy`]; with a depth pass,
    /// the depth patches' term included).
    pub energy: Vec<Real>,
    /// Indices of the markers used as handles in this frame.
    pub markers_used: Vec<usize>,
    /// Mesh vertex of every marker's handle, `None` for markers never observed yet.
    pub handle_vertices: Vec<Option<u32>>,
    /// True when every marker was missing: the finger was left at its start shape.
    pub all_markers_missing: bool,
    /// True when the frame started from the previous frame's shape rather than the rest shape.
    pub warm_started: bool,
    /// Rotations computed by the SVD fallback.
    pub svd_fallbacks: usize,
    /// Depth patches the last registration pass pulled the surface with (0 without depth).
    #[serde(default)]
    pub depth_patches: usize,
    /// Depth pixels pooled into them.
    #[serde(default)]
    pub depth_pixels: usize,
}

/// The result of one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeEstimate {
    /// Deformed hand shape.
    pub shape: HandShape,
    /// One report per finger.
    pub reports: Vec<FingerReport>,
}

/// Per-finger solver state.
#[derive(Debug)]
struct FingerState {
    solver: PartSolver,
    workspace: ArapWorkspace,
    info: ArapInfo,
    rest_index: PointIndex,
    base_targets: Vec<Point3>,
    is_base: Vec<bool>,
    /// Handle vertex of every marker, once observed.
    marker_handle: Vec<Option<u32>>,
    /// Slot in the solver's handle list of every marker.
    marker_slot: Vec<Option<usize>>,
    handle_targets: Vec<Option<Point3>>,
    has_previous: bool,
    /// The patches depth pixels are pooled over (made when the options enable depth).
    patches: Option<SurfacePatches>,
}

/// SR-ARAP shape estimation for every finger of a hand.
#[derive(Debug)]
pub struct MultiShapeEstimator {
    hand: HandModel,
    options: ShapeConfig,
    fingers: Vec<FingerState>,
}

impl MultiShapeEstimator {
    /// Builds and factorises one solver per finger (base vertices fixed at rest) and attaches
    /// every marker to its nearest rest vertex, so that the first frame may be strongly bent or
    /// miss markers: the estimator a one-shot estimation and a live stream both want.
    ///
    /// ```
    /// use moe_arap::{MultiShapeEstimator, ShapeConfig};
    /// use moe_geom::{FingerParams, HandModel, HandPreset};
    ///
    /// let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default())?;
    /// let mut arap = MultiShapeEstimator::new(hand.clone(), ShapeConfig::default())?;
    /// // The markers where the camera saw them (here: at rest), in the hand frame.
    /// let estimate = arap.estimate(&hand.rest_keypoints())?;
    /// assert_eq!(estimate.shape.fingers.len(), 2);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// Invalid options, or a finger mesh the solver rejects.
    pub fn new(hand: HandModel, options: ShapeConfig) -> Result<Self, ArapError> {
        let rest = hand.rest_keypoints();
        let mut estimator = Self::unattached(hand, options)?;
        estimator.assign_handles(&rest)?;
        Ok(estimator)
    }

    /// As [`MultiShapeEstimator::new`], but a marker is attached to the vertex nearest to where
    /// it is first observed (the frame it is first seen in must then be close to rest).
    ///
    /// # Errors
    /// Invalid options, or a finger mesh the solver rejects.
    pub fn unattached(hand: HandModel, options: ShapeConfig) -> Result<Self, ArapError> {
        let config = ArapConfig {
            energy: options.energy,
            alpha: options.alpha,
            iterations: options.iterations,
            parallel: false,
        };
        config.validate()?;
        options.depth.validate()?;
        let (depth_on, spacing) = (options.depth.enabled, options.depth.patch_spacing_m);
        let fingers = hand
            .fingers()
            .par_iter()
            .map(|f| {
                let mesh = f.model.mesh();
                let base = f.model.base_vertices();
                let solver = PartSolver::new(mesh, &config, base, &[])?;
                let workspace = solver.workspace();
                let mut is_base = vec![false; mesh.num_vertices()];
                for &b in base {
                    is_base[b as usize] = true;
                }
                let markers = f.model.marker_vertices().len();
                Ok(FingerState {
                    workspace,
                    info: ArapInfo::default(),
                    rest_index: PointIndex::new(mesh.vertices(), "finger rest vertices")?,
                    base_targets: base.iter().map(|&b| mesh.vertices()[b as usize]).collect(),
                    is_base,
                    marker_handle: vec![None; markers],
                    marker_slot: vec![None; markers],
                    handle_targets: Vec::new(),
                    has_previous: false,
                    patches: depth_on
                        .then(|| SurfacePatches::new(mesh.vertices(), mesh.faces(), spacing)),
                    solver,
                })
            })
            .collect::<Result<Vec<_>, ArapError>>()?;
        Ok(Self {
            hand,
            options,
            fingers,
        })
    }

    /// The hand model.
    pub fn hand(&self) -> &HandModel {
        &self.hand
    }

    /// The options.
    pub fn options(&self) -> &ShapeConfig {
        &self.options
    }

    /// Handle vertex of every marker of finger `finger` (`None` until attached: never with
    /// [`MultiShapeEstimator::new`], until first observed with `unattached`).
    ///
    /// # Panics
    /// If `finger` is out of range (a programming error).
    pub fn handle_vertices(&self, finger: usize) -> &[Option<u32>] {
        &self.fingers[finger].marker_handle
    }

    /// Assigns handle vertices to the markers observed in `keypoints` that have none yet, without
    /// solving. Passing the hand's rest keypoints ([`HandModel::rest_keypoints`]) attaches every
    /// marker to its nearest rest vertex before the first real frame — what a one-shot
    /// estimation from a single, possibly strongly bent frame needs.
    ///
    /// # Errors
    /// As [`MultiShapeEstimator::estimate`].
    pub fn assign_handles(&mut self, keypoints: &HandKeypoints) -> Result<(), ArapError> {
        self.check_keypoints(keypoints)?;
        for ((state, finger), kp) in self
            .fingers
            .iter_mut()
            .zip(self.hand.fingers())
            .zip(&keypoints.fingers)
        {
            let finger_from_hand = finger.hand_from_finger.inverse();
            let kp_in_finger: Vec<Option<Point3>> = kp
                .iter()
                .map(|p| p.map(|p| finger_from_hand.transform_point(&p)))
                .collect();
            state.assign_new_handles(&kp_in_finger)?;
        }
        Ok(())
    }

    fn check_keypoints(&self, keypoints: &HandKeypoints) -> Result<(), ArapError> {
        keypoints.check_against(&self.hand).map_err(|e| match e {
            moe_geom::GeomError::NonFinitePoint { .. } => self.locate_non_finite(keypoints),
            other => ArapError::Geom(other),
        })
    }

    /// Forgets the previous frame's shapes (handle assignments are kept).
    pub fn reset_tracking(&mut self) {
        for f in &mut self.fingers {
            f.has_previous = false;
        }
    }

    /// Estimates the hand shape from one frame of keypoints (hand frame).
    ///
    /// # Errors
    /// Keypoints that do not fit the hand (finger or marker counts), non-finite keypoints.
    pub fn estimate(&mut self, keypoints: &HandKeypoints) -> Result<ShapeEstimate, ArapError> {
        self.estimate_with(keypoints, None)
    }

    /// As [`MultiShapeEstimator::estimate`], registered to `depth` as well when the options
    /// enable it ([`ShapeDepth`]): after the markers-only solve, each pass associates the
    /// depth pixels with the fingers as the current estimate predicts them and solves again
    /// with the patches' soft pulls. A finger with no marker in view is left as the markers
    /// left it.
    ///
    /// # Errors
    /// As [`MultiShapeEstimator::estimate`].
    pub fn estimate_with(
        &mut self,
        keypoints: &HandKeypoints,
        depth: Option<&DepthImage<'_>>,
    ) -> Result<ShapeEstimate, ArapError> {
        self.check_keypoints(keypoints)?;
        let warm = self.options.warm_start;
        let results = self
            .fingers
            .par_iter_mut()
            .zip(self.hand.fingers().par_iter())
            .zip(keypoints.fingers.par_iter())
            .enumerate()
            .map(|(i, ((state, finger), kp))| {
                let finger_from_hand = finger.hand_from_finger.inverse();
                let kp_in_finger: Vec<Option<Point3>> = kp
                    .iter()
                    .map(|p| p.map(|p| finger_from_hand.transform_point(&p)))
                    .collect();
                let report = state.solve(i, &kp_in_finger, warm)?;
                let vertices = if report.all_markers_missing && !(warm && state.has_previous) {
                    finger
                        .hand_from_finger
                        .transform_points(state.solver.rest_vertices())
                } else {
                    finger
                        .hand_from_finger
                        .transform_points(state.workspace.vertices())
                };
                Ok((vertices, report))
            })
            .collect::<Result<Vec<_>, ArapError>>()?;
        let (fingers, mut reports): (Vec<_>, Vec<_>) = results.into_iter().unzip();
        let mut shape = HandShape { fingers };
        let settings = &self.options.depth;
        if let (true, Some(depth)) = (settings.enabled, depth) {
            for _ in 0..settings.passes {
                let found = associate_depth(&self.hand, &shape, depth, &settings.association())?;
                self.fingers
                    .par_iter_mut()
                    .zip(self.hand.fingers().par_iter())
                    .zip(found.par_iter())
                    .zip(reports.par_iter_mut().zip(shape.fingers.par_iter_mut()))
                    .try_for_each(|(((state, finger), found), (report, vertices))| {
                        if report.all_markers_missing {
                            return Ok(());
                        }
                        state.register_depth(finger, found, depth, settings, report)?;
                        *vertices = finger
                            .hand_from_finger
                            .transform_points(state.workspace.vertices());
                        Ok::<_, ArapError>(())
                    })?;
            }
        }
        Ok(ShapeEstimate { shape, reports })
    }

    fn locate_non_finite(&self, keypoints: &HandKeypoints) -> ArapError {
        for (finger, kp) in keypoints.fingers.iter().enumerate() {
            if let Some(marker) = kp
                .iter()
                .position(|p| p.is_some_and(|p| !moe_geom::math::is_finite_point(&p)))
            {
                return ArapError::NonFiniteKeypoint { finger, marker };
            }
        }
        ArapError::NonFiniteKeypoint {
            finger: 0,
            marker: 0,
        }
    }
}

impl FingerState {
    /// Solves one frame for this finger; `kp` are the keypoints in the finger frame.
    fn solve(
        &mut self,
        finger: usize,
        kp: &[Option<Point3>],
        warm: bool,
    ) -> Result<FingerReport, ArapError> {
        self.assign_new_handles(kp)?;
        let markers_used: Vec<usize> = (0..kp.len()).filter(|&m| kp[m].is_some()).collect();
        let warm_started = warm && self.has_previous;
        if markers_used.is_empty() {
            return Ok(FingerReport {
                finger,
                iterations: 0,
                energy: Vec::new(),
                markers_used,
                handle_vertices: self.marker_handle.clone(),
                all_markers_missing: true,
                warm_started,
                svd_fallbacks: 0,
                depth_patches: 0,
                depth_pixels: 0,
            });
        }
        for t in &mut self.handle_targets {
            *t = None;
        }
        for (m, p) in kp.iter().enumerate() {
            if let (Some(p), Some(slot)) = (p, self.marker_slot[m]) {
                self.handle_targets[slot] = Some(*p);
            }
        }
        let start = if warm_started {
            Start::Previous
        } else {
            Start::Rest
        };
        self.solver.solve_in(
            &mut self.workspace,
            &self.base_targets,
            &self.handle_targets,
            start,
            &mut self.info,
        )?;
        self.has_previous = true;
        Ok(FingerReport {
            finger,
            iterations: self.info.iterations,
            energy: self.info.energy.clone(),
            markers_used,
            handle_vertices: self.marker_handle.clone(),
            all_markers_missing: false,
            warm_started,
            svd_fallbacks: self.info.svd_fallbacks,
            depth_patches: 0,
            depth_pixels: 0,
        })
    }

    /// One registration pass to the depth pixels `found` on this finger (hand frame), from
    /// the shape the workspace holds, with the handles of the frame's markers.
    fn register_depth(
        &mut self,
        finger: &HandFinger,
        found: &FingerDepth,
        depth: &DepthImage<'_>,
        settings: &ShapeDepth,
        report: &mut FingerReport,
    ) -> Result<(), ArapError> {
        let Some(patches) = &self.patches else {
            return Ok(());
        };
        let finger_from_hand = finger.hand_from_finger.inverse();
        let pixels = surface_pixels(
            &found.points,
            depth,
            &settings.noise,
            finger_from_hand.iso(),
        );
        let predicted = self.workspace.vertices();
        let pooled = pool_pixels(
            &pixels,
            finger.model.mesh().faces(),
            predicted,
            patches,
            settings.min_pixels,
            &settings.noise,
        );
        report.depth_patches = pooled.len();
        report.depth_pixels = pooled.iter().map(|p| p.pixels).sum();
        if pooled.is_empty() {
            return Ok(());
        }
        let rows: Vec<SurfaceRow> = pooled
            .into_iter()
            .map(|p| {
                let at = p.predicted(|v| predicted[v as usize]);
                settings.row(p, at)
            })
            .collect();
        let terms = self.solver.surface_terms(rows)?;
        self.solver.solve_in_with(
            &mut self.workspace,
            &self.base_targets,
            &self.handle_targets,
            Start::Previous,
            &mut self.info,
            Some(&terms),
        )?;
        report.iterations += self.info.iterations;
        report.energy.clone_from(&self.info.energy);
        report.svd_fallbacks += self.info.svd_fallbacks;
        Ok(())
    }

    /// Gives every newly observed marker its handle vertex (the nearest usable rest vertex).
    fn assign_new_handles(&mut self, kp: &[Option<Point3>]) -> Result<(), ArapError> {
        let mut changed = false;
        for (m, p) in kp.iter().enumerate() {
            let Some(p) = p else { continue };
            if self.marker_handle[m].is_some() {
                continue;
            }
            let taken = |v: usize| self.is_base[v] || self.marker_handle.contains(&Some(v as u32));
            let nearest = self
                .rest_index
                .k_nearest(p, HANDLE_CANDIDATES)
                .into_iter()
                .find(|n| !taken(n.index));
            if let Some(n) = nearest {
                self.marker_handle[m] = Some(n.index as u32);
                changed = true;
            }
        }
        if changed {
            let mut handles = Vec::new();
            for (m, h) in self.marker_handle.iter().enumerate() {
                self.marker_slot[m] = h.map(|v| {
                    handles.push(v);
                    handles.len() - 1
                });
            }
            self.solver.set_handles(&handles)?;
            self.handle_targets = vec![None; handles.len()];
        }
        Ok(())
    }
}

impl moe_geom::ShapeEstimator for MultiShapeEstimator {
    type Error = ArapError;

    /// The shape from the observation's markers, and its depth image when the options
    /// enable it (its pulls, pose and time are not used).
    fn estimate_shape(&mut self, observation: &Observation<'_>) -> Result<HandShape, ArapError> {
        let keypoints = observation.keypoints.ok_or(ArapError::MissingKeypoints)?;
        Ok(self
            .estimate_with(keypoints, observation.depth.as_ref())?
            .shape)
    }

    fn reset(&mut self) {
        self.reset_tracking();
    }
}
