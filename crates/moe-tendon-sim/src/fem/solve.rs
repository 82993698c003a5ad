//! Assembly and solve of one linearised system (elasticity, mass, interaction terms, rank-one
//! terms by a Woodbury update).

use moe_geom::{Matrix3, Point3, Real, Vector3};

use super::model::NO_SLOT;
use super::{BodyState, Drive, FemModel, FemWorkspace, StepContext};
use crate::error::SimError;
use crate::linsys::FIXED;
use crate::terms::Terms;

/// Coefficients of one linearised solve `(c_M M + c_K K + c_E K_ext + c_D D_ext) Δx = c_F f + …`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Coefficients {
    pub(super) mass: Real,
    pub(super) stiffness: Real,
    pub(super) external: Real,
    pub(super) damping: Real,
    pub(super) force: Real,
    /// `h` for the momentum term `h M v₀` (0 for static solves).
    pub(super) momentum: Real,
    /// Add the derivative of the elements' rotations to the elastic stiffness (the exact
    /// Hessian of the corotated energy) instead of the corotated approximation `R K⁰ Rᵀ`.
    pub(super) exact: bool,
}

impl Coefficients {
    /// A static solve's coefficients: no mass, damping or momentum; the exact Hessian when
    /// `exact`.
    pub(super) fn statics(exact: bool) -> Self {
        Self {
            mass: 0.0,
            stiffness: 1.0,
            external: 1.0,
            damping: 0.0,
            force: 1.0,
            momentum: 0.0,
            exact,
        }
    }
}

impl FemModel {
    /// Assembles and solves one linearised system; leaves `Δx` in `ws.dx` and the linearised
    /// end values of the rank-one terms in `ws.woodbury.values`.
    /// `state` is the linearisation point; `drive` holds the fixed nodes' targets, gravity and
    /// the interaction terms built at `state`.
    pub(super) fn solve(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        c: Coefficients,
        state: &BodyState,
        drive: &Drive<'_, '_>,
        move_fixed: bool,
    ) -> Result<(), SimError> {
        let (x, v) = (&state.x[..], &state.v[..]);
        let (targets, gravity, terms) =
            (drive.inputs.targets, &drive.inputs.gravity, &*drive.terms);
        let sys = &self.system;
        let m = terms.rank_ones.len();
        if m > self.max_rank_ones {
            return Err(SimError::LengthMismatch {
                what: "rank-one terms (at most)",
                expected: self.max_rank_ones,
                got: m,
            });
        }
        let FemWorkspace {
            buf,
            force,
            coupling,
            dx,
            slope,
            grads,
            shifted,
            woodbury,
            ..
        } = ws;
        for i in 0..x.len() {
            dx[i] = if self.fixed[i] && move_fixed {
                targets[i] - x[i]
            } else {
                Vector3::zeros()
            };
        }
        self.assemble(
            &mut buf.values,
            force,
            coupling,
            dx,
            c,
            x,
            terms,
            gravity,
            ctx,
        )?;
        // Right-hand sides: column 0 the base system, columns 1..=m the rank-one gradients.
        sys.prepare_rhs(buf, 1 + m);
        for i in 0..x.len() {
            let fi = sys.free_of(i as u32);
            if fi == FIXED {
                continue;
            }
            let r = force[i] * c.force + v[i] * (c.momentum * self.mass[i]) + coupling[i];
            for d in 0..3 {
                buf.rhs[(3 * fi as usize + d, 0)] = r[d];
            }
        }
        // Rank-one values shifted by the prescribed motion of fixed nodes.
        shifted.clear();
        for (j, r) in terms.rank_ones.iter().enumerate() {
            let mut g = r.value;
            for &(n, grad) in &r.gradient {
                let fi = sys.free_of(n);
                if fi == FIXED {
                    g += grad.dot(&dx[n as usize]);
                } else {
                    for d in 0..3 {
                        buf.rhs[(3 * fi as usize + d, 1 + j)] += grad[d];
                    }
                }
            }
            shifted.push(g);
        }
        // Keep the free gradients (the solve overwrites them with Y_j = A⁻¹G_j).
        let n_rows = buf.rhs.nrows();
        grads.clear();
        for j in 0..m {
            grads.extend((0..n_rows).map(|i| buf.rhs[(i, 1 + j)]));
        }
        sys.factor_and_solve(buf, 1 + m)
            .map_err(|_| SimError::NotPositiveDefinite {
                step: ctx.step,
                finger: ctx.finger,
            })?;
        let nrows = buf.rhs.nrows();
        woodbury
            .solve(terms, shifted, grads, buf, c.external)
            .map_err(|_| SimError::SingularRankOneSystem {
                step: ctx.step,
                finger: ctx.finger,
            })?;
        let combo = &woodbury.combo;
        // Δx_free = y₀ + Σ_j combo_j Y_j.
        for (i, dxi) in dx.iter_mut().enumerate() {
            let fi = sys.free_of(i as u32);
            if fi == FIXED {
                continue;
            }
            let mut d = Vector3::zeros();
            for r in 0..3 {
                let row = 3 * fi as usize + r;
                debug_assert!(row < nrows);
                let mut s = buf.rhs[(row, 0)];
                for (j, cj) in combo.iter().enumerate() {
                    s += cj * buf.rhs[(row, 1 + j)];
                }
                d[r] = s;
            }
            *dxi = d;
        }
        // Directional derivative of the potential's decrease along Δx (for line searches).
        let mut s = 0.0;
        for (i, (f, d)) in force.iter().zip(dx.iter()).enumerate() {
            if sys.free_of(i as u32) != FIXED {
                s += f.dot(d);
            }
        }
        for r in &terms.rank_ones {
            if !r.unilateral || r.value > 0.0 {
                let gd: Real = r
                    .gradient
                    .iter()
                    .map(|&(n, g)| g.dot(&dx[n as usize]))
                    .sum();
                s -= r.stiffness * r.value * gd;
            }
        }
        *slope = s;
        Ok(())
    }

