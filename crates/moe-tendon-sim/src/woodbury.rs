//! Exact rank-one updates of a factorised system (Woodbury identity) with a pull-only active set,
//! for penalties on scalars that depend on many nodes (tendon lengths).

use moe_geom::Real;

use crate::linsys::SystemBuffers;
use crate::terms::Terms;

/// The small `m × m` system of the active set was singular: neither its Cholesky nor its LU
/// factorisation could be solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct SingularWoodbury;

/// Scratch memory and results of the Woodbury solve, sized once for up to `m` rank-one terms so
/// that a solve does not allocate (the dense `k × k` active-set matrix lives in a reused
/// vector that is lent to nalgebra's Cholesky and handed back).
#[derive(Debug, Clone, Default)]
pub(crate) struct Woodbury {
    /// `G_iᵀ y₀`.
    gy0: Vec<Real>,
    /// `G_iᵀ Y_j`, entry `(i, j)` at `i + m j`.
    gy: Vec<Real>,
    weight: Vec<Real>,
    active: Vec<bool>,
    a: Vec<Real>,
    gu: Vec<Real>,
    idx: Vec<usize>,
    z: Vec<Real>,
    /// The active-set matrix (column-major), its copy for the LU fallback, and the right-hand
    /// side / solution.
    s: Vec<Real>,
    s_copy: Vec<Real>,
    rhs: Vec<Real>,
    /// Coefficients of `Y_j` in `Δx − y₀`.
    pub(crate) combo: Vec<Real>,
    /// Linearised end values `g_j + G_jᵀ Δx` (0 when inactive).
    pub(crate) values: Vec<Real>,
}

impl Woodbury {
    /// Scratch for up to `m` rank-one terms.
    pub(crate) fn new(m: usize) -> Self {
        let mut w = Self::default();
        w.reserve(m);
        w
    }

    /// Makes room for `m` terms (allocates only when `m` exceeds what was reserved before).
    fn reserve(&mut self, m: usize) {
        fn room<T>(v: &mut Vec<T>, n: usize) {
            v.reserve(n.saturating_sub(v.len()));
        }
        for v in [
            &mut self.gy0,
            &mut self.weight,
            &mut self.a,
            &mut self.gu,
            &mut self.z,
            &mut self.rhs,
            &mut self.combo,
            &mut self.values,
        ] {
            room(v, m);
        }
        room(&mut self.active, m);
        room(&mut self.idx, m);
        for v in [&mut self.gy, &mut self.s, &mut self.s_copy] {
            room(v, m * m);
        }
    }

    /// Active-set Woodbury solve for the rank-one terms. With `Y_j = A⁻¹G_j`, `y₀ = A⁻¹b` and
    /// the active set `S` (weights `c_j = c_E k_j`), the solution of
    /// `(A + Σ_S c_j G_j G_jᵀ) Δx = b − Σ_S c_j g_j G_j` is `Δx = u − Y_S z` with
    /// `u = y₀ − Σ_S c_j g_j Y_j` and `(diag(1/c_S) + G_Sᵀ Y_S) z = G_Sᵀ u`. Leaves the
    /// coefficients of `Y_j` in `Δx − y₀` in [`Woodbury::combo`] and the linearised end values
    /// `g_j + G_jᵀ Δx` (0 when inactive) in [`Woodbury::values`].
    ///
    /// # Errors
    /// [`SingularWoodbury`] when the active-set system can be solved neither by Cholesky nor by
    /// LU (an infinite stiffness on a zero gradient, say); `combo` and `values` are then
    /// meaningless.
    pub(crate) fn solve(
        &mut self,
        terms: &Terms,
        shifted: &[Real],
        grads_free: &[Real],
        buf: &SystemBuffers,
        c_ext: Real,
    ) -> Result<(), SingularWoodbury> {
        let m = shifted.len();
        self.reserve(m);
        let Self {
            gy0,
            gy,
            weight,
            active,
            a,
            gu,
            idx,
            z,
            s,
            s_copy,
            rhs,
            combo,
            values,
        } = self;
        combo.clear();
        combo.resize(m, 0.0);
        values.clear();
        values.resize(m, 0.0);
        if m == 0 {
            return Ok(());
        }
        let n = buf.rhs.nrows();
        // Gram matrices in the small space.
        gy0.clear();
        gy0.extend((0..m).map(|i| {
            (0..n)
                .map(|r| grads_free[i * n + r] * buf.rhs[(r, 0)])
                .sum::<Real>()
        }));
        gy.clear();
        for j in 0..m {
            gy.extend((0..m).map(|i| {
                (0..n)
                    .map(|r| grads_free[i * n + r] * buf.rhs[(r, 1 + j)])
                    .sum::<Real>()
            }));
        }
        let gy = |i: usize, j: usize| gy[i + m * j];
        weight.clear();
        weight.extend(terms.rank_ones.iter().map(|r| c_ext * r.stiffness));
        active.clear();
        active.extend(
            terms
                .rank_ones
                .iter()
                .zip(shifted)
                .map(|(r, &g)| !r.unilateral || g > 0.0),
        );
        for _ in 0..(2 * m + 2) {
            // u = y0 + Σ_j a_j Y_j with a_j = −c_j g_j on the active set.
            a.clear();
            a.extend((0..m).map(|j| {
                if active[j] {
                    -weight[j] * shifted[j]
                } else {
                    0.0
                }
            }));
            gu.clear();
            gu.extend((0..m).map(|i| gy0[i] + (0..m).map(|j| gy(i, j) * a[j]).sum::<Real>()));
            idx.clear();
            idx.extend((0..m).filter(|&j| active[j]));
            let k = idx.len();
            z.clear();
            z.resize(m, 0.0);
            if k > 0 {
                s.clear();
                for q in 0..k {
                    s.extend((0..k).map(|p| {
                        gy(idx[p], idx[q]) + if p == q { 1.0 / weight[idx[p]] } else { 0.0 }
                    }));
                }
                s_copy.clone_from(s);
                rhs.clear();
                rhs.extend(idx.iter().map(|&j| gu[j]));
                if !solve_small(s, s_copy, rhs, k) {
                    return Err(SingularWoodbury);
                }
                for (p, &j) in idx.iter().enumerate() {
                    z[j] = rhs[p];
                }
            }
            // Δx = y0 + Σ_j (a_j − z_j) Y_j.
            for j in 0..m {
                combo[j] = a[j] - z[j];
            }
            let mut changed = false;
            for i in 0..m {
                let end = shifted[i] + gy0[i] + (0..m).map(|j| gy(i, j) * combo[j]).sum::<Real>();
                let r = &terms.rank_ones[i];
                if r.unilateral {
                    let want = end > 0.0;
                    if want != active[i] {
                        changed = true;
                        active[i] = want;
                    }
                }
                values[i] = end;
            }
            if !changed {
                break;
            }
        }
        for i in 0..m {
            if !active[i] {
                values[i] = 0.0;
            }
        }
        Ok(())
    }
}

