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
//! Contact force and labels: at a saved frame, every surface vertex reports the normal magnitude
//! of the penalty force the obstacles exert on it, `Σ_o k·max(0, −d_o)` newtons, and the force
//! itself, `Σ_o n_o·k·max(0, −d_o)` (world frame, `n_o` the obstacle's outward normal) — the
//! vector sum over a finger's vertices is the net contact force on the finger, smaller than the
//! sum of the magnitudes where the vertices are pushed different ways, as on a convex hull's
//! edge ([`surface_contact`]).
//! A vertex is *in contact* by one of three rules ([`LabelRule`]); "can move" means at least one
//! node of its element is free, so that a press can show in the deformation (a vertex held by
//! the fixed base alone is never labelled by the first two: nothing about the finger's shape can
//! reveal that it is touched):
//!
//! - **press** (the default): the vertex can move, is within `press_distance_m` (1 mm) of an
//!   obstacle, and its finger carries at least `label_force_n` (10 mN) of penalty force in all —
//!   the patch of an active press.
//! - **force**: the vertex's own force is at least `label_force_n` and it can move — only the
//!   few vertices that penetrate (2–3 per frame at the default resolution, half of the patches a
//!   single vertex).
//! - **proximity**: the signed distance is below `contact_distance_m` (1 mm by default); this
//!   labels approach and release frames in which nothing presses yet (18 % of its labelled
//!   frames show no marker moving by 0.1 mm), and was the rule of the first data sets.

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
    /// Which rule labels a vertex as in contact. Default [`LabelRule::Press`].
    pub label_rule: LabelRule,
    /// Proximity rule: a vertex closer than this to an obstacle is in contact, metres.
    /// Default 1e-3.
    pub contact_distance_m: Real,
    /// Force rule: smallest penalty force of a vertex in contact; press rule: smallest total
    /// penalty force of the finger, newtons. Default 1e-2 (at the default stiffness, a
    /// penetration of 1 µm in all).
    pub label_force_n: Real,
    /// Press rule: largest distance of a labelled vertex to the obstacle, metres. Default 1e-3.
    pub press_distance_m: Real,
}

/// How a frame's contact labels are derived from the simulation (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LabelRule {
    /// Active contact: penalty force ≥ `label_force_n` on a vertex that can move.
    Force,
    /// Proximity: signed distance below `contact_distance_m`.
    Proximity,
    /// Pressed patch: a vertex that can move, closer than `press_distance_m` to an obstacle, on a
    /// finger whose vertices together carry at least `label_force_n` of penalty force.
    #[default]
    Press,
}

impl LabelRule {
    /// Stable name (`force`, `proximity`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Force => "force",
            Self::Proximity => "proximity",
            Self::Press => "press",
        }
    }
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            stiffness_n_per_m: 1e4,
            friction: 0.0,
            friction_velocity_m_s: 1e-3,
            label_rule: LabelRule::Press,
            contact_distance_m: 1e-3,
            label_force_n: 1e-2,
            press_distance_m: 1e-3,
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
        require_non_negative("label_force_n", self.label_force_n)?;
        require_non_negative("press_distance_m", self.press_distance_m)?;
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
            terms.point_energy_j += 0.5 * k * sd.distance_m * sd.distance_m;
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

/// What the obstacles do to each surface vertex at one instant.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SurfaceContact {
    /// Smallest signed distance to any obstacle, metres (`+∞` without obstacles; 0 for a point
    /// exactly on an obstacle's surface).
    pub distances_m: Vec<Real>,
    /// Normal magnitude of the penalty force, summed over the obstacles, newtons:
    /// `Σ_o k·max(0, −d_o)`.
    pub forces_n: Vec<Real>,
    /// The penalty force itself, summed over the obstacles, world frame, newtons:
    /// `Σ_o n_o·k·max(0, −d_o)` with `n_o` the obstacle's outward unit normal at the vertex
    /// ([`Obstacle::signed_distance`]). Its norm equals `forces_n` where a single obstacle
    /// presses, and is smaller where several press from different sides.
    pub force_vectors_n: Vec<Vector3>,
}

