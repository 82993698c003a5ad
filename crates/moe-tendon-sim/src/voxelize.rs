//! Volumetric discretisation of a closed surface: a background grid of cubes, each split into six
//! Kuhn tetrahedra, keeping the tetrahedra whose centroid lies inside the surface; the surface
//! vertices are then embedded in the kept tetrahedra (see [`crate::embedding`]).

use moe_geom::math::to_parry;
use moe_geom::{Point3, Real, TriMesh};
use parry3d_f64::math::Pose;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::{TriMesh as ParryTriMesh, TriMeshFlags};
use serde::{Deserialize, Serialize};

use crate::embedding::Embedding;
use crate::error::{SimError, require_positive};
use crate::tetmesh::{KUHN_TETS, TetMesh};

/// Resolution of the background grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VoxelParams {
    /// Edge length of the background cubes, metres. Default 0.0035: about 3 000 tetrahedra for
    /// the default finger (8 cm long, 2.2 cm wide at the base).
    pub cell_size_m: Real,
}

impl Default for VoxelParams {
    fn default() -> Self {
        Self {
            cell_size_m: 0.0035,
        }
    }
}

/// A tet mesh of a body's interior with its surface mesh embedded in it.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeMesh {
    /// The tetrahedra.
    pub tets: TetMesh,
    /// The surface vertices (in the surface mesh's order) embedded in `tets`.
    pub surface: Embedding,
    /// Accuracy of the discretisation.
    pub stats: VoxelStats,
}

/// How well a voxel tet mesh approximates its surface.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct VoxelStats {
    /// Tet-mesh volume divided by the volume enclosed by the surface.
    pub volume_ratio: Real,
    /// Largest distance from a surface vertex to the element it is embedded in, metres.
    pub max_embedding_distance_m: Real,
    /// Mean of that distance over the surface vertices, metres.
    pub mean_embedding_distance_m: Real,
    /// Number of surface vertices outside every element (extrapolated).
    pub outside_vertices: usize,
}

