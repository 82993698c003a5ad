//! Hyper-parameter fitting: maximise the exact log marginal likelihood (paper Eq. 4) over the
//! log-parameters `[log σ², log l, log σ_n²]` with the bounded L-BFGS of [`crate::lbfgs`].
//!
//! Bounds are boxes on the log-parameters (clamping, see [`crate::lbfgs`]). The default start is
//! data-driven: `σ² = mean(r²)`, `l = ¼` of the observations' bounding-box diagonal and
//! `σ_n² = σ²/100`, each clamped into its box. Beyond [`FitConfig::max_fit_points`]
//! observations, the likelihood is evaluated on an evenly strided subset (every `⌈n/max⌉`-th
//! observation), because each evaluation costs `O(n³)`; the GP is then conditioned on all of
//! them.

use moe_geom::{Aabb, Point3, Real};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;
use crate::gp::{Jitter, log_marginal_likelihood_and_grad};
use crate::kernel::{Hyper, KernelKind};
use crate::lbfgs::{LbfgsOptions, minimize_bounded};

/// Box bounds on the hyper-parameters (in their natural units; the optimiser works on logs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HyperBounds {
    /// `(min, max)` signal variance, m² (default `(1e-10, 1)`).
    pub signal_variance: (Real, Real),
    /// `(min, max)` length scale, m (default `(1e-3, 2)`).
    pub lengthscale: (Real, Real),
    /// `(min, max)` noise variance, m² (default `(1e-10, 1e-2)`).
    pub noise_variance: (Real, Real),
}

impl Default for HyperBounds {
    fn default() -> Self {
        Self {
            signal_variance: (1e-10, 1.0),
            lengthscale: (1e-3, 2.0),
            noise_variance: (1e-10, 1e-2),
        }
    }
}

impl HyperBounds {
    /// These bounds with the noise standard deviation at least `sd_m` metres (the upper bound
    /// raised to it if below): for observations known to be that far off the surface — contacts
    /// estimated to a few millimetres — so that the fit does not take their error for shape
    /// (a short length scale bending the surface through every contact). 0 leaves the bounds.
    ///
    /// # Errors
    /// [`GpisError::InvalidParameter`] for a negative or non-finite `sd_m`.
    pub fn with_noise_floor(mut self, sd_m: Real) -> Result<Self, GpisError> {
        if !(sd_m.is_finite() && sd_m >= 0.0) {
            return Err(GpisError::InvalidParameter {
                name: "noise_floor_m",
                value: sd_m,
                reason: "must be a finite distance, 0 or more",
            });
        }
        let v = sd_m * sd_m;
        self.noise_variance.0 = self.noise_variance.0.max(v);
        self.noise_variance.1 = self.noise_variance.1.max(v);
        Ok(self)
    }
}

/// How to fit the hyper-parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitConfig {
    /// Kernel family.
    pub kind: KernelKind,
    /// Box bounds.
    pub bounds: HyperBounds,
    /// Start point; `None` for the data-driven default (module docs).
    pub initial: Option<Hyper>,
    /// Largest number of observations the likelihood is evaluated on (default 400).
    pub max_fit_points: usize,
    /// Iteration limit of the optimiser (default 60).
    pub max_iterations: usize,
    /// Jitter policy for the kernel matrices.
    pub jitter: Jitter,
}

impl Default for FitConfig {
    fn default() -> Self {
        Self {
            kind: KernelKind::Rbf,
            bounds: HyperBounds::default(),
            initial: None,
            max_fit_points: 400,
            max_iterations: 60,
            jitter: Jitter::default(),
        }
    }
}

/// The outcome of [`fit_hyper`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitReport {
    /// The fitted hyper-parameters.
    pub hyper: Hyper,
    /// Log marginal likelihood at the optimum (on the observations used for fitting).
    pub log_marginal_likelihood: Real,
    /// Optimiser iterations.
    pub iterations: usize,
    /// Likelihood evaluations.
    pub evaluations: usize,
    /// Whether the optimiser met a tolerance (rather than its iteration limit).
    pub converged: bool,
    /// Number of observations the likelihood was evaluated on.
    pub points_used: usize,
}

