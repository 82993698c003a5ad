//! Non-negative least squares for a few columns (Lawson and Hanson's active-set method on the
//! normal equations): the load magnitudes along a contact's admissible directions.

use moe_geom::Real;
use nalgebra::{DMatrix, DVector};

/// The solution of `min ‖A a − b‖²` subject to `a ≥ 0`, given the Gram matrix `G = AᵀA` and
/// `h = Aᵀb` (and `‖b‖²`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Nnls {
    /// The coefficients, all ≥ 0.
    pub(crate) coefficients: Vec<Real>,
    /// `‖A a − b‖²` at the solution.
    pub(crate) residual_sq: Real,
}

/// Solves the problem in normal-equation form. Columns of `G` with a zero diagonal (a load that
/// moves no observed coordinate) keep a zero coefficient.
pub(crate) fn nnls(g: &DMatrix<Real>, h: &DVector<Real>, b_sq: Real) -> Nnls {
    let n = h.len();
    let mut a = DVector::<Real>::zeros(n);
    let mut passive = vec![false; n];
    let tol = 1e-12 * (1.0 + g.diagonal().amax());
    for _ in 0..(3 * n + 3) {
        // Gradient of ½‖Aa − b‖²'s negative: w = h − G a.
        let w = h - g * &a;
        let candidate = (0..n)
            .filter(|&j| !passive[j] && g[(j, j)] > 0.0 && w[j] > tol)
            .max_by(|&i, &j| w[i].total_cmp(&w[j]));
        let Some(j) = candidate else {
            break;
        };
        passive[j] = true;
        // Inner loop: solve on the passive set, step back while a coefficient would go negative.
        for _ in 0..(3 * n + 3) {
            let idx: Vec<usize> = (0..n).filter(|&k| passive[k]).collect();
            let z = solve_subset(g, h, &idx);
            if z.iter().all(|&v| v > 0.0) {
                for (p, &k) in idx.iter().enumerate() {
                    a[k] = z[p];
                }
                for k in (0..n).filter(|k| !passive[*k]) {
                    a[k] = 0.0;
                }
                break;
            }
            // Largest step toward z that keeps every coefficient non-negative.
            let mut alpha = Real::INFINITY;
            for (p, &k) in idx.iter().enumerate() {
                if z[p] <= 0.0 {
                    let denom = a[k] - z[p];
                    if denom > 0.0 {
                        alpha = alpha.min(a[k] / denom);
                    } else {
                        alpha = 0.0;
                    }
                }
            }
            let alpha = if alpha.is_finite() { alpha } else { 0.0 };
            for (p, &k) in idx.iter().enumerate() {
                a[k] += alpha * (z[p] - a[k]);
                if a[k] <= tol.min(1e-300) || (z[p] <= 0.0 && a[k] <= 1e-15) {
                    a[k] = 0.0;
                    passive[k] = false;
                }
            }
            if !passive.iter().any(|&p| p) {
                break;
            }
        }
    }
    let residual_sq = (b_sq - 2.0 * a.dot(h) + a.dot(&(g * &a))).max(0.0);
    Nnls {
        coefficients: a.iter().copied().collect(),
        residual_sq,
    }
}

/// The unconstrained least-squares solution on the columns `idx`.
fn solve_subset(g: &DMatrix<Real>, h: &DVector<Real>, idx: &[usize]) -> Vec<Real> {
    let k = idx.len();
    let sub = DMatrix::from_fn(k, k, |i, j| g[(idx[i], idx[j])]);
    let rhs = DVector::from_fn(k, |i, _| h[idx[i]]);
    match sub.clone().cholesky() {
        Some(ch) => ch.solve(&rhs).iter().copied().collect(),
        None => sub
            .pseudo_inverse(1e-12)
            .map(|p| (p * rhs).iter().copied().collect())
            .unwrap_or_else(|_| vec![0.0; k]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solve(a: &DMatrix<Real>, b: &DVector<Real>) -> Nnls {
        nnls(&(a.transpose() * a), &(a.transpose() * b), b.norm_squared())
    }

    #[test]
    fn an_interior_solution_is_the_least_squares_one() {
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        let x = DVector::from_vec(vec![2.0, 3.0]);
        let b = &a * &x;
        let s = solve(&a, &b);
        assert!((s.coefficients[0] - 2.0).abs() < 1e-12);
        assert!((s.coefficients[1] - 3.0).abs() < 1e-12);
        assert!(s.residual_sq < 1e-20);
    }

    #[test]
    fn a_negative_least_squares_coefficient_is_clamped_and_the_rest_refit() {
        // Unconstrained: b = 1·c0 − 1·c1. With a ≥ 0 the second column drops and the first
        // takes the projection of b on it.
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 1.0]);
        let b = DVector::from_vec(vec![1.0, -1.0]);
        let s = solve(&a, &b);
        assert_eq!(s.coefficients[1], 0.0);
        assert!((s.coefficients[0] - 1.0).abs() < 1e-12);
        assert!((s.residual_sq - 1.0).abs() < 1e-12);
        // Every column pointing away: nothing is loaded, the residual is ‖b‖².
        let s = solve(&a, &DVector::from_vec(vec![-1.0, -2.0]));
        assert_eq!(s.coefficients, vec![0.0, 0.0]);
        assert!((s.residual_sq - 5.0).abs() < 1e-12);
    }

    #[test]
    fn the_solution_satisfies_the_optimality_conditions() {
        // A seeded 8 × 5 problem: a ≥ 0, gradient zero on the passive set, ≤ 0 elsewhere.
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as Real / (1u64 << 53) as Real) - 0.5
        };
        for _ in 0..20 {
            let a = DMatrix::from_fn(8, 5, |_, _| next());
            let b = DVector::from_fn(8, |_, _| next());
            let g = a.transpose() * &a;
            let h = a.transpose() * &b;
            let s = nnls(&g, &h, b.norm_squared());
            let x = DVector::from_vec(s.coefficients.clone());
            let w = &h - &g * &x;
            for j in 0..5 {
                assert!(x[j] >= 0.0);
                if x[j] > 0.0 {
                    assert!(w[j].abs() < 1e-9, "{w}");
                } else {
                    assert!(w[j] < 1e-9, "{w}");
                }
            }
            assert!((s.residual_sq - (&a * &x - &b).norm_squared()).abs() < 1e-9);
        }
    }
}
