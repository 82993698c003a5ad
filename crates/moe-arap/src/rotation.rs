//! Best-fitting rotations for the local step.
//!
//! The local step needs, for a 3 × 3 matrix `S = UΣVᵀ`, the rotation that maximises `tr(R S)`:
//! `R = V·diag(1, 1, det(VUᵀ))·Uᵀ` (docs/design.md). When `det S > 0` this is the orthogonal polar factor
//! of `Sᵀ` (`Sᵀ = V Uᵀ · U Σ Uᵀ`), which the scaled Newton iteration `X ← (ζX + ζ⁻¹X⁻ᵀ)/2`
//! (Higham 1986) reaches in a handful of steps of a few dozen flops each — much cheaper than a
//! full SVD, and the result is the same rotation to rounding. Cells whose matrix is
//! ill-conditioned or reflecting (flat one-rings give rank-2 `S`, inverted cells give `det S < 0`)
//! take the SVD route with the determinant correction.

use moe_geom::{Matrix3, Real};

use crate::newton::{Rows, group_newton};

/// Relative determinant below which the Newton route is not trusted: `det S ≤ TOL·‖S‖³`.
const MIN_REL_DET: Real = 1e-9;
/// Maximum Newton steps before falling back to the SVD.
const MAX_NEWTON_STEPS: usize = 24;

/// Like [`fit_rotation`], starting from a nearby rotation `r0` (the previous iteration's): Newton's
/// method on SO(3) (see `newton.rs`), falling back to [`fit_rotation`] when a step is not an
/// ascent direction or it does not converge. (The solver fits two cells at a time through
/// [`fit_rotations_from`].)
#[cfg(test)]
pub(crate) fn fit_rotation_from(s: &Matrix3, r0: &Matrix3) -> (Matrix3, bool) {
    let [fit] = fit_rotations_from::<1>(&[rows(s)], &[rows(r0)]);
    fit
}

/// [`fit_rotation_from`] for `L` independent cells at once (`s` and `r0` row-major); the results
/// are those of `L` separate calls, bit for bit.
#[inline(always)]
pub(crate) fn fit_rotations_from<const L: usize>(
    s: &[Rows; L],
    r0: &[Rows; L],
) -> [(Matrix3, bool); L] {
    let fits = group_newton(s, r0);
    std::array::from_fn(|l| match fits[l] {
        Some(r) => (
            Matrix3::new(
                r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
            ),
            false,
        ),
        None => {
            let m = &s[l];
            fit_rotation(&Matrix3::new(
                m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2],
            ))
        }
    })
}

/// One Newton polar step `(R + R⁻ᵀ)/2`: removes the rounding drift of a nearly orthogonal matrix.
pub(crate) fn orthonormalize(r: &Matrix3) -> Matrix3 {
    let det = r.determinant();
    if det.is_finite() && det > 0.5 {
        (r + cofactor(r) / det) * 0.5
    } else {
        Matrix3::identity()
    }
}

