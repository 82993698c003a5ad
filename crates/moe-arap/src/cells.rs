//! ARAP cells: which edges each vertex's rotation is fitted to, and which rotations act on each
//! edge in the global step.
//!
//! For spokes cells, cell `i` holds the edges from `i` to its one-ring, so every edge lies in the
//! cells of its two end points. For spokes-and-rims cells, cell `i` also holds the edge opposite
//! `i` in each incident triangle, so an interior edge lies in four cells (its end points and the
//! two opposite corners) and a boundary edge in three. With `c_e` cells per edge, the energy
//! `Σ_i Σ_{e∈cell(i)} w_e ‖e′ − R_i e‖²` has the normal equations
//! `Σ_{e∋k} (c_e w_e / 2)(p′_k − p′_l) = Σ_{e∋k} (w_e / 2)(Σ_{i∈cells(e)} R_i)(p_k − p_l)`,
//! which for spokes (`c_e = 2`) is docs/design.md's global step.

use moe_geom::{Real, Topology, TriMesh, Vector3, cotan_weights};

use crate::config::ArapEnergy;

/// One edge of a cell, oriented `a → b`, with its weight and rest vector `p_a − p_b`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CellEdge {
    pub(crate) a: u32,
    pub(crate) b: u32,
    pub(crate) weight: Real,
    pub(crate) rest: Vector3,
    /// `weight · rest`.
    pub(crate) weighted_rest: Vector3,
}

/// Cells, edge data and one-rings of a rest mesh, ready for the local and global steps.
#[derive(Debug, Clone)]
pub(crate) struct Cells {
    /// CSR offsets into `cell_edges`, one range per vertex.
    pub(crate) cell_offsets: Vec<usize>,
    /// The edges of every cell.
    pub(crate) cell_edges: Vec<CellEdge>,
    /// Unique mesh edges `[a, b]`, `a < b`.
    pub(crate) edges: Vec<[u32; 2]>,
    /// Cotangent weight `w_e` of every edge.
    pub(crate) weights: Vec<Real>,
    /// Rest vector `p_a − p_b` of every edge.
    pub(crate) rest_edges: Vec<Vector3>,
    /// CSR offsets into `edge_cells`, one range per edge.
    pub(crate) edge_cell_offsets: Vec<usize>,
    /// Vertices whose rotation acts on each edge in the global step.
    pub(crate) edge_cells: Vec<u32>,
    /// `Σ_{e∈cell(i)} w_e ‖e‖²` per vertex.
    pub(crate) rest_energy: Vec<Real>,
    /// One-ring offsets (CSR, as in [`Topology`]).
    pub(crate) ring_offsets: Vec<usize>,
    /// One-ring neighbours.
    pub(crate) ring_vertices: Vec<u32>,
    /// Edge index of each one-ring entry.
    pub(crate) ring_edges: Vec<u32>,
    /// Per one-ring entry of `v`: `+1` when `v` is the edge's first end point, `−1` otherwise
    /// (the edge's orientation as seen from `v`, applied without a branch).
    pub(crate) ring_signs: Vec<Real>,
}

impl Cells {
    /// Builds the cells of `mesh` for the given energy variant.
    pub(crate) fn new(mesh: &TriMesh, topology: &Topology, energy: ArapEnergy) -> Self {
        let n = mesh.num_vertices();
        let p = mesh.vertices();
        let edges = topology.edges().to_vec();
        let weights = cotan_weights(mesh, topology);
        let rest_edges: Vec<Vector3> = edges
            .iter()
            .map(|&[a, b]| p[a as usize] - p[b as usize])
            .collect();
        let rims = energy == ArapEnergy::SpokesAndRims;

        // Rim edges of every vertex: for face f, corner k, the edge opposite k.
        let mut rim_lists: Vec<Vec<u32>> = vec![Vec::new(); if rims { n } else { 0 }];
        if rims {
            for (f, tri) in mesh.faces().iter().enumerate() {
                for k in 0..3 {
                    rim_lists[tri[k] as usize].push(topology.face_edges()[f][k]);
                }
            }
        }

        let mut ring_offsets = Vec::with_capacity(n + 1);
        let mut ring_vertices = Vec::new();
        let mut ring_edges = Vec::new();
        let mut cell_offsets = Vec::with_capacity(n + 1);
        let mut cell_edges = Vec::new();
        ring_offsets.push(0);
        cell_offsets.push(0);
        let make = |e: u32| {
            let [a, b] = edges[e as usize];
            CellEdge {
                a,
                b,
                weight: weights[e as usize],
                rest: rest_edges[e as usize],
                weighted_rest: rest_edges[e as usize] * weights[e as usize],
            }
        };
        for v in 0..n {
            ring_vertices.extend_from_slice(topology.neighbors(v));
            ring_edges.extend_from_slice(topology.neighbor_edges(v));
            ring_offsets.push(ring_vertices.len());
            cell_edges.extend(topology.neighbor_edges(v).iter().map(|&e| make(e)));
            if let Some(rims) = rim_lists.get(v) {
                cell_edges.extend(rims.iter().map(|&e| make(e)));
            }
            cell_offsets.push(cell_edges.len());
        }

        // Cells containing each edge: its end points, plus the opposite corners for rims.
        let mut edge_cell_offsets = Vec::with_capacity(edges.len() + 1);
        let mut edge_cells = Vec::with_capacity(edges.len() * if rims { 4 } else { 2 });
        edge_cell_offsets.push(0);
        for (e, &[a, b]) in edges.iter().enumerate() {
            edge_cells.push(a);
            edge_cells.push(b);
            if rims {
                let (f0, f1) = topology.edge_faces()[e];
                for f in std::iter::once(f0).chain(f1) {
                    let tri = mesh.faces()[f as usize];
                    let k = (0..3)
                        .find(|&k| topology.face_edges()[f as usize][k] as usize == e)
                        .unwrap_or(0);
                    edge_cells.push(tri[k]);
                }
            }
            edge_cell_offsets.push(edge_cells.len());
        }
        let ring_signs = (0..n)
            .flat_map(|v| {
                let edges = &edges;
                ring_edges[ring_offsets[v]..ring_offsets[v + 1]]
                    .iter()
                    .map(move |&e| {
                        if edges[e as usize][0] as usize == v {
                            1.0
                        } else {
                            -1.0
                        }
                    })
            })
            .collect();
        let rest_energy = (0..n)
            .map(|v| {
                cell_edges[cell_offsets[v]..cell_offsets[v + 1]]
                    .iter()
                    .map(|c| c.weight * c.rest.norm_squared())
                    .sum()
            })
            .collect();
        Self {
            rest_energy,
            cell_offsets,
            cell_edges,
            edges,
            weights,
            rest_edges,
            edge_cell_offsets,
            edge_cells,
            ring_offsets,
            ring_vertices,
            ring_edges,
            ring_signs,
        }
    }

