//! Exact rank-one updates of a factorised system (Woodbury identity) with a pull-only active set,
//! for penalties on scalars that depend on many nodes (tendon lengths).

use moe_geom::Real;

use crate::linsys::SystemBuffers;
use crate::terms::Terms;

/// Active-set Woodbury solve for the rank-one terms. With `Y_j = A⁻¹G_j`, `y₀ = A⁻¹b` and the
/// active set `S` (weights `c_j = c_E k_j`), the solution of
/// `(A + Σ_S c_j G_j G_jᵀ) Δx = b − Σ_S c_j g_j G_j` is `Δx = u − Y_S z` with
/// `u = y₀ − Σ_S c_j g_j Y_j` and `(diag(1/c_S) + G_Sᵀ Y_S) z = G_Sᵀ u`. Returns the coefficients
/// of `Y_j` in `Δx − y₀` and the linearised end values `g_j + G_jᵀ Δx` (0 when inactive).
pub(crate) fn woodbury(
    terms: &Terms,
    shifted: &[Real],
    grads_free: &[Real],
    buf: &SystemBuffers,
    c_ext: Real,
) -> (Vec<Real>, Vec<Real>) {
    let m = shifted.len();
    if m == 0 {
        return (Vec::new(), Vec::new());
    }
    let n = buf.rhs.nrows();
    // Gram matrices in the small space.
    let gy0: Vec<Real> = (0..m)
        .map(|i| {
            (0..n)
                .map(|r| grads_free[i * n + r] * buf.rhs[(r, 0)])
                .sum()
        })
        .collect();
    let gy = nalgebra::DMatrix::<Real>::from_fn(m, m, |i, j| {
        (0..n)
            .map(|r| grads_free[i * n + r] * buf.rhs[(r, 1 + j)])
            .sum()
    });
    let weight: Vec<Real> = terms
        .rank_ones
        .iter()
        .map(|r| c_ext * r.stiffness)
        .collect();
    let mut active: Vec<bool> = terms
        .rank_ones
        .iter()
        .zip(shifted)
        .map(|(r, &g)| !r.unilateral || g > 0.0)
        .collect();
    let mut combo = vec![0.0; m];
    let mut values = vec![0.0; m];
    for _ in 0..(2 * m + 2) {
        // u = y0 + Σ_j a_j Y_j with a_j = −c_j g_j on the active set.
        let a: Vec<Real> = (0..m)
            .map(|j| {
                if active[j] {
                    -weight[j] * shifted[j]
                } else {
                    0.0
                }
            })
            .collect();
        let gu: Vec<Real> = (0..m)
            .map(|i| gy0[i] + (0..m).map(|j| gy[(i, j)] * a[j]).sum::<Real>())
            .collect();
        let idx: Vec<usize> = (0..m).filter(|&j| active[j]).collect();
        let k = idx.len();
        let mut z = vec![0.0; m];
        if k > 0 {
            let s = nalgebra::DMatrix::<Real>::from_fn(k, k, |p, q| {
                gy[(idx[p], idx[q])] + if p == q { 1.0 / weight[idx[p]] } else { 0.0 }
            });
            let rhs = nalgebra::DVector::<Real>::from_fn(k, |p, _| gu[idx[p]]);
            let sol = s
                .clone()
                .cholesky()
                .map(|ch| ch.solve(&rhs))
                .or_else(|| s.lu().solve(&rhs))
                .unwrap_or_else(|| nalgebra::DVector::zeros(k));
            for (p, &j) in idx.iter().enumerate() {
                z[j] = sol[p];
            }
        }
        // Δx = y0 + Σ_j (a_j − z_j) Y_j.
        for j in 0..m {
            combo[j] = a[j] - z[j];
        }
        let mut changed = false;
        for i in 0..m {
            let end = shifted[i] + gy0[i] + (0..m).map(|j| gy[(i, j)] * combo[j]).sum::<Real>();
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
    (combo, values)
}
