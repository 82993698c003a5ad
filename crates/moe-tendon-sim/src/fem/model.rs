//! A body ready to simulate: the tet mesh, its element quantities (shape gradients, volumes,
//! lumped masses), the fixed nodes and the analysed system pattern, with the element-level
//! kinematics and checks the steps share.

use moe_geom::{Matrix3, Point3, Real, Vector3};

use super::{FemWorkspace, StepContext};
use crate::error::SimError;
use crate::linsys::SparseSystem;
use crate::material::Material;
use crate::polar::corotation;
use crate::terms::Terms;
use crate::tetmesh::TetMesh;
use crate::woodbury::Woodbury;

/// A body ready to simulate: the tet mesh, per-element shape gradients, lumped masses, the
/// fixed-node set and the analysed system pattern.
#[derive(Debug, Clone)]
pub struct FemModel {
    pub(super) mesh: TetMesh,
    pub(super) material: Material,
    pub(super) lambda: Real,
    pub(super) mu: Real,
    pub(super) grads: Vec<[Vector3; 4]>,
    pub(super) volumes: Vec<Real>,
    pub(super) mass: Vec<Real>,
    pub(super) fixed: Vec<bool>,
    pub(super) system: SparseSystem,
    pub(super) max_rank_ones: usize,
    /// Static solves and tangents use the exact Hessian of the corotated energy.
    pub(super) exact_static_tangent: bool,
    /// See [`FemModel::set_modelled_line_search`].
    pub(super) modelled_line_search: bool,
    /// Per element and ordered corner pair `4a + b` with free nodes `a > b` (as free indices):
    /// the slot of the pair's block in the pattern ([`SparseSystem::lower_slot`]); [`NO_SLOT`]
    /// otherwise. The element loop adds its blocks without searching the pattern.
    pub(super) element_slots: Vec<[u32; 16]>,
}

/// No block slot (a fixed node, the diagonal, or the upper triangle).
pub(super) const NO_SLOT: u32 = u32::MAX;

/// Shape-function gradients `g_a` (`∇N_a`) and the volume of a rest tetrahedron.
fn shape_gradients(c: &[Point3; 4]) -> ([Vector3; 4], Real) {
    let dm = Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]]);
    let vol = dm.determinant() / 6.0;
    let inv = dm.try_inverse().unwrap_or_else(Matrix3::zeros);
    let g1 = inv.row(0).transpose();
    let g2 = inv.row(1).transpose();
    let g3 = inv.row(2).transpose();
    ([-(g1 + g2 + g3), g1, g2, g3], vol)
}

impl FemModel {
    /// Prepares a body. `fixed[i]` pins node `i` (it follows prescribed targets); `extra_pairs`
    /// are node pairs outside any common element that interaction terms will couple (tendon
    /// segments); `max_rank_ones` bounds the number of rank-one terms per step.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a bad material, [`SimError::LengthMismatch`] when
    /// `fixed` does not match the nodes, [`SimError::NoFixedNodes`] when nothing is fixed.
    pub fn new(
        mesh: TetMesh,
        material: Material,
        fixed: Vec<bool>,
        extra_pairs: &[(u32, u32)],
        max_rank_ones: usize,
    ) -> Result<Self, SimError> {
        material.validate()?;
        if fixed.len() != mesh.num_nodes() {
            return Err(SimError::LengthMismatch {
                what: "fixed-node flags",
                expected: mesh.num_nodes(),
                got: fixed.len(),
            });
        }
        if !fixed.iter().any(|&f| f) {
            return Err(SimError::NoFixedNodes { base_z_m: 0.0 });
        }
        for &(a, b) in extra_pairs {
            for i in [a, b] {
                if i as usize >= mesh.num_nodes() {
                    return Err(SimError::IndexOutOfRange {
                        what: "coupled node",
                        index: i as usize,
                        len: mesh.num_nodes(),
                    });
                }
            }
        }
        let (lambda, mu) = material.lame();
        let mut grads = Vec::with_capacity(mesh.num_tets());
        let mut volumes = Vec::with_capacity(mesh.num_tets());
        let mut mass = vec![0.0; mesh.num_nodes()];
        for t in 0..mesh.num_tets() {
            let (g, v) = shape_gradients(&mesh.corners(t));
            for &n in &mesh.tets()[t] {
                mass[n as usize] += material.density_kg_m3 * v / 4.0;
            }
            grads.push(g);
            volumes.push(v);
        }
        let element_pairs = mesh
            .tets()
            .iter()
            .flat_map(|t| (0..4).flat_map(move |a| (0..4).map(move |b| (t[a], t[b]))));
        let system = SparseSystem::new(
            &fixed,
            element_pairs.chain(extra_pairs.iter().copied()),
            1 + max_rank_ones,
        );
        let element_slots = mesh
            .tets()
            .iter()
            .map(|tet| {
                std::array::from_fn(|ab| {
                    let (fa, fb) = (system.free_of(tet[ab / 4]), system.free_of(tet[ab % 4]));
                    if fa == crate::linsys::FIXED || fb == crate::linsys::FIXED || fa <= fb {
                        NO_SLOT
                    } else {
                        system.lower_slot(fa, fb).unwrap_or(NO_SLOT)
                    }
                })
            })
            .collect();
        Ok(Self {
            mesh,
            material,
            lambda,
            mu,
            grads,
            volumes,
            mass,
            fixed,
            system,
            max_rank_ones,
            exact_static_tangent: false,
            modelled_line_search: false,
            element_slots,
        })
    }

