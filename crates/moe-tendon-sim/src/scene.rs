//! A hand-level scene: a `HandModel` on a wrist that follows a trajectory, tendon schedules per
//! finger, kinematic obstacles, and the explicit-state step.
//!
//! Fingers are simulated in the world frame, each as its own system (their base nodes follow
//! `world_from_hand(t)·hand_from_finger`; fingers do not collide with each other). Every loop
//! is sequential and every reduction runs in a fixed order, so a scene is deterministic: the same
//! configuration gives the same bytes.

use moe_geom::{FingerParams, HandModel, HandPreset, Iso3, Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::body::{FingerBody, FingerInputs};
use crate::camera::RgbdCamera;
use crate::contact::{ContactParams, PosedObstacles, contact_labels, surface_contact};
use crate::error::{SimError, require_non_negative, require_positive};
use crate::fem::{BodyState, FemWorkspace, Integrator, StepContext};
use crate::material::Material;
use crate::obstacle::{Obstacle, ObstacleConfig};
use crate::tendon::{TendonCommand, TendonParams, TendonState};
use crate::trajectory::{ActuationMode, ActuationSchedule, PoseTrajectory};
use crate::voxelize::VoxelParams;

/// Which hand to build: a preset layout of identical parametric fingers. (A hand-model file,
/// with explicitly placed or mesh fingers, is `moe_io::HandConfig`; the `HandModel` it builds
/// goes to [`Scene::with_hand`].)
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PresetHandConfig {
    /// Layout preset. Default two-finger.
    pub preset: HandPreset,
    /// Parametric finger geometry (all fingers identical).
    pub finger: FingerParams,
}

impl Default for PresetHandConfig {
    fn default() -> Self {
        Self {
            preset: HandPreset::TwoFinger,
            finger: FingerParams::default(),
        }
    }
}

/// Dynamic or quasi-static stepping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SolverMode {
    /// Backward Euler with Rayleigh damping (the paper's SOFA setup).
    #[default]
    Dynamic,
    /// A static equilibrium per step (time only drives the trajectories).
    Static,
}

/// Time stepping and divergence limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SolverConfig {
    /// Time step, seconds. Default 0.01.
    pub dt_secs: Real,
    /// Dynamic or static. Default dynamic.
    pub mode: SolverMode,
    /// Static mode: convergence threshold on the largest nodal update, metres. Default 1e-8.
    pub static_tolerance_m: Real,
    /// Static mode: Newton iteration limit. Default 100.
    pub static_max_iterations: usize,
    /// A step whose kinetic energy (per finger) exceeds this has diverged, joules. Default 1.
    pub max_kinetic_energy_j: Real,
    /// Where a run starts ([`Scene::start_state`]): `false` (the default) with every finger in
    /// its rest shape, unloaded, so that it sags under gravity in the first steps; `true` with
    /// every finger in static equilibrium under gravity, the tendon commands and the obstacles
    /// at time 0, as a hand that has been held still before the scene. The difference is the
    /// free sag: 0.2 mm at the default fingertip upright, 4.6 mm with the hand horizontal.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub settled_start: bool,
}

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            dt_secs: 0.01,
            mode: SolverMode::Dynamic,
            static_tolerance_m: 1e-8,
            static_max_iterations: 100,
            max_kinetic_energy_j: 1.0,
            settled_start: false,
        }
    }
}

/// The number of steps of `dt` that cover `duration` (a ratio within 1e-9 of an integer counts as
/// that integer), as a float.
fn steps_covering(duration: Real, dt: Real) -> Real {
    (duration / dt - 1e-9).ceil().max(0.0)
}

/// Most steps a scene may run (`duration_secs / dt_secs`).
pub const MAX_STEPS: u64 = 10_000_000;
/// Most frames a scene may save (`steps / save_every_steps`): every saved frame of a run is
/// kept in memory by [`crate::run_saving`].
pub const MAX_SAVED_FRAMES: u64 = 100_000;
/// Most Newton iterations of a quasi-static step.
pub const MAX_STATIC_ITERATIONS: usize = 10_000;

