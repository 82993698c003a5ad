//! One finger read backwards: from its observed markers and tendon pulls to the loads that
//! explain them and the shape they produce.
//!
//! 1. **Free finger**: in a stream, the finger's own model is simulated from one observation
//!    to the next under the commanded pulls and gravity (backward Euler with the body's
//!    damping), without loads: where an untouched finger would be now, lag included. A lone
//!    observation uses the static equilibrium instead.
//! 2. **Test**: `χ²₀ = ‖m − m_free‖²/σ²` over the observed marker coordinates. Below the
//!    detection threshold no load can pass the test, and the free shape is the answer.
//! 3. **Compliance by reciprocity**: otherwise the tangent of the static problem is factorised
//!    at the linearisation point and solved once per observed coordinate; column `j` evaluated
//!    at a surface point is the response of coordinate `j` to a unit force there.
//! 4. **Search**: every candidate patch (a disc of surface around a movable vertex) gets the
//!    non-negative force along its admissible directions (the inward normal, or a friction
//!    pyramid) that best explains the residual; the best wins. A second load, at least a set
//!    distance away, is kept when it lowers χ² enough.
//! 5. **Gauss–Newton**: the loads are applied in a static solve (their forces halved while the
//!    residual grows), the tangent is factorised again about the loaded shape and the search
//!    repeated, until the places stop changing. In a stream the previous frame's loads are the
//!    start, so a held press costs one or two iterations.
//! 6. **Decision**: the likelihood-ratio statistic `Δχ² = (‖r₀‖² − ‖r‖²)/σ²` must pass the
//!    threshold and the force the minimum; the contact probability is a logistic of `Δχ²`
//!    about the threshold.

mod compliance;
mod depth;
mod free;
mod gauss_newton;
mod outliers;
mod search;
mod stream;
mod uncertainty;

use std::borrow::Cow;

use moe_geom::{FingerModel, Iso3, Point3, Real, Vector3};
use moe_tendon_sim::mechanics::StepContext;
use moe_tendon_sim::{SimError, TendonCommand};

use crate::config::{HandMaterial, PhysicsConfig};
use crate::error::PhysicsError;
use crate::mechanics::{
    FingerMechanics, PatchLoad, StaticSettings, patch_normal, turned_with_patch,
};

pub(crate) use depth::{DepthRow, nearest_depth};
use free::{DynamicFree, FreeReference};
use search::PAIR_SPACING_M;
use stream::Tracked;
use uncertainty::PressedLoads;

/// What a finger's estimate is built from, in the finger frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FingerObservation<'a> {
    /// Marker `m`, `None` when unseen.
    pub(crate) markers: &'a [Option<Point3>],
    /// Gravity, m/s² (finger frame).
    pub(crate) gravity: Vector3,
    /// Where the finger's base is in the world (the free finger is simulated in the world with
    /// its base following it).
    pub(crate) world_from_finger: Iso3,
    /// Pulled length of each tendon, metres.
    pub(crate) pulls: &'a [Real],
    /// Time of the observation, seconds (`None`: a lone frame).
    pub(crate) time_secs: Option<Real>,
    /// The depth image's observations of the surface (none without a depth image).
    pub(crate) depth: &'a [DepthRow],
    /// Per marker slot: the depth image sees an object just in front of the marker's
    /// predicted place (empty without a depth image).
    pub(crate) covered: &'a [bool],
    /// Per candidate: the depth image sees through the place an object touching the finger
    /// there would fill (empty without a depth image or with the test off).
    pub(crate) seen_through: &'a [bool],
    /// The depth image and where the finger is in the hand (none without a depth image).
    pub(crate) image: Option<(moe_geom::depth::DepthImage<'a>, Iso3)>,
}

impl FingerObservation<'_> {
    fn commands(&self) -> Vec<TendonCommand> {
        commands_of(self.pulls)
    }
}

fn commands_of(pulls: &[Real]) -> Vec<TendonCommand> {
    pulls
        .iter()
        .map(|&pull_m| TendonCommand::Displacement { pull_m })
        .collect()
}

/// One estimated load, finger frame.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FingerLoad {
    /// The patch's centre vertex.
    pub(crate) vertex: u32,
    /// The place: rest-surface vertices and weights summing to one (the posterior mean within
    /// `place_radius_m`; the centre vertex alone with a radius of 0).
    pub(crate) place: Vec<(u32, Real)>,
    /// The patch.
    pub(crate) patch: Vec<(u32, Real)>,
    /// Force, newtons.
    pub(crate) force: Vector3,
    /// Standard deviation of the force's magnitude, newtons (from the fit's information).
    pub(crate) force_sd_n: Real,
    /// Posterior standard deviation of the location on the rest surface along the finger's
    /// axis and around it (arc length at the local radius), metres.
    pub(crate) location_sd_m: [Real; 2],
}

