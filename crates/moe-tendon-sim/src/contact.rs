//! Contact between a body's surface vertices and rigid obstacles: an implicit penalty with
//! optional regularised Coulomb friction, and contact labels.
//!
//! A surface vertex `p` (embedded in an element) whose signed distance `d` to an obstacle at its
//! end-of-step pose is negative gets the force `f = −k (d + n·Δp) n` linearised around the start
//! of the step (force `−k d n`, stiffness `k n nᵀ` in the system matrix, so that large `k` is
//! stable at large time steps). Friction (coefficient `μ`) is the damping
//! `c (I − n nᵀ)(v − v_obs)` with `c = μ k |d| / max(|v_t|, v_ε)`: a Coulomb force of magnitude
//! `μ·|f_n|` at sliding speeds above `v_ε`, viscous below it, implicit in the velocity.
//!
//! Labels: a surface vertex is *in contact* when its signed distance to some obstacle at the end
//! of the step is below `contact_distance_m` (1 mm by default), which includes every vertex whose
//! penalty is active.

use moe_geom::{Iso3, Matrix3, Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::embedding::Embedding;
use crate::error::{SimError, require_non_negative, require_positive};
use crate::obstacle::Obstacle;
use crate::terms::{PointTerm, Terms};

/// Contact model parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContactParams {
    /// Penalty stiffness per surface vertex, N/m. Default 1e4 (about 30× the body's stiffness
    /// per vertex at the default resolution; penetration stays in the micrometre range).
    pub stiffness_n_per_m: Real,
    /// Coulomb friction coefficient μ (0 disables friction). Default 0.
    pub friction: Real,
    /// Sliding speed below which friction is viscous, m/s. Default 1e-3.
    pub friction_velocity_m_s: Real,
    /// Label tolerance: a vertex closer than this to an obstacle is in contact, metres.
    /// Default 1e-3.
    pub contact_distance_m: Real,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            stiffness_n_per_m: 1e4,
            friction: 0.0,
            friction_velocity_m_s: 1e-3,
            contact_distance_m: 1e-3,
        }
    }
}

impl ContactParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the bad one.
    pub fn validate(&self) -> Result<(), SimError> {
        require_positive("contact stiffness_n_per_m", self.stiffness_n_per_m)?;
        require_non_negative("friction", self.friction)?;
        require_positive("friction_velocity_m_s", self.friction_velocity_m_s)?;
        require_non_negative("contact_distance_m", self.contact_distance_m)?;
        Ok(())
    }
}

/// Obstacles posed at the start and end of a step.
#[derive(Debug, Clone)]
pub struct PosedObstacles<'a> {
    /// The obstacles.
    pub obstacles: &'a [Obstacle],
    /// `world_from_obstacle` at the start of the step.
    pub start: Vec<Iso3>,
    /// `world_from_obstacle` at the end of the step.
    pub end: Vec<Iso3>,
    /// Step length, seconds (0 for static solves: obstacle velocities are then zero).
    pub dt_secs: Real,
}

impl<'a> PosedObstacles<'a> {
    /// Poses `obstacles` for the step from `t0` to `t1`.
    pub fn new(obstacles: &'a [Obstacle], t0: Real, t1: Real) -> Self {
        Self::with_buffers(obstacles, t0, t1, Vec::new(), Vec::new())
    }

    /// [`PosedObstacles::new`] filling the given vectors (cleared first) instead of new ones.
    pub(crate) fn with_buffers(
        obstacles: &'a [Obstacle],
        t0: Real,
        t1: Real,
        mut start: Vec<Iso3>,
        mut end: Vec<Iso3>,
    ) -> Self {
        start.clear();
        start.extend(obstacles.iter().map(|o| o.pose_at(t0)));
        end.clear();
        end.extend(obstacles.iter().map(|o| o.pose_at(t1)));
        Self {
            obstacles,
            start,
            end,
            dt_secs: t1 - t0,
        }
    }

