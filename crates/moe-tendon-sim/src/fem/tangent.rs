//! The static tangent stiffness of a body at a configuration, factorised once for many solves.
//!
//! An estimator that reads the model backwards needs the body's response to loads it does not
//! know yet: with the tangent `K_T` factorised at a configuration, the displacement of any
//! point under a small load `f` is `K_T⁻¹ f`, and by the symmetry of `K_T` (reciprocity) the
//! displacement of one observed coordinate under a unit load anywhere is one solve with that
//! coordinate's embedding weights as the right-hand side.

use faer::dyn_stack::MemBuffer;
use faer::{Mat, MatMut};
use moe_geom::{Point3, Real, Vector3};

use super::solve::Coefficients;
use super::{FemModel, StepContext};
use crate::error::SimError;
use crate::linsys::FIXED;
use crate::terms::Terms;

/// The static tangent `K_T = K + K_ext + Σ_active k_j G_j G_jᵀ` of a body at one configuration,
/// factorised (see [`FemModel::factor_tangent`]): the elastic stiffness, the stiffness of the
/// interaction terms, and the rank-one terms active at the configuration (a taut tendon) by an
/// exact Woodbury correction. Unknowns are the free nodes' displacements, three rows per free
/// node in the order of [`FemModel::free_index`].
pub struct Tangent {
    values: Vec<Real>,
    l_values: Vec<Real>,
    mem: MemBuffer,
    /// Columns the scratch in `mem` is sized for.
    mem_cols: usize,
    force: Vec<Vector3>,
    coupling: Vec<Vector3>,
    zero_dx: Vec<Vector3>,
    /// Free-row gradients of the active rank-one terms, one column each.
    g: Mat<Real>,
    /// `A⁻¹ G` for the assembled matrix `A` (without the rank-one terms).
    y: Mat<Real>,
    /// `(diag(1/k) + Gᵀ A⁻¹ G)⁻¹`, column-major, `active × active`.
    small_inv: Vec<Real>,
    active: usize,
    factored: bool,
    /// Whether the elastic part is the exact Hessian (else the corotated stiffness).
    exact: bool,
}

impl std::fmt::Debug for Tangent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tangent")
            .field("rows", &self.g.nrows())
            .field("active_rank_ones", &self.active)
            .field("factored", &self.factored)
            .finish_non_exhaustive()
    }
}

impl Tangent {
    /// Number of unknowns (three per free node).
    pub fn num_rows(&self) -> usize {
        self.g.nrows()
    }

    /// Whether the factorised elastic stiffness is the exact Hessian of the corotated energy
    /// (false: the corotated stiffness, used where the exact one is not positive definite or
    /// was not asked for; see [`FemModel::set_exact_static_tangent`]).
    pub fn is_exact(&self) -> bool {
        self.exact
    }

    /// Number of rank-one terms active at the configuration (taut tendons).
    pub fn num_active_rank_ones(&self) -> usize {
        self.active
    }

    /// The forces on every node at the configuration the tangent was factorised at: elastic,
    /// gravity, nodal and point forces (the rank-one terms' forces excepted), newtons.
    pub fn forces(&self) -> &[Vector3] {
        &self.force
    }

    /// Solves `K_T X = B` in place: `b` has [`Tangent::num_rows`] rows (loads on the free nodes)
    /// and any number of columns, and holds the displacements afterwards.
    ///
    /// # Errors
    /// [`SimError::LengthMismatch`] when `b` has the wrong number of rows,
    /// [`SimError::InvalidParameter`] before [`FemModel::factor_tangent`] succeeded.
    pub fn solve_in_place(
        &mut self,
        model: &FemModel,
        mut b: MatMut<'_, Real>,
    ) -> Result<(), SimError> {
        if !self.factored {
            return Err(SimError::InvalidParameter {
                name: "tangent",
                value: 0.0,
                reason: "must be factorised before a solve",
            });
        }
        let rows = self.num_rows();
        if b.nrows() != rows {
            return Err(SimError::LengthMismatch {
                what: "tangent right-hand side rows",
                expected: rows,
                got: b.nrows(),
            });
        }
        let k = b.ncols();
        if k == 0 {
            return Ok(());
        }
        if k > self.mem_cols {
            self.mem = MemBuffer::new(model.system.solve_scratch(k));
            self.mem_cols = k;
        }
        model
            .system
            .solve_factored(&self.l_values, &mut self.mem, b.as_mut());
        let m = self.active;
        if m == 0 {
            return Ok(());
        }
        // X = A⁻¹B − Y S⁻¹ Gᵀ A⁻¹B.
        let mut w = vec![0.0; m];
        for c in 0..k {
            for (i, wi) in w.iter_mut().enumerate() {
                *wi = (0..rows).map(|r| self.g[(r, i)] * b[(r, c)]).sum::<Real>();
            }
            for j in 0..m {
                let zj: Real = (0..m).map(|i| self.small_inv[j + m * i] * w[i]).sum();
                if zj != 0.0 {
                    for r in 0..rows {
                        b[(r, c)] -= self.y[(r, j)] * zj;
                    }
                }
            }
        }
        Ok(())
    }
}

