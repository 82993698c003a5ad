//! Mesh connectivity: unique edges, edge–face incidence, one-rings, boundary loops and connected
//! components.

use crate::math::Point3;
use crate::mesh::TriMesh;

/// Connectivity of a [`TriMesh`], computed once and shared by the algorithms that need it.
///
/// Edges are unique, stored as `[a, b]` with `a < b` and sorted lexicographically, so an edge's
/// index is stable for a given face list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topology {
    num_vertices: usize,
    edges: Vec<[u32; 2]>,
    edge_faces: Vec<(u32, Option<u32>)>,
    face_edges: Vec<[u32; 3]>,
    ring_offsets: Vec<usize>,
    ring_vertices: Vec<u32>,
    ring_edges: Vec<u32>,
}

impl Topology {
    /// Computes the connectivity of a validated mesh (so every edge has one or two faces).
    pub fn new(mesh: &TriMesh) -> Self {
        let n = mesh.num_vertices();
        let faces = mesh.faces();
        let mut half: Vec<([u32; 2], u32, u8)> = Vec::with_capacity(faces.len() * 3);
        for (f, tri) in faces.iter().enumerate() {
            for k in 0..3 {
                let (u, v) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                half.push(([u.min(v), u.max(v)], f as u32, k as u8));
            }
        }
        half.sort_unstable();
        let mut edges: Vec<[u32; 2]> = Vec::with_capacity(half.len() / 2 + 1);
        let mut edge_faces: Vec<(u32, Option<u32>)> = Vec::with_capacity(half.len() / 2 + 1);
        let mut face_edges = vec![[0u32; 3]; faces.len()];
        for (e, f, k) in half {
            if edges.last() == Some(&e) {
                let last = edge_faces.last_mut().expect("edge has a first face");
                last.1 = Some(f);
            } else {
                edges.push(e);
                edge_faces.push((f, None));
            }
            face_edges[f as usize][k as usize] = (edges.len() - 1) as u32;
        }
        // One-rings in CSR form, neighbours sorted by vertex id.
        let mut degree = vec![0usize; n];
        for &[a, b] in &edges {
            degree[a as usize] += 1;
            degree[b as usize] += 1;
        }
        let mut ring_offsets = Vec::with_capacity(n + 1);
        ring_offsets.push(0);
        for d in &degree {
            ring_offsets.push(ring_offsets.last().copied().unwrap_or(0) + d);
        }
        let total = *ring_offsets.last().unwrap_or(&0);
        let mut ring_vertices = vec![0u32; total];
        let mut ring_edges = vec![0u32; total];
        let mut fill = ring_offsets[..n].to_vec();
        for (e, &[a, b]) in edges.iter().enumerate() {
            for (u, v) in [(a, b), (b, a)] {
                let slot = &mut fill[u as usize];
                ring_vertices[*slot] = v;
                ring_edges[*slot] = e as u32;
                *slot += 1;
            }
        }
        // Edges are sorted by (a, b), so each ring is already sorted for the (a, b) entries;
        // sort every ring to make the (b, a) entries sorted too.
        for v in 0..n {
            let (s, t) = (ring_offsets[v], ring_offsets[v + 1]);
            let mut pairs: Vec<(u32, u32)> = ring_vertices[s..t]
                .iter()
                .copied()
                .zip(ring_edges[s..t].iter().copied())
                .collect();
            pairs.sort_unstable();
            for (i, (w, e)) in pairs.into_iter().enumerate() {
                ring_vertices[s + i] = w;
                ring_edges[s + i] = e;
            }
        }
        Self {
            num_vertices: n,
            edges,
            edge_faces,
            face_edges,
            ring_offsets,
            ring_vertices,
            ring_edges,
        }
    }

    /// Number of vertices of the mesh.
    pub fn num_vertices(&self) -> usize {
        self.num_vertices
    }

    /// Unique edges `[a, b]`, `a < b`, sorted.
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// The one or two faces of every edge.
    pub fn edge_faces(&self) -> &[(u32, Option<u32>)] {
        &self.edge_faces
    }

