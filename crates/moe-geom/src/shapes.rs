//! Procedural closed meshes: subdivided icospheres, star-shaped surfaces and superquadrics built
//! from them.
//!
//! Used for obstacles in simulation, for surface-reconstruction benchmarks and in tests; every
//! mesh here is closed, manifold and outward oriented by construction.

use std::collections::HashMap;

use crate::error::GeomError;
use crate::math::{Point3, Real, Vector3};
use crate::mesh::TriMesh;

/// The unit icosahedron subdivided `level` times (each level splits every triangle in four) and
/// projected on the sphere of `radius` about the origin: `10·4^level + 2` vertices.
///
/// # Panics
/// Never for `level ≤ 7` (the mesh is valid by construction).
pub fn icosphere(level: u32, radius: Real) -> TriMesh {
    let (dirs, faces) = unit_icosphere(level);
    let vertices = dirs.iter().map(|d| Point3::from(d * radius)).collect();
    TriMesh::new(vertices, faces).expect("icosphere is a valid closed mesh")
}

/// The regular octahedron with vertices `±radius` on the axes, in the order `+x, −x, +y, −y, +z,
/// −z`: the smallest closed surface on which every vertex has the same valence (4), handy for
/// tests that count cells, edges and one-rings by hand.
///
/// # Panics
/// Never (the mesh is valid by construction) for a finite, non-zero radius.
pub fn octahedron(radius: Real) -> TriMesh {
    let r = radius;
    let vertices = vec![
        Point3::new(r, 0.0, 0.0),
        Point3::new(-r, 0.0, 0.0),
        Point3::new(0.0, r, 0.0),
        Point3::new(0.0, -r, 0.0),
        Point3::new(0.0, 0.0, r),
        Point3::new(0.0, 0.0, -r),
    ];
    let faces = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    TriMesh::new(vertices, faces).expect("the octahedron is a valid closed mesh")
}

/// Unit directions and faces of a subdivided icosahedron (faces counter-clockwise from outside).
pub fn unit_icosphere(level: u32) -> (Vec<Vector3>, Vec<[u32; 3]>) {
    let t = (1.0 + (5.0 as Real).sqrt()) / 2.0;
    let mut v: Vec<Vector3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vector3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(f.len() * 4);
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<Vector3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                (v.len() - 1) as u32
            })
        };
        for &[a, b, c] in &f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v, f)
}

/// The finest subdivision level of the fallible icosphere meshes ([`star_shaped`],
/// [`Superquadric::mesh`], the bodies' meshes): 10·4⁹ + 2 = 2,621,442 vertices.
pub const MAX_SUBDIVISION_LEVEL: u32 = 9;

/// Checks a subdivision level against [`MAX_SUBDIVISION_LEVEL`].
///
/// # Errors
/// [`GeomError::InvalidParameter`] above it.
pub(crate) fn check_subdivision_level(level: u32) -> Result<(), GeomError> {
    if level > MAX_SUBDIVISION_LEVEL {
        return Err(GeomError::InvalidParameter {
            name: "subdivision level",
            value: Real::from(level),
            reason: "at most 9 (2.6 million vertices)",
        });
    }
    Ok(())
}

/// A star-shaped closed surface about `center`: each icosphere direction `d` is pushed to
/// `center + radius(d)·d`. `radius` must be positive.
///
/// # Errors
/// A `level` above [`MAX_SUBDIVISION_LEVEL`]; mesh validation errors if `radius` returns a
/// non-finite or non-positive value.
pub fn star_shaped(
    level: u32,
    center: Point3,
    radius: impl Fn(&Vector3) -> Real,
) -> Result<TriMesh, GeomError> {
    check_subdivision_level(level)?;
    let (dirs, faces) = unit_icosphere(level);
    let vertices = dirs.iter().map(|d| center + d * radius(d)).collect();
    TriMesh::new(vertices, faces)
}

/// Half-axes and exponents of a superquadric (superellipsoid)
/// `(|x/a|^(2/e2) + |y/b|^(2/e2))^(e2/e1) + |z/c|^(2/e1) = 1`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Superquadric {
    /// Half-axes `a, b, c`, metres.
    pub half_axes_m: [Real; 3],
    /// North–south exponent `e1` (1 = ellipsoid, → 0 box-like, 2 = double cone).
    pub e1: Real,
    /// East–west exponent `e2`.
    pub e2: Real,
}