/// Tetrahedralises the interior of the closed surface `surface`.
///
/// The grid is aligned so that its lowest node layer lies in the plane of the surface's lowest
/// point (a finger's base plane z = 0) and is symmetric about the bounding box centre in x and y
/// (so that a body symmetric about its axis gets a symmetric grid). Only the largest
/// node-connected component of kept elements is returned.
///
/// # Errors
/// [`SimError::Geometry`] for an open surface (`GeomError::OpenMesh`; non-manifold surfaces are
/// already rejected by `TriMesh::new`), [`SimError::InvalidParameter`] for a bad cell size and
/// [`SimError::EmptyVolume`] when no element is kept.
pub fn voxelize(surface: &TriMesh, params: &VoxelParams) -> Result<VolumeMesh, SimError> {
    surface.require_closed()?;
    let h = params.cell_size_m;
    require_positive("cell_size_m", h)?;
    let enclosed = surface.signed_volume().abs();
    let bb = surface.aabb();
    let ext = bb.extents();
    let max_cells = 4_000_000.0;
    if (ext.x / h + 2.0) * (ext.y / h + 2.0) * (ext.z / h + 1.0) > max_cells {
        return Err(SimError::InvalidParameter {
            name: "cell_size_m",
            value: h,
            reason: "too small for the body: more than 4e6 background cells",
        });
    }
    let oriented = if surface.signed_volume() < 0.0 {
        surface.flipped()
    } else {
        surface.clone()
    };
    let parry = ParryTriMesh::with_flags(
        oriented.vertices().iter().map(to_parry).collect(),
        oriented.faces().to_vec(),
        TriMeshFlags::ORIENTED,
    )
    .map_err(|e| SimError::InvalidParameter {
        name: "surface mesh",
        value: Real::NAN,
        reason: if e.to_string().is_empty() {
            "rejected by the inside test"
        } else {
            "rejected by the inside test (degenerate triangles?)"
        },
    })?;
    let half = |e: Real| ((0.5 * e / h).ceil() as usize).max(1);
    let (hx, hy) = (half(ext.x), half(ext.y));
    let (nx, ny) = (2 * hx, 2 * hy);
    let nz = ((ext.z / h).ceil() as usize).max(1);
    let c = bb.center();
    let node_pos = |i: usize, j: usize, k: usize| {
        Point3::new(
            c.x + (i as Real - hx as Real) * h,
            c.y + (j as Real - hy as Real) * h,
            bb.min.z + k as Real * h,
        )
    };
    let grid_id = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let mut compact = vec![u32::MAX; (nx + 1) * (ny + 1) * (nz + 1)];
    let mut nodes = Vec::new();
    let mut tets = Vec::new();
    let identity = Pose::IDENTITY;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let corner = |q: usize| (i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1));
                for kt in KUHN_TETS {
                    let ids = kt.map(corner);
                    let centroid = Point3::from(
                        ids.iter()
                            .map(|&(a, b, d)| node_pos(a, b, d).coords)
                            .sum::<moe_geom::Vector3>()
                            / 4.0,
                    );
                    if !parry.contains_point(&identity, to_parry(&centroid)) {
                        continue;
                    }
                    let tet = ids.map(|(a, b, d)| {
                        let g = grid_id(a, b, d);
                        if compact[g] == u32::MAX {
                            compact[g] = nodes.len() as u32;
                            nodes.push(node_pos(a, b, d));
                        }
                        compact[g]
                    });
                    tets.push(tet);
                }
            }
        }
    }
    if tets.is_empty() {
        return Err(SimError::EmptyVolume { cell_size_m: h });
    }
    let (nodes, tets) = moe_geom::largest_component(nodes, tets);
    let tets = TetMesh::new(nodes, tets)?;
    let embedding = Embedding::new(&tets, oriented.vertices());
    let d = embedding.distances_m();
    let stats = VoxelStats {
        volume_ratio: tets.volume() / enclosed,
        max_embedding_distance_m: d.iter().copied().fold(0.0, Real::max),
        mean_embedding_distance_m: d.iter().sum::<Real>() / d.len() as Real,
        outside_vertices: d.iter().filter(|&&x| x > 0.0).count(),
    };
    Ok(VolumeMesh {
        tets,
        surface: embedding,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::{FingerModel, FingerParams};

    #[test]
    fn finger_volume_and_embedding_are_accurate_and_improve_with_resolution() {
        let finger = FingerModel::from_params(&FingerParams::default()).unwrap();
        let mut last_error = Real::INFINITY;
        for cell in [0.005, 0.0035, 0.002] {
            let vm = voxelize(finger.mesh(), &VoxelParams { cell_size_m: cell }).unwrap();
            let s = vm.stats;
            let err = (s.volume_ratio - 1.0).abs();
            // The surface is reproduced exactly at rest.
            for (e, p) in vm.surface.points().iter().zip(finger.mesh().vertices()) {
                assert!((e.position(vm.tets.nodes()) - p).norm() < 1e-12);
            }
            assert!(
                s.max_embedding_distance_m < 0.8 * cell,
                "cell {cell}: {s:?}"
            );
            assert!(err < 0.12, "cell {cell}: volume ratio {}", s.volume_ratio);
            assert!(
                err < last_error + 0.01,
                "cell {cell}: {err} vs {last_error}"
            );
            last_error = err;
            if cell == 0.0035 {
                let n = vm.tets.num_tets();
                assert!(
                    (1500..6000).contains(&n),
                    "{n} tets at the default resolution"
                );
                eprintln!("default resolution: {n} tets, {s:?}");
            }
        }
        assert!(last_error < 0.05);
    }

    #[test]
    fn open_surface_and_bad_cell_size_are_rejected() {
        let finger = FingerModel::from_params(&FingerParams::default()).unwrap();
        let mesh = finger.mesh();
        let open = TriMesh::new(mesh.vertices().to_vec(), mesh.faces()[1..].to_vec());
        // Removing a face leaves isolated-free but open geometry.
        if let Ok(open) = open {
            assert!(matches!(
                voxelize(&open, &VoxelParams::default()),
                Err(SimError::Geometry(moe_geom::GeomError::OpenMesh { .. }))
            ));
        }
        for bad in [0.0, -1.0, Real::NAN] {
            assert!(matches!(
                voxelize(mesh, &VoxelParams { cell_size_m: bad }),
                Err(SimError::InvalidParameter {
                    name: "cell_size_m",
                    ..
                })
            ));
        }
    }
}
