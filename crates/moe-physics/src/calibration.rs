//! Calibration: the hand's material fitted to contact-free observations (markers against
//! pulls), so that the estimator's model is the hand's, not the data generator's.
//!
//! The fitted quantities are Young's modulus `E` and the stiffness-proportional damping time
//! `β` (the lag of a tendon-driven finger). With the tendons driven by displacement, the bend
//! a pull asks for barely depends on `E`; what shows `E` is the finger's own weight (most when
//! the fingers are held sideways) and, through the dynamics, how fast the finger follows its
//! pulls. A calibration recording therefore holds the hand in a few orientations while the
//! tendons move (`fixtures/scenes/calibration.toml` is such a scene).
//!
//! The objective is the RMS distance between the observed markers and the free finger's,
//! simulated through each stream as the estimator simulates it; it is minimised over
//! `(log E, log β)` by Nelder–Mead from the initial material.

use moe_geom::{HandModel, Iso3, OwnedObservation, Point3, Real, Vector3};
use serde::Serialize;

use crate::config::{HandMaterial, PhysicsConfig};
use crate::error::PhysicsError;
use crate::estimator::FullObservation;
use crate::finger::{FingerInverse, FingerObservation};

/// How to calibrate.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationOptions {
    /// Fit the damping time `β` too (else keep the initial one).
    pub fit_damping: bool,
    /// Most evaluations of the objective by the search (each simulates every stream); the
    /// report's count adds three: the start and the two probes of the resolution. Default 60.
    pub max_evaluations: usize,
    /// `E` and `β` stay within this factor of their initial values. Default 4.
    pub range_factor: Real,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        Self {
            fit_damping: true,
            max_evaluations: 60,
            range_factor: 4.0,
        }
    }
}

/// What a calibration found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationReport {
    /// The fitted material (the initial one with `E` and `β` replaced).
    pub material: HandMaterial,
    /// Streams and frames used.
    pub streams: usize,
    /// Frames used.
    pub frames: usize,
    /// RMS marker coordinate residual with the initial material, metres.
    pub rms_initial_m: Real,
    /// RMS marker coordinate residual with the fitted material, metres.
    pub rms_fitted_m: Real,
    /// Relative change of `E` that raises the residual sum of squares by 1 % (how well the
    /// data pin `E` down; large means `E` is barely observable in these frames).
    pub youngs_modulus_resolution: Real,
    /// Evaluations of the objective.
    pub evaluations: usize,
}

/// The calibration problem: one model per finger, re-used for every material tried.
struct Problem<'a> {
    hand: &'a HandModel,
    fingers: Vec<FingerInverse>,
    streams: Vec<Vec<FullObservation<'a>>>,
    initial: HandMaterial,
    /// Whether β is fitted (else the initial material's is kept).
    fit_damping: bool,
    /// Gravity in the world frame, m/s².
    gravity: Vector3,
    evaluations: usize,
}

impl Problem<'_> {
    /// Material at `(log E, log β)` (β the initial material's when it is not fitted).
    fn material(&self, p: &[Real; 2]) -> HandMaterial {
        let mut m = self.initial.clone();
        m.material.youngs_modulus_pa = p[0].exp();
        if self.fit_damping {
            m.material.rayleigh_stiffness = p[1].exp();
        }
        m
    }

    /// `(Σ residual², coordinates)` over every stream and finger at material `m`.
    fn residual(&mut self, m: &HandMaterial) -> Result<(Real, usize), PhysicsError> {
        self.evaluations += 1;
        let mut sum = 0.0;
        let mut count = 0;
        for (f, finger) in self.fingers.iter_mut().enumerate() {
            finger.set_material(m)?;
            let hf = &self.hand.fingers()[f];
            let hand_from_finger: Iso3 = *hf.hand_from_finger.iso();
            let finger_from_hand = hand_from_finger.inverse();
            for stream in &self.streams {
                finger.reset();
                for frame in stream {
                    let markers: Vec<Option<Point3>> = frame.keypoints.fingers[f]
                        .iter()
                        .map(|k| k.map(|p| finger_from_hand * p))
                        .collect();
                    let world_from_hand: Iso3 = *frame.world_from_hand.iso();
                    let gravity = world_from_hand.inverse_transform_vector(&self.gravity);
                    let obs = FingerObservation {
                        markers: &markers,
                        gravity: finger_from_hand * gravity,
                        world_from_finger: world_from_hand * hand_from_finger,
                        pulls: &frame.tendon_pull_m[f],
                        time_secs: frame.time_secs,
                        depth: &[],
                        covered: &[],
                        seen_through: &[],
                        image: None,
                    };
                    let (s, n) = finger.free_residual(&obs)?;
                    sum += s;
                    count += n;
                }
            }
        }
        Ok((sum, count))
    }
}