/// The data-driven start point (module docs), clamped into `bounds`.
pub fn default_initial(points: &[Point3], residuals: &[Real], bounds: &HyperBounds) -> Hyper {
    let n = residuals.len().max(1) as Real;
    let ms = residuals.iter().map(|r| r * r).sum::<Real>() / n;
    let diag = Aabb::from_points(points).map_or(1.0, |b| b.diagonal());
    let sv = ms
        .max(1e-8)
        .clamp(bounds.signal_variance.0, bounds.signal_variance.1);
    Hyper {
        signal_variance: sv,
        lengthscale: (0.25 * diag).clamp(bounds.lengthscale.0, bounds.lengthscale.1),
        noise_variance: (0.01 * sv).clamp(bounds.noise_variance.0, bounds.noise_variance.1),
    }
}

fn check_bounds(b: &HyperBounds) -> Result<(), GpisError> {
    for (name, (lo, hi)) in [
        ("bounds.signal_variance_m2", b.signal_variance),
        ("bounds.lengthscale_m", b.lengthscale),
        ("bounds.noise_variance_m2", b.noise_variance),
    ] {
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
            return Err(GpisError::InvalidParameter {
                name,
                value: lo,
                reason: "bounds must be finite with 0 < min <= max",
            });
        }
    }
    Ok(())
}

