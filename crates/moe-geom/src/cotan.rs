//! Cotangent edge weights and the cotangent Laplacian.
//!
//! The convention (docs/design.md, and Open3D's ARAP): for an edge `ij`,
//!
//! ```text
//! w_ij = max(0, mean over the triangles t ∋ ij of cot(θ_t)),
//! ```
//!
//! where `θ_t` is the angle of triangle `t` at the corner opposite `ij`. An interior edge thus has
//! `(cot α + cot β) / 2`, a boundary edge `cot α`. The Laplacian is `L = D − W` with
//! `D_ii = Σ_j w_ij`: symmetric positive semi-definite, `L·1 = 0`.

use crate::error::GeomError;
use crate::math::{Point3, Real};
use crate::mesh::TriMesh;
use crate::topology::Topology;

/// Cotangent of the angle at `apex` in the triangle `(apex, b, c)`.
pub fn cot_at(apex: &Point3, b: &Point3, c: &Point3) -> Real {
    let (u, v) = (b - apex, c - apex);
    u.dot(&v) / u.cross(&v).norm()
}

/// Cotangent weight of every edge of `topology` (same order as [`Topology::edges`]).
pub fn cotan_weights(mesh: &TriMesh, topology: &Topology) -> Vec<Real> {
    let mut sum = vec![0.0; topology.edges().len()];
    let mut count = vec![0u8; topology.edges().len()];
    for (f, tri) in mesh.faces().iter().enumerate() {
        let p = [0, 1, 2].map(|k| mesh.vertices()[tri[k] as usize]);
        for k in 0..3 {
            let e = topology.face_edges()[f][k] as usize;
            sum[e] += cot_at(&p[k], &p[(k + 1) % 3], &p[(k + 2) % 3]);
            count[e] += 1;
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(&s, &c)| (s / Real::from(c)).max(0.0))
        .collect()
}

/// The cotangent Laplacian `L = D − W` in edge form.
#[derive(Debug, Clone, PartialEq)]
pub struct CotanLaplacian {
    edges: Vec<[u32; 2]>,
    weights: Vec<Real>,
    diagonal: Vec<Real>,
}

impl CotanLaplacian {
    /// Builds the Laplacian of a mesh.
    pub fn new(mesh: &TriMesh, topology: &Topology) -> Self {
        Self::assemble(topology, cotan_weights(mesh, topology))
    }

    /// Builds a Laplacian from given edge weights (one per edge of `topology`).
    ///
    /// # Errors
    /// [`GeomError::LengthMismatch`] when there is not exactly one weight per edge.
    pub fn from_weights(topology: &Topology, weights: Vec<Real>) -> Result<Self, GeomError> {
        if weights.len() != topology.edges().len() {
            return Err(GeomError::LengthMismatch {
                what: "Laplacian edge weights",
                expected: topology.edges().len(),
                got: weights.len(),
            });
        }
        Ok(Self::assemble(topology, weights))
    }

    /// `weights` has one entry per edge of `topology`.
    fn assemble(topology: &Topology, weights: Vec<Real>) -> Self {
        let mut diagonal = vec![0.0; topology.num_vertices()];
        for (&[a, b], &w) in topology.edges().iter().zip(&weights) {
            diagonal[a as usize] += w;
            diagonal[b as usize] += w;
        }
        Self {
            edges: topology.edges().to_vec(),
            weights,
            diagonal,
        }
    }

    /// Edge weights `w_ij`, one per edge.
    pub fn weights(&self) -> &[Real] {
        &self.weights
    }

    /// Diagonal entries `D_ii = Σ_j w_ij`.
    pub fn diagonal(&self) -> &[Real] {
        &self.diagonal
    }

    /// `(row, col, value)` entries of `L`, both triangles, diagonal first then edges.
    pub fn triplets(&self) -> Vec<(usize, usize, Real)> {
        let mut t = Vec::with_capacity(self.diagonal.len() + 2 * self.edges.len());
        t.extend(self.diagonal.iter().enumerate().map(|(i, &d)| (i, i, d)));
        for (&[a, b], &w) in self.edges.iter().zip(&self.weights) {
            t.push((a as usize, b as usize, -w));
            t.push((b as usize, a as usize, -w));
        }
        t
    }

    /// `L · x` for one scalar per vertex.
    ///
    /// # Panics
    /// If `x` does not have one entry per vertex (a programming error).
    pub fn apply(&self, x: &[Real]) -> Vec<Real> {
        assert_eq!(x.len(), self.diagonal.len(), "one value per vertex");
        let mut y: Vec<Real> = self.diagonal.iter().zip(x).map(|(d, v)| d * v).collect();
        for (&[a, b], &w) in self.edges.iter().zip(&self.weights) {
            let (a, b) = (a as usize, b as usize);
            y[a] -= w * x[b];
            y[b] -= w * x[a];
        }
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles forming the unit square, diagonal 0–2.
    fn square() -> TriMesh {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3]]).unwrap()
    }

    #[test]
    fn square_weights_match_hand_computation() {
        let m = square();
        let topo = Topology::new(&m);
        let w = cotan_weights(&m, &topo);
        // Boundary edges are opposite a 45° corner: cot 45° = 1.
        // The diagonal 0–2 is opposite two right angles: (0 + 0) / 2 = 0.
        for (e, &[a, b]) in topo.edges().iter().enumerate() {
            let expected = if [a, b] == [0, 2] { 0.0 } else { 1.0 };
            assert!((w[e] - expected).abs() < 1e-15, "edge {a}-{b}: {}", w[e]);
        }
        let lap = CotanLaplacian::new(&m, &topo);
        assert_eq!(lap.diagonal(), &[2.0, 2.0, 2.0, 2.0]);
        // L x for x = (1, 0, 0, 0): column 0 of L = (2, -1, 0, -1).
        let y = lap.apply(&[1.0, 0.0, 0.0, 0.0]);
        for (a, b) in y.iter().zip([2.0, -1.0, 0.0, -1.0]) {
            assert!((a - b).abs() < 1e-15);
        }
    }

    #[test]
    fn obtuse_triangle_weights_are_clamped() {
        // Apex angle at vertex 2 is 120°: cot = -1/√3, clamped to 0 for the boundary edge 0–1.
        let h = 0.5 / 3f64.sqrt();
        let v = vec![
            Point3::new(-0.5, 0.0, 0.0),
            Point3::new(0.5, 0.0, 0.0),
            Point3::new(0.0, h, 0.0),
        ];
        let m = TriMesh::new(v, vec![[0, 1, 2]]).unwrap();
        let topo = Topology::new(&m);
        let w = cotan_weights(&m, &topo);
        let e01 = topo.edge_index(0, 1).unwrap();
        assert_eq!(w[e01], 0.0);
        // The other two corners are 30°: cot 30° = √3.
        let e02 = topo.edge_index(0, 2).unwrap();
        assert!((w[e02] - 3f64.sqrt()).abs() < 1e-12);
        assert!(
            (cot_at(&m.vertices()[2], &m.vertices()[0], &m.vertices()[1]) + 1.0 / 3f64.sqrt())
                .abs()
                < 1e-12
        );
    }

    #[test]
    fn laplacian_annihilates_constants_and_is_symmetric() {
        let m = crate::mesh::tests::tetrahedron();
        let topo = Topology::new(&m);
        let lap = CotanLaplacian::new(&m, &topo);
        crate::assert_err!(
            CotanLaplacian::from_weights(&topo, vec![1.0; 5]),
            GeomError::LengthMismatch {
                what: "Laplacian edge weights",
                expected: 6,
                got: 5
            }
        );
        assert_eq!(
            CotanLaplacian::from_weights(&topo, lap.weights().to_vec()).unwrap(),
            lap
        );
        let y = lap.apply(&[3.5; 4]);
        assert!(y.iter().all(|v| v.abs() < 1e-12), "{y:?}");
        let n = 4;
        let mut dense = vec![vec![0.0; n]; n];
        for (i, j, v) in lap.triplets() {
            dense[i][j] += v;
        }
        for (i, row) in dense.iter().enumerate() {
            for (j, value) in row.iter().enumerate() {
                assert_eq!(*value, dense[j][i]);
            }
        }
    }
}
