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

/// A single load that the model could not carry in a stream is not solved for again at this
/// fraction of its force or more, at the same place, for [`UNCARRIED_MEMORY_SECS`]: the finger
/// buckles under it (an axial press on the apex), and its state changes little in that time.
const UNCARRIED_FORCE_FRACTION: Real = 0.75;

/// How long a stream remembers a load that could not be carried, seconds.
const UNCARRIED_MEMORY_SECS: Real = 0.25;

/// A search from the previous frame's loads that leaves more than this fraction of the free
/// residual unexplained is repeated from the free shape.
const RESTART_FRACTION: Real = 0.1;

impl FingerInverse {
    /// [`FingerInverse::solve`] within the load search (the loads given at `given_at`): the
    /// loads at the solution, or `Ok(None)` for a load the model cannot carry (a stall, an
    /// inverted element, no equilibrium) or a spent budget, after which every further solve
    /// stops at once.
    fn try_solve(
        &mut self,
        x: &mut Vec<Point3>,
        obs: &FingerObservation<'_>,
        loads: &[(usize, Vector3)],
        given_at: &[Point3],
        solves: &mut usize,
    ) -> Result<Option<Vec<(usize, Vector3)>>, PhysicsError> {
        match self.solve(
            x,
            obs,
            loads,
            given_at,
            "(shape under the estimated loads)",
            solves,
        ) {
            Ok(turned) => Ok(Some(turned)),
            Err(
                PhysicsError::StaticNotConverged { .. }
                | PhysicsError::Model { .. }
                | PhysicsError::FrameBudgetSpent { .. },
            ) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// The proposal's loads solved for from `state`: the whole proposal, else half of it, else
    /// a quarter. A part that the model carries is the first of substeps: the larger parts are
    /// solved for in turn, each from the equilibrium of the one before, up to the whole
    /// proposal or the first that does not converge, and the best fit of them kept. Returns the
    /// first fit better than `state`'s, and whether any solve converged.
    ///
    /// In a stream, the smallest single load the model could not carry is remembered with its
    /// place, and for [`UNCARRIED_MEMORY_SECS`] a load at that place of
    /// [`UNCARRIED_FORCE_FRACTION`] of its force or more is not solved for.
    fn carry(
        &mut self,
        obs: &FingerObservation<'_>,
        state: &Solved,
        proposal: &super::search::Fit,
        solves: &mut usize,
    ) -> Result<(Option<Solved>, bool), PhysicsError> {
        const SCALES: [Real; 3] = [1.0, 0.5, 0.25];
        let parts: Vec<Vec<(usize, Vector3)>> =
            SCALES.iter().map(|&s| self.loads_of(proposal, s)).collect();
        // Whether part `k` is a single load that the stream's memory says is not carried.
        let known =
            |this: &Self, k: usize| match (parts[k].as_slice(), obs.time_secs, this.uncarried) {
                ([(c, f)], Some(t), Some((c0, f0, t0))) => {
                    *c == c0
                        && f.norm() >= UNCARRIED_FORCE_FRACTION * f0
                        && t >= t0
                        && t - t0 <= UNCARRIED_MEMORY_SECS
                }
                _ => false,
            };
        let mut carried = false;
        for k in 0..SCALES.len() {
            if known(self, k) {
                continue;
            }
            // Every part's forces are given in the shape the proposal was made in.
            let mut x = state.x.clone();
            let Some(loads) = self.try_solve(&mut x, obs, &parts[k], &state.x, solves)? else {
                self.remember_uncarried(obs, &parts[k], *solves);
                continue;
            };
            carried = true;
            let chi = self.residual_sq(&x, obs);
            let mut best = Solved { x, loads, chi };
            let mut last = best.x.clone();
            for larger in (0..k).rev() {
                if known(self, larger) {
                    break;
                }
                let Some(loads) =
                    self.try_solve(&mut last, obs, &parts[larger], &state.x, solves)?
                else {
                    self.remember_uncarried(obs, &parts[larger], *solves);
                    break;
                };
                let chi = self.residual_sq(&last, obs);
                if chi < best.chi {
                    best = Solved {
                        x: last.clone(),
                        loads,
                        chi,
                    };
                }
            }
            if best.chi < state.chi {
                return Ok((Some(best), true));
            }
        }
        Ok((None, carried))
    }

    /// Remembers `loads`, whose solve did not converge, when it is a single load in a stream,
    /// the model (not the spent budget) could not carry it, and it is smaller than the load
    /// remembered at the same place.
    fn remember_uncarried(
        &mut self,
        obs: &FingerObservation<'_>,
        loads: &[(usize, Vector3)],
        solves: usize,
    ) {
        let ([(c, f)], Some(t)) = (loads, obs.time_secs) else {
            return;
        };
        if self.budget_end.is_some_and(|end| solves >= end) {
            return;
        }
        let f = f.norm();
        let smaller = match self.uncarried {
            Some((c0, f0, t0)) if c0 == *c && t >= t0 && t - t0 <= UNCARRIED_MEMORY_SECS => f < f0,
            _ => true,
        };
        if smaller {
            self.uncarried = Some((*c, f, t));
        }
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
            let (accepted, carried) = self.carry(obs, state, &proposal, solves)?;
            let Some(next) = accepted else {
                // No part of the proposal converged (or the stream remembers that none
                // does): the loads are not the search's converged answer, and the finger
                // says so.
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
            // Its forces are those at the shape it was found in.
            let mut x = tracked.x.clone();
            if let Ok(loads) = self.solve(&mut x, sobs, &tracked.loads, &tracked.x, "", solves) {
                let chi = self.residual_sq(&x, sobs);
                if chi < chi0 {
                    state = Solved { x, loads, chi };
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

    /// Finger 0 of the two-finger hand's estimator with the default settings, its markers
    /// unseen and its tendons' pulls (zero).
    fn finger() -> (FingerInverse, Vec<Option<Point3>>, Vec<Real>) {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let model = &hand.fingers()[0].model;
        let inverse = FingerInverse::new(
            0,
            model,
            &HandMaterial::default(),
            &PhysicsConfig::default(),
        )
        .unwrap();
        let unseen = vec![None; model.marker_vertices().len()];
        (inverse, unseen, vec![0.0; model.tendon_routes().len()])
    }

    /// The finger upright at the origin, seeing `markers`, at `time_secs`.
    fn observation<'a>(
        markers: &'a [Option<Point3>],
        pulls: &'a [Real],
        time_secs: Option<Real>,
    ) -> FingerObservation<'a> {
        FingerObservation {
            markers,
            gravity: Vector3::new(0.0, 0.0, -9.81),
            world_from_finger: Iso3::identity(),
            pulls,
            time_secs,
            depth: &[],
            covered: &[],
            seen_through: &[],
            image: None,
        }
    }

    /// A proposed load whose solve stalls within its iterations (a 1 N press on the middle of
    /// the finger, from the free shape, with 6 Newton iterations) is carried in
    /// substeps through a quarter and a half of it, to the same equilibrium as a solve given
    /// all the iterations it needs.
    #[test]
    fn a_stalled_loaded_solve_substeps_to_the_same_equilibrium() {
        let (mut inverse, unseen, pulls) = finger();
        let obs_of = |markers| observation(markers, &pulls, None);
        let mut solves = 0;
        let free = inverse.static_free(&obs_of(&unseen), &mut solves).unwrap();
        let c = inverse.candidates.len() / 2;
        let v = inverse.candidates[c] as usize;
        let force = -inverse.rest_normals[v];
        let loads = [(c, force)];
        let mut converged = free.clone();
        inverse
            .solve(
                &mut converged,
                &obs_of(&unseen),
                &loads,
                &free,
                "",
                &mut solves,
            )
            .unwrap();
        // The markers where the press puts them.
        let seen: Vec<Option<Point3>> = inverse
            .markers
            .iter()
            .map(|&m| Some(inverse.mech.surface_position(&converged, m)))
            .collect();
        let obs = obs_of(&seen);

        inverse.config.static_max_iterations = 6;
        let mut direct = free.clone();
        assert!(matches!(
            inverse.solve(&mut direct, &obs, &loads, &free, "", &mut solves),
            Err(PhysicsError::StaticNotConverged { .. })
        ));
        let state = Solved {
            chi: inverse.residual_sq(&free, &obs),
            x: free.clone(),
            loads: Vec::new(),
        };
        let proposal = super::super::search::Fit {
            candidates: vec![c],
            forces: vec![force],
            residual_sq: 0.0,
        };
        let (carried, any) = inverse.carry(&obs, &state, &proposal, &mut solves).unwrap();
        let carried = carried.expect("the whole press, carried in substeps");
        assert!(any);
        assert_eq!(carried.loads, loads);
        let gap = carried
            .x
            .iter()
            .zip(&converged)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        let moved = converged
            .iter()
            .zip(&free)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        assert!(moved > 1e-3, "the press moves the finger: {moved} m");
        assert!(gap < 1e-5, "{gap} m from the converged solve");
        assert!(carried.chi < 1e-12 * state.chi.max(1.0), "{}", carried.chi);
    }

    /// A 1 N press on the middle of the finger that follows the surface: at the solution the
    /// patch has turned by more than 10°, the force with it (its angle to the patch's normal
    /// kept within the solve's 1° tolerance), and the shape is the equilibrium under that force
    /// held fixed.
    #[test]
    fn a_follower_press_turns_with_its_patch_to_an_equilibrium() {
        let (_, unseen, pulls) = finger();
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let config = PhysicsConfig {
            follow_surface: true,
            ..PhysicsConfig::default()
        };
        let mut inverse = FingerInverse::new(
            0,
            &hand.fingers()[0].model,
            &HandMaterial::default(),
            &config,
        )
        .unwrap();
        let obs = observation(&unseen, &pulls, None);
        let mut solves = 0;
        let free = inverse.static_free(&obs, &mut solves).unwrap();
        let c = inverse.candidates.len() / 2;
        let v = inverse.candidates[c] as usize;
        let force = -inverse.rest_normals[v];
        let mut x = free.clone();
        let turned = inverse
            .solve(&mut x, &obs, &[(c, force)], &free, "", &mut solves)
            .unwrap();
        let body = inverse.mech.body();
        let normal = |x: &[Point3]| {
            crate::mechanics::patch_normal(&inverse.patch_faces[c], body, x).unwrap()
        };
        let (before, after) = (normal(&free), normal(&x));
        assert!(before.angle(&after) > 0.175, "{}", before.angle(&after));
        assert!((turned[0].1.norm() - 1.0).abs() < 1e-12);
        assert!(
            (turned[0].1.angle(&after) - force.angle(&before)).abs() < 0.0175,
            "{} against {}",
            turned[0].1.angle(&after),
            force.angle(&before)
        );
        let mut again = x.clone();
        inverse
            .solve_dead(&mut again, &obs, &turned, "", &mut solves)
            .unwrap();
        let gap = again
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        assert!(gap < 1e-5, "{gap} m");
    }

    /// In a stream, a press along the axis on the apex that no part of converges (the finger
    /// buckles) is not solved for again at the same place for a quarter of a second; another
    /// place is, and so is the apex after that.
    #[test]
    fn a_load_that_cannot_be_carried_is_not_tried_again_at_once() {
        let (mut inverse, unseen, pulls) = finger();
        let obs_at = |time_secs| observation(&unseen, &pulls, time_secs);
        let mut solves = 0;
        let free = inverse.static_free(&obs_at(None), &mut solves).unwrap();
        let state = Solved {
            chi: 1.0,
            x: free,
            loads: Vec::new(),
        };
        let apex = (0..inverse.candidates.len())
            .max_by(|&a, &b| {
                let z = |c: usize| inverse.rest_surface[inverse.candidates[c] as usize].z;
                z(a).total_cmp(&z(b))
            })
            .unwrap();
        let press = |c: usize, newtons: Real| super::super::search::Fit {
            candidates: vec![c],
            forces: vec![Vector3::new(0.0, 0.0, -newtons)],
            residual_sq: 0.0,
        };
        let mut tried = |inverse: &mut FingerInverse, c, newtons, t| {
            let before = solves;
            let (found, carried) = inverse
                .carry(&obs_at(t), &state, &press(c, newtons), &mut solves)
                .unwrap();
            (found.is_some() || carried, solves - before)
        };
        // 4 N along the axis on the apex: no part of it (4, 2 or 1 N) converges.
        let (carried, spent) = tried(&mut inverse, apex, 4.0, Some(0.0));
        assert!(!carried);
        assert!(spent >= 3 * inverse.config.static_max_iterations, "{spent}");
        // A tenth of a second later, at 3.2 N: not tried.
        assert_eq!(tried(&mut inverse, apex, 3.2, Some(0.1)), (false, 0));
        // Tried again: at a quarter of its force, at once; lone frames (no time) always; the
        // same press after the memory has passed.
        assert!(tried(&mut inverse, apex, 1.0, Some(0.15)).1 > 0);
        assert!(tried(&mut inverse, apex, 4.0, None).1 > 0);
        assert!(tried(&mut inverse, apex, 4.0, Some(0.6)).1 > 0);
        // Another place is solved for: a press on the middle of the finger is carried.
        let middle = inverse.candidates.len() / 2;
        let (carried, spent) = tried(&mut inverse, middle, 0.2, Some(0.65));
        assert!(carried && spent > 0);
        // A reset forgets.
        let (carried, _) = tried(&mut inverse, apex, 4.0, Some(0.7));
        assert!(!carried);
        inverse.reset();
        assert!(tried(&mut inverse, apex, 4.0, Some(0.75)).1 > 0);
    }
}