    /// The matrix `Q = 2μ I + 2c (tr(S) I − S)⁻¹` with `c = λ (tr S − 3) − 2μ` of element `t`
    /// (`F = R S`): the elastic stiffness gains `−(V/2) R [g_a]× Q [g_b]× Rᵀ` from the
    /// derivative of `R` (with `Rᵀ dR = [ω]×`, `(tr(S) I − S) ω = 2 axial(skew(Rᵀ dF))`).
    /// Zero at rest; `None` where `tr(S) I − S` is singular (a degenerate element).
    fn rotation_stiffness(&self, t: usize, x: &[Point3], r: &Matrix3) -> Option<Matrix3> {
        let f = self.deformation_gradient(t, x);
        let s = r.transpose() * f;
        let s = (s + s.transpose()) * 0.5;
        let tr = s.trace();
        let m = Matrix3::identity() * tr - s;
        let inv = m.try_inverse()?;
        let c = self.lambda * (tr - 3.0) - 2.0 * self.mu;
        Some(Matrix3::identity() * (2.0 * self.mu) + inv * (2.0 * c))
    }

    /// Assembles the lower triangle of `c_M M + c_K K + c_E K_ext + c_D D_ext` at `x` into
    /// `values` (the rank-one terms excepted), the forces at `x` (elastic, gravity, nodal and
    /// point forces with the damping terms' target velocities) into `force`, and into
    /// `coupling` the forces on free nodes from the prescribed motion `dx` of the fixed nodes.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn assemble(
        &self,
        values: &mut [Real],
        force: &mut [Vector3],
        coupling: &mut [Vector3],
        dx: &[Vector3],
        c: Coefficients,
        x: &[Point3],
        terms: &Terms,
        gravity: &Vector3,
        ctx: StepContext,
    ) -> Result<(), SimError> {
        let sys = &self.system;
        values.fill(0.0);
        force.fill(Vector3::zeros());
        coupling.fill(Vector3::zeros());
        // Adds block B = A_ab for the ordered node pair (a, b).
        let couple =
            |values: &mut [Real], coupling: &mut [Vector3], a: u32, b: u32, blk: &Matrix3| {
                let fa = sys.free_of(a);
                if fa == FIXED {
                    return;
                }
                let fb = sys.free_of(b);
                if fb == FIXED {
                    coupling[a as usize] -= blk * dx[b as usize];
                } else if fa >= fb {
                    sys.add_block(values, fa, fb, blk);
                }
            };
        // Elasticity.
        for t in 0..self.mesh.num_tets() {
            let (r, stress) = self.element_state(t, x, ctx)?;
            let tet = &self.mesh.tets()[t];
            let g = &self.grads[t];
            let vol = self.volumes[t];
            let rg = g.map(|ga| r * ga);
            for a in 0..4 {
                force[tet[a] as usize] -= r * (stress * g[a]) * vol;
            }
            let k = c.stiffness * vol;
            let rotation_term = if c.exact {
                self.rotation_stiffness(t, x, &r)
            } else {
                None
            };
            let slots = &self.element_slots[t];
            for a in 0..4 {
                let fa = sys.free_of(tet[a]);
                if fa == FIXED {
                    continue;
                }
                for b in 0..4 {
                    let fb = sys.free_of(tet[b]);
                    // The upper triangle is the lower one's mirror: nothing to add.
                    if fb != FIXED && fa < fb {
                        continue;
                    }
                    let mut blk = (rg[a] * rg[b].transpose() * self.lambda
                        + rg[b] * rg[a].transpose() * self.mu
                        + Matrix3::identity() * (self.mu * g[a].dot(&g[b])))
                        * k;
                    if let Some(q) = &rotation_term {
                        // −(V/2) R [g_a]× Q [g_b]× Rᵀ.
                        blk -= r
                            * g[a].cross_matrix()
                            * q
                            * g[b].cross_matrix()
                            * r.transpose()
                            * (0.5 * k);
                    }
                    let slot = slots[4 * a + b];
                    if fb == FIXED {
                        coupling[tet[a] as usize] -= blk * dx[tet[b] as usize];
                    } else if slot != NO_SLOT {
                        sys.add_lower_block_at(values, fb, slot, &blk);
                    } else {
                        sys.add_block(values, fa, fb, &blk);
                    }
                }
            }
        }
        // Mass and gravity.
        for (i, (fi_force, &mass)) in force.iter_mut().zip(&self.mass).enumerate() {
            *fi_force += gravity * mass;
            let fi = sys.free_of(i as u32);
            if fi != FIXED && c.mass != 0.0 {
                sys.add_block(
                    values,
                    fi,
                    fi,
                    &Matrix3::from_diagonal_element(c.mass * mass),
                );
            }
        }
        for &(n, f) in &terms.nodal_forces {
            force[n as usize] += f;
        }
        // Point terms.
        for p in &terms.points {
            let e = &p.point;
            let blk = p.stiffness * c.external + p.damping * c.damping;
            // The damping force −D(v − v_t) contributes h²·D v_t to the right-hand side.
            let damp_force = if c.damping != 0.0 {
                p.damping * p.target_velocity
            } else {
                Vector3::zeros()
            };
            for k in 0..4 {
                force[e.nodes[k] as usize] += (p.force + damp_force) * e.weights[k];
                for l in 0..4 {
                    let b = blk * (e.weights[k] * e.weights[l]);
                    couple(values, coupling, e.nodes[k], e.nodes[l], &b);
                }
            }
        }
        // Pair terms.
        for p in &terms.pairs {
            let nodes: [u32; 8] = std::array::from_fn(|k| {
                if k < 4 {
                    p.a.nodes[k]
                } else {
                    p.b.nodes[k - 4]
                }
            });
            let w: [Real; 8] = std::array::from_fn(|k| {
                if k < 4 {
                    p.a.weights[k]
                } else {
                    -p.b.weights[k - 4]
                }
            });
            for k in 0..8 {
                for l in 0..8 {
                    let b = p.stiffness * (c.external * w[k] * w[l]);
                    couple(values, coupling, nodes[k], nodes[l], &b);
                }
            }
        }
        Ok(())
    }
}
