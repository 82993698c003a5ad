//! SR-ARAP on any mesh (`ArapSolver`): a mesh of one connected part is solved whole; a mesh
//! of several parts by one solver per part, run in parallel.
//!
//! The SR-ARAP energy couples a vertex only to its one-ring, so the parts of a mesh that share no
//! edge are independent problems: the whole system is block diagonal. Solving each part with its
//! own factorisation on its own thread gives the same shape (to rounding) in a fraction of the
//! wall time: a hand exported as one mesh with a part per finger solves as fast as the per-finger
//! estimator.

use moe_geom::{Point3, Real, Topology, TriMesh};
use rayon::prelude::*;

use crate::config::ArapConfig;
use crate::error::ArapError;
use crate::solver::{ArapInfo, ArapSolution, PartSolver, Start, check_id, check_inputs};

/// One connected part of the mesh with its solver.
#[derive(Debug)]
struct Part {
    solver: PartSolver,
    /// Global id of every local vertex.
    vertices: Vec<u32>,
    /// Positions, in the global fixed list, of the part's fixed vertices (local order).
    fixed: Vec<usize>,
    /// Positions, in the global handle list, of the part's handles (local order).
    handles: Vec<usize>,
}

#[derive(Debug)]
enum Layout {
    /// A connected mesh: one solver.
    Whole(Box<PartSolver>),
    /// Two or more parts; `rest` is the whole rest mesh.
    Parts { parts: Vec<Part>, rest: Vec<Point3> },
}

/// The SR-ARAP solver of a mesh of one or many connected parts, for one constraint structure:
/// `fixed` vertices (always constrained, eliminated from the factorised system) and switchable
/// `handles` (constrained in a solve when a target is given, through a small Schur complement;
/// see the crate documentation). Factorised once when built; each solve runs
/// `config.iterations` local/global iterations.
///
/// A connected mesh is one factorised system (its local step on the thread pool with
/// `ArapConfig::parallel`). A mesh of several parts — a hand exported as one mesh — gets one
/// system per part, solved in parallel with sequential local steps, the whole mesh's smoothing
/// weight (α is relative to the whole surface area), and a solve returns the vertices in the
/// mesh's order, the energies summed over the parts, and the handles used in handle order: the
/// same shape as one system, to rounding, in a fraction of the time.
#[derive(Debug)]
pub struct ArapSolver {
    config: ArapConfig,
    surface_area: Real,
    num_vertices: usize,
    fixed: Vec<u32>,
    handles: Vec<u32>,
    layout: Layout,
}

