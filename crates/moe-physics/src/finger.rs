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

use moe_geom::math::UnitQuat;
use moe_geom::{FingerModel, Iso3, Point3, Real, Vector3};
use moe_tendon_sim::mechanics::StepContext;
use moe_tendon_sim::{BodyState, SimError, TendonCommand};
use nalgebra::{DMatrix, DVector};

use crate::config::{HandMaterial, PhysicsConfig};
use crate::error::PhysicsError;
use crate::mechanics::{FingerMechanics, PatchLoad, StaticSettings};
use crate::nnls::nnls;

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
    /// Linear solves of the frame (Newton iterations and dynamic steps).
    pub(crate) solves: usize,
}

/// The linear model of the markers about one configuration.
struct Linear {
    /// Observed coordinates.
    n_obs: usize,
    /// Residual to explain: the free residual linearised at the configuration.
    r: Vec<Real>,
    /// `responses[(c·3 + d)·n_obs + j]`: response of observed coordinate `j` to a unit force
    /// along axis `d` over candidate `c`'s patch.
    responses: Vec<Real>,
    /// Per candidate: inward unit normal over its patch.
    inward: Vec<Vector3>,
}

impl Linear {
    /// The response of the observed coordinates to force `f` at candidate `c`, into `out`.
    fn response_into(&self, c: usize, f: &Vector3, out: &mut [Real]) {
        let n = self.n_obs;
        let base = 3 * c * n;
        for (j, o) in out.iter_mut().enumerate().take(n) {
            *o = self.responses[base + j] * f.x
                + self.responses[base + n + j] * f.y
                + self.responses[base + 2 * n + j] * f.z;
        }
    }

    fn response(&self, c: usize, f: &Vector3) -> Vec<Real> {
        let mut out = vec![0.0; self.n_obs];
        self.response_into(c, f, &mut out);
        out
    }
}

fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// A fit of loads at some candidates.
#[derive(Debug, Clone)]
struct Fit {
    candidates: Vec<usize>,
    forces: Vec<Vector3>,
    residual_sq: Real,
}

/// A static solution under some loads.
#[derive(Debug, Clone)]
struct Solved {
    /// Node positions.
    x: Vec<Point3>,
    /// `(candidate, force)`.
    loads: Vec<(usize, Vector3)>,
    /// ‖m − m(x)‖² over the observed coordinates.
    chi: Real,
}

/// The previous frame's loads, to start from.
#[derive(Debug, Clone)]
struct Tracked {
    x: Vec<Point3>,
    loads: Vec<(usize, Vector3)>,
}

/// The free finger simulated through the stream, in the world frame with its base following
/// the wrist (as the hand moves, the finger's inertia shows).
#[derive(Debug, Clone)]
struct DynamicFree {
    state: BodyState,
    time_secs: Real,
    pulls: Vec<Real>,
    world_from_finger: Iso3,
    /// Gravity in the world frame, m/s².
    gravity: Vector3,
}

