//! One step of a body: [`FemModel::step`] and its allocation-free form, dispatching to the
//! backward-Euler step or the static Newton iterations.

use moe_geom::Real;

use super::{
    BodyState, Drive, FemInputs, FemModel, FemWorkspace, Integrator, StepContext, StepReport,
};
use crate::error::SimError;

/// Figures of one step without the rank-one values (those stay in the workspace).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Advance {
    /// Kinetic energy at the end of the step, joules.
    pub(crate) kinetic_energy_j: Real,
    /// Linear solves.
    pub(crate) iterations: usize,
}

impl Advance {
    /// The public report of this step (copies the rank-one values out of the workspace).
    pub(crate) fn report(&self, ws: &FemWorkspace) -> StepReport {
        StepReport {
            kinetic_energy_j: self.kinetic_energy_j,
            iterations: self.iterations,
            rank_one_values: ws.woodbury.values.clone(),
        }
    }
}

impl FemModel {
    /// Advances the body by one step.
    ///
    /// `state`: node positions and velocities (updated in place); `inputs`: the fixed nodes'
    /// targets, gravity and the interaction terms (see [`FemInputs`]).
    ///
    /// # Errors
    /// Length mismatches, [`SimError::InvalidParameter`] for a bad time step or tolerance,
    /// [`SimError::InvertedElement`], [`SimError::NotPositiveDefinite`],
    /// [`SimError::NonFinite`], [`SimError::StaticNotConverged`],
    /// [`SimError::SingularRankOneSystem`].
    pub fn step(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        integrator: Integrator,
        state: &mut BodyState,
        inputs: FemInputs<'_>,
    ) -> Result<StepReport, SimError> {
        let a = self.advance(ws, ctx, integrator, state, inputs)?;
        Ok(a.report(ws))
    }

    /// [`FemModel::step`] without allocating: the rank-one values stay in the workspace.
    pub(crate) fn advance(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        integrator: Integrator,
        state: &mut BodyState,
        inputs: FemInputs<'_>,
    ) -> Result<Advance, SimError> {
        // The terms' buffers live in the workspace so that their allocations are reused.
        let mut t = std::mem::take(&mut ws.terms);
        let drive = Drive {
            inputs,
            terms: &mut t,
        };
        let result = self.step_with(ws, ctx, integrator, state, drive);
        ws.terms = t;
        result
    }

    fn step_with(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        integrator: Integrator,
        state: &mut BodyState,
        mut drive: Drive<'_, '_>,
    ) -> Result<Advance, SimError> {
        self.check_len("positions", state.x.len())?;
        self.check_len("velocities", state.v.len())?;
        self.check_len("fixed-node targets", drive.inputs.targets.len())?;
        drive.terms.clear();
        match integrator {
            Integrator::Dynamic { dt_secs } => {
                self.dynamic_step(ws, ctx, dt_secs, state, &mut drive)
            }
            Integrator::Static {
                tolerance_m,
                max_iterations,
            } => self.static_step(ws, ctx, tolerance_m, max_iterations, state, &mut drive),
        }
    }
}
