//! Validated triangle meshes.

use std::collections::HashMap;

use crate::error::GeomError;
use crate::math::{Point3, Real, Vector3, is_finite_point};

/// Relative area below which a face counts as degenerate: `area <= DEGENERATE_REL_AREA · diag²`,
/// where `diag` is the bounding-box diagonal of the mesh.
pub const DEGENERATE_REL_AREA: Real = 1e-14;

/// An axis-aligned bounding box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Componentwise minimum.
    pub min: Point3,
    /// Componentwise maximum.
    pub max: Point3,
}

impl Aabb {
    /// The box around a non-empty set of points; `None` for an empty set.
    pub fn from_points(points: &[Point3]) -> Option<Self> {
        let first = points.first()?;
        let (mut min, mut max) = (*first, *first);
        for p in points {
            min = min.inf(p);
            max = max.sup(p);
        }
        Some(Self { min, max })
    }

    /// Edge lengths of the box.
    pub fn extents(&self) -> Vector3 {
        self.max - self.min
    }

    /// Length of the box diagonal.
    pub fn diagonal(&self) -> Real {
        self.extents().norm()
    }

    /// Centre of the box.
    pub fn center(&self) -> Point3 {
        nalgebra::center(&self.min, &self.max)
    }
}

/// A triangle mesh whose construction checked that it is usable by every algorithm of the
/// workspace: finite coordinates, faces with three distinct in-range vertices and non-zero area,
/// edge-manifold with consistently oriented faces, vertex-manifold, and no isolated vertices.
///
/// Boundaries are allowed (see [`TriMesh::require_closed`] for algorithms that need a closed
/// surface). Faces are counter-clockwise seen from outside for closed meshes made by this crate.
#[derive(Debug, Clone, PartialEq)]
pub struct TriMesh {
    vertices: Vec<Point3>,
    faces: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Builds and validates a mesh.
    ///
    /// # Errors
    /// The first problem found, naming the offending vertex, face or edge (see [`GeomError`]).
    pub fn new(vertices: Vec<Point3>, faces: Vec<[u32; 3]>) -> Result<Self, GeomError> {
        validate(&vertices, &faces)?;
        Ok(Self { vertices, faces })
    }

    /// Builds a mesh from "triangle soup" input such as STL, where each corner repeats its vertex:
    /// vertices closer than `tolerance` are merged (first occurrence wins, order preserved), faces
    /// that collapse are dropped, and the result is validated.
    ///
    /// # Errors
    /// As [`TriMesh::new`]; also [`GeomError::InvalidParameter`] for a negative or non-finite
    /// tolerance.
    pub fn welded(
        vertices: &[Point3],
        faces: &[[u32; 3]],
        tolerance: Real,
    ) -> Result<Self, GeomError> {
        let (v, f) = weld(vertices, faces, tolerance)?;
        Self::new(v, f)
    }

    /// The same topology with new vertex positions (a deformed copy).
    ///
    /// # Errors
    /// [`GeomError::LengthMismatch`] for a wrong count, [`GeomError::NonFiniteVertex`] for NaN.
    /// Positions are not checked for degenerate faces: a deformed mesh may legitimately squash a
    /// triangle.
    pub fn with_vertices(&self, vertices: Vec<Point3>) -> Result<Self, GeomError> {
        if vertices.len() != self.vertices.len() {
            return Err(GeomError::LengthMismatch {
                what: "deformed vertices",
                expected: self.vertices.len(),
                got: vertices.len(),
            });
        }
        if let Some(vertex) = vertices.iter().position(|p| !is_finite_point(p)) {
            return Err(GeomError::NonFiniteVertex { vertex });
        }
        Ok(Self {
            vertices,
            faces: self.faces.clone(),
        })
    }

    /// Vertex positions.
    pub fn vertices(&self) -> &[Point3] {
        &self.vertices
    }

