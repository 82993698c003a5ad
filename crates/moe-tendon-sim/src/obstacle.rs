//! Rigid obstacles: parry3d-f64 shapes with a kinematic pose over time, queried for the signed
//! distance and outward normal at a point.

use moe_geom::math::{from_parry, iso_to_parry, to_parry, vec_to_parry};
use moe_geom::{Iso3, Point3, Real, Vector3};
use parry3d_f64::shape::{SharedShape, TriMeshFlags};
use serde::{Deserialize, Serialize};

use crate::error::SimError;
use crate::trajectory::PoseTrajectory;

/// Geometry of an obstacle in its own frame. SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ObstacleShape {
    /// A sphere centred at the origin.
    Ball {
        /// Radius, metres.
        radius_m: Real,
    },
    /// A box centred at the origin (a thin box is a plate).
    Cuboid {
        /// Half extents along x, y, z, metres.
        half_extents_m: [Real; 3],
    },
    /// A capsule along z, centred at the origin.
    Capsule {
        /// Half length of the segment, metres.
        half_height_m: Real,
        /// Radius, metres.
        radius_m: Real,
    },
    /// A cylinder along y (parry's convention), centred at the origin.
    Cylinder {
        /// Half height, metres.
        half_height_m: Real,
        /// Radius, metres.
        radius_m: Real,
    },
    /// The convex hull of points.
    ConvexHull {
        /// Points, metres.
        points_m: Vec<[Real; 3]>,
    },
    /// A closed, outward-oriented triangle mesh (an object model).
    TriangleMesh {
        /// Vertices, metres.
        vertices_m: Vec<[Real; 3]>,
        /// Triangles.
        faces: Vec<[u32; 3]>,
    },
    /// The half space `n·x ≤ 0` (an infinite floor or an inclined plane once posed).
    HalfSpace {
        /// Outward normal (normalised on build).
        normal: [Real; 3],
    },
}

/// An obstacle of a scene: a shape and its pose over time (obstacle frame → world).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleConfig {
    /// The geometry.
    pub shape: ObstacleShape,
    /// `world_from_obstacle` over time.
    #[serde(default)]
    pub trajectory: PoseTrajectory,
}

/// A built obstacle ready for queries.
#[derive(Clone)]
pub struct Obstacle {
    shape: SharedShape,
    trajectory: PoseTrajectory,
}

impl std::fmt::Debug for Obstacle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Obstacle")
            .field("shape", &self.shape.shape_type())
            .field("trajectory", &self.trajectory)
            .finish()
    }
}

/// Signed distance of a point to an obstacle (negative inside) with the outward normal of the
/// obstacle at the closest surface point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignedDistance {
    /// Signed distance, metres.
    pub distance_m: Real,
    /// Unit outward normal (from the obstacle toward the point when outside).
    pub normal: Vector3,
}

fn positive(obstacle: usize, name: &str, v: Real) -> Result<(), SimError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SimError::InvalidObstacle {
            obstacle,
            reason: format!("{name} = {v} must be finite and positive"),
        })
    }
}

