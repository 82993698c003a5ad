//! A small limited-memory BFGS minimiser with box bounds, for the GP hyper-parameters (3
//! log-parameters) and the sphere fit (4 parameters).
//!
//! Bounds are handled by projection, not by the full L-BFGS-B machinery (no generalised Cauchy
//! point or subspace minimisation): at each iterate the *projected gradient* zeroes the
//! components that point out of the box at an active bound; the two-loop recursion turns it into
//! a quasi-Newton direction, whose active components are zeroed again; a backtracking
//! (Armijo) line search runs along the *projected path* `clamp(x + t·d)`. Curvature pairs are
//! kept only when `sᵀy > 0`, so the implicit Hessian stays positive definite. If the direction is
//! not a descent direction the memory is cleared and steepest descent is used. For a handful of
//! smooth parameters this converges as fast as L-BFGS-B in practice.

use moe_geom::Real;

/// Stopping rules and memory of [`minimize_bounded`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LbfgsOptions {
    /// Number of curvature pairs kept (default 6).
    pub memory: usize,
    /// Maximum number of iterations (default 100).
    pub max_iterations: usize,
    /// Stop when the projected gradient's largest component is below this (default 1e-6).
    pub gradient_tolerance: Real,
    /// Stop when an iteration lowers the value by less than this, relative to `max(1, |f|)`
    /// (default 1e-10).
    pub function_tolerance: Real,
}

impl Default for LbfgsOptions {
    fn default() -> Self {
        Self {
            memory: 6,
            max_iterations: 100,
            gradient_tolerance: 1e-6,
            function_tolerance: 1e-10,
        }
    }
}

/// The outcome of [`minimize_bounded`].
#[derive(Debug, Clone, PartialEq)]
pub struct LbfgsReport {
    /// The best point found (inside the bounds).
    pub x: Vec<Real>,
    /// The objective there.
    pub value: Real,
    /// Iterations taken.
    pub iterations: usize,
    /// Objective evaluations.
    pub evaluations: usize,
    /// Whether a tolerance was met (otherwise the iteration limit or a failed line search).
    pub converged: bool,
}

fn project(x: &mut [Real], lower: &[Real], upper: &[Real]) {
    for ((v, lo), hi) in x.iter_mut().zip(lower).zip(upper) {
        *v = v.clamp(*lo, *hi);
    }
}