/// The pose a fraction `a` of the way from `p0` to `p1` (translation linear, rotation slerp).
fn interpolate(p0: &Iso3, p1: &Iso3, a: Real) -> Iso3 {
    let t = p0.translation.vector.lerp(&p1.translation.vector, a);
    let r: UnitQuat = p0.rotation.slerp(&p1.rotation, a);
    Iso3::from_parts(t.into(), r)
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
    dynamic: Option<DynamicFree>,
    /// The previous observation's contact residual and its time.
    previous_residual: Option<(Real, Vec<Option<Vector3>>)>,
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

/// What the free finger is compared with: the simulated one of a stream, or the static one.
struct FreeReference {
    /// Node positions.
    x: Vec<Point3>,
    /// True when `x` is the simulated (dynamic) free finger.
    dynamic: bool,
}

/// The no-load hypothesis a fit is tested against.
struct Baseline {
    /// ‖m − m(x)‖² of the free shape over the observed coordinates.
    chi0: Real,
    /// Markers used.
    observed: usize,
    /// Observed coordinates (three per marker used).
    n_obs: Real,
}

/// Where the loads are searched from: the static free shape and the markers moved onto it.
struct StaticStart {
    /// Node positions of the static free shape.
    x: Vec<Point3>,
    /// The markers as the static model sees them.
    markers: Vec<Option<Point3>>,
}

/// The loads of a press, described for the estimate.
struct PressedLoads {
    loads: Vec<FingerLoad>,
    /// Per surface vertex: the probability that it is in contact.
    probability: Vec<Real>,
    /// Per surface vertex: the force the loads put on it.
    vertex_force: Vec<Vector3>,
    /// Per load: the normalised posterior over the candidates (empty when undefined).
    posteriors: Vec<Vec<Real>>,
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
        Ok(Self {
            index,
            mech,
            pair_subset,
            rest_normals: normals.clone(),
            markers: finger.marker_vertices().to_vec(),
            rest_surface,
            faces,
            candidates,
            patches,
            patch_nodes,
            area,
            config: config.clone(),
            beta: material.material.rayleigh_stiffness,
            warm_static: None,
            tracked: None,
            dynamic: None,
            previous_residual: None,
            place_memory: None,
            place_prior: None,
            press_belief: None,
            seen_in_stream: Vec::new(),
        })
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

    /// `‖m − m_free‖²` and the number of observed coordinates of one observation, the free
    /// finger simulated through the stream as the estimate does (no load is searched).
    pub(crate) fn free_residual(
        &mut self,
        obs: &FingerObservation<'_>,
    ) -> Result<(Real, usize), PhysicsError> {
        let mut solves = 0;
        let x = match self.advance_dynamic(obs, &mut solves) {
            Some(x) => x,
            None => {
                let x = self.static_free(obs, &mut solves)?;
                self.start_dynamic(obs, &x);
                x
            }
        };
        let n = 3 * obs.markers.iter().filter(|m| m.is_some()).count();
        Ok((self.marker_residual_sq(&x, obs.markers), n))
    }

    /// Forgets the stream.
    pub(crate) fn reset(&mut self) {
        self.warm_static = None;
        self.tracked = None;
        self.dynamic = None;
        self.previous_residual = None;
        self.place_memory = None;
        self.place_prior = None;
        self.press_belief = None;
        self.seen_in_stream.clear();
    }

    /// The log-odds, before this observation's evidence, that the finger is pressed: even odds
    /// without memory or at a stream's first observation. In a stream with `press_hold_secs`
    /// τ, a press believed with probability `p` at the previous observation persists over `Δt`
    /// with probability `a = exp(−Δt/τ)` and is otherwise as likely as not, and a free finger
    /// may be pressed at any observation as likely as not (onsets are not delayed):
    /// `p·(a + (1 − a)/2) + (1 − p)/2 = 1/2 + p·a/2`.
    fn press_prior_logit(&self, obs: &FingerObservation<'_>, stream: bool) -> Real {
        let tau = self.config.press_hold_secs;
        match (self.press_belief, obs.time_secs) {
            (Some((t0, p)), Some(t)) if tau > 0.0 && stream && t > t0 => {
                let a = (-(t - t0) / tau).exp();
                let prior = (0.5 + 0.5 * p * a).min(1.0 - 1e-12);
                (prior / (1.0 - prior)).ln()
            }
            _ => 0.0,
        }
    }

    /// The place prior `prior` (area-weighted when `None`) with the evidence of markers `lost`
    /// (per slot: seen earlier in the stream, hidden now): a marker the camera loses is most
    /// often hidden by the object pressing the finger there, so places within
    /// `hidden_marker_radius_m` of a lost marker are made `1 + hidden_marker_prior` times as
    /// likely (a Gaussian falloff). Unchanged without lost markers or with
    /// `hidden_marker_prior = 0`.
    fn with_hidden_markers(&self, prior: Option<Vec<Real>>, lost: &[bool]) -> Option<Vec<Real>> {
        let k = self.config.hidden_marker_prior;
        let hidden: Vec<Point3> = lost
            .iter()
            .zip(&self.markers)
            .filter(|(l, _)| **l)
            .map(|(_, &v)| self.rest_surface[v as usize])
            .collect();
        if k <= 0.0 || hidden.is_empty() {
            return prior;
        }
        let s2 = 2.0 * self.config.hidden_marker_radius_m.powi(2);
        let mut out: Vec<Real> = (0..self.candidates.len())
            .map(|c| {
                let p = self.rest_surface[self.candidates[c] as usize];
                let near: Real = hidden
                    .iter()
                    .map(|h| (-(p - h).norm_squared() / s2).exp())
                    .fold(0.0, Real::max);
                let base = match &prior {
                    Some(prior) => prior[c],
                    None => self.area[self.candidates[c] as usize],
                };
                base * (1.0 + k * near)
            })
            .collect();
        let total: Real = out.iter().sum();
        if total.is_finite() && total > 0.0 {
            out.iter_mut().for_each(|w| *w /= total);
            Some(out)
        } else {
            prior
        }
    }

    /// The prior over the candidates of a press in this observation from the previous one's
    /// posterior `memory`: each candidate's probability spread by a Gaussian step of
    /// `place_memory_m` on the rest surface, mixed with a new press anywhere (area-weighted)
    /// with probability [`NEW_PLACE_PROBABILITY`].
    fn propagate(&self, memory: &[Real]) -> Vec<Real> {
        let s2 = 2.0 * self.config.place_memory_m.powi(2);
        let position = |c: usize| self.rest_surface[self.candidates[c] as usize];
        let area = |c: usize| self.area[self.candidates[c] as usize];
        let total_area: Real = (0..self.candidates.len()).map(area).sum();
        let peak = memory.iter().copied().fold(0.0, Real::max);
        let mut prior: Vec<Real> = (0..self.candidates.len())
            .map(|c| NEW_PLACE_PROBABILITY * area(c) / total_area)
            .collect();
        let mut kernel = vec![0.0; self.candidates.len()];
        for (from, &m) in memory.iter().enumerate() {
            if m <= 1e-9 * peak {
                continue;
            }
            let p = position(from);
            let mut sum = 0.0;
            for (c, k) in kernel.iter_mut().enumerate() {
                *k = (-(position(c) - p).norm_squared() / s2).exp();
                sum += *k;
            }
            let share = (1.0 - NEW_PLACE_PROBABILITY) * m / sum;
            for (q, k) in prior.iter_mut().zip(&kernel) {
                *q += share * k;
            }
        }
        let total: Real = prior.iter().sum();
        prior.iter_mut().for_each(|q| *q /= total);
        prior
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

    /// Solves the static shape from `x` under `loads`, naming `stage` on failure.
    fn solve(
        &mut self,
        x: &mut Vec<Point3>,
        obs: &FingerObservation<'_>,
        loads: &[(usize, Vector3)],
        stage: &'static str,
    ) -> Result<usize, PhysicsError> {
        let settings = self.settings();
        let ctx = self.ctx();
        let patch: Vec<PatchLoad> = loads
            .iter()
            .map(|&(c, force)| PatchLoad {
                patch: self.patches[c].clone(),
                force,
            })
            .collect();
        self.mech
            .solve_static(x, &obs.commands(), &obs.gravity, &patch, settings, ctx)
            .map_err(|e| to_physics(self.index, stage, e))
    }

    /// The static free shape under the observation's pulls and gravity, warm-started from the
    /// previous one (from rest when that fails).
    fn static_free(
        &mut self,
        obs: &FingerObservation<'_>,
        solves: &mut usize,
    ) -> Result<Vec<Point3>, PhysicsError> {
        const STAGE: &str = "(free shape under the pulls)";
        if let Some(mut x) = self.warm_static.take()
            && let Ok(it) = self.solve(&mut x, obs, &[], STAGE)
        {
            *solves += it;
            self.warm_static = Some(x.clone());
            return Ok(x);
        }
        let mut x = self.mech.rest_nodes().to_vec();
        *solves += self.solve(&mut x, obs, &[], STAGE)?;
        self.warm_static = Some(x.clone());
        Ok(x)
    }

    /// Advances the simulated free finger to the observation's time (pulls interpolated
    /// linearly from the previous observation's). `None` for a lone observation, the first of a
    /// stream, after a gap longer than the horizon, or when a step fails: the stream then
    /// starts again from the static free shape (computed on demand by `start`).
    fn advance_dynamic(
        &mut self,
        obs: &FingerObservation<'_>,
        solves: &mut usize,
    ) -> Option<Vec<Point3>> {
        let t = obs.time_secs?;
        if self.config.dynamic_step_secs <= 0.0 {
            self.dynamic = None;
            return None;
        }
        let mut d = match self.dynamic.take() {
            Some(d)
                if t > d.time_secs
                    && t - d.time_secs <= self.config.stream_reach_secs()
                    && d.pulls.len() == obs.pulls.len() =>
            {
                d
            }
            _ => return None,
        };
        let span = t - d.time_secs;
        let n = ((span / self.config.dynamic_step_secs - 1e-9)
            .ceil()
            .max(1.0) as usize)
            .min(self.config.max_dynamic_steps);
        let h = span / n as Real;
        let ctx = self.ctx();
        let rest = self.mech.rest_nodes().to_vec();
        for k in 1..=n {
            let a = k as Real / n as Real;
            let pulls: Vec<Real> = d
                .pulls
                .iter()
                .zip(obs.pulls)
                .map(|(p0, p1)| p0 + a * (p1 - p0))
                .collect();
            let commands = commands_of(&pulls);
            let pose = interpolate(&d.world_from_finger, &obs.world_from_finger, a);
            let targets: Vec<Point3> = rest.iter().map(|p| pose * p).collect();
            if self
                .mech
                .step_free(&mut d.state, &commands, &d.gravity, &targets, h, ctx)
                .is_err()
            {
                return None;
            }
            *solves += 1;
        }
        d.time_secs = t;
        d.pulls = obs.pulls.to_vec();
        d.world_from_finger = obs.world_from_finger;
        let finger_from_world = obs.world_from_finger.inverse();
        let x = d.state.x.iter().map(|p| finger_from_world * p).collect();
        self.dynamic = Some(d);
        Some(x)
    }

    /// Starts the simulated free finger at rest in the static shape `x`.
    fn start_dynamic(&mut self, obs: &FingerObservation<'_>, x: &[Point3]) {
        self.dynamic = match (obs.time_secs, self.config.dynamic_step_secs > 0.0) {
            (Some(t), true) => Some(DynamicFree {
                state: BodyState {
                    x: x.iter().map(|p| obs.world_from_finger * p).collect(),
                    v: vec![Vector3::zeros(); x.len()],
                },
                time_secs: t,
                pulls: obs.pulls.to_vec(),
                world_from_finger: obs.world_from_finger,
                gravity: obs.world_from_finger * obs.gravity,
            }),
            _ => None,
        };
    }

    /// Markers with the lag of the contact response taken out. The part of the markers that
    /// contact moves, `r = m − m_free`, follows its static value `u` with the body's damping
    /// time `β` (a first-order lag); for `u` held over the interval since the previous
    /// observation, `r_t = a r_{t−1} + (1 − a) u` with `a = exp(−Δt/β)`, so
    /// `u = (r_t − a r_{t−1}) / (1 − a)`, taken with the configured gain. `None` without a
    /// previous residual in the stream.
    fn contact_lag_corrected(
        &mut self,
        obs: &FingerObservation<'_>,
        x_free: &[Point3],
    ) -> Option<Vec<Option<Point3>>> {
        let residual: Vec<Option<Vector3>> = obs
            .markers
            .iter()
            .zip(&self.markers)
            .map(|(m, &v)| m.map(|p| p - self.mech.surface_position(x_free, v)))
            .collect();
        let previous = self.previous_residual.take();
        self.previous_residual = obs.time_secs.map(|t| (t, residual.clone()));
        let gain = self.config.contact_lag_gain;
        let (t, (t0, r0)) = (obs.time_secs?, previous?);
        let dt = t - t0;
        if !(gain > 0.0 && self.beta > 0.0 && dt > 0.0 && dt <= self.config.stream_reach_secs()) {
            return None;
        }
        let a = (-dt / self.beta).exp();
        Some(
            obs.markers
                .iter()
                .zip(residual.iter().zip(&r0))
                .map(|(m, (r, r0))| {
                    let (p, r) = (m.as_ref()?, r.as_ref()?);
                    Some(match r0 {
                        Some(r0) => p + ((r - r0 * a) / (1.0 - a) - r) * gain,
                        None => *p,
                    })
                })
                .collect(),
        )
    }

    /// Surface positions for nodes `x`.
    fn surface_of(&self, x: &[Point3]) -> Vec<Point3> {
        self.mech.body().surface().positions(x)
    }

    /// Vertex normals of the surface `s` (area-weighted).
    fn normals_of(&self, s: &[Point3]) -> Vec<Vector3> {
        let mut n = vec![Vector3::zeros(); s.len()];
        for f in &self.faces {
            let [a, b, c] = f.map(|i| s[i as usize]);
            let fn_ = (b - a).cross(&(c - a));
            for &i in f {
                n[i as usize] += fn_;
            }
        }
        n.iter_mut().for_each(|v| {
            if let Some(u) = v.try_normalize(0.0) {
                *v = u;
            }
        });
        n
    }

    /// ‖m − m(x)‖² over the observed coordinates.
    fn marker_residual_sq(&self, x: &[Point3], markers: &[Option<Point3>]) -> Real {
        markers
            .iter()
            .zip(&self.markers)
            .filter_map(|(m, &v)| m.map(|p| (p - self.mech.surface_position(x, v)).norm_squared()))
            .sum()
    }

    /// The marker (slot) that nodes `x` leave furthest from its observation, when that is more
    /// than `outlier_sigma` standard deviations and a marker can be spared (`observed` above
    /// the fewest the estimator works with).
    fn outlier(&self, x: &[Point3], markers: &[Option<Point3>], observed: usize) -> Option<usize> {
        let limit = self.config.outlier_sigma * self.config.marker_sigma_m;
        if limit.is_nan() || limit <= 0.0 || observed <= self.config.min_markers {
            return None;
        }
        markers
            .iter()
            .zip(&self.markers)
            .enumerate()
            .filter_map(|(slot, (m, &v))| {
                m.map(|p| (slot, (p - self.mech.surface_position(x, v)).norm()))
            })
            .filter(|&(_, d)| d > limit)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(slot, _)| slot)
    }

    /// The linear model about nodes `x` where `loads` act.
    fn linearise(
        &mut self,
        x: &[Point3],
        obs: &FingerObservation<'_>,
        loads: &[(usize, Vector3)],
        solves: &mut usize,
    ) -> Result<Linear, PhysicsError> {
        let mut axes = Vec::new();
        let mut r = Vec::new();
        for (slot, m) in obs.markers.iter().enumerate() {
            if let Some(p) = m {
                let v = self.markers[slot];
                let model = self.mech.surface_position(x, v);
                for d in 0..3 {
                    axes.push((v, d));
                    r.push(p[d] - model[d]);
                }
            }
        }
        let patch_loads: Vec<PatchLoad> = loads
            .iter()
            .map(|&(c, force)| PatchLoad {
                patch: self.patches[c].clone(),
                force,
            })
            .collect();
        let ctx = self.ctx();
        let fields = self
            .mech
            .reciprocal_fields(x, &obs.commands(), &obs.gravity, &patch_loads, &axes, ctx)
            .map_err(|e| to_physics(self.index, "(tangent)", e))?;
        *solves += 1;
        let n_obs = axes.len();
        // Row-major copy: row `3i + d` holds the `n_obs` responses at free node `i`, axis `d`.
        let rows = fields.nrows();
        let mut rm = vec![0.0; rows * n_obs];
        for j in 0..n_obs {
            for row in 0..rows {
                rm[row * n_obs + j] = fields[(row, j)];
            }
        }
        let nc = self.candidates.len();
        let mut responses = vec![0.0; 3 * nc * n_obs];
        for (c, nodes) in self.patch_nodes.iter().enumerate() {
            let out = &mut responses[3 * c * n_obs..3 * (c + 1) * n_obs];
            for &(i, w) in nodes {
                for d in 0..3 {
                    let src = &rm[(3 * i as usize + d) * n_obs..(3 * i as usize + d + 1) * n_obs];
                    let dst = &mut out[d * n_obs..(d + 1) * n_obs];
                    for (o, s) in dst.iter_mut().zip(src) {
                        *o += w * s;
                    }
                }
            }
        }
        let normals = self.normals_of(&self.surface_of(x));
        let inward = self
            .patches
            .iter()
            .map(|patch| {
                let n: Vector3 = patch.iter().map(|&(u, s)| normals[u as usize] * s).sum();
                -n.try_normalize(0.0).unwrap_or_else(Vector3::zeros)
            })
            .collect();
        let mut lin = Linear {
            n_obs,
            r,
            responses,
            inward,
        };
        let mut buf = vec![0.0; n_obs];
        for &(c, f) in loads {
            lin.response_into(c, &f, &mut buf);
            for (r, b) in lin.r.iter_mut().zip(&buf) {
                *r += b;
            }
        }
        Ok(lin)
    }

    /// The admissible force directions at a patch with inward normal `inward`: the normal, or
    /// the edges of the friction pyramid around it.
    fn directions(&self, inward: &Vector3) -> Vec<Vector3> {
        let mu = self.config.friction;
        if mu <= 0.0 {
            return vec![*inward];
        }
        let helper = if inward.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let t1 = inward.cross(&helper).normalize();
        let t2 = inward.cross(&t1);
        vec![
            inward + t1 * mu,
            inward - t1 * mu,
            inward + t2 * mu,
            inward - t2 * mu,
        ]
    }

    /// The best single load at candidate `c` for residual `r`, with its residual.
    fn fit_single(
        &self,
        lin: &Linear,
        r: &[Real],
        r_sq: Real,
        c: usize,
        buf: &mut [Real],
    ) -> (Vector3, Real) {
        if self.config.friction <= 0.0 {
            let n = lin.inward[c];
            lin.response_into(c, &n, buf);
            let uu = dot(buf, buf);
            let ur = dot(buf, r);
            if uu > 0.0 && ur > 0.0 {
                (n * (ur / uu), (r_sq - ur * ur / uu).max(0.0))
            } else {
                (Vector3::zeros(), r_sq)
            }
        } else {
            let fit = self.fit(lin, r, &[c]);
            (fit.forces[0], fit.residual_sq)
        }
    }

    /// The best single load at every candidate for residual `r`.
    fn single_fits(&self, lin: &Linear, r: &[Real]) -> Vec<(Vector3, Real)> {
        let r_sq = dot(r, r);
        let mut buf = vec![0.0; lin.n_obs];
        (0..self.candidates.len())
            .map(|c| self.fit_single(lin, r, r_sq, c, &mut buf))
            .collect()
    }

    /// Fits loads at `cands` to residual `r`: non-negative combinations of each candidate's
    /// admissible directions.
    fn fit(&self, lin: &Linear, r: &[Real], cands: &[usize]) -> Fit {
        let mut cols: Vec<Vec<Real>> = Vec::new();
        let mut dirs: Vec<(usize, Vector3)> = Vec::new();
        for (k, &c) in cands.iter().enumerate() {
            for d in self.directions(&lin.inward[c]) {
                cols.push(lin.response(c, &d));
                dirs.push((k, d));
            }
        }
        let n = cols.len();
        let g = DMatrix::from_fn(n, n, |i, j| dot(&cols[i], &cols[j]));
        let h = DVector::from_fn(n, |i, _| dot(&cols[i], r));
        let sol = nnls(&g, &h, dot(r, r));
        let mut forces = vec![Vector3::zeros(); cands.len()];
        for (a, (k, d)) in sol.coefficients.iter().zip(&dirs) {
            forces[*k] += d * *a;
        }
        Fit {
            candidates: cands.to_vec(),
            forces,
            residual_sq: sol.residual_sq,
        }
    }

    /// The best single load.
    fn best_single(&self, lin: &Linear) -> Option<Fit> {
        let singles = self.single_fits(lin, &lin.r);
        // With a prior over the place, the most probable place: −log of likelihood × prior.
        let two_sigma2 = 2.0 * self.config.marker_sigma_m.powi(2);
        let cost = |c: usize, res: Real| match &self.place_prior {
            Some(prior) => res / two_sigma2 - prior[c].max(Real::MIN_POSITIVE).ln(),
            None => res,
        };
        singles
            .iter()
            .enumerate()
            .filter(|(_, (f, _))| f.norm() > 0.0)
            .min_by(|a, b| cost(a.0, a.1.1).total_cmp(&cost(b.0, b.1.1)))
            .map(|(c, &(f, res))| Fit {
                candidates: vec![c],
                forces: vec![f],
                residual_sq: res,
            })
    }

    /// Whether candidate `c` is at least the minimum separation from rest point `p`.
    fn far_from(&self, c: usize, p: &Point3) -> bool {
        (self.rest_surface[self.candidates[c] as usize] - p).norm()
            >= self.config.min_load_separation_m
    }

    /// The best pair of loads: every pair of a sparse subset of the candidates (at least the
    /// minimum separation apart) along their inward normals, then, from the best of them and
    /// from `first` with its best partner, each load placed again given the other over all
    /// candidates until neither moves; the best pair wins.
    fn best_pair(&self, lin: &Linear, first: usize) -> Option<Fit> {
        let n = self.candidates.len();
        let best_with = |fixed: usize| {
            let p = self.rest_surface[self.candidates[fixed] as usize];
            (0..n)
                .filter(|&c| self.far_from(c, &p))
                .map(|c| self.fit(lin, &lin.r, &[fixed, c]))
                .min_by(|a, b| a.residual_sq.total_cmp(&b.residual_sq))
        };
        // Coarse exhaustive search on the normal directions.
        let sub = &self.pair_subset;
        let cols: Vec<Vec<Real>> = sub
            .iter()
            .map(|&c| lin.response(c, &lin.inward[c]))
            .collect();
        let h: Vec<Real> = cols.iter().map(|u| dot(u, &lin.r)).collect();
        let g: Vec<Real> = cols.iter().map(|u| dot(u, u)).collect();
        let r_sq = dot(&lin.r, &lin.r);
        let mut coarse: Option<(Real, usize, usize)> = None;
        for i in 0..sub.len() {
            let pi = self.rest_surface[self.candidates[sub[i]] as usize];
            for j in (i + 1)..sub.len() {
                if !self.far_from(sub[j], &pi) {
                    continue;
                }
                let gij = dot(&cols[i], &cols[j]);
                let res = pair_residual(r_sq, g[i], g[j], gij, h[i], h[j]);
                if coarse.is_none_or(|c| res < c.0) {
                    coarse = Some((res, sub[i], sub[j]));
                }
            }
        }
        let mut starts: Vec<Fit> = Vec::new();
        if let Some((_, a, b)) = coarse {
            starts.push(self.fit(lin, &lin.r, &[a, b]));
        }
        if let Some(p) = best_with(first) {
            starts.push(p);
        }
        let mut best: Option<Fit> = None;
        for mut pair in starts {
            for _ in 0..PAIR_SWEEPS {
                let mut moved = false;
                for k in 0..2 {
                    let other = pair.candidates[1 - k];
                    let Some(again) = best_with(other) else {
                        continue;
                    };
                    if again.residual_sq < pair.residual_sq * (1.0 - 1e-12) {
                        let mut c = vec![0; 2];
                        let mut f = vec![Vector3::zeros(); 2];
                        c[1 - k] = other;
                        f[1 - k] = again.forces[0];
                        c[k] = again.candidates[1];
                        f[k] = again.forces[1];
                        pair = Fit {
                            candidates: c,
                            forces: f,
                            residual_sq: again.residual_sq,
                        };
                        moved = true;
                    }
                }
                if !moved {
                    break;
                }
            }
            if best
                .as_ref()
                .is_none_or(|b| pair.residual_sq < b.residual_sq)
            {
                best = Some(pair);
            }
        }
        best
    }

    /// The loads of a fit scaled by `scale`, each capped at the largest plausible force, and
    /// without loads of zero force.
    fn loads_of(&self, fit: &Fit, scale: Real) -> Vec<(usize, Vector3)> {
        let cap = self.config.max_force_n;
        fit.candidates
            .iter()
            .zip(&fit.forces)
            .filter(|(_, f)| f.norm() > 0.0)
            .map(|(&c, f)| {
                let f = f * scale;
                let m = f.norm();
                (c, if m > cap { f * (cap / m) } else { f })
            })
            .collect()
    }

    /// Gauss–Newton on `count` loads from `state` (updated in place); returns the linear model
    /// about the final state.
    fn gauss_newton(
        &mut self,
        obs: &FingerObservation<'_>,
        state: &mut Solved,
        count: usize,
        solves: &mut usize,
    ) -> Result<Linear, PhysicsError> {
        let mut lin = self.linearise(&state.x, obs, &state.loads, solves)?;
        for _ in 0..self.config.gauss_newton_iterations {
            let proposal = match state.loads.first() {
                Some(&(first, _)) if count >= 2 => self.best_pair(&lin, first),
                _ => self.best_single(&lin),
            };
            let Some(proposal) = proposal else {
                break;
            };
            let proposed = self.loads_of(&proposal, 1.0);
            let same_places = proposed.len() == state.loads.len()
                && proposed.iter().zip(&state.loads).all(|(a, b)| a.0 == b.0);
            let total: Real = proposed.iter().map(|l| l.1.norm()).sum();
            let change: Real = if same_places {
                proposed
                    .iter()
                    .zip(&state.loads)
                    .map(|(a, b)| (a.1 - b.1).norm())
                    .sum()
            } else {
                Real::INFINITY
            };
            if change <= self.config.force_tolerance * total.max(self.config.min_force_n) {
                break;
            }
            let mut accepted = None;
            for scale in [1.0, 0.5, 0.25] {
                let loads = self.loads_of(&proposal, scale);
                let mut x = state.x.clone();
                match self.solve(&mut x, obs, &loads, "(shape under the estimated loads)") {
                    Ok(it) => {
                        *solves += it;
                        let chi = self.marker_residual_sq(&x, obs.markers);
                        if chi < state.chi {
                            accepted = Some(Solved { x, loads, chi });
                            break;
                        }
                    }
                    // A load the model cannot carry (an inverted element, no equilibrium):
                    // try a smaller one.
                    Err(PhysicsError::StaticNotConverged { .. } | PhysicsError::Model { .. }) => {}
                    Err(e) => return Err(e),
                }
            }
            let Some(next) = accepted else {
                break;
            };
            *state = next;
            lin = self.linearise(&state.x, obs, &state.loads, solves)?;
        }
        Ok(lin)
    }

    /// Gauss–Newton from `state` with as many loads as it carries (one when none), then, from a
    /// single load, a pair when the second pays its way.
    fn search_loads(
        &mut self,
        obs: &FingerObservation<'_>,
        mut state: Solved,
        solves: &mut usize,
    ) -> Result<(Solved, Linear), PhysicsError> {
        let sigma2 = self.config.marker_sigma_m.powi(2);
        let count = state.loads.len().max(1);
        let mut lin = self.gauss_newton(obs, &mut state, count, solves)?;
        if count == 1 && self.config.max_loads_per_finger >= 2 && !state.loads.is_empty() {
            let mut two = state.clone();
            let lin2 = self.gauss_newton(obs, &mut two, 2, solves)?;
            if two.loads.len() == 2
                && two
                    .loads
                    .iter()
                    .all(|f| f.1.norm() >= self.config.min_force_n)
                && (state.chi - two.chi) / sigma2 >= self.config.second_load_chi2
            {
                state = two;
                lin = lin2;
            }
        }
        Ok((state, lin))
    }

    /// Estimates the finger's loads and shape from one observation.
    pub(crate) fn estimate(
        &mut self,
        obs: &FingerObservation<'_>,
    ) -> Result<FingerEstimate, PhysicsError> {
        let observed = obs.markers.iter().filter(|m| m.is_some()).count();
        if observed < self.config.min_markers {
            self.reset();
            return Err(PhysicsError::TooFewMarkers {
                finger: self.index,
                observed,
                needed: self.config.min_markers,
            });
        }
        let result = self.estimate_observed(obs, observed);
        if result.is_err() {
            self.tracked = None;
        }
        result
    }

    /// Estimates the loads and shape from an observation with enough markers (`observed`).
    fn estimate_observed(
        &mut self,
        obs: &FingerObservation<'_>,
        observed: usize,
    ) -> Result<FingerEstimate, PhysicsError> {
        let sigma2 = self.config.marker_sigma_m.powi(2);
        let mut solves = 0;
        let free = self.free_reference(obs, &mut solves)?;
        self.update_place_prior(obs, free.dynamic);
        let lag_corrected = self.contact_lag_corrected(obs, &free.x);
        let markers: Vec<Option<Point3>> = lag_corrected.unwrap_or_else(|| obs.markers.to_vec());
        let base = Baseline {
            chi0: self.marker_residual_sq(&free.x, &markers),
            observed,
            n_obs: (3 * observed) as Real,
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
        let sobs = FingerObservation {
            markers: &start.markers,
            ..*obs
        };
        let (state, lin) = self.search_held_press(&sobs, &start.x, base.chi0, &mut solves)?;
        // A marker the best fit leaves far off — a blob taken for the wrong marker; no load of
        // the model moves one marker millimetres away from where its neighbours put it — is
        // left out, and the loads are searched again from the free shape without it.
        let (base, state, lin) = match self.outlier(&state.x, &start.markers, observed) {
            Some(worst) => self.search_without_marker(obs, &start, worst, &base, &mut solves)?,
            None => (base, state, lin),
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
        let PressedLoads {
            loads,
            probability,
            vertex_force,
            posteriors,
        } = self.describe_loads(&lin, &state, pressed_probability);
        self.remember_press(posteriors, &state);
        let surface = self.estimated_surface(&free, &state.x, &start.x);
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
            solves,
        })
    }

    /// The free reference: the simulated free finger in a stream, else the static one.
    fn free_reference(
        &mut self,
        obs: &FingerObservation<'_>,
        solves: &mut usize,
    ) -> Result<FreeReference, PhysicsError> {
        Ok(match self.advance_dynamic(obs, solves) {
            Some(x) => FreeReference { x, dynamic: true },
            None => {
                let x = self.static_free(obs, solves)?;
                self.start_dynamic(obs, &x);
                FreeReference { x, dynamic: false }
            }
        })
    }

    /// Sets this observation's place prior from the remembered press and the hidden markers.
    fn update_place_prior(&mut self, obs: &FingerObservation<'_>, dynamic: bool) {
        // The place's prior: the previous press, while the stream goes on.
        let memory = self.place_memory.take();
        let remembered = match memory {
            Some(m) if dynamic && self.config.place_memory_m > 0.0 => Some(self.propagate(&m)),
            _ => None,
        };
        // Markers seen earlier in the stream and hidden now: the marker history's evidence.
        if !dynamic || self.seen_in_stream.len() != obs.markers.len() {
            self.seen_in_stream = vec![false; obs.markers.len()];
        }
        let lost: Vec<bool> = obs
            .markers
            .iter()
            .zip(&self.seen_in_stream)
            .map(|(m, &seen)| m.is_none() && seen)
            .collect();
        for (seen, m) in self.seen_in_stream.iter_mut().zip(obs.markers) {
            *seen |= m.is_some();
        }
        self.place_prior = self.with_hidden_markers(remembered, &lost);
    }

    /// The estimate of an unpressed finger: the free shape, no loads, `statistic` as given.
    fn free_estimate(
        &self,
        x_free: &[Point3],
        base: &Baseline,
        statistic: Real,
        solves: usize,
    ) -> FingerEstimate {
        let rms = (base.chi0 / base.n_obs).sqrt();
        FingerEstimate {
            loads: Vec::new(),
            surface: self.surface_of(x_free),
            probability: vec![0.0; self.rest_surface.len()],
            vertex_force: vec![Vector3::zeros(); self.rest_surface.len()],
            pressed_probability: 0.0,
            statistic,
            free_rms_m: rms,
            fit_rms_m: rms,
            observed_markers: base.observed,
            solves,
        }
    }

    /// The static free shape and the markers the loads are fitted to on it.
    fn static_start(
        &mut self,
        obs: &FingerObservation<'_>,
        free: &FreeReference,
        markers: Vec<Option<Point3>>,
        solves: &mut usize,
    ) -> Result<StaticStart, PhysicsError> {
        // The loads act on the static model: the markers are moved by the free finger's lag
        // (static minus simulated), and the static free shape is the start.
        if free.dynamic {
            let x = self.static_free(obs, solves)?;
            let moved = markers
                .iter()
                .zip(&self.markers)
                .map(|(m, &v)| {
                    m.map(|p| {
                        p + (self.mech.surface_position(&x, v)
                            - self.mech.surface_position(&free.x, v))
                    })
                })
                .collect();
            Ok(StaticStart { x, markers: moved })
        } else {
            Ok(StaticStart {
                x: free.x.clone(),
                markers,
            })
        }
    }

    /// Searches the loads of `sobs` from the previous frame's press (when it helps) and, if
    /// that leaves too much of `chi0` unexplained, again from the static free shape `x_static`.
    fn search_held_press(
        &mut self,
        sobs: &FingerObservation<'_>,
        x_static: &[Point3],
        chi0: Real,
        solves: &mut usize,
    ) -> Result<(Solved, Linear), PhysicsError> {
        let mut state = Solved {
            x: x_static.to_vec(),
            loads: Vec::new(),
            chi: chi0,
        };
        // A held press: start from the previous frame's loads when they explain the markers
        // better than none.
        let fresh = state.clone();
        let mut from_tracked = false;
        if let Some(tracked) = self.tracked.take() {
            let mut x = tracked.x;
            if let Ok(it) = self.solve(&mut x, sobs, &tracked.loads, "") {
                *solves += it;
                let chi = self.marker_residual_sq(&x, sobs.markers);
                if chi < chi0 {
                    state = Solved {
                        x,
                        loads: tracked.loads,
                        chi,
                    };
                    from_tracked = true;
                }
            }
        }
        let (mut state, mut lin) = self.search_loads(sobs, state, solves)?;
        // The previous frame's loads can hold the search in a place the press has left: when
        // they leave a tenth of the residual unexplained, search from the free shape too.
        if from_tracked && state.chi > RESTART_FRACTION * chi0 {
            let (other, other_lin) = self.search_loads(sobs, fresh, solves)?;
            if other.chi < state.chi {
                state = other;
                lin = other_lin;
            }
        }
        Ok((state, lin))
    }

    /// Searches the loads again from the static free shape with marker slot `worst` left out;
    /// returns the baseline without it, the fit and its linear model.
    fn search_without_marker(
        &mut self,
        obs: &FingerObservation<'_>,
        start: &StaticStart,
        worst: usize,
        base: &Baseline,
        solves: &mut usize,
    ) -> Result<(Baseline, Solved, Linear), PhysicsError> {
        let mut kept = start.markers.clone();
        kept[worst] = None;
        let chi0 = self.marker_residual_sq(&start.x, &kept);
        let fresh = Solved {
            x: start.x.clone(),
            loads: Vec::new(),
            chi: chi0,
        };
        let kobs = FingerObservation {
            markers: &kept,
            ..*obs
        };
        let (state, lin) = self.search_loads(&kobs, fresh, solves)?;
        let base = Baseline {
            chi0,
            observed: base.observed - 1,
            n_obs: base.n_obs - 3.0,
        };
        Ok((base, state, lin))
    }

    /// The found loads as outputs, with the contact region, vertex forces and place posteriors.
    fn describe_loads(
        &self,
        lin: &Linear,
        state: &Solved,
        pressed_probability: Real,
    ) -> PressedLoads {
        let nv = self.rest_surface.len();
        let mut probability = vec![0.0; nv];
        let mut vertex_force = vec![Vector3::zeros(); nv];
        let fit = Fit {
            candidates: state.loads.iter().map(|l| l.0).collect(),
            forces: state.loads.iter().map(|l| l.1).collect(),
            residual_sq: state.chi,
        };
        let force_sd = self.force_spread(lin, &fit);
        let mut loads = Vec::with_capacity(state.loads.len());
        let mut posteriors = Vec::with_capacity(state.loads.len());
        for (k, &(c, f)) in state.loads.iter().enumerate() {
            let (location_sd_m, place, posterior) = self.location_spread(lin, &fit, k);
            posteriors.push(posterior);
            for &(u, s) in &self.patches[c] {
                vertex_force[u as usize] += f * s;
            }
            let centre: Point3 = place
                .iter()
                .map(|&(u, w)| self.rest_surface[u as usize].coords * w)
                .sum::<Vector3>()
                .into();
            let normal = -lin.inward[c];
            let r = self.config.contact_radius_m;
            for (u, p) in self.rest_surface.iter().enumerate() {
                // The contact region: the rest surface within the radius, on the patch's side.
                if (p - centre).norm() <= r && self.rest_normals[u].dot(&normal) > 0.0 {
                    probability[u] = pressed_probability;
                }
            }
            loads.push(FingerLoad {
                vertex: self.candidates[c],
                place,
                patch: self.patches[c].clone(),
                force: f,
                force_sd_n: force_sd[k],
                location_sd_m,
            });
        }
        PressedLoads {
            loads,
            probability,
            vertex_force,
            posteriors,
        }
    }

    /// Remembers the press for the next observation: its place (one load only) and its loads.
    fn remember_press(&mut self, mut posteriors: Vec<Vec<Real>>, state: &Solved) {
        // One press in a stream is remembered; two, or none, are not.
        self.place_memory = match posteriors.pop() {
            Some(p)
                if self.config.place_memory_m > 0.0 && posteriors.is_empty() && !p.is_empty() =>
            {
                Some(p)
            }
            _ => None,
        };
        self.tracked = Some(Tracked {
            x: state.x.clone(),
            loads: state.loads.clone(),
        });
    }

    /// The estimated surface from the loaded static nodes `x_loaded`.
    fn estimated_surface(
        &self,
        free: &FreeReference,
        x_loaded: &[Point3],
        x_static: &[Point3],
    ) -> Vec<Point3> {
        // The estimated shape: the free finger (simulated, in a stream) moved by what the loads
        // do to the static one.
        if free.dynamic {
            let x: Vec<Point3> = free
                .x
                .iter()
                .zip(x_loaded.iter().zip(x_static))
                .map(|(f, (l, s))| f + (l - s))
                .collect();
            self.surface_of(&x)
        } else {
            self.surface_of(x_loaded)
        }
    }

    /// The Cramér–Rao bound of a press at every candidate place, linearised at the static free
    /// shape under `obs`'s pulls and gravity with every marker observed: the Fisher information
    /// of the marker coordinates (independent Gaussian noise of `sigma_m` per coordinate, over
    /// `frames` independent frames of a held press) about the press's place on the surface
    /// (along the finger's axis and around it) and its force vector, at a force of
    /// `force_n` along the inward normal. Per candidate: its vertex, the bound's standard
    /// deviations along and around (metres) and of the force's magnitude (newtons).
    pub(crate) fn location_bounds(
        &mut self,
        obs: &FingerObservation<'_>,
        force_n: Real,
        sigma_m: Real,
        frames: usize,
    ) -> Result<Vec<(u32, [Real; 3])>, PhysicsError> {
        let mut solves = 0;
        let x = self.static_free(obs, &mut solves)?;
        let all: Vec<Option<Point3>> = self
            .markers
            .iter()
            .map(|&v| Some(self.mech.surface_position(&x, v)))
            .collect();
        let full = FingerObservation {
            markers: &all,
            ..*obs
        };
        let lin = self.linearise(&x, &full, &[], &mut solves)?;
        let n_obs = lin.n_obs;
        // Reciprocal fields again, to differentiate them in space.
        let axes: Vec<(u32, usize)> = self
            .markers
            .iter()
            .flat_map(|&v| (0..3).map(move |d| (v, d)))
            .collect();
        let fields = self
            .mech
            .reciprocal_fields(&x, &obs.commands(), &obs.gravity, &[], &axes, self.ctx())
            .map_err(|e| to_physics(self.index, "(tangent)", e))?;
        let info_scale = frames.max(1) as Real / (sigma_m * sigma_m);
        let mut out = Vec::with_capacity(self.candidates.len());
        for (c, patch) in self.patches.iter().enumerate() {
            let inward = lin.inward[c];
            let force = inward * force_n;
            // Tangent directions at the patch: around the axis and along it.
            let n = -inward;
            let around = Vector3::z()
                .cross(&n)
                .try_normalize(1e-6)
                .unwrap_or_else(Vector3::y);
            let along = n.cross(&around).normalize();
            // Jacobian columns: place along, place around, force x, y, z.
            let mut j = DMatrix::<Real>::zeros(n_obs, 5);
            for (col, dir) in [along, around].iter().enumerate() {
                for &(u, share) in patch {
                    for (i, grad) in self.mech.load_weight_gradients(u) {
                        let dw = grad.dot(dir) * share;
                        for k in 0..n_obs {
                            let mut s = 0.0;
                            for a in 0..3 {
                                s += fields[(3 * i as usize + a, k)] * force[a];
                            }
                            j[(k, col)] += dw * s;
                        }
                    }
                }
            }
            let base = 3 * c * n_obs;
            for d in 0..3 {
                for k in 0..n_obs {
                    j[(k, 2 + d)] = lin.responses[base + d * n_obs + k];
                }
            }
            let info = j.transpose() * &j * info_scale;
            let bound = match info.try_inverse() {
                Some(cov) => {
                    let f = DVector::from_column_slice(inward.as_slice());
                    let cov_f = cov.view((2, 2), (3, 3)).into_owned();
                    [
                        cov[(0, 0)].max(0.0).sqrt(),
                        cov[(1, 1)].max(0.0).sqrt(),
                        (f.transpose() * cov_f * &f)[(0, 0)].max(0.0).sqrt(),
                    ]
                }
                None => [Real::INFINITY; 3],
            };
            out.push((self.candidates[c], bound));
        }
        Ok(out)
    }

    /// Standard deviation of each load's magnitude at fixed places and directions: `σ` times
    /// the square root of the diagonal of the inverse Gram matrix of their response columns.
    fn force_spread(&self, lin: &Linear, fit: &Fit) -> Vec<Real> {
        let cols: Vec<Vec<Real>> = fit
            .candidates
            .iter()
            .zip(&fit.forces)
            .map(|(&c, f)| lin.response(c, &f.try_normalize(0.0).unwrap_or(lin.inward[c])))
            .collect();
        let n = cols.len();
        let g = DMatrix::from_fn(n, n, |i, j| dot(&cols[i], &cols[j]));
        let sigma = self.config.marker_sigma_m;
        match g.try_inverse() {
            Some(inv) => (0..n)
                .map(|k| sigma * inv[(k, k)].max(0.0).sqrt())
                .collect(),
            None => vec![Real::INFINITY; n],
        }
    }

    /// Posterior standard deviations of load `k`'s place along the finger's axis and around
    /// it: every candidate weighted by its prior (its area, or the remembered place's
    /// [`Self::propagate`]) and the likelihood of its best single load for the residual the
    /// other loads leave; also the place ([`Self::local_place`]) and the normalised posterior.
    fn location_spread(
        &self,
        lin: &Linear,
        fit: &Fit,
        k: usize,
    ) -> ([Real; 2], Vec<(u32, Real)>, Vec<Real>) {
        let sigma2 = self.config.marker_sigma_m.powi(2);
        let mut r = lin.r.clone();
        let mut buf = vec![0.0; lin.n_obs];
        for (j, (&c, f)) in fit.candidates.iter().zip(&fit.forces).enumerate() {
            if j != k {
                lin.response_into(c, f, &mut buf);
                r.iter_mut().zip(&buf).for_each(|(r, b)| *r -= b);
            }
        }
        let singles = self.single_fits(lin, &r);
        let best = singles.iter().map(|f| f.1).fold(Real::INFINITY, Real::min);
        let weights: Vec<Real> = singles
            .iter()
            .enumerate()
            .map(|(c, f)| {
                let prior = match &self.place_prior {
                    Some(prior) => prior[c],
                    None => self.area[self.candidates[c] as usize],
                };
                prior * (-(f.1 - best) / (2.0 * sigma2)).exp()
            })
            .collect();
        let centre = fit.candidates[k];
        let place = self.local_place(centre, &weights);
        let wsum: Real = weights.iter().sum();
        if wsum.is_nan() || wsum <= 0.0 {
            return ([Real::NAN; 2], place, Vec::new());
        }
        let posterior: Vec<Real> = weights.iter().map(|w| w / wsum).collect();
        let position = |c: usize| self.rest_surface[self.candidates[c] as usize];
        let mut mean = Vector3::zeros();
        for (c, w) in weights.iter().enumerate() {
            mean += position(c).coords * (w / wsum);
        }
        let mean_angle = mean.y.atan2(mean.x);
        let radius = (mean.x * mean.x + mean.y * mean.y).sqrt().max(1e-4);
        let (mut along, mut around) = (0.0, 0.0);
        for (c, w) in weights.iter().enumerate() {
            let p = position(c);
            along += w / wsum * (p.z - mean.z).powi(2);
            let da = (p.y.atan2(p.x) - mean_angle + std::f64::consts::PI)
                .rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            around += w / wsum * (da * radius).powi(2);
        }
        ([along.sqrt(), around.sqrt()], place, posterior)
    }

    /// The place of a load whose best patch is candidate `centre`, from the posterior
    /// `weights` over every candidate: the centre vertex alone, or with `place_radius_m > 0`
    /// the normalised weights of the candidates within that radius on the centre's side.
    fn local_place(&self, centre: usize, weights: &[Real]) -> Vec<(u32, Real)> {
        let v0 = self.candidates[centre];
        let r = self.config.place_radius_m;
        if r <= 0.0 {
            return vec![(v0, 1.0)];
        }
        let (p0, n0) = (
            self.rest_surface[v0 as usize],
            self.rest_normals[v0 as usize],
        );
        let mut place: Vec<(u32, Real)> = self
            .candidates
            .iter()
            .zip(weights)
            .filter(|&(&v, &w)| {
                w > 0.0
                    && (self.rest_surface[v as usize] - p0).norm() <= r
                    && self.rest_normals[v as usize].dot(&n0) > 0.0
            })
            .map(|(&v, &w)| (v, w))
            .collect();
        let total: Real = place.iter().map(|p| p.1).sum();
        if !(total.is_finite() && total > 0.0) {
            return vec![(v0, 1.0)];
        }
        place.iter_mut().for_each(|p| p.1 /= total);
        place
    }
}

/// A search from the previous frame's loads that leaves more than this fraction of the free
/// residual unexplained is repeated from the free shape.
const RESTART_FRACTION: Real = 0.1;
/// With memory of a press's place, the probability that the next observation's press is a new
/// one, anywhere on the finger.
const NEW_PLACE_PROBABILITY: Real = 0.05;
/// Spacing of the candidates of the coarse pair search, metres.
const PAIR_SPACING_M: Real = 0.005;
/// Alternating re-placements of a pair's loads.
const PAIR_SWEEPS: usize = 6;

/// `‖r − a₁u₁ − a₂u₂‖²` at the best `a ≥ 0`, from `‖r‖²`, the Gram entries and `h = uᵀr`.
fn pair_residual(r_sq: Real, g11: Real, g22: Real, g12: Real, h1: Real, h2: Real) -> Real {
    let single = |g: Real, h: Real| {
        if g > 0.0 && h > 0.0 {
            r_sq - h * h / g
        } else {
            r_sq
        }
    };
    let det = g11 * g22 - g12 * g12;
    if det > 1e-12 * g11 * g22 {
        let a1 = (g22 * h1 - g12 * h2) / det;
        let a2 = (g11 * h2 - g12 * h1) / det;
        if a1 >= 0.0 && a2 >= 0.0 {
            return (r_sq - a1 * h1 - a2 * h2).max(0.0);
        }
    }
    single(g11, h1).min(single(g22, h2)).max(0.0)
}

/// Units of χ² per unit of log-odds of the evidence for a press: the statistic's excess over
/// the detection threshold, tempered (a χ² difference `Δ` is a likelihood ratio of `e^{Δ/2}`
/// for an exact model; the model error makes it a weaker one).
const EVIDENCE_SCALE: Real = 4.0;

fn logistic(t: Real) -> Real {
    1.0 / (1.0 + (-t).exp())
}