/// Fits the hyper-parameters of a zero-mean GP to `residuals` at `points`.
///
/// # Errors
/// [`GpisError::TooFewObservations`] below 3 observations, invalid bounds or start, non-finite
/// data, or a singular kernel at the start point.
pub fn fit_hyper(
    points: &[Point3],
    residuals: &[Real],
    config: &FitConfig,
) -> Result<FitReport, GpisError> {
    check_bounds(&config.bounds)?;
    if points.len() != residuals.len() {
        return Err(GpisError::LengthMismatch {
            what: "observation values",
            expected: points.len(),
            got: residuals.len(),
        });
    }
    if points.len() < 3 {
        return Err(GpisError::TooFewObservations {
            method: "hyper-parameter fitting",
            what: "observations",
            needed: 3,
            got: points.len(),
        });
    }
    crate::error::check_iterations("fit_max_iterations", config.max_iterations)?;
    if config.max_fit_points > crate::reconstruct::MAX_EXACT_OBSERVATIONS {
        return Err(GpisError::InvalidParameter {
            name: "max_fit_points",
            value: config.max_fit_points as Real,
            reason: "the likelihood is evaluated on at most 20,000 observations",
        });
    }
    let stride = points.len().div_ceil(config.max_fit_points.max(3));
    let (pts, res): (Vec<Point3>, Vec<Real>) = points
        .iter()
        .zip(residuals)
        .step_by(stride)
        .map(|(p, r)| (*p, *r))
        .unzip();
    let start = match config.initial {
        Some(h) => {
            h.validate()?;
            h
        }
        None => default_initial(&pts, &res, &config.bounds),
    };
    let b = &config.bounds;
    let lower = [
        b.signal_variance.0.ln(),
        b.lengthscale.0.ln(),
        b.noise_variance.0.ln(),
    ];
    let upper = [
        b.signal_variance.1.ln(),
        b.lengthscale.1.ln(),
        b.noise_variance.1.ln(),
    ];
    let objective = |theta: &[Real]| {
        let hyper = Hyper::from_log([theta[0], theta[1], theta[2]]);
        log_marginal_likelihood_and_grad(&pts, &res, config.kind, &hyper, &config.jitter)
            .map(|(lml, g)| (-lml, g.iter().map(|v| -v).collect()))
    };
    let lbfgs = LbfgsOptions {
        max_iterations: config.max_iterations,
        gradient_tolerance: 1e-4,
        function_tolerance: 1e-9,
        ..LbfgsOptions::default()
    };
    let report = minimize_bounded(objective, &start.to_log(), &lower, &upper, &lbfgs)?;
    Ok(FitReport {
        hyper: Hyper::from_log([report.x[0], report.x[1], report.x[2]]),
        log_marginal_likelihood: -report.value,
        iterations: report.iterations,
        evaluations: report.evaluations,
        converged: report.converged,
        points_used: pts.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gp::{cholesky_with_jitter, kernel_matrix};
    use crate::kernel::Kernel;
    use moe_geom::SeededRng;

    /// Draws `f ~ GP(0, k)` at random points via the Cholesky factor, plus Gaussian noise.
    fn sample_gp(kind: KernelKind, truth: &Hyper, n: usize, seed: u64) -> (Vec<Point3>, Vec<Real>) {
        let mut rng = SeededRng::new(seed);
        let pts: Vec<Point3> = (0..n)
            .map(|_| Point3::new(rng.uniform(), rng.uniform(), rng.uniform()))
            .collect();
        let mut k = kernel_matrix(&pts, &Kernel::new(kind, truth), 0.0);
        let (l, _) = cholesky_with_jitter(&mut k, &Jitter::default()).unwrap();
        let z: Vec<Real> = (0..n).map(|_| rng.normal()).collect();
        let y = (0..n)
            .map(|i| {
                let f: Real = (0..=i).map(|j| l[(i, j)] * z[j]).sum();
                f + truth.noise_variance.sqrt() * rng.normal()
            })
            .collect();
        (pts, y)
    }

    #[test]
    fn fitting_recovers_known_hyper_parameters() {
        for (kind, seed) in [(KernelKind::Rbf, 11), (KernelKind::Matern32, 14)] {
            let truth = Hyper {
                signal_variance: 0.5,
                lengthscale: 0.3,
                noise_variance: 1e-3,
            };
            let (pts, y) = sample_gp(kind, &truth, 500, seed);
            let cfg = FitConfig {
                kind,
                max_iterations: 200,
                max_fit_points: 1000,
                ..FitConfig::default()
            };
            let fit = fit_hyper(&pts, &y, &cfg).unwrap();
            let h = fit.hyper;
            let rel = |a: Real, b: Real| (a / b).ln().abs();
            assert!(
                rel(h.lengthscale, truth.lengthscale) < 0.15,
                "{kind:?} {h:?}"
            );
            assert!(
                rel(h.signal_variance, truth.signal_variance) < 0.7,
                "{kind:?} {h:?}"
            );
            assert!(
                rel(h.noise_variance, truth.noise_variance) < 0.4,
                "{kind:?} {h:?}"
            );
            // The optimum beats the truth's likelihood (it maximises it).
            let (lml_truth, _) =
                log_marginal_likelihood_and_grad(&pts, &y, kind, &truth, &Jitter::default())
                    .unwrap();
            assert!(fit.log_marginal_likelihood >= lml_truth - 1e-6);
        }
    }

    /// A floor below the data's noise leaves the fit where it was; one above holds the fitted
    /// noise at the floor; a floor above the upper bound raises it; bad floors are typed.
    #[test]
    fn a_noise_floor_bounds_the_fitted_noise_from_below() {
        let truth = Hyper {
            signal_variance: 0.5,
            lengthscale: 0.3,
            noise_variance: 1e-3,
        };
        let (pts, y) = sample_gp(KernelKind::Rbf, &truth, 300, 11);
        let fit_with = |floor: Real| {
            let cfg = FitConfig {
                bounds: HyperBounds::default().with_noise_floor(floor).unwrap(),
                max_iterations: 200,
                max_fit_points: 1000,
                ..FitConfig::default()
            };
            fit_hyper(&pts, &y, &cfg).unwrap().hyper
        };
        let free = fit_with(0.0);
        assert!(free.noise_variance < 2e-3, "{free:?}");
        let low = fit_with(0.01);
        assert!(
            (low.noise_variance / free.noise_variance - 1.0).abs() < 1e-3,
            "{low:?} {free:?}"
        );
        let high = fit_with(0.08);
        assert!(
            (high.noise_variance / 0.0064 - 1.0).abs() < 1e-9,
            "{high:?}"
        );
        let above = HyperBounds::default().with_noise_floor(0.2).unwrap();
        assert_eq!(above.noise_variance, (0.2 * 0.2, 0.2 * 0.2));
        assert_eq!(
            HyperBounds::default().with_noise_floor(0.0).unwrap(),
            HyperBounds::default()
        );
        for bad in [-1e-3, Real::NAN, Real::INFINITY] {
            assert!(matches!(
                HyperBounds::default().with_noise_floor(bad),
                Err(GpisError::InvalidParameter {
                    name: "noise_floor_m",
                    ..
                })
            ));
        }
    }

    #[test]
    fn too_few_observations_are_reported() {
        let err = fit_hyper(&[Point3::origin(); 2], &[0.0; 2], &FitConfig::default()).unwrap_err();
        assert!(matches!(
            err,
            GpisError::TooFewObservations {
                needed: 3,
                got: 2,
                ..
            }
        ));
    }
}