fn dot(a: &[Real], b: &[Real]) -> Real {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Minimises `f` over the box `lower ≤ x ≤ upper`, starting from `x0` (projected into the box).
///
/// `f` returns the value and the gradient. An error at the start point is returned; an error
/// during the line search counts as an infinite value (the step is shortened).
///
/// # Errors
/// The objective's error at the (projected) start point.
///
/// # Panics
/// If `x0`, `lower` and `upper` differ in length or a lower bound exceeds its upper bound
/// (programming errors).
pub fn minimize_bounded<E>(
    mut f: impl FnMut(&[Real]) -> Result<(Real, Vec<Real>), E>,
    x0: &[Real],
    lower: &[Real],
    upper: &[Real],
    config: &LbfgsOptions,
) -> Result<LbfgsReport, E> {
    let n = x0.len();
    assert!(
        lower.len() == n && upper.len() == n,
        "bounds match the dimension"
    );
    assert!(
        lower.iter().zip(upper).all(|(l, u)| l <= u),
        "lower <= upper"
    );
    let mut x = x0.to_vec();
    project(&mut x, lower, upper);
    let (mut fx, mut g) = f(&x)?;
    let mut evaluations = 1;
    let mut memory: Vec<(Vec<Real>, Vec<Real>, Real)> = Vec::new(); // (s, y, 1/(sᵀy))
    let active = |x: &[Real], g: &[Real], i: usize| {
        (x[i] <= lower[i] && g[i] > 0.0) || (x[i] >= upper[i] && g[i] < 0.0)
    };
    for iteration in 0..config.max_iterations {
        let pg: Vec<Real> = (0..n)
            .map(|i| if active(&x, &g, i) { 0.0 } else { g[i] })
            .collect();
        let pg_max = pg.iter().fold(0.0 as Real, |m, v| m.max(v.abs()));
        if pg_max < config.gradient_tolerance || !pg_max.is_finite() {
            return Ok(LbfgsReport {
                x,
                value: fx,
                iterations: iteration,
                evaluations,
                converged: pg_max.is_finite(),
            });
        }
        // Two-loop recursion on the projected gradient.
        let mut q = pg.clone();
        let mut alphas = Vec::with_capacity(memory.len());
        for (s, y, rho) in memory.iter().rev() {
            let a = rho * dot(s, &q);
            for (qi, yi) in q.iter_mut().zip(y) {
                *qi -= a * yi;
            }
            alphas.push(a);
        }
        let gamma = memory
            .last()
            .map_or(1.0 / pg_max.max(1e-300), |(s, y, _)| dot(s, y) / dot(y, y));
        for qi in &mut q {
            *qi *= gamma;
        }
        for ((s, y, rho), a) in memory.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &q);
            for (qi, si) in q.iter_mut().zip(s) {
                *qi += (a - b) * si;
            }
        }
        let mut d: Vec<Real> = q.iter().map(|v| -v).collect();
        for (i, di) in d.iter_mut().enumerate() {
            if active(&x, &g, i) {
                *di = 0.0;
            }
        }
        if dot(&d, &pg) >= 0.0 || d.iter().any(|v| !v.is_finite()) {
            memory.clear();
            let scale = 1.0 / pg_max;
            d = pg.iter().map(|v| -v * scale).collect();
        }
        // Backtracking Armijo search along the projected path.
        let mut t = 1.0;
        let mut accepted = None;
        for _ in 0..40 {
            let mut xn: Vec<Real> = x.iter().zip(&d).map(|(xi, di)| xi + t * di).collect();
            project(&mut xn, lower, upper);
            let step: Vec<Real> = xn.iter().zip(&x).map(|(a, b)| a - b).collect();
            if step.iter().all(|v| *v == 0.0) {
                break;
            }
            evaluations += 1;
            if let Ok((fn_, gn)) = f(&xn)
                && fn_.is_finite()
                && fn_ <= fx + 1e-4 * dot(&g, &step)
            {
                accepted = Some((xn, fn_, gn, step));
                break;
            }
            t *= 0.5;
        }
        let Some((xn, fn_, gn, s)) = accepted else {
            return Ok(LbfgsReport {
                x,
                value: fx,
                iterations: iteration + 1,
                evaluations,
                converged: false,
            });
        };
        let y: Vec<Real> = gn.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-12 * dot(&s, &s).sqrt() * dot(&y, &y).sqrt() && sy > 0.0 {
            if memory.len() == config.memory.max(1) {
                memory.remove(0);
            }
            memory.push((s, y, 1.0 / sy));
        }
        let decrease = fx - fn_;
        x = xn;
        g = gn;
        fx = fn_;
        if decrease <= config.function_tolerance * fx.abs().max(1.0) {
            return Ok(LbfgsReport {
                x,
                value: fx,
                iterations: iteration + 1,
                evaluations,
                converged: true,
            });
        }
    }
    Ok(LbfgsReport {
        x,
        value: fx,
        iterations: config.max_iterations,
        evaluations,
        converged: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rosenbrock(x: &[Real]) -> Result<(Real, Vec<Real>), ()> {
        let (a, b) = (x[0], x[1]);
        let f = (1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2);
        let g = vec![
            -2.0 * (1.0 - a) - 400.0 * a * (b - a * a),
            200.0 * (b - a * a),
        ];
        Ok((f, g))
    }

    #[test]
    fn finds_the_rosenbrock_minimum() {
        let cfg = LbfgsOptions {
            max_iterations: 500,
            gradient_tolerance: 1e-9,
            function_tolerance: 0.0,
            ..LbfgsOptions::default()
        };
        let r = minimize_bounded(rosenbrock, &[-1.2, 1.0], &[-5.0; 2], &[5.0; 2], &cfg).unwrap();
        assert!(
            (r.x[0] - 1.0).abs() < 1e-5 && (r.x[1] - 1.0).abs() < 1e-5,
            "{r:?}"
        );
    }

    #[test]
    fn respects_bounds_and_stops_at_the_constrained_minimum() {
        // Minimum of the unconstrained problem is (1, 1); the box caps x0 at 0.5.
        let r = minimize_bounded(
            rosenbrock,
            &[0.0, 0.0],
            &[-2.0, -2.0],
            &[0.5, 2.0],
            &LbfgsOptions {
                max_iterations: 500,
                function_tolerance: 0.0,
                ..LbfgsOptions::default()
            },
        )
        .unwrap();
        assert!((r.x[0] - 0.5).abs() < 1e-9, "{r:?}");
        assert!((r.x[1] - 0.25).abs() < 1e-5, "{r:?}");
    }
}