/// Fits `E` (and `β`) of `initial` to contact-free `streams` of `hand`: each stream in time
/// order, each observation with its markers, tendon pulls, wrist pose and time (a stream's first
/// frame is taken at rest in its static shape).
///
/// # Errors
/// No frames, observations that lack one of those or do not fit the hand, invalid material or
/// settings, or a static solve that fails for every material tried.
pub fn calibrate(
    hand: &HandModel,
    streams: &[Vec<OwnedObservation>],
    initial: &HandMaterial,
    config: &PhysicsConfig,
    options: &CalibrationOptions,
) -> Result<CalibrationReport, PhysicsError> {
    initial.validate()?;
    initial.check_hand(hand)?;
    config.validate()?;
    let frames: usize = streams.iter().map(Vec::len).sum();
    if frames == 0 {
        return Err(PhysicsError::Missing {
            what: "contact-free frames to calibrate from",
        });
    }
    let stream_count = streams.len();
    let streams = check_frames(hand, streams)?;
    if !(options.range_factor.is_finite() && options.range_factor > 1.0) {
        return Err(PhysicsError::InvalidParameter {
            name: "range_factor",
            value: options.range_factor,
            reason: "must be finite and above 1",
        });
    }
    let fingers = hand
        .fingers()
        .iter()
        .enumerate()
        .map(|(i, f)| FingerInverse::new(i, &f.model, initial, config))
        .collect::<Result<Vec<_>, _>>()?;
    let mut problem = Problem {
        hand,
        fingers,
        streams,
        initial: initial.clone(),
        fit_damping: options.fit_damping,
        gravity: Vector3::from(config.gravity_m_s2),
        evaluations: 0,
    };
    let start = [
        initial.material.youngs_modulus_pa.ln(),
        initial.material.rayleigh_stiffness.max(1e-6).ln(),
    ];
    let (ss0, count) = problem.residual(initial)?;
    let bound = options.range_factor.ln();
    let lo = [start[0] - bound, start[1] - bound];
    let hi = [start[0] + bound, start[1] + bound];
    let dims = if options.fit_damping { 2 } else { 1 };
    // A failed solve makes a material infinitely bad, not the calibration fail.
    let mut objective = |p: &[Real; 2]| -> Real {
        let clamped = [p[0].clamp(lo[0], hi[0]), p[1].clamp(lo[1], hi[1])];
        let penalty = (p[0] - clamped[0]).powi(2) + (p[1] - clamped[1]).powi(2);
        let m = problem.material(&clamped);
        match problem.residual(&m) {
            Ok((s, _)) => s * (1.0 + penalty),
            Err(_) => Real::INFINITY,
        }
    };
    let (best, ss_best) = nelder_mead(&mut objective, start, ss0, dims, options.max_evaluations);
    let best = [best[0].clamp(lo[0], hi[0]), best[1].clamp(lo[1], hi[1])];
    // How sharply the residual rises with E about the fit.
    let h = 0.05;
    let up = objective(&[best[0] + h, best[1]]);
    let down = objective(&[best[0] - h, best[1]]);
    let curvature = (up + down - 2.0 * ss_best) / (h * h);
    let youngs_modulus_resolution = if curvature > 0.0 {
        (2.0 * 0.01 * ss_best / curvature).sqrt()
    } else {
        Real::INFINITY
    };
    let mut material = problem.material(&best);
    material.hand = Some(moe_geom::HandSignature::counts_of(hand));
    Ok(CalibrationReport {
        material,
        streams: stream_count,
        frames,
        rms_initial_m: (ss0 / count.max(1) as Real).sqrt(),
        rms_fitted_m: (ss_best / count.max(1) as Real).sqrt(),
        youngs_modulus_resolution,
        evaluations: problem.evaluations,
    })
}

