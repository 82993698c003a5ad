//! A simulated finger: its voxel tet mesh with the fixed base, the embedded surface mesh and
//! tendons, and the step that gathers tendon and contact terms.

use moe_geom::{FingerModel, Point3, Real, Vector3};

use crate::contact::{ContactParams, PosedObstacles, add_contact_terms};
use crate::embedding::Embedding;
use crate::error::SimError;
use crate::fem::{
    Advance, BodyState, FemInputs, FemModel, FemWorkspace, Integrator, StepContext, StepReport,
};
use crate::material::Material;
use crate::tendon::{Tendon, TendonCommand, TendonParams};
use crate::terms::Terms;
use crate::voxelize::{VoxelParams, VoxelStats, voxelize};

/// Nodes within this height above the finger's base plane are fixed, metres.
pub const BASE_TOLERANCE_M: Real = 1e-9;

/// A finger ready to simulate, in its own (finger) frame at rest.
#[derive(Debug, Clone)]
pub struct FingerBody {
    fem: FemModel,
    surface: Embedding,
    tendons: Vec<Tendon>,
    stats: VoxelStats,
    /// Per surface vertex: whether it can move (computed once from the fixed nodes).
    movable: Vec<bool>,
}

/// External inputs of one finger step besides the state.
#[derive(Debug, Clone)]
pub struct FingerInputs<'a> {
    /// Positions of every node's rest point mapped to the world at the end of the step (only
    /// the fixed nodes' entries are used).
    pub targets: &'a [Point3],
    /// Gravity, m/s², world frame.
    pub gravity: Vector3,
    /// One command per tendon.
    pub commands: &'a [TendonCommand],
    /// Tendon material.
    pub tendon: &'a TendonParams,
    /// Obstacles posed for the step.
    pub obstacles: &'a PosedObstacles<'a>,
    /// Contact model.
    pub contact: &'a ContactParams,
}

impl FingerBody {
    /// Tetrahedralises `finger`, fixes the nodes on its base plane (z ≤ the highest base vertex
    /// + [`BASE_TOLERANCE_M`] in the finger frame), embeds its surface and its tendon routes.
    ///
    /// # Errors
    /// Invalid material or resolution, an open surface, [`SimError::NoFixedNodes`],
    /// [`SimError::TendonOutsideBody`].
    pub fn new(
        finger: &FingerModel,
        material: &Material,
        voxel: &VoxelParams,
    ) -> Result<Self, SimError> {
        material.validate()?;
        let vm = voxelize(finger.mesh(), voxel)?;
        let base_z = finger
            .base_vertices()
            .iter()
            .map(|&v| finger.mesh().vertices()[v as usize].z)
            .fold(Real::NEG_INFINITY, Real::max);
        let fixed: Vec<bool> = vm
            .tets
            .nodes()
            .iter()
            .map(|p| p.z <= base_z + BASE_TOLERANCE_M)
            .collect();
        if !fixed.iter().any(|&f| f) {
            return Err(SimError::NoFixedNodes { base_z_m: base_z });
        }
        let tendons = finger
            .tendon_routes()
            .iter()
            .enumerate()
            .map(|(i, r)| Tendon::new(&vm.tets, i, r))
            .collect::<Result<Vec<_>, _>>()?;
        let pairs: Vec<(u32, u32)> = tendons.iter().flat_map(|t| t.coupled_pairs()).collect();
        let fem = FemModel::new(vm.tets, material.clone(), fixed, &pairs, tendons.len())?;
        let movable = vm
            .surface
            .points()
            .iter()
            .map(|e| {
                e.nodes
                    .iter()
                    .zip(&e.weights)
                    .any(|(&n, &w)| w != 0.0 && !fem.fixed()[n as usize])
            })
            .collect();
        Ok(Self {
            fem,
            surface: vm.surface,
            tendons,
            stats: vm.stats,
            movable,
        })
    }

    /// The FEM model (tet mesh, masses, fixed nodes).
    pub fn fem(&self) -> &FemModel {
        &self.fem
    }

    /// The FEM model, to change how it solves (see [`FemModel::set_exact_static_tangent`]).
    pub fn fem_mut(&mut self) -> &mut FemModel {
        &mut self.fem
    }

    /// The surface vertices, embedded in the tets (same order as the finger mesh).
    pub fn surface(&self) -> &Embedding {
        &self.surface
    }

    /// Per surface vertex: whether it can move, i.e. at least one node of its element with a
    /// non-zero weight is free. A vertex held by the fixed base alone cannot.
    pub fn movable_surface_vertices(&self) -> &[bool] {
        &self.movable
    }

    /// The tendons.
    pub fn tendons(&self) -> &[Tendon] {
        &self.tendons
    }

    /// Accuracy of the tetrahedralisation.
    pub fn voxel_stats(&self) -> VoxelStats {
        self.stats
    }

    /// The scratch memory for [`FingerBody::step`] with its term buffers sized for every tendon
    /// term and one contact term per surface vertex and obstacle, so that no step among
    /// `num_obstacles` obstacles allocates.
    pub fn workspace(&self, num_obstacles: usize) -> FemWorkspace {
        let mut ws = self.fem.workspace();
        let route_points: usize = self.tendons.iter().map(|t| t.points().len()).sum();
        let segments = route_points.saturating_sub(self.tendons.len());
        let gradient_len = self.tendons.iter().map(Tendon::num_nodes).max();
        ws.reserve_terms(
            self.surface.points().len() * num_obstacles + route_points,
            segments,
            self.tendons.len(),
            gradient_len.unwrap_or(0),
        );
        ws
    }

    /// Advances the finger by one step.
    ///
    /// # Errors
    /// [`SimError::LengthMismatch`] for a wrong number of commands; everything
    /// [`FemModel::step`] reports.
    pub fn step(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        integrator: Integrator,
        state: &mut BodyState,
        inputs: &FingerInputs<'_>,
    ) -> Result<StepReport, SimError> {
        Ok(self.advance(ws, ctx, integrator, state, inputs)?.report(ws))
    }

    /// [`FingerBody::step`] without allocating (the rank-one values stay in the workspace).
    pub(crate) fn advance(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        integrator: Integrator,
        state: &mut BodyState,
        inputs: &FingerInputs<'_>,
    ) -> Result<Advance, SimError> {
        self.check_commands(inputs)?;
        let fem_inputs = FemInputs {
            targets: inputs.targets,
            gravity: inputs.gravity,
            terms: &mut self.terms_fn(inputs),
        };
        self.fem.advance(ws, ctx, integrator, state, fem_inputs)
    }

    /// The tendon and contact terms of a step.
    fn terms_fn<'s>(
        &'s self,
        inputs: &'s FingerInputs<'_>,
    ) -> impl FnMut(&[Point3], &[Vector3], &mut Terms) + 's {
        move |x: &[Point3], v: &[Vector3], terms: &mut Terms| {
            for (tendon, &cmd) in self.tendons.iter().zip(inputs.commands) {
                tendon.add_terms(x, cmd, inputs.tendon, terms);
            }
            add_contact_terms(&self.surface, x, v, inputs.obstacles, inputs.contact, terms);
        }
    }

    fn check_commands(&self, inputs: &FingerInputs<'_>) -> Result<(), SimError> {
        if inputs.commands.len() != self.tendons.len() {
            return Err(SimError::LengthMismatch {
                what: "tendon commands",
                expected: self.tendons.len(),
                got: inputs.commands.len(),
            });
        }
        Ok(())
    }
}