/// Row-major copy of a matrix.
#[inline]
pub(crate) fn rows(m: &Matrix3) -> Rows {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

/// The rotation `R = V·diag(1, 1, det(VUᵀ))·Uᵀ` for `S = UΣVᵀ`, and whether the SVD route was used.
pub(crate) fn fit_rotation(s: &Matrix3) -> (Matrix3, bool) {
    let norm = s.norm();
    if !(norm > 0.0 && norm.is_finite()) {
        return (Matrix3::identity(), true);
    }
    let x0 = s.transpose() / norm;
    if x0.determinant() > MIN_REL_DET
        && let Some(r) = polar_newton(x0)
    {
        return (r, false);
    }
    (svd_rotation(s), true)
}

/// Orthogonal polar factor of a well-conditioned matrix with positive determinant.
fn polar_newton(mut x: Matrix3) -> Option<Matrix3> {
    for _ in 0..MAX_NEWTON_STEPS {
        let det = x.determinant();
        if det.is_nan() || det <= 0.0 {
            return None;
        }
        // X⁻ᵀ = cof(X) / det(X).
        let inv_t = cofactor(&x) / det;
        let zeta = (inv_t.norm() / x.norm()).sqrt();
        let next = (x * zeta + inv_t / zeta) * 0.5;
        let change = (next - x).norm();
        x = next;
        if change < 1e-13 {
            // One more unscaled step polishes the last digits.
            let det = x.determinant();
            return Some((x + cofactor(&x) / det) * 0.5);
        }
    }
    None
}

/// Matrix of cofactors (so that `X⁻ᵀ = cof(X) / det X`).
fn cofactor(m: &Matrix3) -> Matrix3 {
    let c0 = m.column(1).cross(&m.column(2));
    let c1 = m.column(2).cross(&m.column(0));
    let c2 = m.column(0).cross(&m.column(1));
    // For columns a, b, c of M the rows of det(M)·M⁻¹ are b×c, c×a, a×b, so those cross
    // products are the columns of det(M)·M⁻ᵀ.
    Matrix3::from_columns(&[c0, c1, c2])
}

/// The determinant-corrected SVD rotation.
pub(crate) fn svd_rotation(s: &Matrix3) -> Matrix3 {
    let svd = s.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    // Singular values are sorted in decreasing order, so the last column pairs with the smallest.
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant();
    let mut v_fixed = v;
    if d < 0.0 {
        v_fixed.column_mut(2).neg_mut();
    }
    v_fixed * u.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::Vector3;

    fn rotation(axis: Vector3, angle: Real) -> Matrix3 {
        let iso = moe_geom::Iso3::new(Vector3::zeros(), axis.normalize() * angle);
        iso.rotation.to_rotation_matrix().into_inner()
    }

    /// Deterministic pseudo-random matrices.
    fn matrices() -> Vec<Matrix3> {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
        };
        (0..500).map(|_| Matrix3::from_fn(|_, _| next())).collect()
    }

    #[test]
    fn newton_route_matches_the_svd_convention() {
        let mut newton = 0;
        for s in matrices() {
            let (r, fallback) = fit_rotation(&s);
            let reference = svd_rotation(&s);
            assert!((r - reference).norm() < 1e-10, "{s}: {r} vs {reference}");
            assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-12);
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            newton += usize::from(!fallback);
        }
        // About half the random matrices have a positive determinant.
        assert!(newton > 150, "{newton}");
    }

    #[test]
    fn warm_started_group_newton_matches_the_svd_convention() {
        let start = rotation(Vector3::new(1.0, 2.0, -0.5), 0.3);
        let mut group = 0;
        for s in matrices() {
            // Warm starts near the answer (as in the ARAP iterations) and at the identity.
            let reference = svd_rotation(&s);
            for r0 in [reference * start, Matrix3::identity()] {
                let (r, fallback) = fit_rotation_from(&s, &r0);
                assert!((r - reference).norm() < 1e-10, "{s}: {r} vs {reference}");
                assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-13);
                group += usize::from(!fallback);
            }
        }
        assert!(group > 200, "{group}");
        // A flat, symmetric S (a planar cell at rest) gives the identity without the SVD.
        let flat = Matrix3::new(2.0, 0.3, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0, 0.0);
        let (r, fallback) = fit_rotation_from(&flat, &Matrix3::identity());
        assert!(!fallback);
        assert!((r - Matrix3::identity()).norm() < 1e-15);
    }

    #[test]
    fn recovers_the_rotation_of_a_rotated_covariance() {
        // S = Σ w e (R e)ᵀ = C Rᵀ with C symmetric positive definite: the fit returns R.
        let r = rotation(Vector3::new(0.3, -1.0, 0.4), 1.1);
        let c = Matrix3::new(2.0, 0.3, 0.1, 0.3, 1.0, -0.2, 0.1, -0.2, 0.5);
        let (fit, fallback) = fit_rotation(&(c * r.transpose()));
        assert!(!fallback);
        assert!((fit - r).norm() < 1e-12);
        // A flat (rank-2) covariance still determines the rotation, through the SVD route.
        let flat = Matrix3::new(2.0, 0.3, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0, 0.0);
        let (fit, fallback) = fit_rotation(&(flat * r.transpose()));
        assert!(fallback);
        assert!((fit - r).norm() < 1e-10, "{fit} vs {r}");
    }

    #[test]
    fn reflections_are_corrected_to_rotations() {
        let s = Matrix3::from_diagonal(&Vector3::new(3.0, 2.0, -1.0));
        let (r, fallback) = fit_rotation(&s);
        assert!(fallback);
        assert!((r - Matrix3::identity()).norm() < 1e-12, "{r}");
        assert_eq!(fit_rotation(&Matrix3::zeros()).0, Matrix3::identity());
    }
}
