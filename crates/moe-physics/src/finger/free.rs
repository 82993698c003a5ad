//! The free reference: the finger without loads — simulated through a stream of observations
//! (backward Euler with the body's damping, its base following the wrist) or, for a lone
//! observation, the static equilibrium — and the shapes built on it.

use moe_geom::math::UnitQuat;
use moe_geom::{Iso3, Point3, Real, Vector3};
use moe_tendon_sim::BodyState;

use super::{Baseline, DepthRow, FingerEstimate, FingerInverse, FingerObservation, commands_of};
use crate::error::PhysicsError;

/// The free finger simulated through the stream, in the world frame with its base following
/// the wrist (as the hand moves, the finger's inertia shows).
#[derive(Debug, Clone)]
pub(super) struct DynamicFree {
    pub(super) state: BodyState,
    pub(super) time_secs: Real,
    pub(super) pulls: Vec<Real>,
    pub(super) world_from_finger: Iso3,
    /// Gravity in the world frame, m/s².
    pub(super) gravity: Vector3,
}

/// The pose a fraction `a` of the way from `p0` to `p1` (translation linear, rotation slerp).
fn interpolate(p0: &Iso3, p1: &Iso3, a: Real) -> Iso3 {
    let t = p0.translation.vector.lerp(&p1.translation.vector, a);
    let r: UnitQuat = p0.rotation.slerp(&p1.rotation, a);
    Iso3::from_parts(t.into(), r)
}

/// What the free finger is compared with: the simulated one of a stream, or the static one.
#[derive(Debug)]
pub(super) struct FreeReference {
    /// Node positions.
    pub(super) x: Vec<Point3>,
    /// True when `x` is the simulated (dynamic) free finger.
    pub(super) dynamic: bool,
}

/// Where the loads are searched from: the static free shape and the markers moved onto it.
pub(super) struct StaticStart {
    /// Node positions of the static free shape.
    pub(super) x: Vec<Point3>,
    /// The markers as the static model sees them.
    pub(super) markers: Vec<Option<Point3>>,
    /// The depth observations as the static model sees them.
    pub(super) depth: Vec<DepthRow>,
}

impl FingerInverse {
    /// `‖m − m_free‖²` and the number of observed coordinates of one observation, the free
    /// finger simulated through the stream as the estimate does (no load is searched).
    pub(crate) fn free_residual(
        &mut self,
        obs: &FingerObservation<'_>,
    ) -> Result<(Real, usize), PhysicsError> {
        let mut solves = 0;
        let x = match self.advance_dynamic(obs, &mut solves) {
            Some(x) => x,
            None => {
                let x = self.static_free(obs, &mut solves)?;
                self.start_dynamic(obs, &x);
                x
            }
        };
        let n = 3 * obs.markers.iter().filter(|m| m.is_some()).count() + obs.depth.len();
        Ok((self.residual_sq(&x, obs), n))
    }

    /// The static free shape under the observation's pulls and gravity, warm-started from the
    /// previous one (from rest when that fails).
    pub(super) fn static_free(
        &mut self,
        obs: &FingerObservation<'_>,
        solves: &mut usize,
    ) -> Result<Vec<Point3>, PhysicsError> {
        const STAGE: &str = "(free shape under the pulls)";
        if let Some(mut x) = self.warm_static.take()
            && self.solve(&mut x, obs, &[], &[], STAGE, solves).is_ok()
        {
            self.warm_static = Some(x.clone());
            return Ok(x);
        }
        let mut x = self.mech.rest_nodes().to_vec();
        self.solve(&mut x, obs, &[], &[], STAGE, solves)?;
        self.warm_static = Some(x.clone());
        Ok(x)
    }

    /// Advances the simulated free finger to the observation's time (pulls interpolated
    /// linearly from the previous observation's). `None` for a lone observation, the first of a
    /// stream, after a gap longer than the horizon, or when a step fails: the stream then
    /// starts again from the static free shape (computed on demand by `start`).
    fn advance_dynamic(
        &mut self,
        obs: &FingerObservation<'_>,
        solves: &mut usize,
    ) -> Option<Vec<Point3>> {
        let t = obs.time_secs?;
        if self.config.dynamic_step_secs <= 0.0 {
            self.dynamic = None;
            return None;
        }
        let mut d = match self.dynamic.take() {
            Some(d)
                if t > d.time_secs
                    && t - d.time_secs <= self.config.stream_reach_secs()
                    && d.pulls.len() == obs.pulls.len() =>
            {
                d
            }
            _ => return None,
        };
        let span = t - d.time_secs;
        let n = ((span / self.config.dynamic_step_secs - 1e-9)
            .ceil()
            .max(1.0) as usize)
            .min(self.config.max_dynamic_steps);
        let h = span / n as Real;
        let ctx = self.ctx();
        let rest = self.mech.rest_nodes().to_vec();
        for k in 1..=n {
            let a = k as Real / n as Real;
            let pulls: Vec<Real> = d
                .pulls
                .iter()
                .zip(obs.pulls)
                .map(|(p0, p1)| p0 + a * (p1 - p0))
                .collect();
            let commands = commands_of(&pulls);
            let pose = interpolate(&d.world_from_finger, &obs.world_from_finger, a);
            let targets: Vec<Point3> = rest.iter().map(|p| pose * p).collect();
            if self
                .mech
                .step_free(&mut d.state, &commands, &d.gravity, &targets, h, ctx)
                .is_err()
            {
                return None;
            }
            *solves += 1;
        }
        d.time_secs = t;
        d.pulls = obs.pulls.to_vec();
        d.world_from_finger = obs.world_from_finger;
        let finger_from_world = obs.world_from_finger.inverse();
        let x = d.state.x.iter().map(|p| finger_from_world * p).collect();
        self.dynamic = Some(d);
        Some(x)
    }

