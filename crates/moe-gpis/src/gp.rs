//! Exact GP regression by Cholesky factorisation, with the log marginal likelihood (paper Eq. 4)
//! and its analytic gradient.
//!
//! The GP models the residual `r = y − m(x)` of the observations about the mean function `m`
//! (the mean is added back by the caller, see [`mod@crate::reconstruct`]). With `K_y = K + σ_n² I`:
//!
//! ```text
//! α = K_y⁻¹ r,   μ(x*) = m(x*) + k*ᵀ α,   var(x*) = k(x*, x*) − ‖L⁻¹ k*‖²   (K_y = L Lᵀ)
//! log p(r | X) = −½ rᵀ α − Σ log L_ii − (n/2) log 2π
//! ∂ log p / ∂θ_j = ½ tr((α αᵀ − K_y⁻¹) ∂K_y/∂θ_j)
//! ```
//!
//! The variance is that of the latent surface function (noise excluded).
//!
//! **Jitter strategy.** If the Cholesky factorisation fails, or a pivot is below `1e-12` of the
//! mean diagonal (numerically rank deficient, e.g. duplicated points with zero noise), a
//! diagonal jitter `ε·d̄` is added, starting at [`Jitter::initial_relative`] of the mean diagonal
//! `d̄` and multiplied by [`Jitter::factor`] until [`Jitter::max_relative`]; beyond that the
//! factorisation fails with [`GpisError::SingularKernel`]. The jitter used is reported.

use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Mat, Par, Side};
use moe_geom::{Point3, Real};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::GpisError;
use crate::kernel::{Hyper, Kernel, KernelKind};

/// Diagonal jitter policy for nearly singular kernel matrices (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Jitter {
    /// First jitter tried, relative to the mean diagonal of `K_y` (default `1e-10`).
    pub initial_relative: Real,
    /// Largest jitter tried before giving up (default `1e-6`; `0` disables jitter).
    pub max_relative: Real,
    /// Growth factor between attempts (default `10`).
    pub factor: Real,
}

impl Default for Jitter {
    fn default() -> Self {
        Self {
            initial_relative: 1e-10,
            max_relative: 1e-6,
            factor: 10.0,
        }
    }
}

/// Smallest accepted pivot `L_ii²`, relative to the mean diagonal.
const MIN_RELATIVE_PIVOT: Real = 1e-12;

/// The kernel matrix `K + σ_n² I` of a point set.
pub(crate) fn kernel_matrix(points: &[Point3], kernel: &Kernel, noise_variance: Real) -> Mat<Real> {
    let n = points.len();
    let mut k = Mat::<Real>::zeros(n, n);
    // Fill columns in parallel (n ≤ a few thousand: each column is independent).
    let cols: Vec<Vec<Real>> = (0..n)
        .into_par_iter()
        .map(|j| {
            (0..n)
                .map(|i| {
                    kernel.eval(&points[i], &points[j]) + if i == j { noise_variance } else { 0.0 }
                })
                .collect()
        })
        .collect();
    for (j, col) in cols.iter().enumerate() {
        for (i, &v) in col.iter().enumerate() {
            k[(i, j)] = v;
        }
    }
    k
}

/// Lower Cholesky factor of `k` (modified in place by jitter), and the absolute jitter added.
pub(crate) fn cholesky_with_jitter(
    k: &mut Mat<Real>,
    jitter: &Jitter,
) -> Result<(Mat<Real>, Real), GpisError> {
    let n = k.nrows();
    let mean_diag = (0..n).map(|i| k[(i, i)]).sum::<Real>() / n.max(1) as Real;
    if !mean_diag.is_finite() || mean_diag <= 0.0 {
        return Err(GpisError::SingularKernel {
            n,
            max_relative_jitter: 0.0,
        });
    }
    let accept = |l: &Mat<Real>| {
        (0..n).all(|i| {
            let p = l[(i, i)];
            p.is_finite() && p * p >= MIN_RELATIVE_PIVOT * mean_diag
        })
    };
    let mut added = 0.0;
    let mut rel = 0.0;
    loop {
        if let Ok(llt) = k.llt(Side::Lower) {
            let l = llt.L().to_owned();
            if accept(&l) {
                return Ok((l, added));
            }
        }
        rel = if rel == 0.0 {
            jitter.initial_relative
        } else {
            rel * jitter.factor.max(1.5)
        };
        if !(rel > 0.0 && rel <= jitter.max_relative * (1.0 + 1e-9)) {
            return Err(GpisError::SingularKernel {
                n,
                max_relative_jitter: jitter.max_relative,
            });
        }
        let target = rel * mean_diag;
        for i in 0..n {
            k[(i, i)] += target - added;
        }
        added = target;
    }
}