/// Most times a quasi-static step whose equilibrium is not found in its iterations is halved:
/// it is solved again from its start as 2, then 4, then 8 substeps (the wrist, the tendon
/// schedules and the obstacles at the substeps' times), each with the step's iteration limit.
pub const MAX_STATIC_SUBSTEP_HALVINGS: u32 = 3;

/// A complete scripted scene (TOML/JSON through serde; every field has a default).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneConfig {
    /// The hand.
    pub hand: PresetHandConfig,
    /// Silicone body.
    pub material: Material,
    /// Tet-mesh resolution.
    pub voxel: VoxelParams,
    /// Tendon material.
    pub tendon: TendonParams,
    /// Contact model.
    pub contact: ContactParams,
    /// Time stepping.
    pub solver: SolverConfig,
    /// Gravity in the world frame, m/s². Default (0, 0, −9.81).
    pub gravity_m_s2: [Real; 3],
    /// Simulated duration, seconds. Default 1.
    pub duration_secs: Real,
    /// A frame is saved every this many steps (and at the end). Default 10.
    pub save_every_steps: u64,
    /// `world_from_hand` over time.
    pub wrist: PoseTrajectory,
    /// Tendon schedule per finger (missing fingers keep their tendons at 0).
    pub actuation: Vec<ActuationSchedule>,
    /// Rigid obstacles.
    pub obstacles: Vec<ObstacleConfig>,
    /// The wrist camera that records episodes (it does not affect the physics).
    pub camera: RgbdCamera,
}

impl Default for SceneConfig {
    fn default() -> Self {
        Self {
            hand: PresetHandConfig::default(),
            material: Material::default(),
            voxel: VoxelParams::default(),
            tendon: TendonParams::default(),
            contact: ContactParams::default(),
            solver: SolverConfig::default(),
            gravity_m_s2: [0.0, 0.0, -9.81],
            duration_secs: 1.0,
            save_every_steps: 10,
            wrist: PoseTrajectory::default(),
            actuation: Vec::new(),
            obstacles: Vec::new(),
            camera: RgbdCamera::default(),
        }
    }
}

/// The full state of a scene: everything a step reads and writes besides the scene itself.
#[derive(Debug, Clone, PartialEq)]
pub struct SimState {
    /// Steps taken.
    pub step: u64,
    /// Simulated time, seconds.
    pub time_secs: Real,
    /// One per finger.
    pub fingers: Vec<BodyState>,
}

impl SimState {
    /// A 64-bit FNV-1a digest of the exact bits of the time, positions and velocities: equal
    /// digests mean bit-identical states (determinism checks on one machine).
    pub fn digest(&self) -> u64 {
        let mut h = Fnv::new();
        h.eat(self.time_secs.to_bits());
        for f in &self.fingers {
            for p in &f.x {
                p.coords.iter().for_each(|c| h.eat(c.to_bits()));
            }
            for v in &f.v {
                v.iter().for_each(|c| h.eat(c.to_bits()));
            }
        }
        h.0
    }

    /// A 64-bit FNV-1a digest of the step count and of the node positions rounded to multiples
    /// of `quantum_m`: insensitive to last-bit differences between CPUs (SIMD width and FMA
    /// choices of the linear algebra), for golden tests across machines.
    pub fn rounded_digest(&self, quantum_m: Real) -> u64 {
        let mut h = Fnv::new();
        h.eat(self.step);
        for f in &self.fingers {
            for p in &f.x {
                p.coords
                    .iter()
                    .for_each(|c| h.eat((c / quantum_m).round() as i64 as u64));
            }
        }
        h.0
    }
}

/// 64-bit FNV-1a over little-endian words.
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }

    fn eat(&mut self, word: u64) {
        for b in word.to_le_bytes() {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }
}

/// Figures of one scene step.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct StepInfo {
    /// Index of the step just taken (0-based).
    pub step: u64,
    /// Time at the end of the step, seconds.
    pub time_secs: Real,
    /// Kinetic energy per finger, joules.
    pub kinetic_energy_j: Vec<Real>,
    /// Linear solves per finger.
    pub iterations: Vec<usize>,
    /// Static mode: the substeps each finger's step took (1 where its equilibrium was found
    /// in one; see [`MAX_STATIC_SUBSTEP_HALVINGS`]). Empty in dynamic mode.
    pub substeps: Vec<usize>,
    /// Tendon lengths and tensions per finger.
    pub tendons: Vec<Vec<TendonState>>,
}