    /// Starts the simulated free finger at rest in the static shape `x`.
    fn start_dynamic(&mut self, obs: &FingerObservation<'_>, x: &[Point3]) {
        self.dynamic = match (obs.time_secs, self.config.dynamic_step_secs > 0.0) {
            (Some(t), true) => Some(DynamicFree {
                state: BodyState {
                    x: x.iter().map(|p| obs.world_from_finger * p).collect(),
                    v: vec![Vector3::zeros(); x.len()],
                },
                time_secs: t,
                pulls: obs.pulls.to_vec(),
                world_from_finger: obs.world_from_finger,
                gravity: obs.world_from_finger * obs.gravity,
            }),
            _ => None,
        };
    }

    /// The free reference: the simulated free finger in a stream, else the static one.
    pub(super) fn free_reference(
        &mut self,
        obs: &FingerObservation<'_>,
        solves: &mut usize,
    ) -> Result<FreeReference, PhysicsError> {
        Ok(match self.advance_dynamic(obs, solves) {
            Some(x) => FreeReference { x, dynamic: true },
            None => {
                let x = self.static_free(obs, solves)?;
                self.start_dynamic(obs, &x);
                FreeReference { x, dynamic: false }
            }
        })
    }

    /// The static free shape and the markers the loads are fitted to on it.
    pub(super) fn static_start(
        &mut self,
        obs: &FingerObservation<'_>,
        free: &FreeReference,
        markers: Vec<Option<Point3>>,
        solves: &mut usize,
    ) -> Result<StaticStart, PhysicsError> {
        let x = if free.dynamic {
            self.static_free(obs, solves)?
        } else {
            free.x.clone()
        };
        Ok(self.start_on(obs.depth, free, x, markers))
    }

    /// The markers and depth observations moved onto the static free shape `x`: in a stream,
    /// the loads act on the static model, so the observations are moved by the free finger's
    /// lag (static minus simulated).
    pub(super) fn start_on(
        &self,
        depth: &[DepthRow],
        free: &FreeReference,
        x: Vec<Point3>,
        markers: Vec<Option<Point3>>,
    ) -> StaticStart {
        if !free.dynamic {
            return StaticStart {
                x,
                markers,
                depth: depth.to_vec(),
            };
        }
        let moved = markers
            .iter()
            .zip(&self.markers)
            .map(|(m, &v)| {
                m.map(|p| {
                    p + (self.mech.surface_position(&x, v) - self.mech.surface_position(&free.x, v))
                })
            })
            .collect();
        let depth = self.shifted_rows(depth, &free.x, &x);
        StaticStart {
            x,
            markers: moved,
            depth,
        }
    }

    /// The estimate of an unpressed finger: the free shape, no loads, `statistic` as given.
    pub(super) fn free_estimate(
        &self,
        x_free: &[Point3],
        base: &Baseline,
        statistic: Real,
        solves: usize,
    ) -> FingerEstimate {
        let rms = (base.chi0 / base.n_obs).sqrt();
        FingerEstimate {
            loads: Vec::new(),
            surface: self.surface_of(x_free),
            probability: vec![0.0; self.rest_surface.len()],
            vertex_force: vec![Vector3::zeros(); self.rest_surface.len()],
            pressed_probability: 0.0,
            statistic,
            free_rms_m: rms,
            fit_rms_m: rms,
            observed_markers: base.observed,
            depth_rows: base.depth.0,
            depth_pixels: base.depth.1,
            solves,
            degraded: false,
        }
    }

    /// The estimated surface from the loaded static nodes `x_loaded`.
    pub(super) fn estimated_surface(
        &self,
        free: &FreeReference,
        x_loaded: &[Point3],
        x_static: &[Point3],
    ) -> Vec<Point3> {
        // The estimated shape: the free finger (simulated, in a stream) moved by what the loads
        // do to the static one.
        if free.dynamic {
            let x: Vec<Point3> = free
                .x
                .iter()
                .zip(x_loaded.iter().zip(x_static))
                .map(|(f, (l, s))| f + (l - s))
                .collect();
            self.surface_of(&x)
        } else {
            self.surface_of(x_loaded)
        }
    }
}