    /// For every face, the indices of its edges; entry `k` is the edge opposite corner `k`.
    pub fn face_edges(&self) -> &[[u32; 3]] {
        &self.face_edges
    }

    /// Neighbours of vertex `v`, sorted by id.
    pub fn neighbors(&self, v: usize) -> &[u32] {
        &self.ring_vertices[self.ring_offsets[v]..self.ring_offsets[v + 1]]
    }

    /// Edge indices matching [`Topology::neighbors`] one to one.
    pub fn neighbor_edges(&self, v: usize) -> &[u32] {
        &self.ring_edges[self.ring_offsets[v]..self.ring_offsets[v + 1]]
    }

    /// Index of edge `(a, b)` if it exists (either order).
    pub fn edge_index(&self, a: u32, b: u32) -> Option<usize> {
        let ring = self.neighbors(a as usize);
        let k = ring.binary_search(&b).ok()?;
        Some(self.neighbor_edges(a as usize)[k] as usize)
    }

    /// Edges with a single face, sorted.
    pub fn boundary_edges(&self) -> Vec<[u32; 2]> {
        self.edges
            .iter()
            .zip(&self.edge_faces)
            .filter(|(_, (_, second))| second.is_none())
            .map(|(e, _)| *e)
            .collect()
    }

    /// Boundary loops as vertex cycles, each following the orientation of its faces and starting
    /// at its smallest vertex; loops sorted by that vertex. Empty for a closed mesh.
    pub fn boundary_loops(&self, mesh: &TriMesh) -> Vec<Vec<u32>> {
        // The directed boundary half-edge u -> v is the one that appears in its face.
        let mut next: std::collections::BTreeMap<u32, u32> = std::collections::BTreeMap::new();
        for (e, &(f, second)) in self.edge_faces.iter().enumerate() {
            if second.is_some() {
                continue;
            }
            let [a, b] = self.edges[e];
            let tri = mesh.faces()[f as usize];
            let forward = (0..3).any(|k| tri[k] == a && tri[(k + 1) % 3] == b);
            let (u, v) = if forward { (a, b) } else { (b, a) };
            next.insert(u, v);
        }
        let mut loops = Vec::new();
        while let Some((&start, _)) = next.iter().next() {
            let mut cycle = vec![start];
            let mut cur = next.remove(&start).expect("start is in the map");
            while cur != start {
                cycle.push(cur);
                match next.remove(&cur) {
                    Some(v) => cur = v,
                    None => break,
                }
            }
            loops.push(cycle);
        }
        loops
    }