impl Superquadric {
    /// Distance from the centre to the surface along the unit direction `d` (the surface is
    /// star-shaped about its centre).
    pub fn radius(&self, d: &Vector3) -> Real {
        let [a, b, c] = self.half_axes_m;
        let xy = ((d.x / a).abs().powf(2.0 / self.e2) + (d.y / b).abs().powf(2.0 / self.e2))
            .powf(self.e2 / self.e1);
        let f = xy + (d.z / c).abs().powf(2.0 / self.e1);
        f.powf(-self.e1 / 2.0)
    }

    /// The closed mesh on a subdivided icosahedron of `level`.
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] for non-positive axes, exponents outside `[0.1, 4]` or a
    /// `level` above [`MAX_SUBDIVISION_LEVEL`].
    pub fn mesh(&self, level: u32) -> Result<TriMesh, GeomError> {
        for (name, v) in [
            ("superquadric half axis", self.half_axes_m[0]),
            ("superquadric half axis", self.half_axes_m[1]),
            ("superquadric half axis", self.half_axes_m[2]),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GeomError::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be positive",
                });
            }
        }
        for (name, v) in [("superquadric e1", self.e1), ("superquadric e2", self.e2)] {
            if !(0.1..=4.0).contains(&v) {
                return Err(GeomError::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be in [0.1, 4]",
                });
            }
        }
        star_shaped(level, Point3::origin(), |d| self.radius(d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::Topology;

    #[test]
    fn octahedron_is_closed_outward_and_of_the_right_volume() {
        let m = octahedron(2.0);
        m.require_closed().unwrap();
        assert_eq!(Topology::new(&m).euler_characteristic(), 2);
        // Eight tetrahedra of volume r³/6 each.
        assert!((m.signed_volume() - 8.0 * 8.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn icosphere_is_closed_with_euler_characteristic_two() {
        let m = icosphere(3, 2.0);
        assert_eq!(m.num_vertices(), 10 * 64 + 2);
        m.require_closed().unwrap();
        assert_eq!(Topology::new(&m).euler_characteristic(), 2);
        assert!(m.signed_volume() > 0.0, "outward oriented");
        let v_sphere = 4.0 / 3.0 * std::f64::consts::PI * 8.0;
        assert!((m.signed_volume() - v_sphere).abs() < 0.02 * v_sphere);
    }

    #[test]
    fn superquadric_with_unit_exponents_is_the_ellipsoid() {
        let q = Superquadric {
            half_axes_m: [0.03, 0.02, 0.01],
            e1: 1.0,
            e2: 1.0,
        };
        let m = q.mesh(4).unwrap();
        m.require_closed().unwrap();
        for p in m.vertices() {
            let f = (p.x / 0.03).powi(2) + (p.y / 0.02).powi(2) + (p.z / 0.01).powi(2);
            assert!((f - 1.0).abs() < 1e-9, "{f}");
        }
        let v = 4.0 / 3.0 * std::f64::consts::PI * 0.03 * 0.02 * 0.01;
        assert!((m.signed_volume() - v).abs() < 0.01 * v);
        // Small exponents approach the box: the volume grows toward 8abc.
        let boxy = Superquadric {
            e1: 0.2,
            e2: 0.2,
            ..q
        }
        .mesh(4)
        .unwrap();
        assert!(boxy.signed_volume() > 0.8 * 8.0 * 0.03 * 0.02 * 0.01);
        crate::assert_err!(
            Superquadric { e1: 0.0, ..q }.mesh(2),
            GeomError::InvalidParameter {
                name: "superquadric e1",
                value: 0.0,
                ..
            }
        );
    }

    #[test]
    fn subdivision_levels_are_bounded() {
        let q = Superquadric {
            half_axes_m: [0.03, 0.02, 0.01],
            e1: 1.0,
            e2: 1.0,
        };
        for level in [MAX_SUBDIVISION_LEVEL + 1, u32::MAX] {
            crate::assert_err!(
                q.mesh(level),
                GeomError::InvalidParameter {
                    name: "subdivision level",
                    ..
                }
            );
            crate::assert_err!(
                star_shaped(level, Point3::origin(), |_| 1.0),
                GeomError::InvalidParameter {
                    name: "subdivision level",
                    ..
                }
            );
        }
        assert!(check_subdivision_level(MAX_SUBDIVISION_LEVEL).is_ok());
    }
}