/// Every frame with what calibration needs of it (markers, pulls, pose and a finite time),
/// checked against the hand.
fn check_frames<'a>(
    hand: &HandModel,
    streams: &'a [Vec<OwnedObservation>],
) -> Result<Vec<Vec<FullObservation<'a>>>, PhysicsError> {
    streams
        .iter()
        .map(|stream| {
            stream
                .iter()
                .map(|frame| {
                    let full = FullObservation::of(&frame.view())?;
                    crate::estimator::check_observation(hand, &full)?;
                    match full.time_secs {
                        Some(t) if t.is_finite() => Ok(full),
                        Some(t) => Err(PhysicsError::InvalidParameter {
                            name: "calibration frame time_secs",
                            value: t,
                            reason: "must be finite",
                        }),
                        None => Err(PhysicsError::Missing {
                            what: "the time of a calibration frame",
                        }),
                    }
                })
                .collect()
        })
        .collect()
}

/// Nelder–Mead on the first `dims` coordinates of `x0` (the others fixed), from a simplex of
/// steps of 0.2 (in log units); returns the best point and its value.
fn nelder_mead(
    f: &mut impl FnMut(&[Real; 2]) -> Real,
    x0: [Real; 2],
    f0: Real,
    dims: usize,
    max_evaluations: usize,
) -> ([Real; 2], Real) {
    let mut simplex: Vec<([Real; 2], Real)> = vec![(x0, f0)];
    for d in 0..dims {
        let mut x = x0;
        x[d] += 0.2;
        let v = f(&x);
        simplex.push((x, v));
    }
    let mut evaluations = dims;
    let n = dims;
    while evaluations < max_evaluations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let (best, worst) = (simplex[0].1, simplex[n].1);
        let spread = simplex
            .iter()
            .map(|(x, _)| {
                (0..n)
                    .map(|d| (x[d] - simplex[0].0[d]).abs())
                    .fold(0.0, Real::max)
            })
            .fold(0.0, Real::max);
        if spread < 1e-3 || (worst - best).abs() <= 1e-9 * best.abs() {
            break;
        }
        let mut centroid = [0.0; 2];
        for (x, _) in &simplex[..n] {
            for d in 0..n {
                centroid[d] += x[d] / n as Real;
            }
        }
        centroid[n..2].copy_from_slice(&x0[n..2]);
        let along = |t: Real| {
            let mut p = centroid;
            for d in 0..n {
                p[d] = centroid[d] + t * (simplex[n].0[d] - centroid[d]);
            }
            p
        };
        let xr = along(-1.0);
        let fr = f(&xr);
        evaluations += 1;
        if fr < simplex[0].1 && evaluations < max_evaluations {
            let xe = along(-2.0);
            let fe = f(&xe);
            evaluations += 1;
            simplex[n] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < simplex[n - 1].1 {
            simplex[n] = (xr, fr);
        } else if evaluations < max_evaluations {
            let t = if fr < simplex[n].1 { -0.5 } else { 0.5 };
            let xc = along(t);
            let fc = f(&xc);
            evaluations += 1;
            if fc < simplex[n].1.min(fr) {
                simplex[n] = (xc, fc);
            } else {
                // Shrink toward the best.
                let b = simplex[0].0;
                for vertex in simplex.iter_mut().skip(1) {
                    if evaluations >= max_evaluations {
                        break;
                    }
                    let mut x = vertex.0;
                    for d in 0..n {
                        x[d] = b[d] + 0.5 * (x[d] - b[d]);
                    }
                    *vertex = (x, f(&x));
                    evaluations += 1;
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nelder_mead_finds_the_minimum_of_a_bowl() {
        let mut f = |p: &[Real; 2]| (p[0] - 1.0).powi(2) + 3.0 * (p[1] + 0.5).powi(2) + 2.0;
        let x0 = [0.0, 0.0];
        let f0 = f(&x0);
        let (x, v) = nelder_mead(&mut f, x0, f0, 2, 200);
        assert!(
            (x[0] - 1.0).abs() < 2e-3 && (x[1] + 0.5).abs() < 2e-3,
            "{x:?}"
        );
        assert!((v - 2.0).abs() < 1e-5);
        // One dimension: the second coordinate stays put.
        let (x, _) = nelder_mead(&mut f, x0, f0, 1, 200);
        assert!((x[0] - 1.0).abs() < 2e-3 && x[1] == 0.0, "{x:?}");
    }
}
