//! Interaction terms that tendons, contacts and tests add to a body's linearised step: forces at
//! embedded points with their stiffness and damping, stiffness between pairs of embedded points,
//! and rank-one penalty terms solved exactly by a Woodbury update.

use moe_geom::{Matrix3, Real, Vector3};

use crate::embedding::Embedded;

/// A force at an embedded point, with its linearisation.
///
/// At the end of the step the point receives `force − stiffness·Δp − damping·(v − target_velocity)`
/// (`Δp` its displacement over the step, `v` its end-of-step velocity). `stiffness` and `damping`
/// must be symmetric positive semi-definite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointTerm {
    /// Where the force acts.
    pub point: Embedded,
    /// Force at the start of the step, newtons.
    pub force: Vector3,
    /// Stiffness `−∂f/∂p`, N/m.
    pub stiffness: Matrix3,
    /// Damping `−∂f/∂v`, N·s/m (ignored by static solves).
    pub damping: Matrix3,
    /// Velocity toward which the damping drives the point (e.g. an obstacle's), m/s.
    pub target_velocity: Vector3,
}

/// Stiffness coupling two embedded points: the force on `a` is `−K(Δa − Δb)` and on `b` its
/// opposite (a cable segment's geometric stiffness). `K` symmetric positive semi-definite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairTerm {
    /// First point.
    pub a: Embedded,
    /// Second point.
    pub b: Embedded,
    /// The coupling stiffness, N/m.
    pub stiffness: Matrix3,
}

/// A penalty `½ k (g + Gᵀ Δx)²` on a scalar `g` that depends on many nodes (a tendon's length
/// excess): it contributes the force `−k g G` and the rank-one stiffness `k G Gᵀ`, solved exactly
/// by the Woodbury identity without touching the sparsity pattern. A unilateral term is active
/// only while its linearised value at the end of the step is positive (a cable that can only
/// pull), found by an active-set iteration in the small Woodbury space.
#[derive(Debug, Clone, PartialEq)]
pub struct RankOneTerm {
    /// `∂g/∂x` per node: `(node, gradient)`, nodes distinct.
    pub gradient: Vec<(u32, Vector3)>,
    /// Penalty stiffness `k`, N/m.
    pub stiffness: Real,
    /// The value `g` at the start of the step, metres.
    pub value: Real,
    /// Only active while `g > 0` (pull-only).
    pub unilateral: bool,
}

/// All interaction terms of one step of one body.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Terms {
    /// Constant forces on nodes, newtons.
    pub nodal_forces: Vec<(u32, Vector3)>,
    /// Forces at embedded points.
    pub points: Vec<PointTerm>,
    /// Pairwise couplings.
    pub pairs: Vec<PairTerm>,
    /// Rank-one penalties.
    pub rank_ones: Vec<RankOneTerm>,
}

impl Terms {
    /// Removes every term, keeping the allocations.
    pub fn clear(&mut self) {
        self.nodal_forces.clear();
        self.points.clear();
        self.pairs.clear();
        self.rank_ones.clear();
    }
}
