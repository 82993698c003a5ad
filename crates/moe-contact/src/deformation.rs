//! Local measures of how a finger's surface deformed from rest, per vertex, as network input.
//!
//! A press dents the surface and flattens or compresses it around the contact; bending by the
//! tendons curves the whole finger smoothly. Three measures separate the two, each zero at rest
//! and unchanged by any rigid motion of the finger (so they do not depend on the frame the
//! positions are given in):
//!
//! 0. the change in normal curvature at the vertex: `((xᵢ − x̄ᵢ)·nᵢ − (Xᵢ − X̄ᵢ)·Nᵢ) / sᵢ`, with
//!    `x̄ᵢ` the mean of the one-ring, `nᵢ` the area-weighted unit normal, capitals the rest mesh,
//!    and `sᵢ` the rest one-ring's mean edge length (a dent on an outward-oriented surface is
//!    negative);
//! 1. the same change averaged over the vertex and its one-ring (a two-ring smoothing, which
//!    keeps a patch's signal where single-vertex noise averages out);
//! 2. the areal strain of the one-ring: `Aᵢ / A⁰ᵢ − 1`, with `Aᵢ` the area of the faces around
//!    the vertex.
//!
//! A learnability probe on simulated presses found that such features (displacement along the
//! rest normal, the two-ring change in curvature, position along the finger) let a per-vertex
//! classifier find contact patches that the positions alone make hard to learn.

use moe_geom::{Point3, Topology, TriMesh, Vector3};

/// The rest-state quantities of one finger mesh that the measures are taken against.
#[derive(Debug, Clone)]
pub(crate) struct DeformationFeatures {
    faces: Vec<[u32; 3]>,
    /// One-rings of the mesh.
    topology: Topology,
    /// `1 / sᵢ`.
    inv_scale: Vec<f64>,
    /// `(Xᵢ − X̄ᵢ)·Nᵢ` at rest.
    rest_offset: Vec<f64>,
    /// `1 / A⁰ᵢ` (0 for a vertex without area, whose strain is then 0).
    inv_rest_area: Vec<f64>,
}

impl DeformationFeatures {
    /// The rest quantities of `mesh` (a validated finger mesh).
    pub(crate) fn new(mesh: &TriMesh) -> Self {
        let topology = Topology::new(mesh);
        let rest = mesh.vertices();
        let inv_scale = (0..mesh.num_vertices())
            .map(|v| {
                let nb = topology.neighbors(v);
                let mean = nb
                    .iter()
                    .map(|&j| (rest[j as usize] - rest[v]).norm())
                    .sum::<f64>()
                    / nb.len().max(1) as f64;
                if mean > 0.0 { 1.0 / mean } else { 0.0 }
            })
            .collect();
        let mut this = Self {
            faces: mesh.faces().to_vec(),
            topology,
            inv_scale,
            rest_offset: Vec::new(),
            inv_rest_area: Vec::new(),
        };
        let (offset, area) = this.offsets_and_areas(rest);
        this.rest_offset = offset;
        this.inv_rest_area = area
            .iter()
            .map(|&a| if a > 0.0 { 1.0 / a } else { 0.0 })
            .collect();
        this
    }

    /// Number of vertices of the mesh.
    pub(crate) fn num_vertices(&self) -> usize {
        self.inv_scale.len()
    }

    /// `(xᵢ − x̄ᵢ)·nᵢ` and `Aᵢ` of every vertex of `x`.
    fn offsets_and_areas(&self, x: &[Point3]) -> (Vec<f64>, Vec<f64>) {
        let n = self.num_vertices();
        let mut normal = vec![Vector3::zeros(); n];
        let mut area = vec![0.0; n];
        for f in &self.faces {
            let [a, b, c] = f.map(|v| x[v as usize]);
            let w = (b - a).cross(&(c - a)); // |w| = 2·area
            let half = 0.5 * w.norm();
            for &v in f {
                normal[v as usize] += w;
                area[v as usize] += half;
            }
        }
        let offset = (0..n)
            .map(|v| {
                let nb = self.topology.neighbors(v);
                let norm = normal[v].norm();
                if nb.is_empty() || norm == 0.0 {
                    return 0.0;
                }
                let mean = nb
                    .iter()
                    .fold(Vector3::zeros(), |s, &j| s + x[j as usize].coords)
                    / nb.len() as f64;
                (x[v].coords - mean).dot(&normal[v]) / norm
            })
            .collect();
        (offset, area)
    }