    /// Connected components: a component id per vertex (numbered by smallest vertex) and the
    /// number of components.
    pub fn connected_components(&self) -> (Vec<u32>, usize) {
        let n = self.num_vertices;
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn find(p: &mut [u32], mut i: u32) -> u32 {
            while p[i as usize] != i {
                p[i as usize] = p[p[i as usize] as usize];
                i = p[i as usize];
            }
            i
        }
        for &[a, b] in &self.edges {
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
        let mut label = vec![u32::MAX; n];
        let mut ids = vec![u32::MAX; n];
        let mut count = 0u32;
        for v in 0..n as u32 {
            let r = find(&mut parent, v) as usize;
            if ids[r] == u32::MAX {
                ids[r] = count;
                count += 1;
            }
            label[v as usize] = ids[r];
        }
        (label, count as usize)
    }

    /// Euler characteristic V − E + F.
    pub fn euler_characteristic(&self) -> i64 {
        self.num_vertices as i64 - self.edges.len() as i64 + self.face_edges.len() as i64
    }
}

/// Keeps the largest set of cells (triangles, tetrahedra, …) connected through shared vertices
/// and renumbers the vertices they use in order of first use. Ties go to the component with the
/// smallest vertex id, so the result is deterministic. Vertex ids must be in range.
pub fn largest_component<const N: usize>(
    vertices: Vec<Point3>,
    cells: Vec<[u32; N]>,
) -> (Vec<Point3>, Vec<[u32; N]>) {
    fn find(parent: &mut [u32], mut a: u32) -> u32 {
        while parent[a as usize] != a {
            parent[a as usize] = parent[parent[a as usize] as usize];
            a = parent[a as usize];
        }
        a
    }
    // Union into the smaller root: a component's root is its smallest vertex id.
    let mut parent: Vec<u32> = (0..vertices.len() as u32).collect();
    for c in &cells {
        for k in 1..N {
            let (a, b) = (find(&mut parent, c[0]), find(&mut parent, c[k]));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    let mut count = vec![0usize; vertices.len()];
    for c in &cells {
        if N > 0 {
            count[find(&mut parent, c[0]) as usize] += 1;
        }
    }
    let root = (0..vertices.len())
        .max_by_key(|&r| (count[r], std::cmp::Reverse(r)))
        .unwrap_or(0) as u32;
    let mut remap = vec![u32::MAX; vertices.len()];
    let mut kept_vertices = Vec::new();
    let mut kept_cells = Vec::new();
    for c in &cells {
        if N == 0 || find(&mut parent, c[0]) != root {
            continue;
        }
        kept_cells.push(c.map(|i| {
            if remap[i as usize] == u32::MAX {
                remap[i as usize] = kept_vertices.len() as u32;
                kept_vertices.push(vertices[i as usize]);
            }
            remap[i as usize]
        }));
    }
    (kept_vertices, kept_cells)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Point3;
    use crate::mesh::tests::tetrahedron;

    #[test]
    fn tetrahedron_topology() {
        let t = tetrahedron();
        let topo = Topology::new(&t);
        assert_eq!(topo.edges().len(), 6);
        assert_eq!(topo.euler_characteristic(), 2);
        assert!(topo.boundary_edges().is_empty());
        assert!(topo.boundary_loops(&t).is_empty());
        assert_eq!(topo.neighbors(0), &[1, 2, 3]);
        assert_eq!(topo.connected_components().1, 1);
        for (f, tri) in t.faces().iter().enumerate() {
            for k in 0..3 {
                let e = topo.edges()[topo.face_edges()[f][k] as usize];
                let (u, v) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                assert_eq!(e, [u.min(v), u.max(v)]);
            }
        }
        assert_eq!(topo.edge_index(3, 1), topo.edge_index(1, 3));
        assert_eq!(topo.edge_index(1, 1), None);
    }

    #[test]
    fn square_has_one_boundary_loop_and_two_triangles_two_components() {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(5.0, 0.0, 0.0),
            Point3::new(6.0, 0.0, 0.0),
            Point3::new(5.0, 1.0, 0.0),
        ];
        let m = TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]]).unwrap();
        let topo = Topology::new(&m);
        let loops = topo.boundary_loops(&m);
        assert_eq!(loops, vec![vec![0, 1, 2, 3], vec![4, 5, 6]]);
        let (label, count) = topo.connected_components();
        assert_eq!(count, 2);
        assert_eq!(label, vec![0, 0, 0, 0, 1, 1, 1]);
        // Square: V − E + F = 4 − 5 + 2 = 1 (a disk); triangle: 3 − 3 + 1 = 1.
        assert_eq!(topo.euler_characteristic(), 2);
    }

    #[test]
    fn largest_component_keeps_the_bigger_piece_renumbered() {
        let p = |x: f64| Point3::new(x, 0.0, 0.0);
        let vertices = vec![p(0.0), p(1.0), p(2.0), p(3.0), p(4.0), p(5.0), p(6.0)];
        // Component {4, 5, 6, 3} has two triangles, {0, 1, 2} one.
        let cells = vec![[0, 1, 2], [4, 5, 6], [3, 4, 6]];
        let (v, c) = largest_component(vertices, cells);
        assert_eq!(v, vec![p(4.0), p(5.0), p(6.0), p(3.0)]);
        assert_eq!(c, vec![[0, 1, 2], [3, 0, 2]]);
        let (v, c) = largest_component::<3>(Vec::new(), Vec::new());
        assert!(v.is_empty() && c.is_empty());
    }
}
