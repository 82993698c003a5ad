//! Rotation part of the polar decomposition `F = R·S` of a 3 × 3 deformation gradient.

use moe_geom::Matrix3;

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
    use moe_geom::{Real, Vector3};
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

    #[test]
    fn inverted_gradient_has_no_rotation() {
        let f = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.5));
        assert!(polar_rotation(&f).is_none());
        assert!(polar_rotation(&Matrix3::zeros()).is_none());
    }
}