/// Solves `L Lᵀ x = b` for one right-hand side.
fn llt_solve(l: &Mat<Real>, b: &[Real]) -> Vec<Real> {
    let n = b.len();
    let mut x = Mat::<Real>::from_fn(n, 1, |i, _| b[i]);
    solve_lower_triangular_in_place(l.as_ref(), x.as_mut(), Par::Seq);
    solve_upper_triangular_in_place(l.as_ref().transpose(), x.as_mut(), Par::Seq);
    (0..n).map(|i| x[(i, 0)]).collect()
}

fn check_inputs(points: &[Point3], residuals: &[Real]) -> Result<(), GpisError> {
    if points.len() != residuals.len() {
        return Err(GpisError::LengthMismatch {
            what: "observation values",
            expected: points.len(),
            got: residuals.len(),
        });
    }
    if points.is_empty() {
        return Err(GpisError::TooFewObservations {
            method: "gp",
            what: "observations",
            needed: 1,
            got: 0,
        });
    }
    for (index, (p, r)) in points.iter().zip(residuals).enumerate() {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite() && r.is_finite()) {
            return Err(GpisError::NonFiniteObservation {
                what: "observation",
                index,
            });
        }
    }
    Ok(())
}

/// A GP conditioned exactly on its observations.
#[derive(Debug, Clone)]
pub struct ExactGp {
    points: Vec<Point3>,
    kind: KernelKind,
    hyper: Hyper,
    factor: Mat<Real>,
    alpha: Vec<Real>,
    jitter: Real,
    lml: Real,
}

impl ExactGp {
    /// Conditions a zero-mean GP on `residuals` observed at `points`.
    ///
    /// # Errors
    /// Invalid hyper-parameters, non-finite or mismatched inputs, or
    /// [`GpisError::SingularKernel`] (see the jitter strategy in the module docs).
    pub fn condition(
        points: &[Point3],
        residuals: &[Real],
        kind: KernelKind,
        hyper: &Hyper,
        jitter: &Jitter,
    ) -> Result<Self, GpisError> {
        hyper.validate()?;
        check_inputs(points, residuals)?;
        let kernel = Kernel::new(kind, hyper);
        let mut k = kernel_matrix(points, &kernel, hyper.noise_variance);
        let (factor, added) = cholesky_with_jitter(&mut k, jitter)?;
        let alpha = llt_solve(&factor, residuals);
        let n = points.len() as Real;
        let data_fit: Real = residuals.iter().zip(&alpha).map(|(r, a)| r * a).sum();
        let log_det_half: Real = (0..points.len()).map(|i| factor[(i, i)].ln()).sum();
        let lml = -0.5 * data_fit - log_det_half - 0.5 * n * (2.0 * std::f64::consts::PI).ln();
        Ok(Self {
            points: points.to_vec(),
            kind,
            hyper: *hyper,
            factor,
            alpha,
            jitter: added,
            lml,
        })
    }

    /// The kernel.
    pub fn kernel(&self) -> Kernel {
        Kernel::new(self.kind, &self.hyper)
    }

    /// The hyper-parameters.
    pub fn hyper(&self) -> &Hyper {
        &self.hyper
    }

    /// The observation points.
    pub fn points(&self) -> &[Point3] {
        &self.points
    }

    /// The weights `α = K_y⁻¹ r`.
    pub fn alpha(&self) -> &[Real] {
        &self.alpha
    }

    /// Absolute diagonal jitter that was added to `K_y` (0 when none was needed).
    pub fn jitter(&self) -> Real {
        self.jitter
    }

