//! The static Newton iterations and the total potential their line search decreases.

use moe_geom::{Matrix3, Point3, Real, Vector3};

use super::solve::Coefficients;
use super::step::Advance;
use super::{BodyState, Drive, FemModel, FemWorkspace, StepContext};
use crate::error::SimError;
use crate::terms::Terms;

/// Consecutive Newton iterations with an indefinite exact tangent after which a static solve
/// keeps to the corotated tangent.
const INDEFINITE_RUN: usize = 3;

/// Newton iterations after which a static solve is slow: it goes on with the exact Hessian
/// (where it was asked for the corotated stiffness), and lengthens the full steps the energy
/// lets it.
const SLOW_RUN: usize = 20;

/// The longest a slow solve's step is stretched: 64 Newton steps.
const MAX_STRETCH: Real = 64.0;

impl FemModel {
    /// Newton iterations on the static equilibrium with a backtracking line search; the
    /// velocities are set to zero.
    pub(super) fn static_step(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        tolerance_m: Real,
        max_iterations: usize,
        state: &mut BodyState,
        drive: &mut Drive<'_, '_>,
    ) -> Result<Advance, SimError> {
        crate::error::require_positive("tolerance_m", tolerance_m)?;
        let mut c = Coefficients::statics(self.exact_static_tangent);
        // The corotated stiffness, positive definite, where the exact Hessian is not.
        let fallback = Coefficients { exact: false, ..c };
        let gravity = drive.inputs.gravity;
        state.v.iter_mut().for_each(|v| *v = Vector3::zeros());
        let mut update = Real::INFINITY;
        // Consecutive iterations whose exact tangent was not positive definite: past
        // `INDEFINITE_RUN`, the solve keeps to the corotated one instead of assembling and
        // factorising twice an iteration (a load past the finger's stability limit).
        let mut indefinite = 0;
        for it in 0..max_iterations.max(1) {
            // The corotated stiffness omits the rotations' derivative: its Newton converges
            // linearly, too slowly where the rotations matter (a finger pressed along its
            // axis). A solve that has not converged in `SLOW_RUN` iterations goes on with the
            // exact Hessian, which converges quadratically.
            if it == SLOW_RUN {
                c = Coefficients::statics(true);
            }
            drive.terms.clear();
            (drive.inputs.terms)(&state.x, &state.v, drive.terms);
            let (x, targets) = (&state.x, drive.inputs.targets);
            let moves_fixed = it == 0 && (0..x.len()).any(|i| self.fixed[i] && targets[i] != x[i]);
            let this = if indefinite >= INDEFINITE_RUN {
                fallback
            } else {
                c
            };
            match self.solve(ws, ctx, this, state, drive, it == 0) {
                Err(SimError::NotPositiveDefinite { .. }) if this.exact => {
                    indefinite += 1;
                    self.solve(ws, ctx, fallback, state, drive, it == 0)?;
                }
                Ok(()) if this.exact => indefinite = 0,
                other => other?,
            }
            // Backtracking line search on the total potential, every term evaluated exactly
            // where the step leads (contacts that begin or end along it included): the
            // corotational tangent omits the derivative of the rotations, and the interaction
            // terms are linearised at `x`, so a full step can overshoot.
            let mut alpha: Real = 1.0;
            if !moves_fixed {
                let slope: Real = ws.force_dot_dx();
                let modelled = self.modelled_line_search;
                let e0 = if modelled {
                    self.modelled_potential(
                        &state.x,
                        &ws.dx,
                        0.0,
                        &gravity,
                        drive.terms,
                        &mut ws.trial,
                    )?
                } else {
                    self.potential(&state.x, &gravity, drive.terms)?
                };
                let mut accepted = None;
                for _ in 0..30 {
                    let e = if modelled {
                        self.modelled_potential(
                            &state.x,
                            &ws.dx,
                            alpha,
                            &gravity,
                            drive.terms,
                            &mut ws.trial,
                        )
                    } else {
                        self.trial_potential(state, alpha, &gravity, drive, ws)
                    };
                    match e {
                        Ok(e) if e <= e0 - 1e-4 * alpha * slope.max(0.0) => {
                            accepted = Some(e);
                            break;
                        }
                        _ => alpha *= 0.5,
                    }
                }
                match accepted {
                    // No decrease found: the energy change is below round-off (near the
                    // solution) or the model is poor; take the Newton step and let the
                    // convergence test below judge it.
                    None => alpha = 1.0,
                    // A slow solve whose full step is accepted creeps along a direction its
                    // model thinks stiffer than it is (a tip sliding off a convex obstacle): the
                    // step is lengthened while the energy keeps falling.
                    Some(mut best) if it >= SLOW_RUN && alpha == 1.0 && !modelled => {
                        while alpha < MAX_STRETCH {
                            let e =
                                self.trial_potential(state, 2.0 * alpha, &gravity, drive, ws)?;
                            if e < best {
                                best = e;
                                alpha *= 2.0;
                            } else {
                                break;
                            }
                        }
                    }
                    Some(_) => {}
                }
            }
            // Convergence is judged on the full Newton step, not the damped one: a
            // heavily damped step is small without the state being near equilibrium.
            let x = &mut state.x;
            update = 0.0;
            for (xi, d) in x.iter_mut().zip(&ws.dx) {
                *xi += d * alpha;
                update = update.max(d.norm());
            }
            self.check_finite(&state.x, &state.v, ctx)?;
            if update < tolerance_m {
                self.check_elements(&state.x, ctx)?;
                return Ok(Advance {
                    kinetic_energy_j: 0.0,
                    iterations: it + 1,
                });
            }
        }
        Err(SimError::StaticNotConverged {
            step: ctx.step,
            finger: ctx.finger,
            iterations: max_iterations,
            update_m: update,
        })
    }

