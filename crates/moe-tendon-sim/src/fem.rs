//! Corotational linear elasticity on linear tetrahedra with lumped mass, Rayleigh damping,
//! fixed (Dirichlet) nodes, and a linearly implicit backward-Euler or a quasi-static Newton step.
//! The equations are in the crate documentation.

use moe_geom::{Matrix3, Point3, Real, Vector3};

use crate::error::SimError;
use crate::linsys::{FIXED, SparseSystem, SystemBuffers};
use crate::material::Material;
use crate::polar::polar_rotation;
use crate::terms::Terms;
use crate::tetmesh::TetMesh;
use crate::woodbury::Woodbury;

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

/// A body ready to simulate: the tet mesh, per-element shape gradients, lumped masses, the
/// fixed-node set and the analysed system pattern.
#[derive(Debug)]
pub struct FemModel {
    mesh: TetMesh,
    material: Material,
    lambda: Real,
    mu: Real,
    grads: Vec<[Vector3; 4]>,
    volumes: Vec<Real>,
    mass: Vec<Real>,
    fixed: Vec<bool>,
    system: SparseSystem,
    max_rank_ones: usize,
}

/// Reusable per-body scratch memory: keeping one per body makes the step allocation-free
/// (everything is sized by [`FemModel::workspace`]; only the interaction terms' buffers grow
/// while a step needs more terms than any step before, unless reserved up front as
/// [`FingerBody::workspace`](crate::FingerBody::workspace) does). [`FemModel::step`] still
/// allocates the [`StepReport::rank_one_values`] it returns when there are rank-one terms;
/// [`Scene::step_into`](crate::Scene::step_into) does not.
pub struct FemWorkspace {
    buf: SystemBuffers,
    force: Vec<Vector3>,
    coupling: Vec<Vector3>,
    dx: Vec<Vector3>,
    /// Static line search: positions along the Newton step.
    trial: Vec<Point3>,
    slope: Real,
    terms: Terms,
    /// Free-node gradients of the rank-one terms, one column of `3·n_free` per term.
    grads: Vec<Real>,
    /// Rank-one values shifted by the prescribed motion of the fixed nodes.
    shifted: Vec<Real>,
    woodbury: Woodbury,
}

impl FemWorkspace {
    /// `f·Δx` of the last solve: the directional derivative of the potential's decrease.
    fn force_dot_dx(&self) -> Real {
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
    }
}

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

impl std::fmt::Debug for FemWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemWorkspace")
            .field("nodes", &self.force.len())
            .finish_non_exhaustive()
    }
}

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