    /// Exact log marginal likelihood of the residuals (paper Eq. 4).
    pub fn log_marginal_likelihood(&self) -> Real {
        self.lml
    }

    /// Posterior mean of the residual field, `k*ᵀ α` (add the mean function for the SDF).
    pub fn mean_residual(&self, p: &Point3) -> Real {
        let kernel = self.kernel();
        self.points
            .iter()
            .zip(&self.alpha)
            .map(|(x, a)| a * kernel.eval(p, x))
            .sum()
    }

    /// Posterior variance of the latent function at each query point (batched triangular solve;
    /// queries are processed in parallel chunks).
    pub fn variances(&self, queries: &[Point3]) -> Vec<Real> {
        let kernel = self.kernel();
        let n = self.points.len();
        queries
            .par_chunks(512)
            .flat_map_iter(|chunk| {
                let mut ks = Mat::<Real>::from_fn(n, chunk.len(), |i, j| {
                    kernel.eval(&self.points[i], &chunk[j])
                });
                solve_lower_triangular_in_place(self.factor.as_ref(), ks.as_mut(), Par::Seq);
                (0..chunk.len())
                    .map(|j| {
                        let v2: Real = (0..n).map(|i| ks[(i, j)] * ks[(i, j)]).sum();
                        (kernel.signal_variance - v2).max(0.0)
                    })
                    .collect::<Vec<_>>()
            })
            .collect()
    }
}

