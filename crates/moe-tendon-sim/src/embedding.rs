//! Barycentric embedding of points (surface vertices, tendon route points) in a tet mesh: each
//! embedded point follows its element as `x = Σ_k w_k x_{n_k}` (SOFA's barycentric mapping).

use moe_geom::{Point3, Real, Vector3};

use crate::tetmesh::{TetMesh, barycentric};

/// Tolerance on the smallest barycentric coordinate for a point to count as inside an element.
pub const INSIDE_TOLERANCE: Real = 1e-9;

/// One embedded point: its element, the element's nodes and the barycentric weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Embedded {
    /// Index of the element.
    pub tet: u32,
    /// The element's four node ids.
    pub nodes: [u32; 4],
    /// Barycentric weights (sum 1). Negative entries mean the point lies outside the element and
    /// is extrapolated from it.
    pub weights: [Real; 4],
}

impl Embedded {
    /// Position of the point for the node positions `x`.
    #[inline]
    pub fn position(&self, x: &[Point3]) -> Point3 {
        let mut p = Vector3::zeros();
        for k in 0..4 {
            p += x[self.nodes[k] as usize].coords * self.weights[k];
        }
        Point3::from(p)
    }

    /// Velocity of the point for the node velocities `v`.
    #[inline]
    pub fn velocity(&self, v: &[Vector3]) -> Vector3 {
        let mut p = Vector3::zeros();
        for k in 0..4 {
            p += v[self.nodes[k] as usize] * self.weights[k];
        }
        p
    }
}

/// Where each of a list of points sits in a tet mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct Embedding {
    points: Vec<Embedded>,
    distances_m: Vec<Real>,
}

impl Embedding {
    /// Embeds `points` (rest positions, same frame as `mesh`): each point goes to the element
    /// that contains it (the one whose smallest barycentric coordinate is largest), or, for a
    /// point outside the mesh, to the nearest element, with unclamped (extrapolated) weights so
    /// that the rest position is reproduced exactly.
    pub fn new(mesh: &TetMesh, points: &[Point3]) -> Self {
        let locator = Locator::new(mesh);
        let mut out = Vec::with_capacity(points.len());
        let mut distances_m = Vec::with_capacity(points.len());
        for p in points {
            let (tet, dist) = locator.locate(mesh, p);
            let weights = mesh.barycentric(tet, p);
            out.push(Embedded {
                tet: tet as u32,
                nodes: mesh.tets()[tet],
                weights,
            });
            distances_m.push(dist);
        }
        Self {
            points: out,
            distances_m,
        }
    }

    /// The embedded points.
    pub fn points(&self) -> &[Embedded] {
        &self.points
    }

    /// Number of embedded points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when no point is embedded.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Distance from each rest point to its element (0 inside), metres: how far it is
    /// extrapolated.
    pub fn distances_m(&self) -> &[Real] {
        &self.distances_m
    }

    /// Positions of all embedded points for node positions `x`.
    pub fn positions(&self, x: &[Point3]) -> Vec<Point3> {
        self.points.iter().map(|e| e.position(x)).collect()
    }

    /// Writes the positions of all embedded points for node positions `x` into `out`.
    pub fn positions_into(&self, x: &[Point3], out: &mut Vec<Point3>) {
        out.clear();
        out.extend(self.points.iter().map(|e| e.position(x)));
    }
}

/// Approximate distance from `p` to an element with barycentric coordinates `w`: the distance
/// to the point whose coordinates are `w` clamped to be non-negative and renormalised (exact
/// inside, 0; a close upper bound outside).
fn distance_to_tet(c: &[Point3; 4], w: &[Real; 4], p: &Point3) -> Real {
    if w.iter().all(|&x| x >= -INSIDE_TOLERANCE) {
        return 0.0;
    }
    let clamped = w.map(|x| x.max(0.0));
    let s: Real = clamped.iter().sum();
    let q = (0..4).fold(Vector3::zeros(), |acc, k| {
        acc + c[k].coords * (clamped[k] / s)
    });
    (q - p.coords).norm()
}

/// A uniform grid over element bounding boxes for point location.
pub(crate) struct Locator {
    origin: Point3,
    cell: Real,
    dims: [usize; 3],
    bins: Vec<Vec<u32>>,
}