impl Obstacle {
    /// Builds obstacle number `index` of a scene.
    ///
    /// # Errors
    /// [`SimError::InvalidObstacle`] for non-positive sizes, a degenerate hull or an invalid
    /// triangle mesh; [`SimError::InvalidKeyframe`] for a bad trajectory.
    pub fn new(index: usize, config: &ObstacleConfig) -> Result<Self, SimError> {
        config.trajectory.validate("obstacle trajectory")?;
        let v = |p: &[Real; 3]| to_parry(&Point3::from(*p));
        let shape = match &config.shape {
            ObstacleShape::Ball { radius_m } => {
                positive(index, "radius_m", *radius_m)?;
                SharedShape::ball(*radius_m)
            }
            ObstacleShape::Cuboid { half_extents_m: h } => {
                for &e in h {
                    positive(index, "half_extents_m", e)?;
                }
                SharedShape::cuboid(h[0], h[1], h[2])
            }
            ObstacleShape::Capsule {
                half_height_m,
                radius_m,
            } => {
                positive(index, "half_height_m", *half_height_m)?;
                positive(index, "radius_m", *radius_m)?;
                SharedShape::capsule_z(*half_height_m, *radius_m)
            }
            ObstacleShape::Cylinder {
                half_height_m,
                radius_m,
            } => {
                positive(index, "half_height_m", *half_height_m)?;
                positive(index, "radius_m", *radius_m)?;
                SharedShape::cylinder(*half_height_m, *radius_m)
            }
            ObstacleShape::ConvexHull { points_m } => {
                let pts: Vec<_> = points_m.iter().map(v).collect();
                if pts.iter().any(|p| !p.is_finite()) {
                    return Err(SimError::InvalidObstacle {
                        obstacle: index,
                        reason: "convex hull point is not finite".into(),
                    });
                }
                let degenerate = || SimError::InvalidObstacle {
                    obstacle: index,
                    reason: format!("the convex hull of {} points is degenerate", pts.len()),
                };
                let hull = SharedShape::convex_hull(&pts).ok_or_else(degenerate)?;
                let volume = hull.mass_properties(1.0).mass();
                if volume.is_nan() || volume <= 0.0 {
                    return Err(degenerate());
                }
                hull
            }
            ObstacleShape::TriangleMesh { vertices_m, faces } => {
                let verts: Vec<moe_geom::Point3> =
                    vertices_m.iter().map(|p| Point3::from(*p)).collect();
                // Validate (manifold, closed) with moe-geom first for a precise message.
                let mesh = moe_geom::TriMesh::new(verts, faces.clone()).map_err(|e| {
                    SimError::InvalidObstacle {
                        obstacle: index,
                        reason: e.to_string(),
                    }
                })?;
                mesh.require_closed()
                    .map_err(|e| SimError::InvalidObstacle {
                        obstacle: index,
                        reason: e.to_string(),
                    })?;
                let mesh = if mesh.signed_volume() < 0.0 {
                    mesh.flipped()
                } else {
                    mesh
                };
                SharedShape::trimesh_with_flags(
                    mesh.vertices().iter().map(to_parry).collect(),
                    mesh.faces().to_vec(),
                    TriMeshFlags::ORIENTED,
                )
                .map_err(|e| SimError::InvalidObstacle {
                    obstacle: index,
                    reason: format!("{e:?}"),
                })?
            }
            ObstacleShape::HalfSpace { normal } => {
                let n = Vector3::from(*normal);
                let len = n.norm();
                positive(index, "normal length", len)?;
                SharedShape::halfspace(vec_to_parry(&(n / len)))
            }
        };
        Ok(Self {
            shape,
            trajectory: config.trajectory.clone(),
        })
    }

    /// `world_from_obstacle` at time `t`.
    pub fn pose_at(&self, t: Real) -> Iso3 {
        self.trajectory.pose_at(t)
    }

