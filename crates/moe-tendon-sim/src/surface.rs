//! Triangle meshes of obstacle surfaces, for rendering and for placing objects.
//!
//! A triangle-mesh obstacle is its own surface. Every other shape is sampled by projecting the
//! vertices of an icosphere that encloses it onto its surface, keeping the icosphere's triangles:
//! exact vertices on the surface, flat faces where the shape is flat, and chords across edges
//! and corners no longer than the icosphere's edge. A half space is drawn as a 2 m square.

use moe_geom::shapes::icosphere;
use moe_geom::{Iso3, Point3, Vector3};

use crate::error::SimError;
use crate::obstacle::{Obstacle, ObstacleConfig, ObstacleShape};

/// Subdivision level of the enclosing icosphere (642 vertices).
const LEVEL: u32 = 3;

/// Vertices and triangles of an obstacle's surface in its own frame.
///
/// # Errors
/// An invalid shape (see [`Obstacle::new`]).
pub fn obstacle_surface(shape: &ObstacleShape) -> Result<(Vec<Point3>, Vec<[u32; 3]>), SimError> {
    match shape {
        ObstacleShape::TriangleMesh { vertices_m, faces } => Ok((
            vertices_m.iter().map(|v| Point3::from(*v)).collect(),
            faces.clone(),
        )),
        ObstacleShape::HalfSpace { normal } => {
            let n = Vector3::from(*normal).normalize();
            let a = if n.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let u = n.cross(&a).normalize();
            let v = n.cross(&u);
            let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                .map(|(s, t)| Point3::from(u * s + v * t));
            Ok((corners.to_vec(), vec![[0, 1, 2], [0, 2, 3]]))
        }
        _ => {
            let obstacle = Obstacle::new(
                0,
                &ObstacleConfig {
                    shape: shape.clone(),
                    trajectory: Default::default(),
                },
            )?;
            let radius = enclosing_radius(shape);
            let sphere = icosphere(LEVEL, radius);
            let identity = Iso3::identity();
            let vertices = sphere
                .vertices()
                .iter()
                .map(|p| {
                    obstacle
                        .signed_distance(&identity, p)
                        .map_or(*p, |s| p - s.normal * s.distance_m)
                })
                .collect();
            Ok((vertices, sphere.faces().to_vec()))
        }
    }
}

/// A radius (with margin) of a sphere about the origin that encloses the shape.
fn enclosing_radius(shape: &ObstacleShape) -> f64 {
    let r = match shape {
        ObstacleShape::Ball { radius_m } => *radius_m,
        ObstacleShape::Cuboid { half_extents_m: h } => Vector3::from(*h).norm(),
        ObstacleShape::Capsule {
            half_height_m,
            radius_m,
        }
        | ObstacleShape::Cylinder {
            half_height_m,
            radius_m,
        } => half_height_m + radius_m,
        ObstacleShape::ConvexHull { points_m } => points_m
            .iter()
            .map(|p| Vector3::from(*p).norm())
            .fold(0.0, f64::max),
        ObstacleShape::TriangleMesh { vertices_m, .. } => vertices_m
            .iter()
            .map(|p| Vector3::from(*p).norm())
            .fold(0.0, f64::max),
        ObstacleShape::HalfSpace { .. } => 1.0,
    };
    2.0 * r + 1e-3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampled_surfaces_lie_on_the_shapes() {
        let shapes = [
            ObstacleShape::Ball { radius_m: 0.02 },
            ObstacleShape::Cuboid {
                half_extents_m: [0.01, 0.02, 0.03],
            },
            ObstacleShape::Capsule {
                half_height_m: 0.02,
                radius_m: 0.01,
            },
            ObstacleShape::Cylinder {
                half_height_m: 0.02,
                radius_m: 0.01,
            },
            ObstacleShape::ConvexHull {
                points_m: vec![
                    [0.0, 0.0, 0.0],
                    [0.02, 0.0, 0.0],
                    [0.0, 0.02, 0.0],
                    [0.0, 0.0, 0.02],
                ],
            },
        ];
        for shape in shapes {
            let (v, f) = obstacle_surface(&shape).unwrap();
            let obstacle = Obstacle::new(
                0,
                &ObstacleConfig {
                    shape: shape.clone(),
                    trajectory: Default::default(),
                },
            )
            .unwrap();
            for p in &v {
                let d = obstacle
                    .signed_distance(&Iso3::identity(), p)
                    .map_or(0.0, |s| s.distance_m);
                assert!(d.abs() < 1e-9, "{shape:?}: vertex {p} is {d} m off");
            }
            assert!(f.iter().flatten().all(|&i| (i as usize) < v.len()));
        }
        // The cuboid's extreme vertices reach its corners.
        let (v, _) = obstacle_surface(&ObstacleShape::Cuboid {
            half_extents_m: [0.01, 0.02, 0.03],
        })
        .unwrap();
        let max_x = v.iter().map(|p| p.x).fold(f64::MIN, f64::max);
        assert!((max_x - 0.01).abs() < 1e-12);
    }
}