impl Locator {
    pub(crate) fn new(mesh: &TetMesh) -> Self {
        let bb = moe_geom::Aabb::from_points(mesh.nodes()).expect("validated mesh is non-empty");
        let mean_edge = mesh.volume().cbrt() / (mesh.num_tets() as Real / 6.0).cbrt();
        let cell = mean_edge.max(bb.diagonal() * 1e-6);
        let ext = bb.extents();
        let dims = [0, 1, 2].map(|k| ((ext[k] / cell).floor() as usize + 1).min(1024));
        let mut bins = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let me = Self {
            origin: bb.min,
            cell,
            dims,
            bins: Vec::new(),
        };
        for (t, tet) in mesh.tets().iter().enumerate() {
            let pts = tet.map(|i| mesh.nodes()[i as usize]);
            let lo = me.cell_of(&pts.iter().fold(pts[0], |a, b| a.inf(b)));
            let hi = me.cell_of(&pts.iter().fold(pts[0], |a, b| a.sup(b)));
            for k in lo[2]..=hi[2] {
                for j in lo[1]..=hi[1] {
                    for i in lo[0]..=hi[0] {
                        bins[me.bin(i, j, k)].push(t as u32);
                    }
                }
            }
        }
        Self { bins, ..me }
    }

    fn cell_of(&self, p: &Point3) -> [usize; 3] {
        [0, 1, 2].map(|k| {
            let c = ((p[k] - self.origin[k]) / self.cell).floor();
            (c.max(0.0) as usize).min(self.dims[k] - 1)
        })
    }

    fn bin(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// The element containing `p` (largest smallest barycentric coordinate among the
    /// candidates), else the nearest element; returns it with the distance to it.
    pub(crate) fn locate(&self, mesh: &TetMesh, p: &Point3) -> (usize, Real) {
        let c = self.cell_of(p);
        let inside_grid = (0..3).all(|k| {
            let rel = (p[k] - self.origin[k]) / self.cell;
            rel >= 0.0 && rel < self.dims[k] as Real
        });
        if inside_grid {
            let mut best: Option<(usize, Real)> = None;
            for &t in &self.bins[self.bin(c[0], c[1], c[2])] {
                let w = mesh.barycentric(t as usize, p);
                let m = w.iter().copied().fold(Real::INFINITY, Real::min);
                if best.is_none_or(|(_, bm)| m > bm) {
                    best = Some((t as usize, m));
                }
            }
            if let Some((t, m)) = best
                && m >= -INSIDE_TOLERANCE
            {
                return (t, 0.0);
            }
        }
        // Outside every element: the nearest one (exhaustive; only for the few points outside).
        let mut best = (0usize, Real::INFINITY);
        for t in 0..mesh.num_tets() {
            let corners = mesh.corners(t);
            let w = barycentric(&corners, p);
            let d = distance_to_tet(&corners, &w, p);
            if d < best.1 {
                best = (t, d);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_points_reproduce_rest_and_follow_affine_motion() {
        let mesh =
            TetMesh::box_grid(Point3::origin(), Point3::new(1.0, 2.0, 1.0), [2, 3, 2]).unwrap();
        let pts = vec![
            Point3::new(0.1, 0.1, 0.1),
            Point3::new(0.99, 1.99, 0.5),
            Point3::new(0.5, 1.0, 0.5),
            Point3::new(1.2, 1.0, 0.5), // outside: extrapolated
        ];
        let emb = Embedding::new(&mesh, &pts);
        assert_eq!(emb.distances_m()[..3], [0.0, 0.0, 0.0]);
        // The clamped-barycentric distance is an upper bound, exact for the closest face.
        let d = emb.distances_m()[3];
        assert!((0.2 - 1e-9..0.3).contains(&d), "{d}");
        for (e, p) in emb.points().iter().zip(&pts) {
            assert!((e.position(mesh.nodes()) - p).norm() < 1e-12);
        }
        let a = moe_geom::Matrix3::new(1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.0, 0.05, 1.2);
        let moved: Vec<Point3> = mesh
            .nodes()
            .iter()
            .map(|x| Point3::from(a * x.coords + Vector3::new(0.5, -1.0, 2.0)))
            .collect();
        for (e, p) in emb.points().iter().zip(&pts) {
            let expected = a * p.coords + Vector3::new(0.5, -1.0, 2.0);
            assert!((e.position(&moved).coords - expected).norm() < 1e-12);
        }
    }
}
