//! Reusable per-body scratch memory of the step.

use moe_geom::{Point3, Real, Vector3};

use crate::linsys::SystemBuffers;
use crate::terms::Terms;
use crate::woodbury::Woodbury;

/// Reusable per-body scratch memory: keeping one per body makes the step allocation-free
/// (everything is sized by [`FemModel::workspace`](super::FemModel::workspace); only the interaction terms' buffers grow
/// while a step needs more terms than any step before, unless reserved up front as
/// [`FingerBody::workspace`](crate::mechanics::FingerBody::workspace) does). [`FemModel::step`](super::FemModel::step) still
/// allocates the [`StepReport::rank_one_values`](super::StepReport::rank_one_values) it returns when there are rank-one terms;
/// [`Scene::step_into`](crate::Scene::step_into) does not.
pub struct FemWorkspace {
    pub(super) buf: SystemBuffers,
    pub(super) force: Vec<Vector3>,
    pub(super) coupling: Vec<Vector3>,
    pub(super) dx: Vec<Vector3>,
    /// Static line search: positions along the Newton step.
    pub(super) trial: Vec<Point3>,
    pub(super) slope: Real,
    pub(super) terms: Terms,
    /// Static line search: the interaction terms at the positions along the Newton step.
    pub(super) trial_terms: Terms,
    /// Free-node gradients of the rank-one terms, one column of `3·n_free` per term.
    pub(super) grads: Vec<Real>,
    /// Rank-one values shifted by the prescribed motion of the fixed nodes.
    pub(super) shifted: Vec<Real>,
    pub(super) woodbury: Woodbury,
}

impl FemWorkspace {
    /// `f·Δx` of the last solve: the directional derivative of the potential's decrease.
    pub(super) fn force_dot_dx(&self) -> Real {
        self.slope
    }

    /// Reserves room in the interaction-term buffers (see [`Terms::reserve`]).
    pub(crate) fn reserve_terms(
        &mut self,
        points: usize,
        pairs: usize,
        rank_ones: usize,
        gradient_len: usize,
    ) {
        self.terms.reserve(points, pairs, rank_ones, gradient_len);
        self.trial_terms
            .reserve(points, pairs, rank_ones, gradient_len);
    }
}

impl std::fmt::Debug for FemWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemWorkspace")
            .field("nodes", &self.force.len())
            .finish_non_exhaustive()
    }
}