    /// Number of vertices.
    pub(crate) fn num_vertices(&self) -> usize {
        self.ring_offsets.len() - 1
    }

    /// The edges of cell `v`.
    pub(crate) fn cell(&self, v: usize) -> &[CellEdge] {
        &self.cell_edges[self.cell_offsets[v]..self.cell_offsets[v + 1]]
    }

    /// The one-ring of `v`.
    pub(crate) fn ring(&self, v: usize) -> &[u32] {
        &self.ring_vertices[self.ring_offsets[v]..self.ring_offsets[v + 1]]
    }

    /// Edge indices of the one-ring of `v`.
    pub(crate) fn ring_edge_ids(&self, v: usize) -> &[u32] {
        &self.ring_edges[self.ring_offsets[v]..self.ring_offsets[v + 1]]
    }

    /// Orientation signs of the one-ring edges of `v` (see `ring_signs`).
    pub(crate) fn ring_edge_signs(&self, v: usize) -> &[Real] {
        &self.ring_signs[self.ring_offsets[v]..self.ring_offsets[v + 1]]
    }

    /// The vertices whose rotations act on edge `e`.
    pub(crate) fn cells_of_edge(&self, e: usize) -> &[u32] {
        &self.edge_cells[self.edge_cell_offsets[e]..self.edge_cell_offsets[e + 1]]
    }

    /// System-matrix weight of edge `e`: `c_e w_e / 2`.
    pub(crate) fn matrix_weight(&self, e: usize) -> Real {
        self.weights[e] * self.cells_of_edge(e).len() as Real / 2.0
    }

    /// The data term `Σ_{e∈cell(v)} w_e ‖(p′_a − p′_b) − R e‖²` of one cell.
    #[cfg(test)]
    pub(crate) fn cell_energy(
        &self,
        v: usize,
        deformed: &[moe_geom::Point3],
        r: &moe_geom::Matrix3,
    ) -> Real {
        self.cell(v)
            .iter()
            .map(|c| {
                let d = deformed[c.a as usize] - deformed[c.b as usize];
                c.weight * (d - r * c.rest).norm_squared()
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spokes_cells_are_one_rings_and_edges_have_two_cells() {
        let m = moe_geom::shapes::octahedron(1.0);
        let topo = Topology::new(&m);
        let cells = Cells::new(&m, &topo, ArapEnergy::Smoothed);
        for v in 0..6 {
            assert_eq!(cells.cell(v).len(), 4);
            assert!(
                cells
                    .cell(v)
                    .iter()
                    .all(|c| c.a as usize == v || c.b as usize == v)
            );
        }
        for e in 0..cells.edges.len() {
            assert_eq!(cells.cells_of_edge(e), &cells.edges[e]);
            assert_eq!(cells.matrix_weight(e), cells.weights[e]);
        }
    }

    #[test]
    fn rims_add_opposite_edges_and_opposite_corners() {
        let m = moe_geom::shapes::octahedron(1.0);
        let topo = Topology::new(&m);
        let cells = Cells::new(&m, &topo, ArapEnergy::SpokesAndRims);
        // Vertex 4 (the top) has 4 spokes and 4 rim edges (the equator).
        assert_eq!(cells.cell(4).len(), 8);
        let e = topo.edge_index(0, 2).unwrap();
        let mut c = cells.cells_of_edge(e).to_vec();
        c.sort_unstable();
        assert_eq!(c, vec![0, 2, 4, 5]);
        assert_eq!(cells.matrix_weight(e), 2.0 * cells.weights[e]);
    }
}
