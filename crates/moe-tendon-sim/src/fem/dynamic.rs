//! The linearly implicit backward-Euler step with Rayleigh damping.

use moe_geom::Real;

use super::solve::Coefficients;
use super::step::Advance;
use super::{BodyState, Drive, FemModel, FemWorkspace, StepContext};
use crate::error::SimError;

impl FemModel {
    /// One backward-Euler step of `h` seconds: a single linear solve.
    pub(super) fn dynamic_step(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        h: Real,
        state: &mut BodyState,
        drive: &mut Drive<'_, '_>,
    ) -> Result<Advance, SimError> {
        crate::error::require_positive("dt_secs", h)?;
        let (alpha, beta) = (
            self.material.rayleigh_mass,
            self.material.rayleigh_stiffness,
        );
        let c = Coefficients {
            mass: 1.0 + h * alpha,
            stiffness: h * beta + h * h,
            external: h * h,
            damping: h,
            force: h * h,
            momentum: h,
            exact: false,
        };
        (drive.inputs.terms)(&state.x, &state.v, drive.terms);
        self.solve(ws, ctx, c, state, drive, true)?;
        let BodyState { x, v } = state;
        for i in 0..x.len() {
            x[i] += ws.dx[i];
            v[i] = ws.dx[i] / h;
        }
        // An element inverted by the step is not an error: its corotated stress (inversion-safe,
        // see `corotation`) pushes it back out in the steps that follow.
        self.check_finite(x, v, ctx)?;
        Ok(Advance {
            kinetic_energy_j: self.kinetic_energy(v),
            iterations: 1,
        })
    }
}
