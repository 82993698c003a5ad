//! Gauss–Newton: the loads applied in static solves and searched again about the loaded shape
//! until the places stop moving, started from the previous frame's press in a stream.

use moe_geom::{Point3, Real, Vector3};

use super::compliance::Linear;
use super::{FingerInverse, FingerObservation};
use crate::error::PhysicsError;

/// A static solution under some loads.
#[derive(Debug, Clone)]
pub(super) struct Solved {
    /// Node positions.
    pub(super) x: Vec<Point3>,
    /// `(candidate, force)`.
    pub(super) loads: Vec<(usize, Vector3)>,
    /// ‖m − m(x)‖² over the observed coordinates.
    pub(super) chi: Real,
}

/// A search from the previous frame's loads that leaves more than this fraction of the free
/// residual unexplained is repeated from the free shape.
const RESTART_FRACTION: Real = 0.1;

/// A loaded solve that does not converge is repeated in this many halvings of the step from
/// the loads its start is in equilibrium with (2, then 4 substeps).
const SUBSTEP_HALVINGS: u32 = 2;

impl FingerInverse {
    /// Solves the static shape under `loads` from `x`, the equilibrium under `from`; a solve
    /// that does not converge, or meets an element the model cannot carry, is repeated from `x`
    /// in 2, then 4 substeps, each moving the loads part of the way from `from` to `loads` (both
    /// sets applied, scaled by `1 − t` and `t`) and starting from the substep before. A spent
    /// budget ends it at once.
    fn solve_from(
        &mut self,
        x: &mut Vec<Point3>,
        obs: &FingerObservation<'_>,
        from: &[(usize, Vector3)],
        loads: &[(usize, Vector3)],
        solves: &mut usize,
    ) -> Result<(), PhysicsError> {
        const STAGE: &str = "(shape under the estimated loads)";
        let start = x.clone();
        let mut error = match self.solve(x, obs, loads, STAGE, solves) {
            Ok(()) => return Ok(()),
            Err(e @ (PhysicsError::StaticNotConverged { .. } | PhysicsError::Model { .. })) => e,
            Err(e) => return Err(e),
        };
        for halvings in 1..=SUBSTEP_HALVINGS {
            let n = 1usize << halvings;
            let mut y = start.clone();
            let mut done = true;
            for k in 1..=n {
                let t = k as Real / n as Real;
                let step: Vec<(usize, Vector3)> = if k == n {
                    loads.to_vec()
                } else {
                    from.iter()
                        .map(|&(c, f)| (c, f * (1.0 - t)))
                        .chain(loads.iter().map(|&(c, f)| (c, f * t)))
                        .collect()
                };
                match self.solve(&mut y, obs, &step, STAGE, solves) {
                    Ok(()) => {}
                    Err(
                        e @ (PhysicsError::StaticNotConverged { .. } | PhysicsError::Model { .. }),
                    ) => {
                        error = e;
                        done = false;
                        break;
                    }
                    Err(e) => return Err(e),
                }
            }
            if done {
                *x = y;
                return Ok(());
            }
        }
        Err(error)
    }

    /// Gauss–Newton on `count` loads from `state` (updated in place); returns the linear model
    /// about the final state.
    fn gauss_newton(
        &mut self,
        obs: &FingerObservation<'_>,
        state: &mut Solved,
        count: usize,
        solves: &mut usize,
    ) -> Result<Linear, PhysicsError> {
        let mut lin = self.linearise(&state.x, obs, &state.loads, solves)?;
        for _ in 0..self.config.gauss_newton_iterations {
            let proposal = match state.loads.first() {
                Some(&(first, _)) if count >= 2 => self.best_pair(&lin, first),
                _ => self.best_single(&lin),
            };
            let Some(proposal) = proposal else {
                break;
            };
            let proposed = self.loads_of(&proposal, 1.0);
            let same_places = proposed.len() == state.loads.len()
                && proposed.iter().zip(&state.loads).all(|(a, b)| a.0 == b.0);
            let total: Real = proposed.iter().map(|l| l.1.norm()).sum();
            let change: Real = if same_places {
                proposed
                    .iter()
                    .zip(&state.loads)
                    .map(|(a, b)| (a.1 - b.1).norm())
                    .sum()
            } else {
                Real::INFINITY
            };
            if change <= self.config.force_tolerance * total.max(self.config.min_force_n) {
                break;
            }
            let mut accepted = None;
            let mut carried = false;
            for scale in [1.0, 0.5, 0.25] {
                let loads = self.loads_of(&proposal, scale);
                let mut x = state.x.clone();
                match self.solve_from(&mut x, obs, &state.loads, &loads, solves) {
                    Ok(()) => {
                        carried = true;
                        let chi = self.residual_sq(&x, obs);
                        if chi < state.chi {
                            accepted = Some(Solved { x, loads, chi });
                            break;
                        }
                    }
                    // A load the model cannot carry (an inverted element, no equilibrium):
                    // try a smaller one. With the frame's budget spent, every further solve
                    // stops at once and the search keeps what it has.
                    Err(
                        PhysicsError::StaticNotConverged { .. }
                        | PhysicsError::Model { .. }
                        | PhysicsError::FrameBudgetSpent { .. },
                    ) => {}
                    Err(e) => return Err(e),
                }
            }
            let Some(next) = accepted else {
                // No step of the proposal could be solved for, even in substeps: the loads
                // are not the search's converged answer, and the finger says so.
                if !carried {
                    self.degraded = true;
                }
                break;
            };
            *state = next;
            lin = self.linearise(&state.x, obs, &state.loads, solves)?;
        }
        Ok(lin)
    }