impl FemModel {
    /// Free index of a node (its rows `3i..3i + 3` in a [`Tangent`]'s unknowns), `None` for a
    /// fixed node or an index out of range.
    pub fn free_index(&self, node: u32) -> Option<usize> {
        if node as usize >= self.mesh.num_nodes() {
            return None;
        }
        match self.system.free_of(node) {
            FIXED => None,
            i => Some(i as usize),
        }
    }

    /// Allocates a [`Tangent`] for this body (factorise it with [`FemModel::factor_tangent`]).
    pub fn tangent(&self) -> Tangent {
        let n = self.mesh.num_nodes();
        let rows = 3 * self.system.n_free();
        let buf = self.system.buffers();
        Tangent {
            values: buf.values,
            l_values: vec![0.0; self.system.factor_len()],
            mem: MemBuffer::new(self.system.solve_scratch(1)),
            mem_cols: 1,
            force: vec![Vector3::zeros(); n],
            coupling: vec![Vector3::zeros(); n],
            zero_dx: vec![Vector3::zeros(); n],
            g: Mat::zeros(rows, 0),
            y: Mat::zeros(rows, 0),
            small_inv: Vec::new(),
            active: 0,
            factored: false,
            exact: false,
        }
    }

    /// Assembles and factorises the static tangent at node positions `x` with the interaction
    /// `terms` built at `x` (a tendon's terms from [`crate::mechanics::Tendon::add_terms`], for
    /// example) and `gravity`. Unilateral rank-one terms are active where their value is
    /// positive; the prescribed nodes do not move.
    ///
    /// # Errors
    /// [`SimError::LengthMismatch`] for a wrong count, [`SimError::InvertedElement`],
    /// [`SimError::NotPositiveDefinite`], [`SimError::SingularRankOneSystem`] (each with
    /// `ctx`'s step and finger).
    pub fn factor_tangent(
        &self,
        tangent: &mut Tangent,
        x: &[Point3],
        terms: &Terms,
        gravity: &Vector3,
        ctx: StepContext,
    ) -> Result<(), SimError> {
        tangent.factored = false;
        self.check_len("positions", x.len())?;
        let rows = 3 * self.system.n_free();
        if tangent.num_rows() != rows || tangent.force.len() != x.len() {
            *tangent = self.tangent();
        }
        if terms.rank_ones.len() > self.max_rank_ones {
            return Err(SimError::LengthMismatch {
                what: "rank-one terms (at most)",
                expected: self.max_rank_ones,
                got: terms.rank_ones.len(),
            });
        }
        let not_pd = SimError::NotPositiveDefinite {
            step: ctx.step,
            finger: ctx.finger,
        };
        // The exact Hessian is indefinite past a stability limit (a buckling finger): the
        // corotated stiffness, positive definite, stands in for it there.
        let mut factored = false;
        for exact in [self.exact_static_tangent, false] {
            let c = Coefficients::statics(exact);
            self.assemble(
                &mut tangent.values,
                &mut tangent.force,
                &mut tangent.coupling,
                &tangent.zero_dx,
                c,
                x,
                terms,
                gravity,
                ctx,
            )?;
            if self
                .system
                .factor_values(&tangent.values, &mut tangent.l_values, &mut tangent.mem)
                .is_ok()
            {
                factored = true;
                tangent.exact = exact;
                break;
            }
            if !exact {
                break;
            }
        }
        if !factored {
            return Err(not_pd);
        }
        // The active rank-one terms: their free gradients and A⁻¹ of them.
        let active: Vec<usize> = terms
            .rank_ones
            .iter()
            .enumerate()
            .filter(|(_, r)| !r.unilateral || r.value > 0.0)
            .map(|(j, _)| j)
            .collect();
        let m = active.len();
        tangent.active = m;
        tangent.g = Mat::zeros(rows, m);
        for (col, &j) in active.iter().enumerate() {
            for &(node, grad) in &terms.rank_ones[j].gradient {
                if let Some(i) = self.free_index(node) {
                    for d in 0..3 {
                        tangent.g[(3 * i + d, col)] += grad[d];
                    }
                }
            }
        }
        tangent.y = tangent.g.clone();
        if m > tangent.mem_cols {
            tangent.mem = MemBuffer::new(self.system.solve_scratch(m));
            tangent.mem_cols = m;
        }
        self.system
            .solve_factored(&tangent.l_values, &mut tangent.mem, tangent.y.as_mut());
        let mut s = nalgebra::DMatrix::<Real>::zeros(m, m);
        for a in 0..m {
            for b in 0..m {
                s[(a, b)] = (0..rows)
                    .map(|r| tangent.g[(r, a)] * tangent.y[(r, b)])
                    .sum::<Real>();
            }
            s[(a, a)] += 1.0 / terms.rank_ones[active[a]].stiffness;
        }
        let inv = s.try_inverse().ok_or(SimError::SingularRankOneSystem {
            step: ctx.step,
            finger: ctx.finger,
        })?;
        tangent.small_inv = inv.as_slice().to_vec();
        tangent.factored = true;
        Ok(())
    }
}