/// The surface of one finger in a [`SimFrame`].
#[derive(Debug, Clone, PartialEq)]
pub struct FingerSimFrame {
    /// Surface vertices in the hand frame (same order as the finger mesh), metres.
    pub vertices_in_hand: Vec<Point3>,
    /// Surface vertices in the world frame, metres.
    pub vertices_in_world: Vec<Point3>,
    /// Smallest signed distance of each vertex to any obstacle, metres (+∞ without obstacles).
    pub distances_m: Vec<Real>,
    /// Normal magnitude of the obstacles' penalty force on each vertex, newtons.
    pub contact_force_n: Vec<Real>,
    /// The net contact force on the finger, hand frame, newtons: the vector sum of the
    /// vertices' penalty forces
    /// ([`SurfaceContact::net_force_n`](crate::SurfaceContact::net_force_n)).
    /// Where vertices are pushed different ways (a finger on an edge, or squeezed from two
    /// sides) its norm is smaller than the sum of `contact_force_n`.
    pub force_in_hand_n: Vector3,
    /// Contact label per vertex, by the scene's [`ContactParams::label_rule`].
    pub labels: Vec<bool>,
    /// The command of each tendon at this time, with its unit (a pull in metres or a tension in
    /// newtons).
    pub tendons: Vec<TendonCommand>,
}

/// The hand's surfaces at one instant: a time sample of the simulation, as saved every
/// [`SceneConfig::save_every_steps`] steps (not a coordinate frame: those are the markers of
/// `moe_geom::transform::frame`).
#[derive(Debug, Clone, PartialEq)]
pub struct SimFrame {
    /// Steps taken.
    pub step: u64,
    /// Time, seconds.
    pub time_secs: Real,
    /// `world_from_hand` at this time.
    pub world_from_hand: Iso3,
    /// One per finger.
    pub fingers: Vec<FingerSimFrame>,
}

impl SimFrame {
    /// The pulled length of every tendon, metres: `[finger][tendon]`.
    ///
    /// # Errors
    /// [`SimError::ForceDriven`] naming the first tendon driven by force, whose command is a
    /// tension, not a length.
    pub fn tendon_pulls_m(&self) -> Result<Vec<Vec<Real>>, SimError> {
        self.fingers
            .iter()
            .enumerate()
            .map(|(finger, g)| {
                g.tendons
                    .iter()
                    .enumerate()
                    .map(|(tendon, c)| match *c {
                        TendonCommand::Displacement { pull_m } => Ok(pull_m),
                        TendonCommand::Force { .. } => {
                            Err(SimError::ForceDriven { finger, tendon })
                        }
                    })
                    .collect()
            })
            .collect()
    }
}

/// A runnable scene: the built hand, finger bodies, obstacles and per-finger scratch memory.
#[derive(Debug)]
pub struct Scene {
    config: SceneConfig,
    hand: HandModel,
    bodies: Vec<FingerBody>,
    obstacles: Vec<Obstacle>,
    workspaces: Vec<FemWorkspace>,
    targets: Vec<Vec<Point3>>,
    /// Per-step scratch: the tendon commands of a finger.
    commands: Vec<TendonCommand>,
    /// Per-step scratch: obstacle poses at the start and the end of the step.
    poses: (Vec<Iso3>, Vec<Iso3>),
    /// Static mode: a finger's positions before its step, to substep from when the step's
    /// equilibrium is not found in one.
    backup: Vec<Point3>,
}

/// The finger bodies of a hand at one material and tet resolution (voxelised, with their
/// surfaces and tendon routes embedded), built once for the many scenes that share them
/// ([`Scene::with_bodies`]): a data set's trajectories.
#[derive(Debug, Clone)]
pub struct HandBodies {
    hand: HandModel,
    material: Material,
    voxel: VoxelParams,
    bodies: Vec<FingerBody>,
}