/// A finger's estimate, finger frame.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FingerEstimate {
    /// The loads found (empty when none passed the test).
    pub(crate) loads: Vec<FingerLoad>,
    /// The estimated surface (under the loads, when any).
    pub(crate) surface: Vec<Point3>,
    /// Per vertex: contact probability.
    pub(crate) probability: Vec<Real>,
    /// Per vertex: force, newtons.
    pub(crate) vertex_force: Vec<Vector3>,
    /// Probability that the finger is pressed.
    pub(crate) pressed_probability: Real,
    /// The likelihood-ratio statistic of the best loads against none.
    pub(crate) statistic: Real,
    /// RMS of the observed marker coordinates about the free shape, metres.
    pub(crate) free_rms_m: Real,
    /// RMS about the estimate, metres.
    pub(crate) fit_rms_m: Real,
    /// Markers used.
    pub(crate) observed_markers: usize,
    /// Depth observations used (patches of pooled pixels).
    pub(crate) depth_rows: usize,
    /// Depth pixels pooled into them.
    pub(crate) depth_pixels: usize,
    /// Linear solves of the frame (Newton iterations and dynamic steps).
    pub(crate) solves: usize,
    /// Whether the load search stopped short of its converged answer (the budget spent, or
    /// a proposal of which the model could carry no part): the estimate is the best found.
    pub(crate) degraded: bool,
}

/// Rounds of a follower solve at the full load: solves under the loads as they stand, each
/// followed by the loads turned to where their patches face ([`PhysicsConfig::follow_surface`]).
const FOLLOW_ROUNDS: usize = 8;

/// A follower solve has converged when no load turns by more than this in a round, radians
/// (1°: the force along it is then within 0.02 % of the converged one, and a small press
/// costs no second solve).
const FOLLOW_TOLERANCE_RAD: Real = 0.0175;

/// A follower load whose first full solve turns it by more than this (radians, 10°) is raised
/// in the steps of [`FOLLOW_RAMP`] instead.
const FOLLOW_JUMP_RAD: Real = 0.175;

/// The fractions of its force through which a follower load is raised when the whole of it at
/// once turns too far.
const FOLLOW_RAMP: [Real; 4] = [0.2, 0.4, 0.6, 0.8];

/// The start of an observation's estimate: the free finger it is compared with.
#[derive(Debug)]
pub(crate) struct Begun {
    free: FreeReference,
    solves: usize,
}

/// The per-finger estimator.
#[derive(Debug)]
pub(crate) struct FingerInverse {
    index: usize,
    mech: FingerMechanics,
    markers: Vec<u32>,
    rest_surface: Vec<Point3>,
    faces: Vec<[u32; 3]>,
    /// Surface vertices that can move, the centres of candidate patches.
    candidates: Vec<u32>,
    /// Per candidate: its patch `(vertex, share)`.
    patches: Vec<Vec<(u32, Real)>>,
    /// Per candidate: the free nodes its patch's load acts on, `(free index, weight)`.
    patch_nodes: Vec<Vec<(u32, Real)>>,
    /// Per candidate: the surface triangles touching its patch, each weighted by the shares of
    /// its corners in the patch, whose normals a follower load turns with (built only with
    /// [`PhysicsConfig::follow_surface`]; empty otherwise).
    patch_faces: Vec<Vec<([u32; 3], Real)>>,
    /// Per surface vertex: a third of its faces' areas.
    area: Vec<Real>,
    /// Candidates at least [`PAIR_SPACING_M`] apart: the coarse pair search.
    pair_subset: Vec<usize>,
    /// Per surface vertex: the outward normal at rest.
    rest_normals: Vec<Vector3>,
    config: PhysicsConfig,
    /// The body's stiffness-proportional damping time, seconds.
    beta: Real,
    warm_static: Option<Vec<Point3>>,
    tracked: Option<Tracked>,
    /// With the lag taken out, the previous frame's loads placed on the observation as
    /// measured, to start that search from.
    tracked_measured: Option<Tracked>,
    dynamic: Option<DynamicFree>,
    /// The previous observation's contact residual and its time.
    previous_residual: Option<stream::LagResidual>,
    /// The posterior over the candidates of the previous observation's press (one load, in a
    /// stream), for `place_memory_m`.
    place_memory: Option<Vec<Real>>,
    /// This observation's prior over the candidates (normalised), when memory applies.
    place_prior: Option<Vec<Real>>,
    /// The previous observation's time and the belief then that the finger was pressed, for
    /// `press_hold_secs`.
    press_belief: Option<(Real, Real)>,
    /// Per marker slot: seen in an observation of this stream (for `hidden_marker_prior`).
    seen_in_stream: Vec<bool>,
    /// The patches depth pixels are pooled over.
    depth_patches: moe_geom::depth::SurfacePatches,
    /// The previous observation's dent (estimated surface minus free surface) while a press
    /// is held in a stream: where the depth image is predicted to see the surface.
    previous_dent: Option<Vec<Vector3>>,
    /// While a load search runs (its solves get `search_max_iterations`): the count of the
    /// frame's solves at which its budget is spent ([`PhysicsConfig::frame_solve_budget`];
    /// `usize::MAX` without one).
    budget_end: Option<usize>,
    /// Whether this frame's search stopped short (its budget, or a proposal not carried).
    degraded: bool,
    /// The last single load proposed in this stream of which no part converged: its
    /// candidate, force magnitude (newtons) and the observation's time.
    uncarried: Option<(usize, Real, Real)>,
    /// How far from its base the finger can put a marker, however it bends or stretches:
    /// twice its rest surface's furthest point, metres.
    reach_m: Real,
}