    /// Signed distance from `p_in_world` to the obstacle posed at `world_from_obstacle`.
    /// `None` when the point lies exactly on the surface (no normal can be derived).
    pub fn signed_distance(
        &self,
        world_from_obstacle: &Iso3,
        p_in_world: &Point3,
    ) -> Option<SignedDistance> {
        let pose = iso_to_parry(world_from_obstacle);
        let proj = self.shape.project_point(&pose, to_parry(p_in_world), false);
        let q = from_parry(proj.point);
        let d = p_in_world - q;
        let dist = d.norm();
        if dist.is_nan() || dist <= 1e-14 {
            return None;
        }
        let (distance_m, normal) = if proj.is_inside {
            (-dist, -d / dist)
        } else {
            (dist, d / dist)
        };
        Some(SignedDistance { distance_m, normal })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn signed_distances_of_the_basic_shapes() {
        let id = Iso3::identity();
        let ball = obstacle(ObstacleShape::Ball { radius_m: 1.0 });
        let s = ball
            .signed_distance(&id, &Point3::new(0.0, 0.0, 0.5))
            .unwrap();
        assert!((s.distance_m + 0.5).abs() < 1e-12);
        assert!((s.normal - Vector3::z()).norm() < 1e-12);
        let plate = obstacle(ObstacleShape::Cuboid {
            half_extents_m: [1.0, 1.0, 0.01],
        });
        let s = plate
            .signed_distance(&id, &Point3::new(0.2, 0.3, 0.05))
            .unwrap();
        assert!((s.distance_m - 0.04).abs() < 1e-12);
        let floor = obstacle(ObstacleShape::HalfSpace {
            normal: [0.0, 0.0, 2.0],
        });
        let pose = Iso3::translation(0.0, 0.0, 1.0);
        let s = floor
            .signed_distance(&pose, &Point3::new(5.0, -3.0, 0.75))
            .unwrap();
        assert!((s.distance_m + 0.25).abs() < 1e-12, "{s:?}");
        assert!((s.normal - Vector3::z()).norm() < 1e-12);
        let hull = obstacle(ObstacleShape::ConvexHull {
            points_m: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
        });
        let s = hull
            .signed_distance(&id, &Point3::new(0.1, 0.1, -0.2))
            .unwrap();
        assert!((s.distance_m - 0.2).abs() < 1e-12);
    }

    #[test]
    fn capsule_cylinder_mesh_and_inclined_plane() {
        let id = Iso3::identity();
        let capsule = obstacle(ObstacleShape::Capsule {
            half_height_m: 1.0,
            radius_m: 0.5,
        });
        let s = capsule
            .signed_distance(&id, &Point3::new(0.0, 0.0, 2.0))
            .unwrap();
        assert!((s.distance_m - 0.5).abs() < 1e-12);
        assert!((s.normal - Vector3::z()).norm() < 1e-12);
        let cylinder = obstacle(ObstacleShape::Cylinder {
            half_height_m: 1.0,
            radius_m: 0.5,
        });
        let s = cylinder
            .signed_distance(&id, &Point3::new(0.2, 0.0, 0.0))
            .unwrap();
        assert!((s.distance_m + 0.3).abs() < 1e-12, "{s:?}");
        // A closed tetrahedron as a triangle mesh (inside test through oriented pseudo-normals).
        let tet = obstacle(ObstacleShape::TriangleMesh {
            vertices_m: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            faces: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        });
        let s = tet
            .signed_distance(&id, &Point3::new(0.1, 0.1, 0.05))
            .unwrap();
        assert!((s.distance_m + 0.05).abs() < 1e-12, "{s:?}");
        assert!((s.normal + Vector3::z()).norm() < 1e-12);
        let s = tet
            .signed_distance(&id, &Point3::new(0.1, 0.1, -0.3))
            .unwrap();
        assert!((s.distance_m - 0.3).abs() < 1e-12);
        // An inclined plane: the floor rotated 30° about x.
        let plane = obstacle(ObstacleShape::HalfSpace {
            normal: [0.0, 0.0, 1.0],
        });
        let angle = 30f64.to_radians();
        let pose = Iso3::rotation(Vector3::x() * angle);
        let n = pose * Vector3::z();
        let p = Point3::new(0.3, 0.0, 0.0) + n * 0.2;
        let s = plane.signed_distance(&pose, &p).unwrap();
        assert!((s.distance_m - 0.2).abs() < 1e-12);
        assert!((s.normal - n).norm() < 1e-12);
    }

    #[test]
    fn bad_obstacles_are_named() {
        let bad = ObstacleConfig {
            shape: ObstacleShape::Ball { radius_m: -1.0 },
            trajectory: PoseTrajectory::default(),
        };
        assert!(matches!(
            Obstacle::new(3, &bad),
            Err(SimError::InvalidObstacle { obstacle: 3, .. })
        ));
        let flat = ObstacleConfig {
            shape: ObstacleShape::ConvexHull {
                points_m: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            },
            trajectory: PoseTrajectory::default(),
        };
        moe_geom::assert_err!(
            Obstacle::new(2, &flat),
            SimError::InvalidObstacle { obstacle: 2, reason }
                if reason == "the convex hull of 3 points is degenerate"
        );
    }
}
