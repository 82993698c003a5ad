//! Stationary covariance kernels: RBF (squared exponential, paper Eq. 2) and Matérn 3/2.
//!
//! With `r = ‖x − x'‖`, signal variance `σ²` and length scale `l`:
//!
//! ```text
//! RBF:        k(r) = σ² exp(−r² / (2 l²))
//! Matérn 3/2: k(r) = σ² (1 + a) exp(−a),   a = √3 r / l
//! ```
//!
//! Derivatives with respect to the log-parameters (used by the marginal-likelihood gradient):
//! `∂k/∂log σ² = k` for both; `∂k/∂log l = k · r²/l²` (RBF) and `σ² a² exp(−a)` (Matérn 3/2).

use moe_geom::{Point3, Real};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;

/// Which covariance function the GP uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KernelKind {
    /// Squared exponential (the paper's choice): infinitely smooth surfaces.
    #[default]
    Rbf,
    /// Matérn ν = 3/2: once-differentiable, follows sharper curvature changes.
    Matern32,
}

/// The GP hyper-parameters, in SI units (the SDF is in metres).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Hyper {
    /// Signal variance `σ²` of the kernel (m²).
    pub signal_variance: Real,
    /// Length scale `l` (m).
    pub lengthscale: Real,
    /// Observation noise variance `σ_n²` (m²).
    pub noise_variance: Real,
}

impl Hyper {
    /// Checks that every parameter is finite, the variance and length scale positive and the
    /// noise non-negative.
    ///
    /// # Errors
    /// [`GpisError::InvalidParameter`] naming the parameter.
    pub fn validate(&self) -> Result<(), GpisError> {
        let checks = [
            ("signal_variance_m2", self.signal_variance, false),
            ("lengthscale_m", self.lengthscale, false),
            ("noise_variance_m2", self.noise_variance, true),
        ];
        for (name, value, zero_ok) in checks {
            let ok = value.is_finite() && (value > 0.0 || (zero_ok && value == 0.0));
            if !ok {
                return Err(GpisError::InvalidParameter {
                    name,
                    value,
                    reason: if zero_ok {
                        "must be finite and >= 0"
                    } else {
                        "must be finite and > 0"
                    },
                });
            }
        }
        Ok(())
    }

    /// `[log σ², log l, log σ_n²]`, the optimiser's coordinates.
    pub fn to_log(&self) -> [Real; 3] {
        [
            self.signal_variance.ln(),
            self.lengthscale.ln(),
            self.noise_variance.ln(),
        ]
    }

    /// Inverse of [`Hyper::to_log`].
    pub fn from_log(theta: [Real; 3]) -> Self {
        Self {
            signal_variance: theta[0].exp(),
            lengthscale: theta[1].exp(),
            noise_variance: theta[2].exp(),
        }
    }
}

/// A kernel with its parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Kernel {
    /// Covariance family.
    pub kind: KernelKind,
    /// Signal variance `σ²` (m²).
    pub signal_variance: Real,
    /// Length scale `l` (m).
    pub lengthscale: Real,
}

const SQRT3: Real = 1.732_050_807_568_877_2;

impl Kernel {
    /// The kernel of a hyper-parameter set.
    pub fn new(kind: KernelKind, hyper: &Hyper) -> Self {
        Self {
            kind,
            signal_variance: hyper.signal_variance,
            lengthscale: hyper.lengthscale,
        }
    }

    /// `k(r)` from the squared distance `r²`.
    #[inline]
    pub fn eval_r2(&self, r2: Real) -> Real {
        match self.kind {
            KernelKind::Rbf => {
                self.signal_variance * (-0.5 * r2 / (self.lengthscale * self.lengthscale)).exp()
            }
            KernelKind::Matern32 => {
                let a = SQRT3 * r2.sqrt() / self.lengthscale;
                self.signal_variance * (1.0 + a) * (-a).exp()
            }
        }
    }