/// Solves the `k × k` system `s x = rhs` (column-major `s`, `s_copy` an equal copy) in place in
/// `rhs`: nalgebra's Cholesky, or its LU when the Cholesky fails. The vectors are lent to
/// nalgebra and handed back on the Cholesky path; the rare fallback drops them (the next solve
/// reallocates). Returns false when both fail.
fn solve_small(s: &mut Vec<Real>, s_copy: &mut Vec<Real>, rhs: &mut Vec<Real>, k: usize) -> bool {
    let dim = nalgebra::Dyn(k);
    let matrix = |v: &mut Vec<Real>| {
        nalgebra::DMatrix::from_data(nalgebra::VecStorage::new(dim, dim, std::mem::take(v)))
    };
    let mut b = nalgebra::DVector::from_data(nalgebra::VecStorage::new(
        dim,
        nalgebra::U1,
        std::mem::take(rhs),
    ));
    let solved = match nalgebra::Cholesky::new(matrix(s)) {
        Some(ch) => {
            ch.solve_mut(&mut b);
            *s = ch.unpack_dirty().data.into();
            true
        }
        None => nalgebra::LU::new(matrix(s_copy)).solve_mut(&mut b),
    };
    *rhs = b.data.into();
    solved
}

#[cfg(test)]
mod tests {
    use moe_geom::{Point3, Vector3};

    use crate::error::SimError;
    use crate::fem::{BodyState, FemInputs, FemModel, Integrator, StepContext};
    use crate::material::Material;
    use crate::terms::RankOneTerm;
    use crate::tetmesh::TetMesh;

    /// One dynamic step of a small block with a single rank-one term of the given stiffness and
    /// gradient (at a free node); the rank-one values it reports.
    fn step_with(stiffness: f64, gradient: Vector3) -> Result<Vec<f64>, SimError> {
        let mesh =
            TetMesh::box_grid(Point3::origin(), Point3::new(0.01, 0.01, 0.02), [1, 1, 2]).unwrap();
        let fixed: Vec<bool> = mesh.nodes().iter().map(|p| p.z < 1e-9).collect();
        let free = fixed.iter().position(|&f| !f).unwrap() as u32;
        let model = FemModel::new(mesh, Material::default(), fixed, &[], 1).unwrap();
        let x = model.mesh().nodes().to_vec();
        let targets = x.clone();
        let v = vec![Vector3::zeros(); x.len()];
        let mut state = BodyState { x, v };
        let mut ws = model.workspace();
        model
            .step(
                &mut ws,
                StepContext { step: 3, finger: 2 },
                Integrator::Dynamic { dt_secs: 0.01 },
                &mut state,
                FemInputs {
                    targets: &targets,
                    gravity: Vector3::zeros(),
                    terms: &mut |_, _, t| {
                        let mut g = t.gradient_buffer();
                        g.push((free, gradient));
                        t.rank_ones.push(RankOneTerm {
                            gradient: g,
                            stiffness,
                            value: 1e-3,
                            unilateral: false,
                        });
                    },
                },
            )
            .map(|r| r.rank_one_values)
    }

    #[test]
    fn a_singular_active_set_system_is_an_error_naming_step_and_finger() {
        // A finite penalty on a constant (zero gradient): the small system is `1/k`, and the
        // end value is the start value.
        let values = step_with(1e3, Vector3::zeros()).unwrap();
        assert_eq!(values, vec![1e-3]);
        // An infinite penalty on a constant: the small system is `1/∞ + 0 = 0`, which neither
        // Cholesky nor LU can solve; the term cannot be honoured and the step says so instead of
        // dropping it.
        assert_eq!(
            step_with(f64::INFINITY, Vector3::zeros()),
            Err(SimError::SingularRankOneSystem { step: 3, finger: 2 })
        );
    }
}
