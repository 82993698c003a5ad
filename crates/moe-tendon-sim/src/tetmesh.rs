//! Linear tetrahedral meshes: validation, a structured box mesher and barycentric coordinates.

use moe_geom::{Point3, Real, Vector3};

use crate::error::SimError;

/// A tetrahedral mesh with positively oriented elements (`det[x1−x0, x2−x0, x3−x0] > 0`).
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    nodes: Vec<Point3>,
    tets: Vec<[u32; 4]>,
}

/// The six tetrahedra of the Kuhn (Freudenthal) split of a cube around its diagonal 0–7, with
/// corner `k` at offset `(k & 1, (k >> 1) & 1, (k >> 2) & 1)`. Every cube of a grid split this way
/// shares the same face diagonals with its neighbours, so the tet mesh is conforming.
pub(crate) const KUHN_TETS: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// Signed volume of the tetrahedron `(a, b, c, d)`.
pub(crate) fn signed_volume(a: &Point3, b: &Point3, c: &Point3, d: &Point3) -> Real {
    (b - a).cross(&(c - a)).dot(&(d - a)) / 6.0
}

impl TetMesh {
    /// Builds a tet mesh, reorienting negatively oriented elements.
    ///
    /// # Errors
    /// [`SimError::TetIndexOutOfRange`] for a bad index; [`SimError::DegenerateTet`] for an
    /// element whose volume is below `1e-12 × (bounding-box diagonal)³`;
    /// [`SimError::LengthMismatch`] for an empty mesh; a non-finite node gives
    /// [`moe_geom::GeomError::NonFiniteVertex`].
    pub fn new(nodes: Vec<Point3>, mut tets: Vec<[u32; 4]>) -> Result<Self, SimError> {
        if tets.is_empty() || nodes.is_empty() {
            return Err(SimError::LengthMismatch {
                what: "tet mesh elements (at least)",
                expected: 1,
                got: 0,
            });
        }
        if let Some(vertex) = nodes
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
        {
            return Err(moe_geom::GeomError::NonFiniteVertex { vertex }.into());
        }
        let diag = moe_geom::Aabb::from_points(&nodes).map_or(0.0, |b| b.diagonal());
        let min_volume = 1e-12 * diag.powi(3);
        for (t, tet) in tets.iter_mut().enumerate() {
            for &i in tet.iter() {
                if i as usize >= nodes.len() {
                    return Err(SimError::TetIndexOutOfRange {
                        tet: t,
                        index: i,
                        len: nodes.len(),
                    });
                }
            }
            let p = tet.map(|i| nodes[i as usize]);
            let mut v = signed_volume(&p[0], &p[1], &p[2], &p[3]);
            if v < 0.0 {
                tet.swap(2, 3);
                v = -v;
            }
            if v.is_nan() || v <= min_volume {
                return Err(SimError::DegenerateTet { tet: t, volume: v });
            }
        }
        Ok(Self { nodes, tets })
    }