impl HandBodies {
    /// Builds every finger's body of `hand`.
    ///
    /// # Errors
    /// The finger-building errors of [`FingerBody::new`].
    pub fn new(
        hand: HandModel,
        material: &Material,
        voxel: &VoxelParams,
    ) -> Result<Self, SimError> {
        let bodies = hand
            .fingers()
            .iter()
            .map(|f| FingerBody::new(&f.model, material, voxel))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            hand,
            material: material.clone(),
            voxel: voxel.clone(),
            bodies,
        })
    }

    /// The hand.
    pub fn hand(&self) -> &HandModel {
        &self.hand
    }
}

impl Scene {
    /// Builds the scene's parametric hand and everything else.
    ///
    /// # Errors
    /// Any invalid parameter, keyframe, obstacle, or geometry (see [`Scene::with_hand`]).
    pub fn new(config: SceneConfig) -> Result<Self, SimError> {
        let hand = HandModel::preset(config.hand.preset, &config.hand.finger)?;
        Self::with_hand(config, hand)
    }

    /// Builds a scene around a given hand (e.g. fingers from the user's own meshes); the
    /// `hand` section of `config` is ignored.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (material, time step ≤ 0, duration, limits),
    /// [`SimError::InvalidKeyframe`], [`SimError::LengthMismatch`] (actuation values),
    /// [`SimError::IndexOutOfRange`] (more schedules than fingers),
    /// [`SimError::InvalidObstacle`], and the finger-building errors of [`FingerBody::new`].
    pub fn with_hand(config: SceneConfig, hand: HandModel) -> Result<Self, SimError> {
        Self::build(config, hand, None)
    }