    /// Replaces the material (elasticity, density and damping) without rebuilding the body:
    /// what a calibration that tries many materials on one mesh needs.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a bad material (the model is then unchanged).
    pub fn set_material(&mut self, material: &Material) -> Result<(), SimError> {
        material.validate()?;
        let (lambda, mu) = material.lame();
        let scale = material.density_kg_m3 / self.material.density_kg_m3;
        self.mass.iter_mut().for_each(|m| *m *= scale);
        self.lambda = lambda;
        self.mu = mu;
        self.material = material.clone();
        Ok(())
    }

    /// Whether static solves and [`FemModel::factor_tangent`] use the exact Hessian of the
    /// corotated energy (the derivative of the elements' rotations included) instead of the
    /// corotated stiffness `R K⁰ Rᵀ` that dynamic steps use. The equilibrium is the same; the
    /// exact tangent makes Newton converge quadratically and is the true linear response (the
    /// compliance an estimator reads), which the corotated one is not under large rotation and
    /// stress. Default off (the simulator's data do not depend on it).
    pub fn set_exact_static_tangent(&mut self, exact: bool) {
        self.exact_static_tangent = exact;
    }

    /// See [`FemModel::set_exact_static_tangent`].
    pub fn exact_static_tangent(&self) -> bool {
        self.exact_static_tangent
    }

    /// Whether the static line search decreases the total potential with the interaction
    /// terms replaced by their quadratic models around the iterate (cheaper: no terms are made
    /// along the step) instead of every term made where the step leads (the default). The
    /// exact potential sees a contact begin or end along the step, which the models cannot;
    /// for terms their models follow closely (tendons, dead loads: the physics estimator's)
    /// the two agree, and a slow solve lengthens its steps only with the exact one.
    pub fn set_modelled_line_search(&mut self, modelled: bool) {
        self.modelled_line_search = modelled;
    }

    /// See [`FemModel::set_modelled_line_search`].
    pub fn modelled_line_search(&self) -> bool {
        self.modelled_line_search
    }

    /// The tet mesh (rest shape).
    pub fn mesh(&self) -> &TetMesh {
        &self.mesh
    }

    /// The material.
    pub fn material(&self) -> &Material {
        &self.material
    }

    /// Lumped nodal masses, kilograms.
    pub fn masses(&self) -> &[Real] {
        &self.mass
    }

    /// Which nodes are fixed.
    pub fn fixed(&self) -> &[bool] {
        &self.fixed
    }

    /// Number of free (unknown) nodes.
    pub fn num_free_nodes(&self) -> usize {
        self.system.n_free()
    }

    /// Allocates the scratch memory for [`FemModel::step`].
    pub fn workspace(&self) -> FemWorkspace {
        let n = self.mesh.num_nodes();
        let m = self.max_rank_ones;
        let mut terms = Terms::default();
        terms.reserve(0, 0, m, 0);
        FemWorkspace {
            buf: self.system.buffers(),
            force: vec![Vector3::zeros(); n],
            coupling: vec![Vector3::zeros(); n],
            dx: vec![Vector3::zeros(); n],
            trial: vec![Point3::origin(); n],
            slope: 0.0,
            trial_terms: terms.clone(),
            terms,
            grads: Vec::with_capacity(3 * self.system.n_free() * m),
            shifted: Vec::with_capacity(m),
            woodbury: Woodbury::new(m),
        }
    }