/// Coefficients of one linearised solve `(c_M M + c_K K + c_E K_ext + c_D D_ext) Δx = c_F f + …`.
#[derive(Debug, Clone, Copy)]
struct Coefficients {
    mass: Real,
    stiffness: Real,
    external: Real,
    damping: Real,
    force: Real,
    /// `h` for the momentum term `h M v₀` (0 for static solves).
    momentum: Real,
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
        })
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
            terms,
            grads: Vec::with_capacity(3 * self.system.n_free() * m),
            shifted: Vec::with_capacity(m),
            woodbury: Woodbury::new(m),
        }
    }

    /// Deformation gradient of element `t` at node positions `x`.
    #[inline]
    fn deformation_gradient(&self, t: usize, x: &[Point3]) -> Matrix3 {
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

    /// Rotation and corotated Cauchy stress `σ(S − I)` of element `t`.
    #[inline]
    fn element_state(
        &self,
        t: usize,
        x: &[Point3],
        ctx: StepContext,
    ) -> Result<(Matrix3, Matrix3), SimError> {
        let f = self.deformation_gradient(t, x);
        let r = polar_rotation(&f).ok_or(SimError::InvertedElement {
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

    fn check_len(&self, what: &'static str, got: usize) -> Result<(), SimError> {
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

    /// Advances the body by one step.
    ///
    /// `x`, `v`: node positions and velocities (updated in place); `targets`: positions of the
    /// fixed nodes at the end of the step (entries of free nodes are ignored); `gravity`: m/s²;
    /// `terms`: the interaction terms, a function of the current positions and velocities
    /// (called once per linear solve).
    ///
    /// # Errors
    /// Length mismatches, [`SimError::InvalidParameter`] for a bad time step or tolerance,
    /// [`SimError::InvertedElement`], [`SimError::NotPositiveDefinite`],
    /// [`SimError::NonFinite`], [`SimError::StaticNotConverged`],
    /// [`SimError::SingularRankOneSystem`].
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        integrator: Integrator,
        x: &mut [Point3],
        v: &mut [Vector3],
        targets: &[Point3],
        gravity: &Vector3,
        terms: &mut TermsFn<'_>,
    ) -> Result<StepReport, SimError> {
        let a = self.advance(ws, ctx, integrator, x, v, targets, gravity, terms)?;
        Ok(a.report(ws))
    }

    /// [`FemModel::step`] without allocating: the rank-one values stay in the workspace.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn advance(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        integrator: Integrator,
        x: &mut [Point3],
        v: &mut [Vector3],
        targets: &[Point3],
        gravity: &Vector3,
        terms: &mut TermsFn<'_>,
    ) -> Result<Advance, SimError> {
        // The terms' buffers live in the workspace so that their allocations are reused.
        let mut t = std::mem::take(&mut ws.terms);
        let result = self.step_with(ws, ctx, integrator, x, v, targets, gravity, terms, &mut t);
        ws.terms = t;
        result
    }

    #[allow(clippy::too_many_arguments)]
    fn step_with(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        integrator: Integrator,
        x: &mut [Point3],
        v: &mut [Vector3],
        targets: &[Point3],
        gravity: &Vector3,
        terms: &mut TermsFn<'_>,
        t: &mut Terms,
    ) -> Result<Advance, SimError> {
        self.check_len("positions", x.len())?;
        self.check_len("velocities", v.len())?;
        self.check_len("fixed-node targets", targets.len())?;
        t.clear();
        match integrator {
            Integrator::Dynamic { dt_secs: h } => {
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
                };
                terms(x, v, t);
                self.solve(ws, ctx, c, x, v, targets, gravity, t, true)?;
                for i in 0..x.len() {
                    x[i] += ws.dx[i];
                    v[i] = ws.dx[i] / h;
                }
                self.check_finite(x, v, ctx)?;
                self.check_elements(x, ctx)?;
                Ok(Advance {
                    kinetic_energy_j: self.kinetic_energy(v),
                    iterations: 1,
                })
            }
            Integrator::Static {
                tolerance_m,
                max_iterations,
            } => {
                crate::error::require_positive("tolerance_m", tolerance_m)?;
                let c = Coefficients {
                    mass: 0.0,
                    stiffness: 1.0,
                    external: 1.0,
                    damping: 0.0,
                    force: 1.0,
                    momentum: 0.0,
                };
                v.iter_mut().for_each(|v| *v = Vector3::zeros());
                let mut update = Real::INFINITY;
                for it in 0..max_iterations.max(1) {
                    t.clear();
                    terms(x, v, t);
                    let moves_fixed =
                        it == 0 && (0..x.len()).any(|i| self.fixed[i] && targets[i] != x[i]);
                    self.solve(ws, ctx, c, x, v, targets, gravity, t, it == 0)?;
                    // Backtracking line search on the total potential (exact elastic energy,
                    // quadratic models of the interaction terms): the corotational tangent omits
                    // the derivative of the rotations, so a full step can overshoot.
                    let mut alpha: Real = 1.0;
                    if !moves_fixed {
                        let slope: Real = ws.force_dot_dx();
                        let e0 = self.potential(x, &ws.dx, 0.0, gravity, t, &mut ws.trial)?;
                        let mut accepted = false;
                        for _ in 0..30 {
                            match self.potential(x, &ws.dx, alpha, gravity, t, &mut ws.trial) {
                                Ok(e) if e <= e0 - 1e-4 * alpha * slope.max(0.0) => {
                                    accepted = true;
                                    break;
                                }
                                _ => alpha *= 0.5,
                            }
                        }
                        // No decrease found: the energy change is below round-off (near the
                        // solution) or the model is poor; take the Newton step and let the
                        // convergence test below judge it.
                        if !accepted {
                            alpha = 1.0;
                        }
                    }
                    // Convergence is judged on the full Newton step, not the damped one: a
                    // heavily damped step is small without the state being near equilibrium.
                    update = 0.0;
                    for (xi, d) in x.iter_mut().zip(&ws.dx) {
                        *xi += d * alpha;
                        update = update.max(d.norm());
                    }
                    self.check_finite(x, v, ctx)?;
                    if update < tolerance_m {
                        self.check_elements(x, ctx)?;
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
        }
    }

    /// Total potential at `x + α·d`: exact corotated elastic energy
    /// `Σ_e V_e (μ‖S−I‖² + ½λ tr²(S−I))`, the gravity and nodal-load potentials, and the quadratic
    /// models of the interaction terms around `x`.
    fn potential(
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
        let mut e = 0.0;
        for t in 0..self.mesh.num_tets() {
            let (r, _) = self.element_state(t, trial, StepContext::default())?;
            let f = self.deformation_gradient(t, trial);
            let eps = r.transpose() * f - Matrix3::identity();
            let eps = (eps + eps.transpose()) * 0.5;
            e += self.volumes[t]
                * (self.mu * eps.norm_squared() + 0.5 * self.lambda * eps.trace().powi(2));
        }
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

    fn check_finite(&self, x: &[Point3], v: &[Vector3], ctx: StepContext) -> Result<(), SimError> {
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

    /// Assembles and solves one linearised system; leaves `Δx` in `ws.dx` and the linearised
    /// end values of the rank-one terms in `ws.woodbury.values`.
    #[allow(clippy::too_many_arguments)]
    fn solve(
        &self,
        ws: &mut FemWorkspace,
        ctx: StepContext,
        c: Coefficients,
        x: &[Point3],
        v: &[Vector3],
        targets: &[Point3],
        gravity: &Vector3,
        terms: &Terms,
        move_fixed: bool,
    ) -> Result<(), SimError> {
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
        buf.values.fill(0.0);
        force.fill(Vector3::zeros());
        coupling.fill(Vector3::zeros());
        for i in 0..x.len() {
            dx[i] = if self.fixed[i] && move_fixed {
                targets[i] - x[i]
            } else {
                Vector3::zeros()
            };
        }
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
            for a in 0..4 {
                for b in 0..4 {
                    let blk = (rg[a] * rg[b].transpose() * self.lambda
                        + rg[b] * rg[a].transpose() * self.mu
                        + Matrix3::identity() * (self.mu * g[a].dot(&g[b])))
                        * k;
                    couple(&mut buf.values, coupling, tet[a], tet[b], &blk);
                }
            }
        }
        // Mass and gravity.
        for (i, (fi_force, &mass)) in force.iter_mut().zip(&self.mass).enumerate() {
            *fi_force += gravity * mass;
            let fi = sys.free_of(i as u32);
            if fi != FIXED && c.mass != 0.0 {
                sys.add_block(
                    &mut buf.values,
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
                    couple(&mut buf.values, coupling, e.nodes[k], e.nodes[l], &b);
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
                    couple(&mut buf.values, coupling, nodes[k], nodes[l], &b);
                }
            }
        }
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
}