    /// Faces as vertex-index triples.
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// A digest that identifies the mesh: 64-bit FNV-1a over the vertex count, the face count,
    /// every coordinate in nanometres (metres × 10⁹, rounded; vertex order, x y z) and every
    /// face index, as 16 hex digits. Meshes equal to the nanometre (same order) have equal
    /// digests; a vertex moved by more, a reordered vertex or a changed face changes it. A contact model's card records its finger's digest,
    /// so that the model is not run on another finger by mistake.
    pub fn digest(&self) -> String {
        const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
        const PRIME: u64 = 0x0000_0100_0000_01b3;
        let mut h = OFFSET;
        let mut eat = |bytes: &[u8]| {
            for &b in bytes {
                h ^= u64::from(b);
                h = h.wrapping_mul(PRIME);
            }
        };
        eat(&(self.vertices.len() as u64).to_le_bytes());
        eat(&(self.faces.len() as u64).to_le_bytes());
        for p in &self.vertices {
            for c in [p.x, p.y, p.z] {
                // Rounded to the nanometre, so that the last bits of another platform's
                // trigonometry do not change it (and -0 is +0).
                eat(&((c * 1e9).round() as i64).to_le_bytes());
            }
        }
        for f in &self.faces {
            for i in f {
                eat(&i.to_le_bytes());
            }
        }
        format!("{h:016x}")
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of faces.
    pub fn num_faces(&self) -> usize {
        self.faces.len()
    }

    /// Splits the mesh into its vertices and faces.
    pub fn into_parts(self) -> (Vec<Point3>, Vec<[u32; 3]>) {
        (self.vertices, self.faces)
    }

    /// The three corner positions of face `f`.
    pub fn triangle(&self, f: usize) -> [Point3; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Area of every face.
    pub fn face_areas(&self) -> Vec<Real> {
        (0..self.faces.len())
            .map(|f| triangle_area(&self.triangle(f)))
            .collect()
    }

    /// Total surface area.
    pub fn surface_area(&self) -> Real {
        self.face_areas().iter().sum()
    }

    /// Unit normal of every face (right-handed with the face's vertex order).
    pub fn face_normals(&self) -> Vec<Vector3> {
        (0..self.faces.len())
            .map(|f| {
                let [a, b, c] = self.triangle(f);
                (b - a).cross(&(c - a)).normalize()
            })
            .collect()
    }

    /// Area-weighted unit vertex normals.
    pub fn vertex_normals(&self) -> Vec<Vector3> {
        let mut n = vec![Vector3::zeros(); self.vertices.len()];
        for (f, face) in self.faces.iter().enumerate() {
            let [a, b, c] = self.triangle(f);
            let w = (b - a).cross(&(c - a)); // |w| = 2·area
            for &v in face {
                n[v as usize] += w;
            }
        }
        n.into_iter().map(|v| v.normalize()).collect()
    }

    /// Signed enclosed volume (positive for a closed, outward-oriented mesh).
    pub fn signed_volume(&self) -> Real {
        let mut six_v = 0.0;
        for f in 0..self.faces.len() {
            let [a, b, c] = self.triangle(f);
            six_v += a.coords.dot(&b.coords.cross(&c.coords));
        }
        six_v / 6.0
    }

    /// Bounding box of the vertices.
    pub fn aabb(&self) -> Aabb {
        Aabb::from_points(&self.vertices).expect("a validated mesh has vertices")
    }

    /// Checks that the mesh has no boundary edge.
    ///
    /// # Errors
    /// [`GeomError::OpenMesh`] naming the first boundary edge.
    pub fn require_closed(&self) -> Result<(), GeomError> {
        match crate::topology::Topology::new(self)
            .boundary_edges()
            .first()
        {
            Some(&[a, b]) => Err(GeomError::OpenMesh { a, b }),
            None => Ok(()),
        }
    }

    /// Reverses every face's orientation.
    pub fn flipped(&self) -> Self {
        let faces = self.faces.iter().map(|&[a, b, c]| [a, c, b]).collect();
        Self {
            vertices: self.vertices.clone(),
            faces,
        }
    }
}

/// Area of a triangle.
pub fn triangle_area(t: &[Point3; 3]) -> Real {
    0.5 * (t[1] - t[0]).cross(&(t[2] - t[0])).norm()
}

fn validate(vertices: &[Point3], faces: &[[u32; 3]]) -> Result<(), GeomError> {
    if vertices.is_empty() || faces.is_empty() {
        return Err(GeomError::EmptyMesh {
            vertices: vertices.len(),
            faces: faces.len(),
        });
    }
    if let Some(vertex) = vertices.iter().position(|p| !is_finite_point(p)) {
        return Err(GeomError::NonFiniteVertex { vertex });
    }
    let n = vertices.len();
    for (face, tri) in faces.iter().enumerate() {
        for (k, &index) in tri.iter().enumerate() {
            if index as usize >= n {
                return Err(GeomError::FaceIndexOutOfRange {
                    face,
                    index,
                    len: n,
                });
            }
            if tri[..k].contains(&index) {
                return Err(GeomError::RepeatedFaceIndex { face, index });
            }
        }
    }
    let diag = Aabb::from_points(vertices).map_or(0.0, |b| b.diagonal());
    let min_area = DEGENERATE_REL_AREA * diag * diag;
    for (face, &[a, b, c]) in faces.iter().enumerate() {
        let area = triangle_area(&[
            vertices[a as usize],
            vertices[b as usize],
            vertices[c as usize],
        ]);
        if area <= min_area {
            return Err(GeomError::DegenerateFace { face, area });
        }
    }
    // Directed half-edges: each must appear at most once, and an undirected edge in at most two
    // faces, traversed in opposite directions.
    let mut directed: HashMap<(u32, u32), usize> = HashMap::with_capacity(faces.len() * 3);
    let mut undirected: HashMap<(u32, u32), usize> = HashMap::with_capacity(faces.len() * 3);
    for &[a, b, c] in faces {
        for (u, v) in [(a, b), (b, c), (c, a)] {
            *directed.entry((u, v)).or_insert(0) += 1;
            *undirected.entry((u.min(v), u.max(v))).or_insert(0) += 1;
        }
    }
    let mut over: Vec<_> = undirected.iter().filter(|&(_, &c)| c > 2).collect();
    over.sort_unstable();
    if let Some(&(&(a, b), &faces)) = over.first() {
        return Err(GeomError::NonManifoldEdge { a, b, faces });
    }
    let mut same_dir: Vec<_> = directed
        .iter()
        .filter(|&(_, &c)| c > 1)
        .map(|(&e, _)| e)
        .collect();
    same_dir.sort_unstable();
    if let Some(&(u, v)) = same_dir.first() {
        return Err(GeomError::InconsistentOrientation {
            a: u.min(v),
            b: u.max(v),
        });
    }
    // Isolated vertices and vertex fans.
    let mut incident: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (f, tri) in faces.iter().enumerate() {
        for &v in tri {
            incident[v as usize].push(f);
        }
    }
    for (vertex, inc) in incident.iter().enumerate() {
        if inc.is_empty() {
            return Err(GeomError::IsolatedVertex { vertex });
        }
        let fans = count_fans(vertex as u32, inc, faces);
        if fans > 1 {
            return Err(GeomError::NonManifoldVertex { vertex, fans });
        }
    }
    Ok(())
}

/// Number of edge-connected fans among the faces around vertex `v`.
fn count_fans(v: u32, incident: &[usize], faces: &[[u32; 3]]) -> usize {
    // Union faces that share an edge (v, w).
    let mut parent: Vec<usize> = (0..incident.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    let mut by_other: HashMap<u32, usize> = HashMap::new();
    for (k, &f) in incident.iter().enumerate() {
        for &w in &faces[f] {
            if w == v {
                continue;
            }
            if let Some(&j) = by_other.get(&w) {
                let (ra, rb) = (find(&mut parent, k), find(&mut parent, j));
                parent[ra] = rb;
            } else {
                by_other.insert(w, k);
            }
        }
    }
    (0..incident.len())
        .filter(|&k| find(&mut parent, k) == k)
        .count()
}

/// Merges vertices closer than `tolerance` (grid hashing, first occurrence wins) and drops faces
/// that collapse. Returns the new vertices and faces, not validated.
///
/// # Errors
/// [`GeomError::InvalidParameter`] for a bad tolerance, [`GeomError::FaceIndexOutOfRange`] and
/// [`GeomError::NonFiniteVertex`] for input that cannot be welded at all.
pub fn weld(
    vertices: &[Point3],
    faces: &[[u32; 3]],
    tolerance: Real,
) -> Result<(Vec<Point3>, Vec<[u32; 3]>), GeomError> {
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        return Err(GeomError::InvalidParameter {
            name: "weld tolerance",
            value: tolerance,
            reason: "must be finite and non-negative",
        });
    }
    if let Some(vertex) = vertices.iter().position(|p| !is_finite_point(p)) {
        return Err(GeomError::NonFiniteVertex { vertex });
    }
    let cell = if tolerance > 0.0 { tolerance } else { 1.0 };
    let key = |p: &Point3| -> [i64; 3] {
        if tolerance > 0.0 {
            [
                (p.x / cell).floor() as i64,
                (p.y / cell).floor() as i64,
                (p.z / cell).floor() as i64,
            ]
        } else {
            [
                p.x.to_bits() as i64,
                p.y.to_bits() as i64,
                p.z.to_bits() as i64,
            ]
        }
    };
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    let mut remap = Vec::with_capacity(vertices.len());
    let mut out: Vec<Point3> = Vec::new();
    for p in vertices {
        let k = key(p);
        let mut found = None;
        if tolerance > 0.0 {
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(ids) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz])
                            && let Some(&id) = ids
                                .iter()
                                .find(|&&id| (out[id as usize] - p).norm() <= tolerance)
                        {
                            found = Some(id);
                            break 'search;
                        }
                    }
                }
            }
        } else if let Some(ids) = grid.get(&k) {
            found = ids.first().copied();
        }
        let id = found.unwrap_or_else(|| {
            let id = out.len() as u32;
            out.push(*p);
            grid.entry(k).or_default().push(id);
            id
        });
        remap.push(id);
    }
    let mut new_faces = Vec::with_capacity(faces.len());
    for (face, tri) in faces.iter().enumerate() {
        let mut t = [0u32; 3];
        for (k, &i) in tri.iter().enumerate() {
            t[k] = *remap
                .get(i as usize)
                .ok_or(GeomError::FaceIndexOutOfRange {
                    face,
                    index: i,
                    len: vertices.len(),
                })?;
        }
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            new_faces.push(t);
        }
    }
    Ok((out, new_faces))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A unit tetrahedron, outward oriented.
    pub(crate) fn tetrahedron() -> TriMesh {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let f = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        TriMesh::new(v, f).unwrap()
    }

    #[test]
    fn the_digest_tells_meshes_apart() {
        let t = tetrahedron();
        assert_eq!(t.digest(), tetrahedron().digest());
        assert_eq!(t.digest().len(), 16);
        let mut moved = t.vertices().to_vec();
        moved[2].x += 1e-8;
        let moved = TriMesh::new(moved, t.faces().to_vec()).unwrap();
        assert_ne!(moved.digest(), t.digest());
        let mut faces = t.faces().to_vec();
        faces.swap(0, 1);
        let reordered = TriMesh::new(t.vertices().to_vec(), faces).unwrap();
        assert_ne!(reordered.digest(), t.digest());
        // Below a nanometre (another platform's last bits) the digest holds.
        let mut jittered = t.vertices().to_vec();
        jittered[1].y += 1e-13;
        let jittered = TriMesh::new(jittered, t.faces().to_vec()).unwrap();
        assert_eq!(jittered.digest(), t.digest());
        // -0 is +0.
        let mut signed = t.vertices().to_vec();
        for p in &mut signed {
            p.x = if p.x == 0.0 { -0.0 } else { p.x };
        }
        assert_eq!(
            TriMesh::new(signed, t.faces().to_vec()).unwrap().digest(),
            t.digest()
        );
    }

    #[test]
    fn tetrahedron_measures() {
        let t = tetrahedron();
        assert!((t.signed_volume() - 1.0 / 6.0).abs() < 1e-15);
        let expected_area = 1.5 + 3f64.sqrt() / 2.0;
        assert!((t.surface_area() - expected_area).abs() < 1e-14);
        t.require_closed().unwrap();
        assert!(t.flipped().signed_volume() < 0.0);
    }

    #[test]
    fn validation_names_the_offending_element() {
        let t = tetrahedron();
        let (mut v, f) = t.clone().into_parts();
        v[2].y = Real::NAN;
        assert_eq!(
            TriMesh::new(v, f.clone()),
            Err(GeomError::NonFiniteVertex { vertex: 2 })
        );

        let (v, mut f2) = t.clone().into_parts();
        f2[3] = [1, 2, 9];
        assert_eq!(
            TriMesh::new(v.clone(), f2),
            Err(GeomError::FaceIndexOutOfRange {
                face: 3,
                index: 9,
                len: 4
            })
        );
        let mut f3 = f.clone();
        f3[1] = [0, 1, 0];
        assert_eq!(
            TriMesh::new(v.clone(), f3),
            Err(GeomError::RepeatedFaceIndex { face: 1, index: 0 })
        );
        // Collinear face.
        let vc = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(2.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        assert!(matches!(
            TriMesh::new(vc, vec![[0, 1, 2], [0, 1, 3]]),
            Err(GeomError::DegenerateFace { face: 0, .. })
        ));
        // Three faces on one edge.
        let vn = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, -1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        assert_eq!(
            TriMesh::new(vn, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]),
            Err(GeomError::NonManifoldEdge {
                a: 0,
                b: 1,
                faces: 3
            })
        );
        // Isolated vertex.
        let (mut vi, fi) = t.clone().into_parts();
        vi.push(Point3::new(5.0, 5.0, 5.0));
        assert_eq!(
            TriMesh::new(vi, fi),
            Err(GeomError::IsolatedVertex { vertex: 4 })
        );
        // Flipped face.
        let mut ff = f.clone();
        ff[0] = [0, 1, 2];
        assert!(matches!(
            TriMesh::new(v.clone(), ff),
            Err(GeomError::InconsistentOrientation { .. })
        ));
        // Bow-tie: two triangles sharing only vertex 0.
        let vb = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
            Point3::new(-1.0, 0.0, 0.0),
            Point3::new(-1.0, -1.0, 0.0),
        ];
        assert_eq!(
            TriMesh::new(vb, vec![[0, 1, 2], [0, 3, 4]]),
            Err(GeomError::NonManifoldVertex { vertex: 0, fans: 2 })
        );
        assert!(matches!(
            TriMesh::new(vec![], vec![]),
            Err(GeomError::EmptyMesh { .. })
        ));
    }

    #[test]
    fn welding_soup_recovers_the_indexed_mesh() {
        let t = tetrahedron();
        let mut soup = Vec::new();
        let mut faces = Vec::new();
        for f in t.faces() {
            let base = soup.len() as u32;
            for &v in f {
                // Perturb well below the tolerance, as float STL writers do.
                soup.push(t.vertices()[v as usize] + Vector3::repeat(1e-9));
            }
            faces.push([base, base + 1, base + 2]);
        }
        let w = TriMesh::welded(&soup, &faces, 1e-6).unwrap();
        assert_eq!(w.num_vertices(), 4);
        assert_eq!(w.num_faces(), 4);
        w.require_closed().unwrap();
        assert!((w.signed_volume() - 1.0 / 6.0).abs() < 1e-8);
    }

    #[test]
    fn open_mesh_is_reported() {
        let (v, mut f) = tetrahedron().into_parts();
        f.pop();
        let open = TriMesh::new(v, f).unwrap();
        assert!(matches!(
            open.require_closed(),
            Err(GeomError::OpenMesh { .. })
        ));
    }
}
