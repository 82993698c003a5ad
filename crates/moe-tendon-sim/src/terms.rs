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
///
/// [`Terms::clear`] keeps every allocation, including the gradient vectors of the rank-one
/// terms (handed out again by [`Terms::gradient_buffer`]), so that a workspace reused every step
/// stops allocating once its buffers have grown to the step's needs.
#[derive(Debug, Clone, Default)]
pub struct Terms {
    /// Constant forces on nodes, newtons.
    pub nodal_forces: Vec<(u32, Vector3)>,
    /// Forces at embedded points.
    pub points: Vec<PointTerm>,
    /// Pairwise couplings.
    pub pairs: Vec<PairTerm>,
    /// Rank-one penalties.
    pub rank_ones: Vec<RankOneTerm>,
    /// The potential energy of the point terms' forces at the configuration the terms were
    /// made at, joules: what a static solve's line search adds to the elastic, gravity,
    /// nodal-force and rank-one energies (which it computes itself) to decrease the total
    /// potential. Each producer of point terms adds its own: `½ k d²` for a penalty contact at
    /// depth `d`, `T·L` for a cable of tension `T` and length `L`, `−f·p` for a dead load `f` at
    /// `p`. Pair terms (geometric stiffness) carry none.
    pub point_energy_j: Real,
    /// Emptied gradient vectors of cleared rank-one terms, for reuse.
    spare_gradients: Vec<Vec<(u32, Vector3)>>,
}

impl PartialEq for Terms {
    /// Compares the terms (not the spare buffers).
    fn eq(&self, other: &Self) -> bool {
        self.nodal_forces == other.nodal_forces
            && self.point_energy_j == other.point_energy_j
            && self.points == other.points
            && self.pairs == other.pairs
            && self.rank_ones == other.rank_ones
    }
}

impl Terms {
    /// Removes every term, keeping the allocations.
    pub fn clear(&mut self) {
        self.point_energy_j = 0.0;
        self.nodal_forces.clear();
        self.points.clear();
        self.pairs.clear();
        for mut r in self.rank_ones.drain(..) {
            r.gradient.clear();
            self.spare_gradients.push(r.gradient);
        }
    }

    /// An empty vector for a [`RankOneTerm::gradient`]: the allocation of a term removed by
    /// [`Terms::clear`] when there is one (a new, empty vector otherwise).
    pub fn gradient_buffer(&mut self) -> Vec<(u32, Vector3)> {
        self.spare_gradients.pop().unwrap_or_default()
    }

    /// Reserves room for at least `points` point terms, `pairs` pair terms and `rank_ones`
    /// rank-one terms of up to `gradient_len` nodes each, so that steps within these bounds do
    /// not allocate.
    pub fn reserve(&mut self, points: usize, pairs: usize, rank_ones: usize, gradient_len: usize) {
        self.points.reserve(points);
        self.pairs.reserve(pairs);
        self.rank_ones.reserve(rank_ones);
        let spares = rank_ones.saturating_sub(self.spare_gradients.len() + self.rank_ones.len());
        self.spare_gradients.reserve(rank_ones);
        for _ in 0..spares {
            self.spare_gradients.push(Vec::new());
        }
        for g in &mut self.spare_gradients {
            g.reserve(gradient_len);
        }
        for r in &mut self.rank_ones {
            r.gradient
                .reserve(gradient_len.saturating_sub(r.gradient.len()));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clearing_keeps_the_gradient_allocations_for_reuse() {
        let mut terms = Terms::default();
        terms.reserve(5, 3, 2, 16);
        assert!(terms.points.capacity() >= 5 && terms.pairs.capacity() >= 3);
        let mut ptrs = Vec::new();
        for value in [1.0, 2.0] {
            let mut g = terms.gradient_buffer();
            assert!(g.is_empty() && g.capacity() >= 16);
            g.push((3, Vector3::x()));
            ptrs.push(g.as_ptr());
            terms.rank_ones.push(RankOneTerm {
                gradient: g,
                stiffness: 1.0,
                value,
                unilateral: true,
            });
        }
        let copy = terms.clone();
        terms.clear();
        assert!(terms.rank_ones.is_empty());
        assert_ne!(terms, copy);
        // The buffers come back emptied, in reverse order of clearing.
        let a = terms.gradient_buffer();
        let b = terms.gradient_buffer();
        assert!(a.is_empty() && b.is_empty());
        let mut got = vec![a.as_ptr(), b.as_ptr()];
        got.sort();
        ptrs.sort();
        assert_eq!(got, ptrs);
        assert!(terms.gradient_buffer().capacity() == 0);
        assert_eq!(Terms::default(), {
            let mut t = Terms::default();
            t.reserve(1, 1, 1, 1);
            t
        });
    }
}