impl SurfaceContact {
    /// The vector sum of the vertices' penalty forces (world frame, newtons), summed in vertex
    /// order: the net contact force on the body whose vertices these are. Vertices pushed
    /// different ways cancel in part, so its norm is at most the sum of `forces_n`.
    pub fn net_force_n(&self) -> Vector3 {
        self.force_vectors_n
            .iter()
            .fold(Vector3::zeros(), |sum, f| sum + f)
    }
}

/// Per surface vertex: the smallest signed distance to any obstacle at poses `poses` and the
/// penalty force of stiffness `stiffness_n_per_m`, as a magnitude and as a world-frame vector
/// (see [`SurfaceContact`]).
pub fn surface_contact(
    surface_in_world: &[Point3],
    obstacles: &[Obstacle],
    poses: &[Iso3],
    stiffness_n_per_m: Real,
) -> SurfaceContact {
    let mut out = SurfaceContact {
        distances_m: Vec::with_capacity(surface_in_world.len()),
        forces_n: Vec::with_capacity(surface_in_world.len()),
        force_vectors_n: Vec::with_capacity(surface_in_world.len()),
    };
    for p in surface_in_world {
        let (mut d_min, mut force, mut vector) = (Real::INFINITY, 0.0, Vector3::zeros());
        for (o, pose) in obstacles.iter().zip(poses) {
            // A point exactly on the surface has no normal but distance 0 (and no force).
            let sd = o.signed_distance(pose, p);
            let d = sd.map_or(0.0, |s| s.distance_m);
            d_min = d_min.min(d);
            let magnitude = stiffness_n_per_m * (-d).max(0.0);
            force += magnitude;
            if let Some(s) = sd
                && magnitude > 0.0
            {
                vector += s.normal * magnitude;
            }
        }
        out.distances_m.push(d_min);
        out.forces_n.push(force);
        out.force_vectors_n.push(vector);
    }
    out
}

/// Per surface vertex: the smallest signed distance to any obstacle at poses `poses`
/// (`+∞` without obstacles; 0 for a point exactly on an obstacle's surface), metres.
pub fn surface_distances(
    surface_in_world: &[Point3],
    obstacles: &[Obstacle],
    poses: &[Iso3],
) -> Vec<Real> {
    surface_contact(surface_in_world, obstacles, poses, 0.0).distances_m
}

