//! Corotational linear elasticity on linear tetrahedra with lumped mass, Rayleigh damping,
//! fixed (Dirichlet) nodes, and a linearly implicit backward-Euler or a quasi-static Newton step.
//! The equations are in the crate documentation.
//!
//! By concern: the body and its element quantities ([`FemModel`], `model.rs`), the per-body
//! scratch memory ([`FemWorkspace`], `workspace.rs`), the step and its dispatch (`step.rs`), the
//! backward-Euler step (`dynamic.rs`), the static Newton iterations with their line search on
//! the total potential (`newton.rs`), and the assembly and solve of one linearised system
//! (`solve.rs`).

use moe_geom::{Point3, Real, Vector3};

use crate::terms::Terms;

mod dynamic;
mod model;
mod newton;
mod solve;
mod step;
mod tangent;
mod workspace;

pub use model::FemModel;
pub(crate) use step::Advance;
pub use tangent::Tangent;
pub use workspace::FemWorkspace;

/// Builds the interaction terms of a solve from the current positions and velocities.
pub type TermsFn<'a> = dyn FnMut(&[Point3], &[Vector3], &mut Terms) + 'a;

/// Identifies a body in error messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StepContext {
    /// Step index.
    pub step: u64,
    /// Finger (body) index.
    pub finger: usize,
}

/// How a step advances the body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Integrator {
    /// One linearly implicit backward-Euler step of `dt_secs` with Rayleigh damping.
    Dynamic {
        /// Time step, seconds.
        dt_secs: Real,
    },
    /// Newton iterations on the static equilibrium (velocities are set to zero).
    Static {
        /// Stop when the largest nodal update is below this, metres.
        tolerance_m: Real,
        /// Give up after this many iterations.
        max_iterations: usize,
    },
}

/// Node positions and velocities of one body (a finger of a scene: world frame).
#[derive(Debug, Clone, PartialEq)]
pub struct BodyState {
    /// Node positions, metres.
    pub x: Vec<Point3>,
    /// Node velocities, m/s.
    pub v: Vec<Vector3>,
}

/// What drives one step of a body besides its state.
pub struct FemInputs<'a> {
    /// Positions of the fixed nodes at the end of the step (entries of free nodes are ignored).
    pub targets: &'a [Point3],
    /// Gravity, m/s².
    pub gravity: Vector3,
    /// The interaction terms, a function of the current positions and velocities (called once
    /// per linear solve).
    pub terms: &'a mut TermsFn<'a>,
}

impl std::fmt::Debug for FemInputs<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemInputs")
            .field("targets", &self.targets.len())
            .field("gravity", &self.gravity)
            .finish_non_exhaustive()
    }
}

/// Figures of one step.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepReport {
    /// Kinetic energy at the end of the step, joules.
    pub kinetic_energy_j: Real,
    /// Linear solves (1 for a dynamic step; Newton iterations for a static one).
    pub iterations: usize,
    /// Linearised end-of-step value of each rank-one term (0 when inactive), metres.
    pub rank_one_values: Vec<Real>,
}

/// A step's inputs together with the buffer their interaction terms are built into (the
/// workspace's, lent for the step).
struct Drive<'d, 'a> {
    inputs: FemInputs<'a>,
    terms: &'d mut Terms,
}
