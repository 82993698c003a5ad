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

impl FingerInverse {
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
            for scale in [1.0, 0.5, 0.25] {
                let loads = self.loads_of(&proposal, scale);
                let mut x = state.x.clone();
                match self.solve(
                    &mut x,
                    obs,
                    &loads,
                    "(shape under the estimated loads)",
                    solves,
                ) {
                    Ok(()) => {
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