/// The log marginal likelihood (paper Eq. 4) of zero-mean `residuals` at `points` and its
/// gradient with respect to `[log σ², log l, log σ_n²]`.
///
/// # Errors
/// As [`ExactGp::condition`].
pub fn log_marginal_likelihood_and_grad(
    points: &[Point3],
    residuals: &[Real],
    kind: KernelKind,
    hyper: &Hyper,
    jitter: &Jitter,
) -> Result<(Real, [Real; 3]), GpisError> {
    hyper.validate()?;
    check_inputs(points, residuals)?;
    let n = points.len();
    let kernel = Kernel::new(kind, hyper);
    let mut k = kernel_matrix(points, &kernel, hyper.noise_variance);
    let (factor, _) = cholesky_with_jitter(&mut k, jitter)?;
    let alpha = llt_solve(&factor, residuals);
    let data_fit: Real = residuals.iter().zip(&alpha).map(|(r, a)| r * a).sum();
    let log_det_half: Real = (0..n).map(|i| factor[(i, i)].ln()).sum();
    let lml = -0.5 * data_fit - log_det_half - 0.5 * n as Real * (2.0 * std::f64::consts::PI).ln();
    // K_y⁻¹ from the factor: (L Lᵀ)⁻¹.
    // K_y⁻¹ = L⁻ᵀ L⁻¹ from the factor.
    let mut inv = Mat::<Real>::identity(n, n);
    solve_lower_triangular_in_place(factor.as_ref(), inv.as_mut(), Par::Seq);
    solve_upper_triangular_in_place(factor.as_ref().transpose(), inv.as_mut(), Par::Seq);
    // ½ Σ_ij W_ij ∂K_ij, W = ααᵀ − K⁻¹, over the lower triangle (symmetric, off-diagonal ×2).
    // Per-column partial sums in parallel, then a fixed-order total (thread-count independent).
    let partial: Vec<[Real; 3]> = (0..n)
        .into_par_iter()
        .map(|j| {
            let mut g = [0.0; 3];
            for i in j..n {
                let w = alpha[i] * alpha[j] - inv[(i, j)];
                let mult = if i == j { 0.5 } else { 1.0 };
                let (_, dsv, dl) =
                    kernel.eval_with_log_grad((points[i] - points[j]).norm_squared());
                g[0] += mult * w * dsv;
                g[1] += mult * w * dl;
                if i == j {
                    g[2] += 0.5 * w * hyper.noise_variance;
                }
            }
            g
        })
        .collect();
    let grads = partial
        .iter()
        .fold([0.0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
    Ok((lml, grads))
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::SeededRng;

    fn scattered(n: usize, seed: u64) -> Vec<Point3> {
        let mut rng = SeededRng::new(seed);
        (0..n)
            .map(|_| Point3::new(rng.uniform(), rng.uniform(), rng.uniform()))
            .collect()
    }

    #[test]
    fn posterior_mean_interpolates_noise_free_observations() {
        let pts = scattered(40, 1);
        let y: Vec<Real> = pts.iter().map(|p| (3.0 * p.x).sin() + p.y * p.z).collect();
        for kind in [KernelKind::Rbf, KernelKind::Matern32] {
            let hyper = Hyper {
                signal_variance: 1.0,
                lengthscale: 0.4,
                noise_variance: 0.0,
            };
            let gp = ExactGp::condition(&pts, &y, kind, &hyper, &Jitter::default()).unwrap();
            for (p, v) in pts.iter().zip(&y) {
                assert!((gp.mean_residual(p) - v).abs() < 1e-5, "{kind:?}");
            }
            // Variance vanishes at the data and reaches σ² far away.
            let var = gp.variances(&[pts[3], Point3::new(50.0, 0.0, 0.0)]);
            assert!(var[0] < 1e-5, "{var:?}");
            assert!((var[1] - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn lml_gradient_matches_finite_differences() {
        let pts = scattered(30, 2);
        let y: Vec<Real> = pts
            .iter()
            .map(|p| 0.1 * (4.0 * p.x).cos() - 0.05 * p.z)
            .collect();
        for kind in [KernelKind::Rbf, KernelKind::Matern32] {
            let hyper = Hyper {
                signal_variance: 0.02,
                lengthscale: 0.35,
                noise_variance: 1e-3,
            };
            let j = Jitter::default();
            let (lml, g) = log_marginal_likelihood_and_grad(&pts, &y, kind, &hyper, &j).unwrap();
            let gp = ExactGp::condition(&pts, &y, kind, &hyper, &j).unwrap();
            assert!((gp.log_marginal_likelihood() - lml).abs() < 1e-9 * lml.abs().max(1.0));
            let theta = hyper.to_log();
            for d in 0..3 {
                let h = 1e-5;
                let (mut tp, mut tm) = (theta, theta);
                tp[d] += h;
                tm[d] -= h;
                let fp = log_marginal_likelihood_and_grad(&pts, &y, kind, &Hyper::from_log(tp), &j)
                    .unwrap()
                    .0;
                let fm = log_marginal_likelihood_and_grad(&pts, &y, kind, &Hyper::from_log(tm), &j)
                    .unwrap()
                    .0;
                let fd = (fp - fm) / (2.0 * h);
                assert!(
                    (fd - g[d]).abs() < 1e-5 * fd.abs().max(1.0),
                    "{kind:?} param {d}: fd {fd} analytic {}",
                    g[d]
                );
            }
        }
    }

    #[test]
    fn duplicate_points_need_jitter_and_fail_without_it() {
        let mut pts = scattered(10, 3);
        pts.push(pts[0]);
        let y = vec![0.0; pts.len()];
        let hyper = Hyper {
            signal_variance: 1.0,
            lengthscale: 0.3,
            noise_variance: 0.0,
        };
        let gp = ExactGp::condition(&pts, &y, KernelKind::Rbf, &hyper, &Jitter::default()).unwrap();
        assert!(gp.jitter() > 0.0 && gp.jitter() <= 1e-6);
        let none = Jitter {
            max_relative: 0.0,
            ..Jitter::default()
        };
        let err = ExactGp::condition(&pts, &y, KernelKind::Rbf, &hyper, &none).unwrap_err();
        assert!(
            matches!(err, GpisError::SingularKernel { n: 11, .. }),
            "{err}"
        );
    }

    #[test]
    fn non_finite_observations_are_named() {
        let mut pts = scattered(5, 4);
        pts[2].y = Real::NAN;
        let hyper = Hyper {
            signal_variance: 1.0,
            lengthscale: 0.3,
            noise_variance: 1e-4,
        };
        let err = ExactGp::condition(&pts, &[0.0; 5], KernelKind::Rbf, &hyper, &Jitter::default())
            .unwrap_err();
        assert_eq!(
            err,
            GpisError::NonFiniteObservation {
                what: "observation",
                index: 2
            }
        );
    }
}