    /// Deformation gradient of element `t` at node positions `x`.
    #[inline]
    pub(super) fn deformation_gradient(&self, t: usize, x: &[Point3]) -> Matrix3 {
        let tet = &self.mesh.tets()[t];
        let g = &self.grads[t];
        let mut f = Matrix3::zeros();
        for a in 0..4 {
            f += x[tet[a] as usize].coords * g[a].transpose();
        }
        f
    }

    /// Checks every element for inversion at `x`.
    ///
    /// # Errors
    /// [`SimError::InvertedElement`] naming the first element with `det F ≤ 0`.
    pub fn check_elements(&self, x: &[Point3], ctx: StepContext) -> Result<(), SimError> {
        for t in 0..self.mesh.num_tets() {
            let det_f = self.deformation_gradient(t, x).determinant();
            if det_f.is_nan() || det_f <= 0.0 {
                return Err(SimError::InvertedElement {
                    step: ctx.step,
                    finger: ctx.finger,
                    element: t,
                    det_f,
                });
            }
        }
        Ok(())
    }

    /// Corotational elastic forces at node positions `x` (zero at any rigid motion of the rest
    /// shape).
    ///
    /// # Errors
    /// [`SimError::LengthMismatch`] for a wrong count, [`SimError::InvertedElement`].
    pub fn elastic_forces(&self, x: &[Point3]) -> Result<Vec<Vector3>, SimError> {
        self.check_len("positions", x.len())?;
        let mut f = vec![Vector3::zeros(); x.len()];
        for t in 0..self.mesh.num_tets() {
            let (r, stress) = self.element_state(t, x, StepContext::default())?;
            let tet = &self.mesh.tets()[t];
            for a in 0..4 {
                f[tet[a] as usize] -= r * (stress * self.grads[t][a]) * self.volumes[t];
            }
        }
        Ok(f)
    }

    /// Rotation and corotated Cauchy stress `σ(S − I)` of element `t` (inverted or not:
    /// [`corotation`]).
    #[inline]
    pub(super) fn element_state(
        &self,
        t: usize,
        x: &[Point3],
        ctx: StepContext,
    ) -> Result<(Matrix3, Matrix3), SimError> {
        let f = self.deformation_gradient(t, x);
        // Inversion-safe: an inverted element has a proper rotation and a stretch with a
        // negative eigenvalue, whose stress pushes it back out; only a non-finite gradient
        // has none.
        let r = corotation(&f).ok_or(SimError::InvertedElement {
            step: ctx.step,
            finger: ctx.finger,
            element: t,
            det_f: f.determinant(),
        })?;
        let s = r.transpose() * f;
        let eps = (s + s.transpose()) * 0.5 - Matrix3::identity();
        let stress = Matrix3::identity() * (self.lambda * eps.trace()) + eps * (2.0 * self.mu);
        Ok((r, stress))
    }

    pub(super) fn check_len(&self, what: &'static str, got: usize) -> Result<(), SimError> {
        if got != self.mesh.num_nodes() {
            return Err(SimError::LengthMismatch {
                what,
                expected: self.mesh.num_nodes(),
                got,
            });
        }
        Ok(())
    }

    /// Kinetic energy of velocities `v`, joules.
    pub fn kinetic_energy(&self, v: &[Vector3]) -> Real {
        v.iter()
            .zip(&self.mass)
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum()
    }

    pub(super) fn check_finite(
        &self,
        x: &[Point3],
        v: &[Vector3],
        ctx: StepContext,
    ) -> Result<(), SimError> {
        let bad = x
            .iter()
            .zip(v)
            .position(|(p, v)| !(p.coords.iter().chain(v.iter()).all(|c| c.is_finite())));
        match bad {
            Some(node) => Err(SimError::NonFinite {
                step: ctx.step,
                finger: ctx.finger,
                node,
            }),
            None => Ok(()),
        }
    }
}