fn to_physics(finger: usize, stage: &'static str, e: SimError) -> PhysicsError {
    match e {
        SimError::StaticNotConverged {
            iterations,
            update_m,
            ..
        } => PhysicsError::StaticNotConverged {
            finger,
            stage,
            iterations,
            update_m,
        },
        source => PhysicsError::Model { finger, source },
    }
}

/// Per patch: the surface triangles touching it, each weighted by the shares of its corners in
/// the patch.
fn patch_faces(
    patches: &[Vec<(u32, Real)>],
    faces: &[[u32; 3]],
    num_vertices: usize,
) -> Vec<Vec<([u32; 3], Real)>> {
    let mut vertex_faces: Vec<Vec<u32>> = vec![Vec::new(); num_vertices];
    for (i, f) in faces.iter().enumerate() {
        for &v in f {
            vertex_faces[v as usize].push(i as u32);
        }
    }
    patches
        .iter()
        .map(|patch| {
            let mut weighted: Vec<([u32; 3], Real)> = Vec::new();
            for &(u, share) in patch {
                for &fi in &vertex_faces[u as usize] {
                    let f = faces[fi as usize];
                    match weighted.iter_mut().find(|w| w.0 == f) {
                        Some(w) => w.1 += share,
                        None => weighted.push((f, share)),
                    }
                }
            }
            weighted
        })
        .collect()
}

/// The no-load hypothesis a fit is tested against.
struct Baseline {
    /// ‖m − m(x)‖² of the free shape over the observed coordinates.
    chi0: Real,
    /// Markers used.
    observed: usize,
    /// Observed quantities (three per marker used, one per depth observation).
    n_obs: Real,
    /// Depth observations and the pixels pooled into them.
    depth: (usize, usize),
}