impl ArapSolver {
    /// Finds the connected parts of `mesh` and builds and factorises a system for each (in
    /// parallel).
    ///
    /// # Errors
    /// Naming vertices by their ids in `mesh`: an invalid config, an out-of-range or repeated
    /// id, a handle that is also fixed, a part with no fixed vertex ([`ArapError::Unanchored`],
    /// its lowest vertex).
    pub fn new(
        mesh: &TriMesh,
        config: &ArapConfig,
        fixed: &[u32],
        handles: &[u32],
    ) -> Result<Self, ArapError> {
        config.validate()?;
        let n = mesh.num_vertices();
        let topology = Topology::new(mesh);
        let (label, count) = topology.connected_components();
        // Every vertex of a `TriMesh` is in a face and every face has area, so every part has
        // cells and a positive area.
        if count < 2 {
            let whole = PartSolver::new(mesh, config, fixed, handles)?;
            return Ok(Self {
                config: config.clone(),
                surface_area: whole.surface_area(),
                num_vertices: n,
                fixed: fixed.to_vec(),
                handles: handles.to_vec(),
                layout: Layout::Whole(Box::new(whole)),
            });
        }
        let mut part_area = vec![0.0; count];
        for (f, a) in mesh.faces().iter().zip(mesh.face_areas()) {
            part_area[label[f[0] as usize] as usize] += a;
        }
        // The checks of `PartSolver::new`, in its order, on global ids.
        let mut is_fixed = vec![false; n];
        for &v in fixed {
            let v = check_id("fixed", v, n)?;
            if std::mem::replace(&mut is_fixed[v], true) {
                return Err(ArapError::DuplicateVertex {
                    what: "fixed",
                    vertex: v,
                });
            }
        }
        let mut anchored = vec![false; count];
        for (v, _) in is_fixed.iter().enumerate().filter(|(_, f)| **f) {
            anchored[label[v] as usize] = true;
        }
        if let Some(vertex) = (0..n).find(|&v| !anchored[label[v] as usize]) {
            return Err(ArapError::Unanchored { vertex });
        }
        let mut is_handle = vec![false; n];
        for &v in handles {
            let vi = check_id("handle", v, n)?;
            if is_fixed[vi] || std::mem::replace(&mut is_handle[vi], true) {
                return Err(ArapError::DuplicateVertex {
                    what: "handle",
                    vertex: vi,
                });
            }
        }

        // Local numbering: vertices of each part in mesh order.
        let mut local = vec![0u32; n];
        let mut vertices: Vec<Vec<u32>> = vec![Vec::new(); count];
        for v in 0..n {
            let part = &mut vertices[label[v] as usize];
            local[v] = part.len() as u32;
            part.push(v as u32);
        }
        let mut faces: Vec<Vec<[u32; 3]>> = vec![Vec::new(); count];
        for f in mesh.faces() {
            faces[label[f[0] as usize] as usize].push(f.map(|v| local[v as usize]));
        }
        let mut part_fixed: Vec<Vec<usize>> = vec![Vec::new(); count];
        for (k, &v) in fixed.iter().enumerate() {
            part_fixed[label[v as usize] as usize].push(k);
        }
        let mut part_handles: Vec<Vec<usize>> = vec![Vec::new(); count];
        for (k, &v) in handles.iter().enumerate() {
            part_handles[label[v as usize] as usize].push(k);
        }
        let rest = mesh.vertices();
        let area = mesh.surface_area();
        let parts = vertices
            .into_par_iter()
            .zip(faces)
            .zip(part_fixed)
            .zip(part_handles)
            .zip(part_area)
            .map(|((((vertices, faces), fixed_k), handles_k), sub_area)| {
                let sub =
                    TriMesh::new(vertices.iter().map(|&v| rest[v as usize]).collect(), faces)?;
                // The smoothing weight is α times the surface area of the whole mesh.
                let sub_config = ArapConfig {
                    parallel: false,
                    alpha: config.alpha * area / sub_area,
                    ..config.clone()
                };
                let local_ids = |ks: &[usize], ids: &[u32]| -> Vec<u32> {
                    ks.iter().map(|&k| local[ids[k] as usize]).collect()
                };
                let solver = PartSolver::new(
                    &sub,
                    &sub_config,
                    &local_ids(&fixed_k, fixed),
                    &local_ids(&handles_k, handles),
                )
                .map_err(|e| match e {
                    ArapError::Unanchored { vertex } => ArapError::Unanchored {
                        vertex: vertices[vertex] as usize,
                    },
                    other => other,
                })?;
                Ok(Part {
                    solver,
                    vertices,
                    fixed: fixed_k,
                    handles: handles_k,
                })
            })
            .collect::<Result<Vec<_>, ArapError>>()?;
        Ok(Self {
            config: config.clone(),
            surface_area: area,
            num_vertices: n,
            fixed: fixed.to_vec(),
            handles: handles.to_vec(),
            layout: Layout::Parts {
                parts,
                rest: rest.to_vec(),
            },
        })
    }