    /// Total potential at `x + α·Δx` (`Δx` the workspace's step), with the interaction terms
    /// made there (velocities `v`).
    fn trial_potential(
        &self,
        state: &BodyState,
        alpha: Real,
        gravity: &Vector3,
        drive: &mut Drive<'_, '_>,
        ws: &mut FemWorkspace,
    ) -> Result<Real, SimError> {
        for ((t, xi), di) in ws.trial.iter_mut().zip(&state.x).zip(&ws.dx) {
            *t = xi + di * alpha;
        }
        ws.trial_terms.clear();
        (drive.inputs.terms)(&ws.trial, &state.v, &mut ws.trial_terms);
        self.potential(&ws.trial, gravity, &ws.trial_terms)
    }

    /// The corotated elastic energy `Σ_e V_e (μ‖S−I‖² + ½λ tr²(S−I))` at `x`.
    fn elastic_energy(&self, x: &[Point3]) -> Result<Real, SimError> {
        let mut e = 0.0;
        for t in 0..self.mesh.num_tets() {
            let (r, _) = self.element_state(t, x, StepContext::default())?;
            let f = self.deformation_gradient(t, x);
            let eps = r.transpose() * f - Matrix3::identity();
            let eps = (eps + eps.transpose()) * 0.5;
            e += self.volumes[t]
                * (self.mu * eps.norm_squared() + 0.5 * self.lambda * eps.trace().powi(2));
        }
        Ok(e)
    }

    /// Total potential at `x` with the interaction `terms` made there: the corotated elastic
    /// energy `Σ_e V_e (μ‖S−I‖² + ½λ tr²(S−I))`, the potentials of gravity and of the nodal
    /// forces, the rank-one penalties `½ k g²` (`g > 0` only, for a unilateral one) and the
    /// point terms' own ([`Terms::point_energy_j`]).
    fn potential(&self, x: &[Point3], gravity: &Vector3, terms: &Terms) -> Result<Real, SimError> {
        let mut e = self.elastic_energy(x)?;
        for (p, m) in x.iter().zip(&self.mass) {
            e -= m * gravity.dot(&p.coords);
        }
        for &(n, f) in &terms.nodal_forces {
            e -= f.dot(&x[n as usize].coords);
        }
        for r in &terms.rank_ones {
            let g = if r.unilateral {
                r.value.max(0.0)
            } else {
                r.value
            };
            e += 0.5 * r.stiffness * g * g;
        }
        Ok(e + terms.point_energy_j)
    }

    /// Total potential at `x + α·d` for the modelled line search (relative to `x`): exact
    /// corotated elastic energy `Σ_e V_e (μ‖S−I‖² + ½λ tr²(S−I))`, the gravity and nodal-load
    /// potentials, and the quadratic models of the interaction terms around `x`.
    fn modelled_potential(
        &self,
        x: &[Point3],
        d: &[Vector3],
        alpha: Real,
        gravity: &Vector3,
        terms: &Terms,
        trial: &mut [Point3],
    ) -> Result<Real, SimError> {
        for ((t, xi), di) in trial.iter_mut().zip(x).zip(d) {
            *t = xi + di * alpha;
        }
        let mut e = self.elastic_energy(trial)?;
        let disp = |i: u32| d[i as usize] * alpha;
        for (i, m) in self.mass.iter().enumerate() {
            e -= m * gravity.dot(&disp(i as u32));
        }
        for &(n, f) in &terms.nodal_forces {
            e -= f.dot(&disp(n));
        }
        let at = |p: &crate::embedding::Embedded| {
            (0..4).fold(Vector3::zeros(), |acc, k| {
                acc + disp(p.nodes[k]) * p.weights[k]
            })
        };
        for p in &terms.points {
            let dp = at(&p.point);
            e += 0.5 * dp.dot(&(p.stiffness * dp)) - p.force.dot(&dp);
        }
        for p in &terms.pairs {
            let dd = at(&p.a) - at(&p.b);
            e += 0.5 * dd.dot(&(p.stiffness * dd));
        }
        for r in &terms.rank_ones {
            let g = r.value
                + r.gradient
                    .iter()
                    .map(|&(n, gr)| gr.dot(&disp(n)))
                    .sum::<Real>();
            let g = if r.unilateral { g.max(0.0) } else { g };
            e += 0.5 * r.stiffness * g * g;
        }
        Ok(e)
    }
}