    /// The three measures of every vertex of `deformed` (one per rest vertex, same order).
    pub(crate) fn compute(&self, deformed: &[Point3]) -> Vec<[f64; 3]> {
        debug_assert_eq!(deformed.len(), self.num_vertices());
        let (offset, area) = self.offsets_and_areas(deformed);
        let curvature: Vec<f64> = offset
            .iter()
            .zip(&self.rest_offset)
            .zip(&self.inv_scale)
            .map(|((o, r), s)| (o - r) * s)
            .collect();
        (0..self.num_vertices())
            .map(|v| {
                let nb = self.topology.neighbors(v);
                let smoothed = (curvature[v]
                    + nb.iter().map(|&j| curvature[j as usize]).sum::<f64>())
                    / (nb.len() + 1) as f64;
                let strain = if self.inv_rest_area[v] > 0.0 {
                    area[v] * self.inv_rest_area[v] - 1.0
                } else {
                    0.0
                };
                [curvature[v], smoothed, strain]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::{Iso3, shapes};

    fn sphere() -> TriMesh {
        shapes::icosphere(3, 0.01)
    }

    #[test]
    fn zero_at_rest_and_under_rigid_motion() {
        let mesh = sphere();
        let features = DeformationFeatures::new(&mesh);
        let motion = Iso3::new(Vector3::new(0.3, -0.1, 0.2), Vector3::new(0.4, -1.1, 0.7));
        for x in [
            mesh.vertices().to_vec(),
            mesh.vertices().iter().map(|p| motion * p).collect(),
        ] {
            for (v, m) in features.compute(&x).iter().enumerate() {
                assert!(m.iter().all(|c| c.abs() < 1e-9), "vertex {v}: {m:?}");
            }
        }
    }

    #[test]
    fn a_dent_is_negative_curvature_and_compression_is_negative_strain() {
        let mesh = sphere();
        let features = DeformationFeatures::new(&mesh);
        // Push the vertex at the north pole inward by a tenth of the radius.
        let top = (0..mesh.num_vertices())
            .max_by(|&a, &b| mesh.vertices()[a].z.total_cmp(&mesh.vertices()[b].z))
            .expect("vertices");
        let mut dented = mesh.vertices().to_vec();
        dented[top].z -= 0.001;
        let m = features.compute(&dented);
        assert!(m[top][0] < -0.1, "{:?}", m[top]);
        assert!(m[top][1] < 0.0 && m[top][1] > m[top][0], "{:?}", m[top]);
        // Far from the dent nothing changed.
        let bottom = (0..mesh.num_vertices())
            .min_by(|&a, &b| mesh.vertices()[a].z.total_cmp(&mesh.vertices()[b].z))
            .expect("vertices");
        assert_eq!(m[bottom], [0.0, 0.0, 0.0]);
        // A uniform shrink by 10 % keeps the shape (curvature offsets scale with the size, the
        // measure divides by the rest edge length: -10 % of the rest offset) and strains the
        // area by 0.9² − 1.
        let shrunk: Vec<Point3> = mesh.vertices().iter().map(|p| p * 0.9).collect();
        let m = features.compute(&shrunk);
        for (v, [_, _, strain]) in m.iter().enumerate() {
            assert!(
                (strain - (0.81 - 1.0)).abs() < 1e-12,
                "vertex {v}: {strain}"
            );
        }
    }
}