/// Contact labels of one finger's vertices under `params.label_rule`. `movable[i]` says whether
/// vertex `i` can move (at least one node of its element is free); the force and press rules
/// never label a vertex that cannot.
///
/// # Panics
/// Never; slices of unequal length are read up to the shortest.
pub fn contact_labels(
    contact: &SurfaceContact,
    movable: &[bool],
    params: &ContactParams,
) -> Vec<bool> {
    match params.label_rule {
        LabelRule::Proximity => contact
            .distances_m
            .iter()
            .map(|&d| d < params.contact_distance_m)
            .collect(),
        LabelRule::Force => contact
            .forces_n
            .iter()
            .zip(movable)
            .map(|(&f, &m)| m && f > 0.0 && f >= params.label_force_n)
            .collect(),
        LabelRule::Press => {
            let total: Real = contact.forces_n.iter().sum();
            let pressed = total > 0.0 && total >= params.label_force_n;
            contact
                .distances_m
                .iter()
                .zip(movable)
                .map(|(&d, &m)| pressed && m && d < params.press_distance_m)
                .collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obstacle::{ObstacleConfig, ObstacleShape};
    use crate::trajectory::PoseTrajectory;

    #[test]
    fn labels_follow_the_force_press_and_proximity_rules() {
        let ball = Obstacle::new(
            0,
            &ObstacleConfig {
                shape: ObstacleShape::Ball { radius_m: 0.01 },
                trajectory: PoseTrajectory::default(),
            },
        )
        .unwrap();
        let pts = [
            Point3::new(0.0, 0.0, 0.0105), // 0.5 mm outside: near
            Point3::new(0.0, 0.0, 0.0115), // 1.5 mm outside: far
            Point3::new(0.0, 0.01, 0.0),   // on the surface: touching, no force
            Point3::new(0.0, 0.0, 0.005),  // inside: pressed
        ];
        let c = surface_contact(&pts, std::slice::from_ref(&ball), &[Iso3::identity()], 1e4);
        let d = &c.distances_m;
        assert!((d[0] - 0.0005).abs() < 1e-12);
        assert_eq!(d[2], 0.0);
        // Only the vertex inside is pressed: 5 mm deep at 1e4 N/m is 50 N.
        assert_eq!(&c.forces_n[..3], &[0.0, 0.0, 0.0]);
        assert!((c.forces_n[3] - 50.0).abs() < 1e-9);
        let proximity = ContactParams {
            label_rule: LabelRule::Proximity,
            ..ContactParams::default()
        };
        let movable = [true; 4];
        let force = ContactParams {
            label_rule: LabelRule::Force,
            label_force_n: 1e-3,
            ..ContactParams::default()
        };
        assert_eq!(
            contact_labels(&c, &movable, &proximity),
            vec![true, false, true, true]
        );
        assert_eq!(
            contact_labels(&c, &movable, &force),
            vec![false, false, false, true]
        );
        // A vertex held by the base is not labelled by the force rule, however hard it is pressed.
        assert_eq!(
            contact_labels(&c, &[true, true, true, false], &force),
            vec![false; 4]
        );
        // The threshold is inclusive and a zero threshold still needs a force.
        let strict = ContactParams {
            label_force_n: 50.0 + 1e-6,
            ..force.clone()
        };
        assert_eq!(contact_labels(&c, &movable, &strict), vec![false; 4]);
        let zero = ContactParams {
            label_force_n: 0.0,
            ..force.clone()
        };
        assert_eq!(
            contact_labels(&c, &movable, &zero),
            vec![false, false, false, true]
        );
        // The press rule labels the near vertices of a pressed finger, not of a merely touched
        // one: 50 N in all here.
        let press = |force: Real| ContactParams {
            label_rule: LabelRule::Press,
            label_force_n: force,
            press_distance_m: 1e-3,
            ..ContactParams::default()
        };
        assert_eq!(
            contact_labels(&c, &movable, &press(10.0)),
            vec![true, false, true, true]
        );
        assert_eq!(contact_labels(&c, &movable, &press(60.0)), vec![false; 4]);
        assert_eq!(
            contact_labels(&c, &[false, true, true, true], &press(10.0)),
            vec![false, false, true, true]
        );
        assert_eq!(surface_distances(&pts, &[], &[]), vec![Real::INFINITY; 4]);
        assert_eq!(surface_contact(&pts, &[], &[], 1e4).forces_n, vec![0.0; 4]);
        // The force vectors: none outside or on the surface, 50 N along +z inside.
        assert_eq!(&c.force_vectors_n[..3], &[Vector3::zeros(); 3]);
        assert!((c.force_vectors_n[3] - Vector3::new(0.0, 0.0, 50.0)).norm() < 1e-9);
    }

    fn obstacle(shape: ObstacleShape) -> Obstacle {
        Obstacle::new(
            0,
            &ObstacleConfig {
                shape,
                trajectory: PoseTrajectory::default(),
            },
        )
        .unwrap()
    }

    /// A slab 2 cm thick whose face toward +z (`up`) or −z lies at height `face_z`.
    fn slab(face_z: Real, up: bool) -> (Obstacle, Iso3) {
        let centre = if up { face_z - 0.01 } else { face_z + 0.01 };
        (
            obstacle(ObstacleShape::Cuboid {
                half_extents_m: [0.05, 0.05, 0.01],
            }),
            Iso3::translation(0.0, 0.0, centre),
        )
    }

    #[test]
    fn a_press_with_one_normal_has_a_net_force_equal_to_the_magnitudes() {
        // A flat face pressed at several depths: every normal is +z, so the vector sum is the
        // sum of the magnitudes, along +z.
        let (plate, pose) = slab(0.0, true);
        let pts: Vec<Point3> = [1e-4, 3e-4, 0.0, -1e-3, 2e-3]
            .iter()
            .enumerate()
            .map(|(i, &depth)| Point3::new(0.004 * i as Real, -0.002, -depth))
            .collect();
        let c = surface_contact(&pts, std::slice::from_ref(&plate), &[pose], 1e4);
        let total: Real = c.forces_n.iter().sum();
        assert!((total - 1e4 * 2.4e-3).abs() < 1e-9, "{total}");
        let net = c.net_force_n();
        assert!((net - Vector3::new(0.0, 0.0, total)).norm() < 1e-9, "{net}");
        for (f, &m) in c.force_vectors_n.iter().zip(&c.forces_n) {
            assert!((f.norm() - m).abs() < 1e-12);
        }
        // A ball pressed by a patch symmetric about its pole: the net force is along the pole's
        // normal, and shorter than the sum of the magnitudes, whose normals tilt apart.
        let ball = obstacle(ObstacleShape::Ball { radius_m: 0.01 });
        let (a, z) = (0.002, 0.0095);
        let patch = [
            Point3::new(0.0, 0.0, z),
            Point3::new(a, 0.0, z),
            Point3::new(-a, 0.0, z),
            Point3::new(0.0, a, z),
            Point3::new(0.0, -a, z),
        ];
        let c = surface_contact(
            &patch,
            std::slice::from_ref(&ball),
            &[Iso3::identity()],
            1e4,
        );
        let total: Real = c.forces_n.iter().sum();
        let net = c.net_force_n();
        assert!(c.forces_n.iter().all(|&f| f > 0.0));
        assert!(net.x.abs() < 1e-12 && net.y.abs() < 1e-12, "{net}");
        assert!(net.z > 0.95 * total && net.z < total, "{net} vs {total}");
    }

    #[test]
    fn a_squeeze_from_two_sides_has_no_net_force() {
        // Slab A below pushes up, slab B above pushes down, each 0.5 mm into a 2 mm thick body.
        let (below, below_pose) = slab(0.0005, true);
        let (above, above_pose) = slab(0.0015, false);
        let obstacles = [below, above];
        let poses = [below_pose, above_pose];
        let body = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.01, 0.0, 0.0),
            Point3::new(0.0, 0.0, 0.002),
            Point3::new(0.01, 0.0, 0.002),
            // In between, clear of both.
            Point3::new(0.005, 0.0, 0.001),
        ];
        let c = surface_contact(&body, &obstacles, &poses, 1e4);
        let total: Real = c.forces_n.iter().sum();
        assert!((total - 4.0 * 5.0).abs() < 1e-9, "{total}");
        assert!(c.net_force_n().norm() < 1e-9, "{}", c.net_force_n());
        assert_eq!(c.forces_n[4], 0.0);
        // A vertex inside both (overlapping slabs) carries both magnitudes and no net force.
        let (low, low_pose) = slab(0.001, true);
        let (high, high_pose) = slab(0.0, false);
        let c = surface_contact(
            &[Point3::new(0.0, 0.0, 0.0005)],
            &[low, high],
            &[low_pose, high_pose],
            1e4,
        );
        assert!((c.forces_n[0] - 10.0).abs() < 1e-9, "{:?}", c.forces_n);
        assert!(
            c.force_vectors_n[0].norm() < 1e-9,
            "{}",
            c.force_vectors_n[0]
        );
    }
}