    /// `k(a, b)`.
    #[inline]
    pub fn eval(&self, a: &Point3, b: &Point3) -> Real {
        self.eval_r2((a - b).norm_squared())
    }

    /// `(k, ∂k/∂log σ², ∂k/∂log l)` at squared distance `r2`.
    #[inline]
    pub(crate) fn eval_with_log_grad(&self, r2: Real) -> (Real, Real, Real) {
        let l2 = self.lengthscale * self.lengthscale;
        match self.kind {
            KernelKind::Rbf => {
                let k = self.signal_variance * (-0.5 * r2 / l2).exp();
                (k, k, k * r2 / l2)
            }
            KernelKind::Matern32 => {
                let a = SQRT3 * r2.sqrt() / self.lengthscale;
                let e = (-a).exp();
                let k = self.signal_variance * (1.0 + a) * e;
                (k, k, self.signal_variance * a * a * e)
            }
        }
    }

    /// The distance beyond which `k(r) < rel_tol · σ²` (the kernel is then treated as zero by
    /// the truncated grid queries). `rel_tol` is clamped to `(0, 0.5]`.
    pub fn cutoff_radius(&self, rel_tol: Real) -> Real {
        let tol = rel_tol.clamp(Real::MIN_POSITIVE, 0.5);
        match self.kind {
            KernelKind::Rbf => self.lengthscale * (2.0 * (1.0 / tol).ln()).sqrt(),
            KernelKind::Matern32 => {
                // Solve (1 + a) e^{-a} = tol for a > 0 by bisection: the left side decreases.
                let (mut lo, mut hi) = (0.0, 1.0);
                while (1.0 + hi) * (-hi as Real).exp() > tol {
                    hi *= 2.0;
                }
                for _ in 0..100 {
                    let mid = 0.5 * (lo + hi);
                    if (1.0 + mid) * (-mid as Real).exp() > tol {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                hi * self.lengthscale / SQRT3
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kernels() -> [Kernel; 2] {
        [KernelKind::Rbf, KernelKind::Matern32].map(|kind| Kernel {
            kind,
            signal_variance: 1.7,
            lengthscale: 0.3,
        })
    }

    #[test]
    fn log_gradients_match_finite_differences() {
        for k in kernels() {
            for r2 in [0.0, 0.01, 0.09, 0.5] {
                let (v, dsv, dl) = k.eval_with_log_grad(r2);
                assert!((v - k.eval_r2(r2)).abs() < 1e-14);
                let h: Real = 1e-6;
                let mut kp = k;
                kp.signal_variance *= h.exp();
                let mut km = k;
                km.signal_variance *= (-h).exp();
                let fd_sv = (kp.eval_r2(r2) - km.eval_r2(r2)) / (2.0 * h);
                let mut kp = k;
                kp.lengthscale *= h.exp();
                let mut km = k;
                km.lengthscale *= (-h).exp();
                let fd_l = (kp.eval_r2(r2) - km.eval_r2(r2)) / (2.0 * h);
                assert!((fd_sv - dsv).abs() < 1e-8, "{:?} sv {fd_sv} {dsv}", k.kind);
                assert!((fd_l - dl).abs() < 1e-8, "{:?} l {fd_l} {dl}", k.kind);
            }
        }
    }

    #[test]
    fn cutoff_radius_reaches_tolerance() {
        for k in kernels() {
            let r = k.cutoff_radius(1e-12);
            let v = k.eval_r2(r * r) / k.signal_variance;
            assert!((v - 1e-12).abs() < 1e-15, "{:?}: {v}", k.kind);
            assert!(k.eval_r2(0.0) == k.signal_variance);
        }
    }

    #[test]
    fn invalid_hyper_parameters_are_named() {
        let h = Hyper {
            signal_variance: 1.0,
            lengthscale: Real::NAN,
            noise_variance: 0.0,
        };
        match h.validate() {
            Err(GpisError::InvalidParameter { name, .. }) => assert_eq!(name, "lengthscale_m"),
            other => panic!("unexpected {other:?}"),
        }
    }
}