impl FingerInverse {
    /// Builds finger `index`'s model.
    pub(crate) fn new(
        index: usize,
        finger: &FingerModel,
        material: &HandMaterial,
        config: &PhysicsConfig,
    ) -> Result<Self, PhysicsError> {
        let mech =
            FingerMechanics::new(finger, &material.material, &config.voxel, &material.tendon)
                .map_err(|e| to_physics(index, "", e))?;
        let mesh = finger.mesh();
        let rest_surface = mesh.vertices().to_vec();
        let faces = mesh.faces().to_vec();
        let mut area = vec![0.0; rest_surface.len()];
        for (f, a) in faces.iter().zip(mesh.face_areas()) {
            for &v in f {
                area[v as usize] += a / 3.0;
            }
        }
        let movable = mech.body().movable_surface_vertices();
        let candidates: Vec<u32> = (0..rest_surface.len() as u32)
            .filter(|&v| movable[v as usize])
            .collect();
        let normals = mesh.vertex_normals();
        let r = config.patch_radius_m;
        let patches: Vec<Vec<(u32, Real)>> = candidates
            .iter()
            .map(|&c| {
                let pc = rest_surface[c as usize];
                let nc = normals[c as usize];
                let mut patch: Vec<(u32, Real)> = (0..rest_surface.len() as u32)
                    .filter_map(|u| {
                        let d = (rest_surface[u as usize] - pc).norm();
                        // One side of the surface only (thin parts have two).
                        (d <= r && movable[u as usize] && normals[u as usize].dot(&nc) > 0.3).then(
                            || {
                                (
                                    u,
                                    area[u as usize] * (1.0 - (d / r).powi(2)).max(0.0) + 1e-12,
                                )
                            },
                        )
                    })
                    .collect();
                if patch.is_empty() {
                    patch.push((c, 1.0));
                }
                let total: Real = patch.iter().map(|p| p.1).sum();
                patch.iter_mut().for_each(|p| p.1 /= total);
                patch
            })
            .collect();
        let patch_nodes = patches
            .iter()
            .map(|patch| {
                let mut nodes: Vec<(u32, Real)> = Vec::new();
                for &(u, share) in patch {
                    for (i, w) in mech.load_free_weights(u) {
                        match nodes.iter_mut().find(|n| n.0 == i) {
                            Some(n) => n.1 += share * w,
                            None => nodes.push((i, share * w)),
                        }
                    }
                }
                nodes
            })
            .collect();
        let patch_faces = if config.follow_surface {
            patch_faces(&patches, &faces, rest_surface.len())
        } else {
            Vec::new()
        };
        let mut pair_subset: Vec<usize> = Vec::new();
        for (c, &v) in candidates.iter().enumerate() {
            let p = rest_surface[v as usize];
            if pair_subset
                .iter()
                .all(|&s| (rest_surface[candidates[s] as usize] - p).norm() >= PAIR_SPACING_M)
            {
                pair_subset.push(c);
            }
        }
        let depth_patches = moe_geom::depth::SurfacePatches::new(
            &rest_surface,
            &faces,
            config.depth.patch_spacing_m,
        );
        let reach_m = 2.0
            * rest_surface
                .iter()
                .map(|p| p.coords.norm())
                .fold(0.0, Real::max);
        Ok(Self {
            index,
            mech,
            reach_m,
            pair_subset,
            depth_patches,
            previous_dent: None,
            budget_end: None,
            degraded: false,
            uncarried: None,
            rest_normals: normals.clone(),
            markers: finger.marker_vertices().to_vec(),
            rest_surface,
            faces,
            candidates,
            patches,
            patch_nodes,
            patch_faces,
            area,
            config: config.clone(),
            beta: material.material.rayleigh_stiffness,
            warm_static: None,
            tracked: None,
            tracked_measured: None,
            dynamic: None,
            previous_residual: None,
            place_memory: None,
            place_prior: None,
            press_belief: None,
            seen_in_stream: Vec::new(),
        })
    }

    /// The surface vertices of the finger's markers, by slot.
    pub(crate) fn marker_vertices(&self) -> &[u32] {
        &self.markers
    }

    /// Replaces the material (and forgets the stream).
    pub(crate) fn set_material(&mut self, material: &HandMaterial) -> Result<(), PhysicsError> {
        self.mech
            .set_material(&material.material)
            .map_err(|e| to_physics(self.index, "", e))?;
        self.beta = material.material.rayleigh_stiffness;
        self.reset();
        Ok(())
    }

    /// Forgets the stream.
    pub(crate) fn reset(&mut self) {
        self.warm_static = None;
        self.tracked = None;
        self.tracked_measured = None;
        self.dynamic = None;
        self.previous_residual = None;
        self.place_memory = None;
        self.place_prior = None;
        self.press_belief = None;
        self.seen_in_stream.clear();
        self.previous_dent = None;
        self.uncarried = None;
    }

    fn settings(&self) -> StaticSettings {
        StaticSettings {
            tolerance_m: self.config.static_tolerance_m,
            max_iterations: self.config.static_max_iterations,
        }
    }

    fn ctx(&self) -> StepContext {
        StepContext {
            step: 0,
            finger: self.index,
        }
    }