    /// Builds a scene around the hand of `bodies`, reusing its finger bodies (no voxelising or
    /// embedding again): the many scenes of a data set share one hand, material and
    /// resolution. The `hand` section of `config` is ignored, as in [`Scene::with_hand`].
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] when `config`'s material or voxel resolution is not the
    /// one the bodies were built with, and the errors of [`Scene::with_hand`].
    pub fn with_bodies(config: SceneConfig, bodies: &HandBodies) -> Result<Self, SimError> {
        if config.material != bodies.material {
            return Err(SimError::InvalidParameter {
                name: "material",
                value: config.material.youngs_modulus_pa,
                reason: "is not the material the shared finger bodies were built with",
            });
        }
        if config.voxel != bodies.voxel {
            return Err(SimError::InvalidParameter {
                name: "voxel cell_size_m",
                value: config.voxel.cell_size_m,
                reason: "is not the resolution the shared finger bodies were built with",
            });
        }
        Self::build(config, bodies.hand.clone(), Some(bodies.bodies.clone()))
    }

    fn build(
        config: SceneConfig,
        hand: HandModel,
        bodies: Option<Vec<FingerBody>>,
    ) -> Result<Self, SimError> {
        config.material.validate()?;
        config.tendon.validate()?;
        config.contact.validate()?;
        let s = &config.solver;
        require_positive("dt_secs", s.dt_secs)?;
        require_positive("static_tolerance_m", s.static_tolerance_m)?;
        require_positive("max_kinetic_energy_j", s.max_kinetic_energy_j)?;
        require_non_negative("duration_secs", config.duration_secs)?;
        if config.save_every_steps == 0 {
            return Err(SimError::InvalidParameter {
                name: "save_every_steps",
                value: 0.0,
                reason: "must be at least 1",
            });
        }
        if !(1..=MAX_STATIC_ITERATIONS).contains(&s.static_max_iterations) {
            return Err(SimError::InvalidParameter {
                name: "static_max_iterations",
                value: s.static_max_iterations as Real,
                reason: "must be between 1 and 10,000",
            });
        }
        // The same count as `num_steps`, in floating point so that a huge ratio cannot wrap.
        let steps = steps_covering(config.duration_secs, s.dt_secs);
        if steps > MAX_STEPS as Real {
            return Err(SimError::InvalidParameter {
                name: "duration_secs / dt_secs (steps)",
                value: steps,
                reason: "a scene may run at most 10,000,000 steps",
            });
        }
        // A run saves its first frame, every `save_every_steps`-th and its last.
        let saved = 1.0 + (steps / config.save_every_steps as Real).ceil();
        if saved > MAX_SAVED_FRAMES as Real {
            return Err(SimError::InvalidParameter {
                name: "duration_secs / dt_secs / save_every_steps (saved frames)",
                value: saved,
                reason: "a scene may save at most 100,000 frames",
            });
        }
        if let Some(&g) = config.gravity_m_s2.iter().find(|g| !g.is_finite()) {
            return Err(SimError::InvalidParameter {
                name: "gravity_m_s2",
                value: g,
                reason: "must be finite",
            });
        }
        config.wrist.validate("wrist trajectory")?;
        if config.actuation.len() > hand.num_fingers() {
            return Err(SimError::IndexOutOfRange {
                what: "actuation schedule finger",
                index: config.actuation.len() - 1,
                len: hand.num_fingers(),
            });
        }
        let bodies = match bodies {
            Some(bodies) => bodies,
            None => HandBodies::new(hand.clone(), &config.material, &config.voxel)?.bodies,
        };
        for (finger, (schedule, body)) in config.actuation.iter().zip(&bodies).enumerate() {
            schedule
                .validate(body.tendons().len())
                .map_err(|e| SimError::Actuation {
                    finger,
                    source: Box::new(e),
                })?;
        }
        let obstacles = config
            .obstacles
            .iter()
            .enumerate()
            .map(|(i, o)| Obstacle::new(i, o))
            .collect::<Result<Vec<_>, _>>()?;
        let workspaces = bodies
            .iter()
            .map(|b| b.workspace(obstacles.len()))
            .collect();
        let max_tendons = bodies.iter().map(|b| b.tendons().len()).max();
        let targets = bodies
            .iter()
            .map(|b| b.fem().mesh().nodes().to_vec())
            .collect();
        Ok(Self {
            config,
            hand,
            bodies,
            workspaces,
            targets,
            commands: Vec::with_capacity(max_tendons.unwrap_or(0)),
            poses: (
                Vec::with_capacity(obstacles.len()),
                Vec::with_capacity(obstacles.len()),
            ),
            obstacles,
            backup: Vec::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &SceneConfig {
        &self.config
    }

    /// The hand.
    pub fn hand(&self) -> &HandModel {
        &self.hand
    }

    /// The finger bodies, in the hand's finger order.
    pub fn bodies(&self) -> &[FingerBody] {
        &self.bodies
    }

    /// The obstacles.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Number of steps that cover `duration_secs`.
    pub fn num_steps(&self) -> u64 {
        steps_covering(self.config.duration_secs, self.config.solver.dt_secs) as u64
    }

    /// `world_from_finger` of finger `i` at time `t`.
    fn world_from_finger(&self, i: usize, t: Real) -> Iso3 {
        self.config.wrist.pose_at(t) * self.hand.fingers()[i].hand_from_finger.iso()
    }

    /// The rest state at time 0: every finger at rest on the wrist's initial pose.
    pub fn initial_state(&self) -> SimState {
        let fingers = self
            .bodies
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let pose = self.world_from_finger(i, 0.0);
                let x = b.fem().mesh().nodes().iter().map(|p| pose * p).collect();
                BodyState {
                    x,
                    v: vec![Vector3::zeros(); b.fem().mesh().num_nodes()],
                }
            })
            .collect();
        SimState {
            step: 0,
            time_secs: 0.0,
            fingers,
        }
    }

    /// The state a run starts from: [`Scene::initial_state`], or with
    /// [`SolverConfig::settled_start`] every finger in static equilibrium at time 0 (gravity,
    /// the tendon commands and the obstacles at time 0; the static mode's tolerance and
    /// iteration limit), with zero velocities.
    ///
    /// # Errors
    /// A settled start whose equilibrium is not found ([`SimError::StaticNotConverged`]) or
    /// that diverges, naming the finger.
    pub fn start_state(&mut self) -> Result<SimState, SimError> {
        let mut state = self.initial_state();
        if !self.config.solver.settled_start {
            return Ok(state);
        }
        let integrator = Integrator::Static {
            tolerance_m: self.config.solver.static_tolerance_m,
            max_iterations: self.config.solver.static_max_iterations,
        };
        let (start, end) = std::mem::take(&mut self.poses);
        let posed = PosedObstacles::with_buffers(&self.obstacles, 0.0, 0.0, start, end);
        let gravity = Vector3::from(self.config.gravity_m_s2);
        let mut result = Ok(());
        for (i, fs) in state.fingers.iter_mut().enumerate() {
            let finger = FingerStep {
                body: &self.bodies[i],
                hand_from_finger: *self.hand.fingers()[i].hand_from_finger.iso(),
                config: &self.config,
                gravity,
                integrator,
                ctx: StepContext { step: 0, finger: i },
            };
            let (ws, targets) = (&mut self.workspaces[i], &mut self.targets[i]);
            if let Err(e) = finger.advance(ws, targets, &mut self.commands, 0.0, &posed, fs) {
                result = Err(e);
                break;
            }
        }
        self.poses = (posed.start, posed.end);
        result.map(|()| state)
    }

    fn check_state(&self, state: &SimState) -> Result<(), SimError> {
        if state.fingers.len() != self.bodies.len() {
            return Err(SimError::StateMismatch {
                what: "number of fingers",
            });
        }
        for (f, b) in state.fingers.iter().zip(&self.bodies) {
            let n = b.fem().mesh().num_nodes();
            if f.x.len() != n || f.v.len() != n {
                return Err(SimError::StateMismatch {
                    what: "number of nodes of a finger",
                });
            }
        }
        Ok(())
    }

    /// Advances `state` by one time step.
    ///
    /// On an error the state is left partly advanced (fingers before the failing one have
    /// stepped, the failing one holds its diverged positions): it is for diagnosis only — restart
    /// from a saved state or from [`Scene::initial_state`].
    ///
    /// # Errors
    /// [`SimError::StateMismatch`] for a foreign state; divergence as
    /// [`SimError::InvertedElement`], [`SimError::NonFinite`], [`SimError::ExplodingEnergy`],
    /// [`SimError::NotPositiveDefinite`] or [`SimError::SingularRankOneSystem`], each naming the
    /// step and finger (and element or node); [`SimError::StaticNotConverged`] in static mode.
    pub fn step(&mut self, state: &mut SimState) -> Result<StepInfo, SimError> {
        let fingers = self.bodies.len();
        let statics = self.config.solver.mode == SolverMode::Static;
        let mut info = StepInfo {
            kinetic_energy_j: Vec::with_capacity(fingers),
            iterations: Vec::with_capacity(fingers),
            substeps: Vec::with_capacity(if statics { fingers } else { 0 }),
            ..StepInfo::default()
        };
        self.step_into(state, &mut info)?;
        Ok(info)
    }

    /// [`Scene::step`] writing the step's figures into `info`, reusing its vectors: once `info`
    /// has held the figures of one step of this scene, a step does not allocate.
    ///
    /// # Errors
    /// As [`Scene::step`]; `info` is then partly overwritten.
    pub fn step_into(&mut self, state: &mut SimState, info: &mut StepInfo) -> Result<(), SimError> {
        self.check_state(state)?;
        let dt = self.config.solver.dt_secs;
        let (t0, t1) = (state.time_secs, state.time_secs + dt);
        let integrator = match self.config.solver.mode {
            SolverMode::Dynamic => Integrator::Dynamic { dt_secs: dt },
            SolverMode::Static => Integrator::Static {
                tolerance_m: self.config.solver.static_tolerance_m,
                max_iterations: self.config.solver.static_max_iterations,
            },
        };
        // The pose buffers are lent to the step's `PosedObstacles` and taken back afterwards.
        let (start, end) = std::mem::take(&mut self.poses);
        let posed = PosedObstacles::with_buffers(&self.obstacles, t0, t1, start, end);
        let gravity = Vector3::from(self.config.gravity_m_s2);
        info.step = state.step;
        info.time_secs = t1;
        info.kinetic_energy_j.clear();
        info.iterations.clear();
        info.substeps.clear();
        info.tendons.resize_with(self.bodies.len(), Vec::new);
        let statics = matches!(integrator, Integrator::Static { .. });
        let mut result = Ok(());
        for i in 0..self.bodies.len() {
            let body = &self.bodies[i];
            let finger = FingerStep {
                body,
                hand_from_finger: *self.hand.fingers()[i].hand_from_finger.iso(),
                config: &self.config,
                gravity,
                integrator,
                ctx: StepContext {
                    step: state.step,
                    finger: i,
                },
            };
            let fs = &mut state.fingers[i];
            if statics {
                self.backup.clear();
                self.backup.extend_from_slice(&fs.x);
            }
            let (ws, targets) = (&mut self.workspaces[i], &mut self.targets[i]);
            let mut substeps = 1;
            let mut advanced = finger.advance(ws, targets, &mut self.commands, t1, &posed, fs);
            if statics && matches!(advanced, Err(SimError::StaticNotConverged { .. })) {
                (advanced, substeps) = finger.substepped(
                    ws,
                    targets,
                    &mut self.commands,
                    &self.obstacles,
                    (t0, t1),
                    &self.backup,
                    fs,
                    advanced,
                );
            }
            let report = match advanced {
                Ok(r) => r,
                Err(e) => {
                    result = Err(e);
                    break;
                }
            };
            let limit = self.config.solver.max_kinetic_energy_j;
            if report.kinetic_energy_j > limit {
                let node = (0..fs.v.len())
                    .max_by(|&a, &b| fs.v[a].norm().total_cmp(&fs.v[b].norm()))
                    .unwrap_or(0);
                result = Err(SimError::ExplodingEnergy {
                    step: state.step,
                    finger: i,
                    node,
                    energy_j: report.kinetic_energy_j,
                    limit_j: limit,
                });
                break;
            }
            info.kinetic_energy_j.push(report.kinetic_energy_j);
            info.iterations.push(report.iterations);
            if statics {
                info.substeps.push(substeps);
            }
            let tendons = &mut info.tendons[i];
            tendons.clear();
            tendons.extend(
                body.tendons()
                    .iter()
                    .zip(&self.commands)
                    .map(|(t, &c)| TendonState {
                        length_m: t.length(&fs.x),
                        tension_n: t.tension(&fs.x, c, &self.config.tendon),
                    }),
            );
        }
        self.poses = (posed.start, posed.end);
        result?;
        state.step += 1;
        state.time_secs = t1;
        Ok(())
    }

    /// The surfaces, distances, contact forces (per vertex and each finger's net force), contact
    /// labels and tendon commands of `state`.
    pub fn frame(&self, state: &SimState) -> SimFrame {
        let t = state.time_secs;
        let world_from_hand = self.config.wrist.pose_at(t);
        let hand_from_world = world_from_hand.inverse();
        let poses: Vec<Iso3> = self.obstacles.iter().map(|o| o.pose_at(t)).collect();
        let fingers = self
            .bodies
            .iter()
            .zip(&state.fingers)
            .enumerate()
            .map(|(i, (b, fs))| {
                let world = b.surface().positions(&fs.x);
                let contact = surface_contact(
                    &world,
                    &self.obstacles,
                    &poses,
                    self.config.contact.stiffness_n_per_m,
                );
                let labels =
                    contact_labels(&contact, b.movable_surface_vertices(), &self.config.contact);
                let force_in_hand_n = hand_from_world.transform_vector(&contact.net_force_n());
                FingerSimFrame {
                    vertices_in_hand: world.iter().map(|p| hand_from_world * p).collect(),
                    vertices_in_world: world,
                    distances_m: contact.distances_m,
                    contact_force_n: contact.forces_n,
                    force_in_hand_n,
                    labels,
                    tendons: (0..b.tendons().len())
                        .map(|j| command(self.config.actuation.get(i), j, t))
                        .collect(),
                }
            })
            .collect();
        SimFrame {
            step: state.step,
            time_secs: t,
            world_from_hand,
            fingers,
        }
    }

    /// Convenience: the contact parameters (label rule).
    pub fn contact_params(&self) -> &ContactParams {
        &self.config.contact
    }
}

