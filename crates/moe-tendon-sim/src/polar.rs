//! Rotation part of the polar decomposition `F = R·S` of a 3 × 3 deformation gradient, and
//! its inversion-safe extension to `det F ≤ 0`.

use moe_geom::{Matrix3, Real};

/// The rotation of a corotated element at deformation gradient `F`, defined for every finite
/// `F`, inverted or not (Irving, Teran and Fedkiw, "Invertible finite elements for robust
/// simulation of large deformation", SCA 2004):
///
/// - `det F > 0`: the polar rotation ([`polar_rotation`]), so `S = Rᵀ F` is the symmetric
///   positive definite stretch;
/// - `det F ≤ 0`: from the singular value decomposition `F = U Σ Vᵀ`, the column of `U` or `V`
///   of the smallest singular value is negated wherever that makes it a proper rotation, with
///   the sign moved onto the singular value. `R = U Vᵀ` is then a rotation and `S = Rᵀ F =
///   V Σ̂ Vᵀ` is symmetric with one negative (or zero) eigenvalue: the element is treated as
///   compressed through itself, and the corotated energy `μ‖S − I‖² + ½λ tr²(S − I)` pushes it
///   back out. Both branches give the same `S` where `det F = 0`, so the energy is continuous
///   across inversion.
///
/// `None` only for a gradient with a non-finite entry (or, never seen, an SVD that does not
/// converge).
pub fn corotation(f: &Matrix3) -> Option<Matrix3> {
    if let Some(r) = polar_rotation(f) {
        return Some(r);
    }
    if !f.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = f.try_svd(true, true, Real::EPSILON, 200)?;
    let (mut u, mut v_t) = (svd.u?, svd.v_t?);
    // The smallest singular value (nalgebra sorts them, but the index is found, not assumed).
    let k = svd.singular_values.imin();
    if u.determinant() < 0.0 {
        u.column_mut(k).neg_mut();
    }
    if v_t.determinant() < 0.0 {
        v_t.row_mut(k).neg_mut();
    }
    Some(u * v_t)
}

/// The rotation `R` of `F = R·S` (`S` symmetric positive definite), by Higham's Newton
/// iteration `X ← ½(γX + γ⁻¹X⁻ᵀ)` with determinant scaling `γ = |det X|^(−1/3)`, which converges
/// quadratically to the orthogonal polar factor. `None` when `det F ≤ 0` (an inverted or
/// degenerate element, whose polar rotation is not a proper rotation).
///
/// Each iteration takes `X⁻ᵀ = cof(X) / det X` from the cofactor matrix, whose first row also
/// gives the determinant, and the scaling from a cube root: no general inverse and no `pow`.
pub fn polar_rotation(f: &Matrix3) -> Option<Matrix3> {
    let det = f.determinant();
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    let mut x = *f;
    let mut scale = true;
    for _ in 0..60 {
        let cof = cofactor(&x);
        let det = x[(0, 0)] * cof[(0, 0)] + x[(0, 1)] * cof[(0, 1)] + x[(0, 2)] * cof[(0, 2)];
        if !(det.is_finite() && det != 0.0) {
            return None;
        }
        let inv_t = cof / det;
        let gamma = if scale { det.abs().cbrt().recip() } else { 1.0 };
        let next = (x * gamma + inv_t / gamma) * 0.5;
        let change = (next - x).norm();
        x = next;
        if change < 1e-3 {
            scale = false;
        }
        if change < 1e-14 {
            break;
        }
    }
    Some(x)
}