    /// Solves the static shape from `x` under `loads`, naming `stage` on failure, and adds its
    /// Newton iterations to `solves` (those of a solve that did not converge as well: they
    /// took their time). The forces of `loads` are given in the shape `given_at` (node
    /// positions; unused without loads). With [`PhysicsConfig::follow_surface`] each turns
    /// with its patch from there ([`Self::solve_following`]). Returns the loads with the
    /// forces the solution is the equilibrium of (as given, for dead loads).
    fn solve(
        &mut self,
        x: &mut Vec<Point3>,
        obs: &FingerObservation<'_>,
        loads: &[(usize, Vector3)],
        given_at: &[Point3],
        stage: &'static str,
        solves: &mut usize,
    ) -> Result<Vec<(usize, Vector3)>, PhysicsError> {
        if !self.config.follow_surface || loads.is_empty() {
            self.solve_dead(x, obs, loads, stage, solves)?;
            return Ok(loads.to_vec());
        }
        // Each patch's normal where the forces were given (`None`: a patch of no area, whose
        // load stays dead).
        let body = self.mech.body();
        let given_normals: Vec<Option<Vector3>> = loads
            .iter()
            .map(|&(c, _)| patch_normal(&self.patch_faces[c], body, given_at))
            .collect();
        let start = x.clone();
        match self.solve_following(x, obs, loads, &given_normals, &[], stage, solves) {
            Ok(turned) => Ok(turned),
            // A budget spent is final.
            Err(e @ PhysicsError::FrameBudgetSpent { .. }) => Err(e),
            Err(_) => {
                // The whole load at once took the finger elsewhere (a large press can buckle
                // a finger under a force that does not turn): again from the start, the load
                // raised in steps that each turn it to where the patch faces.
                *x = start;
                self.solve_following(x, obs, loads, &given_normals, &FOLLOW_RAMP, stage, solves)
            }
        }
    }