    /// Number of connected parts solved separately (1 when the mesh is solved whole).
    pub fn num_parts(&self) -> usize {
        match &self.layout {
            Layout::Whole(_) => 1,
            Layout::Parts { parts, .. } => parts.len(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &ArapConfig {
        &self.config
    }

    /// Surface area of the rest mesh (the scale of the smoothing weight).
    pub fn surface_area(&self) -> Real {
        self.surface_area
    }

    /// Number of vertices of the mesh.
    pub fn num_vertices(&self) -> usize {
        self.num_vertices
    }

    /// Fixed vertex ids, as given.
    pub fn fixed(&self) -> &[u32] {
        &self.fixed
    }

    /// Switchable handle vertex ids, as given.
    pub fn handles(&self) -> &[u32] {
        &self.handles
    }

    /// Solves every part (in parallel) and returns the mesh's vertices in its own order.
    ///
    /// `fixed_targets[k]` is the target of `fixed()[k]`, `handle_targets[k]` that of
    /// `handles()[k]` (`None`: free in this solve). `start` is where the iteration starts:
    /// [`Start::Rest`] (the paper's setting) or given positions, one per vertex.
    ///
    /// # Errors
    /// Wrong target or start counts, non-finite targets or start positions, with indices into
    /// the lists given here.
    pub fn solve(
        &self,
        fixed_targets: &[Point3],
        handle_targets: &[Option<Point3>],
        start: Start<'_>,
    ) -> Result<ArapSolution, ArapError> {
        let (parts, rest) = match &self.layout {
            Layout::Whole(solver) => return solver.solve(fixed_targets, handle_targets, start),
            Layout::Parts { parts, rest } => (parts, rest),
        };
        check_inputs(
            [self.num_vertices, self.fixed.len(), self.handles.len()],
            fixed_targets,
            handle_targets,
            start,
        )?;
        let solutions = parts
            .par_iter()
            .map(|part| {
                let fixed: Vec<Point3> = part.fixed.iter().map(|&k| fixed_targets[k]).collect();
                let handles: Vec<Option<Point3>> =
                    part.handles.iter().map(|&k| handle_targets[k]).collect();
                let positions: Vec<Point3>;
                let start = match start {
                    Start::Positions(p) => {
                        positions = part.vertices.iter().map(|&v| p[v as usize]).collect();
                        Start::Positions(&positions)
                    }
                    other => other,
                };
                part.solver.solve(&fixed, &handles, start)
            })
            .collect::<Result<Vec<_>, ArapError>>()?;
        let mut vertices = rest.clone();
        let mut info = ArapInfo {
            handles_used: handle_targets
                .iter()
                .zip(&self.handles)
                .filter(|(t, _)| t.is_some())
                .map(|(_, &v)| v)
                .collect(),
            ..ArapInfo::default()
        };
        for (part, solution) in parts.iter().zip(solutions) {
            for (&v, p) in part.vertices.iter().zip(&solution.vertices) {
                vertices[v as usize] = *p;
            }
            let s = solution.info;
            info.iterations = s.iterations;
            info.svd_fallbacks += s.svd_fallbacks;
            if info.energy.is_empty() {
                info.energy = s.energy;
            } else {
                for (e, x) in info.energy.iter_mut().zip(&s.energy) {
                    *e += x;
                }
            }
        }
        Ok(ArapSolution { vertices, info })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testmesh::jittered_sphere;
    use moe_geom::{Iso3, Vector3};

    /// Two spheres side by side (the second shifted by 3 along x) as one mesh, and its halves.
    fn two_spheres() -> (TriMesh, usize) {
        let a = jittered_sphere(8, 12, 0.05, 1);
        let b = jittered_sphere(9, 10, 0.05, 2);
        let na = a.num_vertices() as u32;
        let mut vertices = a.vertices().to_vec();
        vertices.extend(b.vertices().iter().map(|p| p + Vector3::new(3.0, 0.0, 0.0)));
        let mut faces = a.faces().to_vec();
        faces.extend(b.faces().iter().map(|f| f.map(|v| v + na)));
        (TriMesh::new(vertices, faces).unwrap(), na as usize)
    }

    fn max_error(a: &[Point3], b: &[Point3]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max)
    }

    /// Fixed: a few vertices of each sphere; handles: some of each, the first of each moved.
    fn constraints(na: usize, n: usize) -> (Vec<u32>, Vec<u32>) {
        let fixed = vec![0, 1, 2, na as u32, na as u32 + 1, na as u32 + 3];
        let handles = vec![
            (na - 1) as u32,
            (n - 1) as u32,
            (na / 2) as u32,
            (na + (n - na) / 2) as u32,
        ];
        (fixed, handles)
    }

    #[test]
    fn parts_solved_apart_equal_the_whole_solve() {
        let (mesh, na) = two_spheres();
        let n = mesh.num_vertices();
        let (fixed, handles) = constraints(na, n);
        let config = ArapConfig {
            iterations: 20,
            ..ArapConfig::default()
        };
        let split = ArapSolver::new(&mesh, &config, &fixed, &handles).unwrap();
        assert_eq!(split.num_parts(), 2);
        let whole = PartSolver::new(&mesh, &config, &fixed, &handles).unwrap();
        let motion = Iso3::translation(0.1, -0.05, 0.2);
        let fixed_targets: Vec<Point3> =
            fixed.iter().map(|&v| mesh.vertices()[v as usize]).collect();
        let handle_targets = [
            Some(motion.transform_point(&mesh.vertices()[handles[0] as usize])),
            None,
            Some(mesh.vertices()[handles[2] as usize] + Vector3::new(0.0, 0.3, 0.0)),
            Some(motion.transform_point(&mesh.vertices()[handles[3] as usize])),
        ];
        let jittered: Vec<Point3> = mesh
            .vertices()
            .iter()
            .enumerate()
            .map(|(i, p)| p + Vector3::new(0.01 * (i % 3) as f64, 0.0, -0.01))
            .collect();
        for start in [Start::Rest, Start::Positions(&jittered), Start::Previous] {
            let a = split.solve(&fixed_targets, &handle_targets, start).unwrap();
            let b = whole.solve(&fixed_targets, &handle_targets, start).unwrap();
            let err = max_error(&a.vertices, &b.vertices);
            assert!(err < 1e-12, "{start:?}: {err:e}");
            assert_eq!(a.info.iterations, b.info.iterations);
            assert_eq!(a.info.handles_used, b.info.handles_used);
            assert_eq!(
                a.info.handles_used,
                vec![handles[0], handles[2], handles[3]]
            );
            assert_eq!(a.info.svd_fallbacks, b.info.svd_fallbacks);
            assert_eq!(a.info.energy.len(), b.info.energy.len());
            for (x, y) in a.info.energy.iter().zip(&b.info.energy) {
                assert!((x - y).abs() <= 1e-12 * y.abs().max(1e-12), "{x} vs {y}");
            }
            // The moved handles moved the shape: the check is not vacuous.
            assert!(max_error(&a.vertices, mesh.vertices()) > 0.05);
        }
    }

    #[test]
    fn a_connected_mesh_is_solved_whole() {
        let mesh = jittered_sphere(8, 12, 0.05, 1);
        let split = ArapSolver::new(&mesh, &ArapConfig::default(), &[0, 1, 2], &[]).unwrap();
        assert_eq!(split.num_parts(), 1);
    }

    #[test]
    fn errors_name_the_same_items_as_the_whole_solver() {
        let (mesh, na) = two_spheres();
        let n = mesh.num_vertices();
        let config = ArapConfig::default();
        let both = |fixed: &[u32], handles: &[u32]| {
            let a = ArapSolver::new(&mesh, &config, fixed, handles).unwrap_err();
            let b = PartSolver::new(&mesh, &config, fixed, handles).unwrap_err();
            assert_eq!(a.to_string(), b.to_string());
            a
        };
        // The second sphere has no fixed vertex: its lowest vertex is named.
        assert!(matches!(both(&[0, 1], &[]), ArapError::Unanchored { vertex } if vertex == na));
        assert!(matches!(
            both(&[0, n as u32], &[]),
            ArapError::VertexOutOfRange { what: "fixed", index, .. } if index == n
        ));
        assert!(matches!(
            both(&[0, na as u32, 0], &[]),
            ArapError::DuplicateVertex {
                what: "fixed",
                vertex: 0
            }
        ));
        assert!(matches!(
            both(&[0, na as u32], &[5, na as u32]),
            ArapError::DuplicateVertex { what: "handle", vertex } if vertex == na
        ));
        let split = ArapSolver::new(&mesh, &config, &[0, na as u32], &[3, na as u32 + 3]).unwrap();
        let rest = mesh.vertices();
        let fixed_targets = [rest[0], rest[na]];
        let bad = Point3::new(f64::NAN, 0.0, 0.0);
        assert!(matches!(
            split.solve(&fixed_targets, &[None, Some(bad)], Start::Rest),
            Err(ArapError::NonFiniteTarget {
                what: "handle target",
                index: 1
            })
        ));
        assert!(matches!(
            split.solve(&fixed_targets[..1], &[None, None], Start::Rest),
            Err(ArapError::LengthMismatch {
                what: "fixed targets",
                expected: 2,
                got: 1
            })
        ));
        assert!(matches!(
            split.solve(&fixed_targets, &[None, None], Start::Positions(&rest[..3])),
            Err(ArapError::LengthMismatch {
                what: "start positions",
                ..
            })
        ));
    }
}