/// What one finger's step of a scene needs beside its buffers.
struct FingerStep<'a> {
    body: &'a FingerBody,
    hand_from_finger: Iso3,
    config: &'a SceneConfig,
    gravity: Vector3,
    integrator: Integrator,
    ctx: StepContext,
}

impl FingerStep<'_> {
    /// Advances `fs` to time `t` (the wrist and the tendon schedules at `t`) against `posed`;
    /// leaves the finger's tendon commands in `commands`.
    fn advance(
        &self,
        ws: &mut FemWorkspace,
        targets: &mut [Point3],
        commands: &mut Vec<TendonCommand>,
        t: Real,
        posed: &PosedObstacles<'_>,
        fs: &mut BodyState,
    ) -> Result<crate::fem::Advance, SimError> {
        let pose = self.config.wrist.pose_at(t) * self.hand_from_finger;
        for (target, p) in targets.iter_mut().zip(self.body.fem().mesh().nodes()) {
            *target = pose * p;
        }
        let schedule = self.config.actuation.get(self.ctx.finger);
        commands.clear();
        commands.extend((0..self.body.tendons().len()).map(|j| command(schedule, j, t)));
        let inputs = FingerInputs {
            targets,
            gravity: self.gravity,
            commands,
            tendon: &self.config.tendon,
            obstacles: posed,
            contact: &self.config.contact,
        };
        self.body
            .advance(ws, self.ctx, self.integrator, fs, &inputs)
    }

    /// A static step from `start` over `(t0, t1)` solved again as 2, 4, then 8 substeps, until
    /// every substep's equilibrium is found; the report (iterations summed over the attempts)
    /// and the substeps, or the last failure with `whole`'s substep count of 1.
    #[allow(clippy::too_many_arguments)]
    fn substepped(
        &self,
        ws: &mut FemWorkspace,
        targets: &mut [Point3],
        commands: &mut Vec<TendonCommand>,
        obstacles: &[Obstacle],
        (t0, t1): (Real, Real),
        start: &[Point3],
        fs: &mut BodyState,
        whole: Result<crate::fem::Advance, SimError>,
    ) -> (Result<crate::fem::Advance, SimError>, usize) {
        let mut spent = match &whole {
            Err(SimError::StaticNotConverged { iterations, .. }) => *iterations,
            _ => 0,
        };
        let mut last = whole;
        for halvings in 1..=MAX_STATIC_SUBSTEP_HALVINGS {
            let n = 1usize << halvings;
            fs.x.copy_from_slice(start);
            fs.v.iter_mut().for_each(|v| *v = Vector3::zeros());
            let mut outcome = Ok(());
            for j in 1..=n {
                let ta = t0 + (t1 - t0) * (j - 1) as Real / n as Real;
                let tb = if j == n {
                    t1
                } else {
                    t0 + (t1 - t0) * j as Real / n as Real
                };
                let posed = PosedObstacles::new(obstacles, ta, tb);
                match self.advance(ws, targets, commands, tb, &posed, fs) {
                    Ok(a) => spent += a.iterations,
                    Err(e) => {
                        if let SimError::StaticNotConverged { iterations, .. } = &e {
                            spent += iterations;
                        }
                        outcome = Err(e);
                        break;
                    }
                }
            }
            match outcome {
                Ok(()) => {
                    return (
                        Ok(crate::fem::Advance {
                            kinetic_energy_j: 0.0,
                            iterations: spent,
                        }),
                        n,
                    );
                }
                Err(e @ SimError::StaticNotConverged { .. }) => last = Err(e),
                Err(e) => return (Err(e), n),
            }
        }
        (last, 1)
    }
}

/// The command of tendon `j` at time `t` under `schedule` (none: no pull).
pub(crate) fn command(schedule: Option<&ActuationSchedule>, j: usize, t: Real) -> TendonCommand {
    match schedule {
        None => TendonCommand::Displacement { pull_m: 0.0 },
        Some(s) => {
            let v = s.value_at(j, t);
            match s.mode {
                ActuationMode::Displacement => TendonCommand::Displacement { pull_m: v },
                ActuationMode::Force => TendonCommand::Force { tension_n: v },
            }
        }
    }
}