    /// A follower solve of `loads`, given where their patches' normals were `given_normals`:
    /// the loads raised through the fractions `ramp` of their forces (one
    /// dead solve each, the loads turned to where their patches face before each), then
    /// solved for in full, turned again and solved again until no load turns by more than
    /// [`FOLLOW_TOLERANCE_RAD`] in a round (at most [`FOLLOW_ROUNDS`]). A first full round
    /// that turns a load by more than [`FOLLOW_JUMP_RAD`] fails, so that the caller raises
    /// the load in steps instead.
    #[allow(clippy::too_many_arguments)]
    fn solve_following(
        &mut self,
        x: &mut Vec<Point3>,
        obs: &FingerObservation<'_>,
        loads: &[(usize, Vector3)],
        given_normals: &[Option<Vector3>],
        ramp: &[Real],
        stage: &'static str,
        solves: &mut usize,
    ) -> Result<Vec<(usize, Vector3)>, PhysicsError> {
        let turned_at = |this: &Self, x: &[Point3], scale: Real| -> Vec<(usize, Vector3)> {
            loads
                .iter()
                .zip(given_normals)
                .map(|(&(c, f), from)| {
                    let f = from.as_ref().map_or(f, |from| {
                        turned_with_patch(&f, from, &this.patch_faces[c], this.mech.body(), x)
                    });
                    (c, f * scale)
                })
                .collect()
        };
        for &scale in ramp {
            let part = turned_at(self, x, scale);
            self.solve_dead(x, obs, &part, stage, solves)?;
        }
        let mut current = turned_at(self, x, 1.0);
        let mut moved = Real::INFINITY;
        for round in 0..FOLLOW_ROUNDS {
            let before = x.clone();
            self.solve_dead(x, obs, &current, stage, solves)?;
            moved = x
                .iter()
                .zip(&before)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, Real::max);
            let next = turned_at(self, x, 1.0);
            let turn = next
                .iter()
                .zip(&current)
                .map(|(a, b)| a.1.angle(&b.1))
                .fold(0.0, Real::max);
            if turn <= FOLLOW_TOLERANCE_RAD {
                // The forces `x` is the equilibrium of.
                return Ok(current);
            }
            if round == 0 && ramp.is_empty() && turn > FOLLOW_JUMP_RAD {
                break;
            }
            // Half way to where the patches face: a load that turns strongly with its own
            // press makes the plain fixed point oscillate.
            current = next
                .iter()
                .zip(&current)
                .map(|(n, c)| {
                    let half = nalgebra::Rotation3::rotation_between(&c.1, &n.1)
                        .map_or(n.1, |r| r.powf(0.5) * c.1);
                    (n.0, half)
                })
                .collect();
        }
        Err(PhysicsError::StaticNotConverged {
            finger: self.index,
            stage,
            iterations: FOLLOW_ROUNDS,
            update_m: moved,
        })
    }

    /// Solves the static shape from `x` under the dead loads `loads`, as [`Self::solve`].
    fn solve_dead(
        &mut self,
        x: &mut Vec<Point3>,
        obs: &FingerObservation<'_>,
        loads: &[(usize, Vector3)],
        stage: &'static str,
        solves: &mut usize,
    ) -> Result<(), PhysicsError> {
        let mut settings = self.settings();
        // Within a load search, a solve gets at most its own iterations, and what is left of
        // the frame's budget.
        let mut capped = false;
        if let Some(end) = self.budget_end {
            settings.max_iterations = settings
                .max_iterations
                .min(self.config.search_max_iterations);
            let left = end.saturating_sub(*solves);
            if left == 0 {
                self.degraded = true;
                return Err(PhysicsError::FrameBudgetSpent {
                    finger: self.index,
                    budget: self.config.frame_solve_budget,
                });
            }
            if left < settings.max_iterations {
                settings.max_iterations = left;
                capped = true;
            }
        }
        let ctx = self.ctx();
        let patch: Vec<PatchLoad> = loads
            .iter()
            .map(|&(c, force)| PatchLoad {
                patch: self.patches[c].clone(),
                force,
            })
            .collect();
        match self
            .mech
            .solve_static(x, &obs.commands(), &obs.gravity, &patch, settings, ctx)
        {
            Ok(iterations) => {
                *solves += iterations;
                Ok(())
            }
            Err(SimError::StaticNotConverged { iterations, .. }) if capped => {
                *solves += iterations;
                self.degraded = true;
                Err(PhysicsError::FrameBudgetSpent {
                    finger: self.index,
                    budget: self.config.frame_solve_budget,
                })
            }
            Err(e) => {
                if let SimError::StaticNotConverged { iterations, .. } = e {
                    *solves += iterations;
                }
                Err(to_physics(self.index, stage, e))
            }
        }
    }

    /// Surface positions for nodes `x`.
    fn surface_of(&self, x: &[Point3]) -> Vec<Point3> {
        self.mech.body().surface().positions(x)
    }

    /// ‖m − m(x)‖² over the observed coordinates of `obs` and the whitened squared residuals
    /// of its depth observations.
    fn residual_sq(&self, x: &[Point3], obs: &FingerObservation<'_>) -> Real {
        let markers: Real = obs
            .markers
            .iter()
            .zip(&self.markers)
            .filter_map(|(m, &v)| m.map(|p| (p - self.mech.surface_position(x, v)).norm_squared()))
            .sum();
        markers + self.depth_residual_sq(x, obs.depth)
    }

    /// Estimates the finger's loads and shape from one observation.
    pub(crate) fn estimate(
        &mut self,
        obs: &FingerObservation<'_>,
    ) -> Result<FingerEstimate, PhysicsError> {
        let begun = self.begin(obs)?;
        self.finish(obs, begun)
    }

    /// The first part of an estimate: the markers counted and the free finger found (the
    /// simulated one advanced to the observation, in a stream).
    pub(crate) fn begin(&mut self, obs: &FingerObservation<'_>) -> Result<Begun, PhysicsError> {
        // A marker further from the finger's base than it can reach is not on it.
        let reach_m = self.reach_m;
        for (marker, m) in obs.markers.iter().enumerate() {
            if let Some(p) = m {
                let distance_m = p.coords.norm();
                if distance_m > reach_m {
                    self.reset();
                    return Err(PhysicsError::MarkerOffFinger {
                        finger: self.index,
                        marker,
                        distance_m,
                        reach_m,
                    });
                }
            }
        }
        let observed = obs.markers.iter().filter(|m| m.is_some()).count();
        if observed < self.config.min_markers {
            self.reset();
            return Err(PhysicsError::TooFewMarkers {
                finger: self.index,
                observed,
                needed: self.config.min_markers,
            });
        }
        let mut solves = 0;
        match self.free_reference(obs, &mut solves) {
            Ok(free) => Ok(Begun { free, solves }),
            Err(e) => {
                self.tracked = None;
                Err(e)
            }
        }
    }

    /// Where the surface is expected, finger frame: the free finger with the previous
    /// observation's dent while a press is held.
    pub(crate) fn predicted_surface(&self, begun: &Begun) -> Vec<Point3> {
        let mut surface = self.surface_of(&begun.free.x);
        if let Some(dent) = self.previous_dent.as_ref().filter(|_| begun.free.dynamic) {
            surface.iter_mut().zip(dent).for_each(|(p, d)| *p += d);
        }
        surface
    }

    /// The rest of an estimate begun by [`Self::begin`] with the same observation (now with
    /// its depth observations, when any).
    pub(crate) fn finish(
        &mut self,
        obs: &FingerObservation<'_>,
        begun: Begun,
    ) -> Result<FingerEstimate, PhysicsError> {
        self.degraded = false;
        let mut result = self.estimate_observed(obs, begun);
        self.budget_end = None;
        if let Ok(est) = result.as_mut() {
            est.degraded = self.degraded;
        }
        match &result {
            Ok(est) if !est.loads.is_empty() => {}
            Ok(_) => {
                self.previous_dent = None;
                self.tracked_measured = None;
            }
            Err(_) => {
                self.tracked = None;
                self.tracked_measured = None;
                self.previous_dent = None;
            }
        }
        result
    }

    /// Estimates the loads and shape from an observation with enough markers, from its free
    /// finger.
    fn estimate_observed(
        &mut self,
        obs: &FingerObservation<'_>,
        begun: Begun,
    ) -> Result<FingerEstimate, PhysicsError> {
        let sigma2 = self.config.marker_sigma_m.powi(2);
        let Begun { free, mut solves } = begun;
        let observed = obs.markers.iter().filter(|m| m.is_some()).count();
        self.update_place_prior(obs, free.dynamic);
        // With the contact response's lag taken out, whether the finger is pressed and how hard
        // are read from the corrected observation; `raw` keeps it as measured.
        let raw = obs;
        let corrected = self.contact_lag_corrected(obs, &free.x);
        let lagged = corrected.is_some();
        let (markers, depth_rows) = match corrected {
            Some((markers, rows)) => (markers, Cow::Owned(rows)),
            None => (obs.markers.to_vec(), Cow::Borrowed(obs.depth)),
        };
        let obs = &FingerObservation {
            depth: &depth_rows,
            ..*obs
        };
        let depth = (
            obs.depth.len(),
            obs.depth.iter().map(|r| r.pixels).sum::<usize>(),
        );
        let base = Baseline {
            chi0: self.residual_sq(
                &free.x,
                &FingerObservation {
                    markers: &markers,
                    ..*obs
                },
            ),
            observed,
            n_obs: (3 * observed + depth.0) as Real,
            depth,
        };
        // The belief that the finger is pressed, before this observation's evidence (even odds
        // without memory); the evidence is the statistic against the detection threshold.
        let prior_logit = self.press_prior_logit(obs, free.dynamic);
        let threshold = self.config.detection_chi2;
        let belief =
            move |statistic: Real| logistic(prior_logit + (statistic - threshold) / EVIDENCE_SCALE);
        let remember = |this: &mut Self, p: Real| {
            this.press_belief = obs.time_secs.map(|t| (t, p));
        };
        // Nothing to explain: no load can pass the test (χ² of no load bounds the statistic; the
        // belief remembered is that bound's, below even odds).
        if belief(base.chi0 / sigma2) < 0.5 {
            self.tracked = None;
            remember(self, belief(base.chi0 / sigma2));
            return Ok(self.free_estimate(&free.x, &base, 0.0, solves));
        }
        let start = self.static_start(obs, &free, markers, &mut solves)?;
        // The searches that follow share the frame's budget, in a stream: a lone frame or the
        // first of a stream has no previous press to start from, and searches in full.
        self.budget_end = Some(if self.config.frame_solve_budget > 0 && free.dynamic {
            solves + self.config.frame_solve_budget
        } else {
            usize::MAX
        });
        let sobs = FingerObservation {
            markers: &start.markers,
            depth: &start.depth,
            ..*obs
        };
        // With the lag taken out, the model's misfit is amplified with the rest, so the share
        // of the residual a held press leaves says little of whether the press moved: the
        // place is searched again on the observation as measured, with that test.
        let (state, lin) =
            self.search_held_press(&sobs, &start.x, base.chi0, !lagged, &mut solves)?;
        // The place found, probed again on the surface its load makes: where that surface's
        // own place is seen through, the places seen through on it are made less likely and
        // the search runs again.
        let (state, lin) = match (&obs.image, state.loads.as_slice()) {
            (Some((image, hand_from_finger)), [(c, _)])
                if self.config.depth.seen_through_prior < 1.0 =>
            {
                let fitted = self.surface_of(&state.x);
                if self.seen_through_at(image, &fitted, hand_from_finger, *c) {
                    let flags = self.seen_through(image, &fitted, hand_from_finger, false);
                    let prior = self.place_prior.take();
                    self.place_prior = self.with_seen_through(prior, &flags);
                    self.search_held_press(&sobs, &start.x, base.chi0, !lagged, &mut solves)?
                } else {
                    (state, lin)
                }
            }
            _ => (state, lin),
        };
        // A marker the best fit leaves far off — a blob taken for the wrong marker; no load of
        // the model moves one marker millimetres away from where its neighbours put it — is
        // left out, and the loads are searched again from the free shape without it.
        let (base, state, lin, left_out) = match self.outlier(&state.x, &start.markers, observed) {
            Some(worst) => {
                let (base, state, lin) =
                    self.search_without_marker(obs, &start, worst, &base, &mut solves)?;
                (base, state, lin, Some(worst))
            }
            None => (base, state, lin, None),
        };
        // A second load that no longer pays its way is dropped by the test above; a pair
        // carried from the previous frame is kept while each load carries the minimum force.
        let statistic = (base.chi0 - state.chi) / sigma2;
        let total_force: Real = state.loads.iter().map(|l| l.1.norm()).sum();
        let pressed_probability = belief(statistic);
        // The force floor guards onsets against tiny fits; a press held from the previous
        // observation (memory) is followed down to any force.
        let floor = if prior_logit > 0.0 {
            0.0
        } else {
            self.config.min_force_n
        };
        let pressed = pressed_probability >= 0.5 && total_force > 0.0 && total_force >= floor;
        if !pressed {
            self.tracked = None;
            remember(self, pressed_probability);
            return Ok(self.free_estimate(&free.x, &base, statistic, solves));
        }
        remember(self, pressed_probability);
        // The lag scales the dent but does not move it: with the lag taken out, the place and
        // the shape come from the observation as measured, whose noise the correction does not
        // amplify, and the forces from the corrected one.
        let placed = if lagged {
            self.place_as_measured(raw, &free, &start.x, left_out, &state, &mut solves)?
        } else {
            None
        };
        let (shape_state, shape_lin) = match &placed {
            Some((s, l)) => (s, l),
            None => (&state, &lin),
        };
        let PressedLoads {
            loads,
            probability,
            vertex_force,
            posteriors,
        } = self.describe_loads(shape_lin, shape_state, pressed_probability);
        self.remember_press(posteriors, &state);
        let surface = self.estimated_surface(&free, &shape_state.x, &start.x);
        let free_surface = self.surface_of(&free.x);
        self.previous_dent = Some(
            surface
                .iter()
                .zip(&free_surface)
                .map(|(p, q)| p - q)
                .collect(),
        );
        Ok(FingerEstimate {
            loads,
            surface,
            probability,
            vertex_force,
            pressed_probability,
            statistic,
            free_rms_m: (base.chi0 / base.n_obs).sqrt(),
            fit_rms_m: (state.chi / base.n_obs).sqrt(),
            observed_markers: base.observed,
            depth_rows: base.depth.0,
            depth_pixels: base.depth.1,
            solves,
            degraded: false,
        })
    }

    /// The loads of a pressed observation placed on `raw`, the observation as measured (with
    /// the marker `left_out` of the corrected fit left out here too), with the total force of
    /// `corrected`, the fit to the observation with the lag taken out; `None` when no load
    /// explains `raw`.
    fn place_as_measured(
        &mut self,
        raw: &FingerObservation<'_>,
        free: &free::FreeReference,
        x_static: &[Point3],
        left_out: Option<usize>,
        corrected: &gauss_newton::Solved,
        solves: &mut usize,
    ) -> Result<Option<(gauss_newton::Solved, compliance::Linear)>, PhysicsError> {
        let mut markers = raw.markers.to_vec();
        if let Some(worst) = left_out {
            markers[worst] = None;
        }
        let start = self.start_on(raw.depth, free, x_static.to_vec(), markers);
        let robs = FingerObservation {
            markers: &start.markers,
            depth: &start.depth,
            ..*raw
        };
        let chi0 = self.residual_sq(&start.x, &robs);
        // Started from the previous frame's loads on the measured observation; the corrected
        // fit's loads are remembered apart.
        let corrected_tracked = self.tracked.take();
        self.tracked = self.tracked_measured.take();
        let searched = self.search_held_press(&robs, &start.x, chi0, true, solves);
        self.tracked = corrected_tracked;
        let (mut state, lin) = searched?;
        self.tracked_measured = Some(Tracked {
            x: state.x.clone(),
            loads: state.loads.clone(),
        });
        let measured: Real = state.loads.iter().map(|l| l.1.norm()).sum();
        let wanted: Real = corrected.loads.iter().map(|l| l.1.norm()).sum();
        if !(measured > 0.0 && state.chi < chi0) {
            return Ok(None);
        }
        let scale = wanted / measured;
        state.loads.iter_mut().for_each(|l| l.1 *= scale);
        Ok(Some((state, lin)))
    }
}

/// Units of χ² per unit of log-odds of the evidence for a press: the statistic's excess over
/// the detection threshold, tempered (a χ² difference `Δ` is a likelihood ratio of `e^{Δ/2}`
/// for an exact model; the model error makes it a weaker one).
const EVIDENCE_SCALE: Real = 4.0;

fn logistic(t: Real) -> Real {
    1.0 / (1.0 + (-t).exp())
}