    /// A box `[min, max]` split into `cells[0] × cells[1] × cells[2]` cubes (cuboids), six
    /// Kuhn tetrahedra each. Nodes are numbered x fastest, then y, then z.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a zero cell count or an empty box.
    pub fn box_grid(min: Point3, max: Point3, cells: [usize; 3]) -> Result<Self, SimError> {
        for (k, &n) in cells.iter().enumerate() {
            if n == 0 {
                return Err(SimError::InvalidParameter {
                    name: "box cells",
                    value: 0.0,
                    reason: "every axis needs at least one cell",
                });
            }
            let extent = max[k] - min[k];
            if extent.is_nan() || extent <= 0.0 {
                return Err(SimError::InvalidParameter {
                    name: "box extent",
                    value: extent,
                    reason: "must be positive on every axis",
                });
            }
        }
        let [nx, ny, nz] = cells;
        let id = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
        let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    let t = Vector3::new(
                        i as Real / nx as Real,
                        j as Real / ny as Real,
                        k as Real / nz as Real,
                    );
                    nodes.push(min + (max - min).component_mul(&t));
                }
            }
        }
        let mut tets = Vec::with_capacity(6 * nx * ny * nz);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let corner = |c: usize| id(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                    for t in KUHN_TETS {
                        tets.push(t.map(corner));
                    }
                }
            }
        }
        Self::new(nodes, tets)
    }

    /// Node positions (rest shape).
    pub fn nodes(&self) -> &[Point3] {
        &self.nodes
    }

    /// Elements, four node ids each, positively oriented.
    pub fn tets(&self) -> &[[u32; 4]] {
        &self.tets
    }

    /// Number of nodes.
    pub fn num_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Number of elements.
    pub fn num_tets(&self) -> usize {
        self.tets.len()
    }

    /// The four rest corners of element `t`.
    pub fn corners(&self, t: usize) -> [Point3; 4] {
        self.tets[t].map(|i| self.nodes[i as usize])
    }

    /// Total rest volume, m³.
    pub fn volume(&self) -> Real {
        (0..self.tets.len())
            .map(|t| {
                let p = self.corners(t);
                signed_volume(&p[0], &p[1], &p[2], &p[3])
            })
            .sum()
    }

    /// Barycentric coordinates of `p` in element `t` (they sum to 1; all are ≥ 0 inside).
    pub fn barycentric(&self, t: usize, p: &Point3) -> [Real; 4] {
        barycentric(&self.corners(t), p)
    }
}

/// Barycentric coordinates of `p` with respect to the tetrahedron `c`.
pub(crate) fn barycentric(c: &[Point3; 4], p: &Point3) -> [Real; 4] {
    let m = moe_geom::Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]]);
    match m.try_inverse() {
        Some(inv) => {
            let w = inv * (p - c[0]);
            [1.0 - w.x - w.y - w.z, w.x, w.y, w.z]
        }
        None => [Real::NAN; 4],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_grid_fills_the_box_exactly() {
        let m = TetMesh::box_grid(
            Point3::new(-1.0, 0.0, 0.5),
            Point3::new(1.0, 3.0, 1.0),
            [3, 4, 2],
        )
        .unwrap();
        assert_eq!(m.num_nodes(), 4 * 5 * 3);
        assert_eq!(m.num_tets(), 6 * 3 * 4 * 2);
        assert!((m.volume() - 3.0).abs() < 1e-12);
        // Conforming: every interior triangle is shared by exactly two tets, boundary by one.
        let mut faces = std::collections::HashMap::new();
        for t in m.tets() {
            for skip in 0..4 {
                let mut f: Vec<u32> = (0..4).filter(|&k| k != skip).map(|k| t[k]).collect();
                f.sort_unstable();
                *faces.entry(f).or_insert(0) += 1;
            }
        }
        let boundary = faces.values().filter(|&&c| c == 1).count();
        assert!(faces.values().all(|&c| c == 1 || c == 2));
        // Each boundary square face is two triangles.
        assert_eq!(boundary, 2 * 2 * (3 * 4 + 4 * 2 + 3 * 2));
    }

    #[test]
    fn barycentric_coordinates_reproduce_the_point() {
        let m = TetMesh::box_grid(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [1, 1, 1]).unwrap();
        let p = Point3::new(0.3, 0.2, 0.9);
        for t in 0..m.num_tets() {
            let w = m.barycentric(t, &p);
            assert!((w.iter().sum::<Real>() - 1.0).abs() < 1e-12);
            let c = m.corners(t);
            let q = (0..4).fold(Vector3::zeros(), |acc, k| acc + c[k].coords * w[k]);
            assert!((q - p.coords).norm() < 1e-12);
        }
    }

    #[test]
    fn bad_tets_are_named() {
        let nodes = vec![
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
        ];
        assert!(matches!(
            TetMesh::new(nodes.clone(), vec![[0, 1, 2, 3]]),
            Err(SimError::DegenerateTet { tet: 0, .. })
        ));
        assert!(matches!(
            TetMesh::new(nodes, vec![[0, 1, 2, 9]]),
            Err(SimError::TetIndexOutOfRange {
                tet: 0,
                index: 9,
                ..
            })
        ));
    }
}