/// The cofactor matrix of `m` (`cof(m) = det(m) m⁻ᵀ`).
fn cofactor(m: &Matrix3) -> Matrix3 {
    let c = |r0: usize, r1: usize, c0: usize, c1: usize| {
        m[(r0, c0)] * m[(r1, c1)] - m[(r0, c1)] * m[(r1, c0)]
    };
    Matrix3::new(
        c(1, 2, 1, 2),
        -c(1, 2, 0, 2),
        c(1, 2, 0, 1),
        -c(0, 2, 1, 2),
        c(0, 2, 0, 2),
        -c(0, 2, 0, 1),
        c(0, 1, 1, 2),
        -c(0, 1, 0, 2),
        c(0, 1, 0, 1),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::Vector3;
    use proptest::prelude::*;

    fn orthogonality_error(r: &Matrix3) -> Real {
        (r.transpose() * r - Matrix3::identity()).norm()
    }

    proptest! {
        #[test]
        fn recovers_rotation_of_rotated_stretch(
            ax in -1.0..1.0f64, ay in -1.0..1.0f64, az in -1.0..1.0f64, angle in -3.0..3.0f64,
            s1 in 0.3..3.0f64, s2 in 0.3..3.0f64, s3 in 0.3..3.0f64, shear in -0.5..0.5f64,
        ) {
            let axis = Vector3::new(ax, ay, az + 1e-3);
            let r = nalgebra::Rotation3::new(axis.normalize() * angle).into_inner();
            let b = Matrix3::new(1.0, shear, 0.0, 0.0, 1.0, shear, 0.0, 0.0, 1.0);
            let s = b.transpose() * Matrix3::from_diagonal(&Vector3::new(s1, s2, s3)) * b;
            let f = r * s;
            let got = polar_rotation(&f).unwrap();
            prop_assert!((got - r).norm() < 1e-9, "{got} vs {r}");
            prop_assert!(orthogonality_error(&got) < 1e-12);
            prop_assert!((got.determinant() - 1.0).abs() < 1e-12);
        }
    }

    proptest! {
        #[test]
        fn cofactor_over_determinant_is_the_inverse_transpose(
            a in proptest::collection::vec(-2.0..2.0f64, 9),
        ) {
            let m = Matrix3::from_row_slice(&a) + Matrix3::identity() * 3.0;
            prop_assume!(m.determinant().abs() > 0.1);
            let inv_t = m.try_inverse().unwrap().transpose();
            let got = cofactor(&m) / m.determinant();
            prop_assert!((got - inv_t).norm() < 1e-10 * inv_t.norm().max(1.0), "{got} vs {inv_t}");
        }
    }

    /// The corotated energy density of `F` (unit moduli), as the FEM model computes it.
    fn energy(f: &Matrix3) -> Real {
        let r = corotation(f).unwrap();
        let s = r.transpose() * f;
        let eps = (s + s.transpose()) * 0.5 - Matrix3::identity();
        eps.norm_squared() + 0.5 * eps.trace().powi(2)
    }

    fn rotation(ax: Real, ay: Real, az: Real, angle: Real) -> Matrix3 {
        let axis = Vector3::new(ax, ay, az + 1e-3);
        nalgebra::Rotation3::new(axis.normalize() * angle).into_inner()
    }

    proptest! {
        /// Through inversion — a stretch `t` along one axis from positive to negative, rotated
        /// on both sides — the rotation stays proper, `RᵀF` stays symmetric, and the energy is
        /// that of the signed stretch, `(t − 1)² + ½(t − 1)²` with the other axes unstretched:
        /// continuous at `t = 0` and growing with the inversion.
        #[test]
        fn an_inverted_gradient_is_a_proper_rotation_of_a_signed_stretch(
            ax in -1.0..1.0f64, ay in -1.0..1.0f64, az in -1.0..1.0f64, angle in -3.0..3.0f64,
            bx in -1.0..1.0f64, by in -1.0..1.0f64, bz in -1.0..1.0f64, turn in -3.0..3.0f64,
            t in -0.8..0.8f64,
        ) {
            let (q, w) = (rotation(ax, ay, az, angle), rotation(bx, by, bz, turn));
            let f = q * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, t)) * w;
            let r = corotation(&f).unwrap();
            prop_assert!(orthogonality_error(&r) < 1e-10);
            prop_assert!((r.determinant() - 1.0).abs() < 1e-10);
            let s = r.transpose() * f;
            prop_assert!((s - s.transpose()).norm() < 1e-9, "{s}");
            let want = 1.5 * (t - 1.0).powi(2);
            prop_assert!((energy(&f) - want).abs() < 1e-9, "{} vs {want}", energy(&f));
        }
    }

    #[test]
    fn the_energy_is_continuous_across_inversion() {
        let q = rotation(0.3, -0.7, 0.2, 1.1);
        let at = |t: Real| energy(&(q * Matrix3::from_diagonal(&Vector3::new(1.2, 0.9, t))));
        // Approached from either side, the energy tends to its value at det F = 0.
        for h in [1e-3, 1e-6, 1e-9] {
            assert!((at(h) - at(0.0)).abs() < 10.0 * h, "h = {h}");
            assert!((at(-h) - at(0.0)).abs() < 10.0 * h, "h = {h}");
        }
        // And it grows as the element is pushed further through itself.
        assert!(at(-0.2) > at(-0.1) && at(-0.1) > at(0.0));
        assert!(
            corotation(&Matrix3::zeros()).is_some_and(|r| (r.determinant() - 1.0).abs() < 1e-12)
        );
        assert!(corotation(&Matrix3::from_diagonal_element(Real::NAN)).is_none());
    }

    #[test]
    fn inverted_gradient_has_no_rotation() {
        let f = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.5));
        assert!(polar_rotation(&f).is_none());
        assert!(polar_rotation(&Matrix3::zeros()).is_none());
    }
}