    /// Velocity of the material point of obstacle `k` that is at `p` at the end of the step.
    fn velocity(&self, k: usize, p: &Point3) -> Vector3 {
        if self.dt_secs <= 0.0 {
            return Vector3::zeros();
        }
        let local = self.end[k].inverse_transform_point(p);
        (p - self.start[k].transform_point(&local)) / self.dt_secs
    }
}

/// Adds the penalty (and friction) terms of every penetrating surface vertex.
pub(crate) fn add_contact_terms(
    surface: &Embedding,
    x: &[Point3],
    v: &[Vector3],
    posed: &PosedObstacles<'_>,
    params: &ContactParams,
    terms: &mut Terms,
) {
    if posed.obstacles.is_empty() {
        return;
    }
    let k = params.stiffness_n_per_m;
    for e in surface.points() {
        let p = e.position(x);
        for (o, obstacle) in posed.obstacles.iter().enumerate() {
            let Some(sd) = obstacle.signed_distance(&posed.end[o], &p) else {
                continue;
            };
            if sd.distance_m >= 0.0 {
                continue;
            }
            let n = sd.normal;
            let nn = n * n.transpose();
            let v_obs = posed.velocity(o, &p);
            let damping = if params.friction > 0.0 {
                let vt = (Matrix3::identity() - nn) * (e.velocity(v) - v_obs);
                let c = params.friction * k * (-sd.distance_m)
                    / vt.norm().max(params.friction_velocity_m_s);
                (Matrix3::identity() - nn) * c
            } else {
                Matrix3::zeros()
            };
            terms.points.push(PointTerm {
                point: *e,
                force: n * (-k * sd.distance_m),
                stiffness: nn * k,
                damping,
                target_velocity: v_obs,
            });
        }
    }
}

/// Per surface vertex: the smallest signed distance to any obstacle at poses `poses`
/// (`+∞` without obstacles; 0 for a point exactly on an obstacle's surface), metres.
pub fn surface_distances(
    surface_in_world: &[Point3],
    obstacles: &[Obstacle],
    poses: &[Iso3],
) -> Vec<Real> {
    surface_in_world
        .iter()
        .map(|p| {
            obstacles
                .iter()
                .zip(poses)
                // A point exactly on the surface has no normal but distance 0.
                .map(|(o, pose)| o.signed_distance(pose, p).map_or(0.0, |s| s.distance_m))
                .fold(Real::INFINITY, Real::min)
        })
        .collect()
}

/// Contact labels from signed distances under the documented rule (`d < contact_distance_m`).
pub fn contact_labels(distances_m: &[Real], params: &ContactParams) -> Vec<bool> {
    distances_m
        .iter()
        .map(|&d| d < params.contact_distance_m)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obstacle::{ObstacleConfig, ObstacleShape};
    use crate::trajectory::PoseTrajectory;

    #[test]
    fn labels_follow_the_distance_rule_including_points_on_the_surface() {
        let ball = Obstacle::new(
            0,
            &ObstacleConfig {
                shape: ObstacleShape::Ball { radius_m: 0.01 },
                trajectory: PoseTrajectory::default(),
            },
        )
        .unwrap();
        let pts = [
            Point3::new(0.0, 0.0, 0.0105), // 0.5 mm outside: labelled
            Point3::new(0.0, 0.0, 0.0115), // 1.5 mm outside: not labelled
            Point3::new(0.0, 0.01, 0.0),   // on the surface: labelled
            Point3::new(0.0, 0.0, 0.005),  // inside: labelled
        ];
        let d = surface_distances(&pts, std::slice::from_ref(&ball), &[Iso3::identity()]);
        assert!((d[0] - 0.0005).abs() < 1e-12);
        assert_eq!(d[2], 0.0);
        let labels = contact_labels(&d, &ContactParams::default());
        assert_eq!(labels, vec![true, false, true, true]);
        assert_eq!(surface_distances(&pts, &[], &[]), vec![Real::INFINITY; 4]);
    }
}