    /// Gauss–Newton from `state` with as many loads as it carries (one when none), then, from a
    /// single load, a pair when the second pays its way.
    pub(super) fn search_loads(
        &mut self,
        obs: &FingerObservation<'_>,
        mut state: Solved,
        solves: &mut usize,
    ) -> Result<(Solved, Linear), PhysicsError> {
        let sigma2 = self.config.marker_sigma_m.powi(2);
        let count = state.loads.len().max(1);
        let mut lin = self.gauss_newton(obs, &mut state, count, solves)?;
        if count == 1 && self.config.max_loads_per_finger >= 2 && !state.loads.is_empty() {
            let mut two = state.clone();
            let lin2 = self.gauss_newton(obs, &mut two, 2, solves)?;
            if two.loads.len() == 2
                && two
                    .loads
                    .iter()
                    .all(|f| f.1.norm() >= self.config.min_force_n)
                && (state.chi - two.chi) / sigma2 >= self.config.second_load_chi2
            {
                state = two;
                lin = lin2;
            }
        }
        Ok((state, lin))
    }

    /// Searches the loads of `sobs` from the previous frame's press (when it helps) and, if
    /// that leaves too much of `chi0` unexplained and `restart` allows, again from the static
    /// free shape `x_static`.
    pub(super) fn search_held_press(
        &mut self,
        sobs: &FingerObservation<'_>,
        x_static: &[Point3],
        chi0: Real,
        restart: bool,
        solves: &mut usize,
    ) -> Result<(Solved, Linear), PhysicsError> {
        let mut state = Solved {
            x: x_static.to_vec(),
            loads: Vec::new(),
            chi: chi0,
        };
        // A held press: start from the previous frame's loads when they explain the markers
        // better than none.
        let fresh = state.clone();
        let mut from_tracked = false;
        if let Some(tracked) = self.tracked.take() {
            let mut x = tracked.x;
            if self.solve(&mut x, sobs, &tracked.loads, "", solves).is_ok() {
                let chi = self.residual_sq(&x, sobs);
                if chi < chi0 {
                    state = Solved {
                        x,
                        loads: tracked.loads,
                        chi,
                    };
                    from_tracked = true;
                }
            }
        }
        let (mut state, mut lin) = self.search_loads(sobs, state, solves)?;
        // The previous frame's loads can hold the search in a place the press has left: when
        // they leave a tenth of the residual unexplained, search from the free shape too.
        if restart && from_tracked && state.chi > RESTART_FRACTION * chi0 {
            let (other, other_lin) = self.search_loads(sobs, fresh, solves)?;
            if other.chi < state.chi {
                state = other;
                lin = other_lin;
            }
        }
        Ok((state, lin))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{HandMaterial, PhysicsConfig};
    use moe_geom::{FingerParams, HandModel, HandPreset, Iso3};

    /// A loaded solve that stalls within its iterations (a 1 N press on the middle of the
    /// finger, from the free shape, with 6 Newton iterations) is substepped from the free
    /// shape's loads, and reaches the same equilibrium as a solve given all the iterations it
    /// needs.
    #[test]
    fn a_stalled_loaded_solve_substeps_to_the_same_equilibrium() {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let model = &hand.fingers()[0].model;
        let mut inverse = FingerInverse::new(
            0,
            model,
            &HandMaterial::default(),
            &PhysicsConfig::default(),
        )
        .unwrap();
        let markers = vec![None; model.marker_vertices().len()];
        let pulls = vec![0.0; model.tendon_routes().len()];
        let obs = FingerObservation {
            markers: &markers,
            gravity: Vector3::new(0.0, 0.0, -9.81),
            world_from_finger: Iso3::identity(),
            pulls: &pulls,
            time_secs: None,
            depth: &[],
            covered: &[],
            seen_through: &[],
            image: None,
        };
        let mut solves = 0;
        let free = inverse.static_free(&obs, &mut solves).unwrap();
        let c = inverse.candidates.len() / 2;
        let v = inverse.candidates[c] as usize;
        let loads = [(c, -inverse.rest_normals[v])];
        let mut converged = free.clone();
        inverse
            .solve(&mut converged, &obs, &loads, "", &mut solves)
            .unwrap();

        inverse.config.static_max_iterations = 6;
        let mut direct = free.clone();
        assert!(matches!(
            inverse.solve(&mut direct, &obs, &loads, "", &mut solves),
            Err(PhysicsError::StaticNotConverged { .. })
        ));
        let mut x = free.clone();
        let before = solves;
        inverse
            .solve_from(&mut x, &obs, &[], &loads, &mut solves)
            .unwrap();
        // The direct attempt and at least two substeps.
        assert!(solves - before > 6 + 2, "{}", solves - before);
        let gap = x
            .iter()
            .zip(&converged)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        let moved = x
            .iter()
            .zip(&free)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        assert!(moved > 1e-3, "the press moves the finger: {moved} m");
        assert!(gap < 1e-5, "{gap} m from the converged solve");
    }
}
