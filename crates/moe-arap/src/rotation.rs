//! Best-fitting rotations for the local step.
//!
//! The local step needs, for a 3 × 3 matrix `S = UΣVᵀ`, the rotation that maximises `tr(R S)`:
//! `R = V·diag(1, 1, det(VUᵀ))·Uᵀ` (DESIGN.md). When `det S > 0` this is the orthogonal polar factor
//! of `Sᵀ` (`Sᵀ = V Uᵀ · U Σ Uᵀ`), which the scaled Newton iteration `X ← (ζX + ζ⁻¹X⁻ᵀ)/2`
//! (Higham 1986) reaches in a handful of steps of a few dozen flops each — much cheaper than a
//! full SVD, and the result is the same rotation to rounding. Cells whose matrix is
//! ill-conditioned or reflecting (flat one-rings give rank-2 `S`, inverted cells give `det S < 0`)
//! take the SVD route with the determinant correction.

use moe_geom::{Matrix3, Real, Vector3};

/// Relative determinant below which the Newton route is not trusted: `det S ≤ TOL·‖S‖³`.
const MIN_REL_DET: Real = 1e-9;
/// Maximum Newton steps before falling back to the SVD.
const MAX_NEWTON_STEPS: usize = 24;

/// Newton steps on the rotation group tried from a warm start before the polar route.
const MAX_GROUP_STEPS: usize = 6;
/// A group Newton step shorter than this (radians) ends the iteration: convergence is quadratic,
/// so the remaining error is of the order of its square (1e-12).
const GROUP_STEP_TOL: Real = 1e-6;

/// Like [`fit_rotation`], starting from a nearby rotation `r0` (the previous iteration's).
///
/// Newton's method on SO(3) for `f(R) = tr(R S)`: with `R = exp([ω]) R₀` (applied through the
/// Cayley retraction) and `M = R₀ S`, the
/// gradient is `g = (M₁₂ − M₂₁, M₂₀ − M₀₂, M₀₁ − M₁₀)` and the Hessian `½(M + Mᵀ) − tr(M) I`, so the
/// step solves `(tr(M) I − ½(M + Mᵀ)) ω = g`. The iteration stops at a point where that matrix is
/// positive definite and the gradient vanishes — the maximiser, which is unique when `S` has full
/// rank or rank 2 — and converges quadratically, so a warm start needs one to three steps. It
/// falls back to [`fit_rotation`] when a step is not an ascent direction or it does not converge.
pub(crate) fn fit_rotation_from(s: &Matrix3, r0: &Matrix3) -> (Matrix3, bool) {
    // Plain row-major arrays: this runs for every vertex in every iteration, and the explicit
    // 3 × 3 arithmetic compiles to a fraction of the generic matrix code.
    let sa = rows(s);
    let mut r = rows(r0);
    for _ in 0..MAX_GROUP_STEPS {
        let m = mul(&r, &sa);
        let g = Vector3::new(m[1][2] - m[2][1], m[2][0] - m[0][2], m[0][1] - m[1][0]);
        let tr = m[0][0] + m[1][1] + m[2][2];
        let p = Matrix3::new(
            tr - m[0][0],
            -0.5 * (m[0][1] + m[1][0]),
            -0.5 * (m[0][2] + m[2][0]),
            -0.5 * (m[0][1] + m[1][0]),
            tr - m[1][1],
            -0.5 * (m[1][2] + m[2][1]),
            -0.5 * (m[0][2] + m[2][0]),
            -0.5 * (m[1][2] + m[2][1]),
            tr - m[2][2],
        );
        let Some(omega) = solve_spd3(&p, &g) else {
            break;
        };
        let theta_sq = omega.norm_squared();
        if theta_sq > 1.0 {
            break;
        }
        r = mul(&cayley(&omega), &r);
        if theta_sq < GROUP_STEP_TOL * GROUP_STEP_TOL {
            // Each Cayley product adds ~1e-16 of drift from orthogonality; the solver bounds it by
            // re-orthonormalising the warm starts once per solve (`orthonormalize`).
            return (
                Matrix3::new(
                    r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
                ),
                false,
            );
        }
    }
    fit_rotation(s)
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
fn rows(m: &Matrix3) -> [[Real; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

/// Product of row-major 3 × 3 matrices.
#[inline]
fn mul(a: &[[Real; 3]; 3], b: &[[Real; 3]; 3]) -> [[Real; 3]; 3] {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

/// The Cayley rotation of `ω` (row-major): `I + c([ω] + [ω]²/2)` with `c = 1/(1 + |ω|²/4)`, a
/// retraction that agrees with `exp([ω])` to second order and needs no trigonometry.
#[inline]
fn cayley(omega: &Vector3) -> [[Real; 3]; 3] {
    let (x, y, z) = (omega.x, omega.y, omega.z);
    let sq = x * x + y * y + z * z;
    let c = 1.0 / (1.0 + 0.25 * sq);
    // [ω]² = ωωᵀ − |ω|² I.
    let h = 0.5 * c;
    [
        [
            1.0 + h * (x * x - sq),
            c * -z + h * x * y,
            c * y + h * x * z,
        ],
        [
            c * z + h * y * x,
            1.0 + h * (y * y - sq),
            c * -x + h * y * z,
        ],
        [
            c * -y + h * z * x,
            c * x + h * z * y,
            1.0 + h * (z * z - sq),
        ],
    ]
}

/// Solves `P x = g` for symmetric `P` through its adjugate; `None` unless `P` is (numerically)
/// positive definite, checked by its leading principal minors. One division and no square root:
/// this sits on the critical path of every local step.
fn solve_spd3(p: &Matrix3, g: &Vector3) -> Option<Vector3> {
    let (a, b, c) = (p[(0, 0)], p[(0, 1)], p[(0, 2)]);
    let (d, e, f) = (p[(1, 1)], p[(1, 2)], p[(2, 2)]);
    // Cofactors of the symmetric matrix [[a, b, c], [b, d, e], [c, e, f]].
    let c00 = d * f - e * e;
    let c01 = c * e - b * f;
    let c02 = b * e - c * d;
    let c11 = a * f - c * c;
    let c12 = b * c - a * e;
    let c22 = a * d - b * b;
    let det = a * c00 + b * c01 + c * c02;
    let scale = a.abs().max(d).max(f);
    // Relative floor: a nearly singular Hessian means a saddle or a degenerate S.
    if a.is_nan() || a <= 0.0 || c22 <= 0.0 || det <= 1e-12 * scale * scale * scale {
        return None;
    }
    let inv = 1.0 / det;
    Some(Vector3::new(
        (c00 * g.x + c01 * g.y + c02 * g.z) * inv,
        (c01 * g.x + c11 * g.y + c12 * g.z) * inv,
        (c02 * g.x + c12 * g.y + c22 * g.z) * inv,
    ))
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
