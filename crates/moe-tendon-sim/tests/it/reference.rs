//! The simulator's finger against an independent FEM code: scikit-fem quadratic tetrahedra on a
//! TetGen mesh of the same finger surface (`tools/fem_reference.py`, fixture
//! `fixtures/mechanics/finger_reference.json`). Both solve linear elasticity for the same
//! per-triangle tractions and body forces; the simulator applies them scaled down by
//! [`SCALE`], where its corotational elasticity is linear, and its response is scaled back.

use std::path::PathBuf;

use moe_geom::{FingerModel, FingerParams, Point3, Real, Vector3};
use moe_tendon_sim::mechanics::{FemInputs, FingerBody, Integrator, StepContext, Terms};
use moe_tendon_sim::{BodyState, Material, TendonCommand, TendonParams, VoxelParams};
use serde::Deserialize;

/// Load scale of the simulator's solves (the reference is linear).
const SCALE: Real = 1e-3;

#[derive(Deserialize)]
struct Reference {
    youngs_modulus_pa: Real,
    poisson_ratio: Real,
    density_kg_m3: Real,
    vertices_m: Vec<[Real; 3]>,
    faces: Vec<[u32; 3]>,
    marker_vertices: Vec<usize>,
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Case {
    name: String,
    gravity_m_s2: [Real; 3],
    /// Rows `[face, tx, ty, tz]`: a constant traction over one surface triangle, pascals.
    face_tractions_pa: Vec<[Real; 4]>,
    /// Largest change of a marker's displacement between the reference's two meshes, relative.
    mesh_change: Real,
    /// Per surface vertex.
    displacement_m: Vec<[Real; 3]>,
}

fn reference() -> Reference {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/mechanics/finger_reference.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// How the simulator's markers compare with the reference's in one case.
#[derive(Debug, Clone, Copy)]
struct Agreement {
    /// Least-squares scale of the simulator's marker displacements onto the reference's: how far
    /// the simulator's markers move, as a fraction of the reference (1 = equally stiff).
    ratio: Real,
    /// Largest marker displacement error, relative to the largest reference marker displacement.
    error: Real,
}

fn agreement(sim: &[Vector3], reference: &[Vector3]) -> Agreement {
    let dot: Real = sim.iter().zip(reference).map(|(s, r)| s.dot(r)).sum();
    let norm2: Real = reference.iter().map(|r| r.norm_squared()).sum();
    let largest = reference.iter().map(|r| r.norm()).fold(0.0, Real::max);
    let error = sim
        .iter()
        .zip(reference)
        .map(|(s, r)| (s - r).norm())
        .fold(0.0, Real::max);
    Agreement {
        ratio: dot / norm2,
        error: error / largest,
    }
}

/// The default finger (finger 0 of every preset hand, in its own frame).
fn default_finger() -> FingerModel {
    FingerModel::from_params(&FingerParams::default()).unwrap()
}

/// The nodal loads of `case`'s tractions times `scale`: each triangle's force, a third to each
/// corner, each corner's share to the nodes of the element it is embedded in.
fn node_loads(
    reference: &Reference,
    case: &Case,
    surface: &[moe_tendon_sim::mechanics::Embedded],
    num_nodes: usize,
    scale: Real,
) -> Vec<(u32, Vector3)> {
    let mut node_force = vec![Vector3::zeros(); num_nodes];
    for row in &case.face_tractions_pa {
        let face = reference.faces[row[0] as usize];
        let [a, b, c] = face.map(|v| Point3::from(reference.vertices_m[v as usize]));
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        let force = Vector3::new(row[1], row[2], row[3]) * (area * scale / 3.0);
        for v in face {
            let e = &surface[v as usize];
            for (&n, &w) in e.nodes.iter().zip(&e.weights) {
                node_force[n as usize] += force * w;
            }
        }
    }
    node_force
        .into_iter()
        .enumerate()
        .filter(|(_, f)| f.norm() > 0.0)
        .map(|(i, f)| (i as u32, f))
        .collect()
}

/// The simulator's surface displacements for every case of `reference`, at `cell_size_m`.
fn simulate(reference: &Reference, cell_size_m: Real) -> Vec<Vec<Vector3>> {
    let material = Material {
        youngs_modulus_pa: reference.youngs_modulus_pa,
        poisson_ratio: reference.poisson_ratio,
        density_kg_m3: reference.density_kg_m3,
        ..Material::default()
    };
    let finger = default_finger();
    let body = FingerBody::new(&finger, &material, &VoxelParams { cell_size_m }).unwrap();
    let (surface, num_nodes) = (body.surface().points(), body.fem().mesh().num_nodes());
    reference
        .cases
        .iter()
        .map(|case| {
            let loads = node_loads(reference, case, surface, num_nodes, SCALE);
            let g = Vector3::from(case.gravity_m_s2) * SCALE;
            static_displacements(&body, &loads, g, &[], 1e-11)
                .into_iter()
                .map(|d| d / SCALE)
                .collect()
        })
        .collect()
}

/// The surface displacements of `body`'s static equilibrium from rest under nodal `loads`,
/// `gravity` and tendon `commands` (none: no tendon terms), to `tolerance_m` (an error
/// otherwise).
fn static_displacements(
    body: &FingerBody,
    loads: &[(u32, Vector3)],
    gravity: Vector3,
    commands: &[TendonCommand],
    tolerance_m: Real,
) -> Vec<Vector3> {
    let fem = body.fem();
    let rest = fem.mesh().nodes().to_vec();
    let params = TendonParams::default();
    let mut state = BodyState {
        x: rest.clone(),
        v: vec![Vector3::zeros(); rest.len()],
    };
    let mut ws = fem.workspace();
    fem.step(
        &mut ws,
        StepContext::default(),
        Integrator::Static {
            tolerance_m,
            max_iterations: 200,
        },
        &mut state,
        FemInputs {
            targets: &rest,
            gravity,
            terms: &mut |x: &[Point3], _, t: &mut Terms| {
                t.nodal_forces.clear();
                t.nodal_forces.extend_from_slice(loads);
                for (tendon, &c) in body.tendons().iter().zip(commands) {
                    tendon.add_terms(x, c, &params, t);
                }
            },
        },
    )
    .unwrap();
    let surface = body.surface();
    surface
        .positions(&state.x)
        .iter()
        .zip(surface.positions(&rest))
        .map(|(p, q)| p - q)
        .collect()
}

/// Per case, the simulator's agreement with the reference on the markers.
fn agreements(reference: &Reference, cell_size_m: Real) -> Vec<Agreement> {
    let sim = simulate(reference, cell_size_m);
    reference
        .cases
        .iter()
        .zip(&sim)
        .map(|(case, u)| {
            let (sim, reference): (Vec<Vector3>, Vec<Vector3>) = reference
                .marker_vertices
                .iter()
                .map(|&m| (u[m], Vector3::from(case.displacement_m[m])))
                .unzip();
            agreement(&sim, &reference)
        })
        .collect()
}

fn print_table(reference: &Reference, label: &str, rows: &[Agreement]) {
    eprintln!("{label}");
    for (case, a) in reference.cases.iter().zip(rows) {
        eprintln!(
            "  {:26} markers move {:.3}x the reference, largest error {:5.1} % (reference mesh change {:.2} %)",
            case.name,
            a.ratio,
            100.0 * a.error,
            100.0 * case.mesh_change
        );
    }
}

#[test]
fn the_fixture_is_the_default_finger_and_a_converged_reference() {
    let reference = reference();
    let finger = default_finger();
    let mesh = finger.mesh();
    assert_eq!(mesh.vertices().len(), reference.vertices_m.len());
    for (p, q) in mesh.vertices().iter().zip(&reference.vertices_m) {
        assert!((p - Point3::from(*q)).norm() < 1e-9, "{p} vs {q:?}");
    }
    let markers: Vec<usize> = finger
        .marker_vertices()
        .iter()
        .map(|&m| m as usize)
        .collect();
    assert_eq!(markers, reference.marker_vertices);
    for case in &reference.cases {
        assert!(
            case.mesh_change < 0.01,
            "{}: the reference moves {:.2} % between its meshes",
            case.name,
            100.0 * case.mesh_change
        );
    }
}

/// The simulator converges to the reference: at 2 mm cells every marker is within 3.5 % of it
/// (7 % in twist), closer than at the default 3.5 mm in every case, where the linear tetrahedra
/// are 8–16 % too stiff (their markers move 0.84–0.92 times as far; 0.99 along the axis).
#[test]
fn the_simulator_converges_to_the_reference_under_refinement() {
    let reference = reference();
    let default = agreements(&reference, VoxelParams::default().cell_size_m);
    let fine = agreements(&reference, 0.002);
    print_table(&reference, "default cells", &default);
    print_table(&reference, "2 mm cells", &fine);
    for ((case, d), f) in reference.cases.iter().zip(&default).zip(&fine) {
        let name = &case.name;
        let (bound, too_stiff) = if name.starts_with("twist") {
            (0.07, 0.80..0.95)
        } else if name == "gravity_minus_z" {
            (0.035, 0.97..1.03)
        } else {
            (0.035, 0.85..0.95)
        };
        assert!(f.error < bound, "{name} at 2 mm: {:.1} %", 100.0 * f.error);
        assert!(
            f.error <= d.error + 1e-3,
            "{name}: no closer at 2 mm ({f:?} vs {d:?})"
        );
        assert!(
            too_stiff.contains(&d.ratio),
            "{name} at the default cells: {d:?}"
        );
    }
}

/// The stiffness error per mesh size (docs/results.md, "The FEM against an independent code"):
/// `cargo test -p moe-tendon-sim --test it reference::stiffness_per_mesh_size -- --ignored
/// --nocapture`.
#[test]
#[ignore = "a report: about a minute"]
fn stiffness_per_mesh_size() {
    let reference = reference();
    for cell in [0.005, 0.004, 0.0035, 0.003, 0.0025, 0.002] {
        let rows = agreements(&reference, cell);
        print_table(&reference, &format!("cell {:.1} mm", cell * 1e3), &rows);
    }
}

/// Marker positions (finger frame) of the default finger at `cell_size_m`, with its tendons
/// held at `pulls` (displacement mode) and the nodal loads of `case` (if any) at full scale.
fn with_tendons(
    reference: &Reference,
    cell_size_m: Real,
    pulls: &[Real],
    case: Option<&Case>,
) -> Vec<Vector3> {
    let finger = default_finger();
    let body =
        FingerBody::new(&finger, &Material::default(), &VoxelParams { cell_size_m }).unwrap();
    let surface = body.surface().points();
    let loads = case.map_or_else(Vec::new, |case| {
        node_loads(reference, case, surface, body.fem().mesh().num_nodes(), 1.0)
    });
    let commands: Vec<TendonCommand> = (0..body.tendons().len())
        .map(|j| TendonCommand::Displacement {
            pull_m: pulls.get(j).copied().unwrap_or(0.0),
        })
        .collect();
    let u = static_displacements(&body, &loads, Vector3::zeros(), &commands, 1e-10);
    finger
        .marker_vertices()
        .iter()
        .map(|&m| u[m as usize])
        .collect()
}

/// How the tendons converge with the mesh (docs/results.md, "The FEM against an independent
/// code"): `cargo test -p moe-tendon-sim --test it reference::tendons_per_mesh_size --
/// --ignored --nocapture`.
#[test]
#[ignore = "a report: about a minute"]
fn tendons_per_mesh_size() {
    let reference = reference();
    let press = reference
        .cases
        .iter()
        .find(|c| c.name == "press_tip_left")
        .unwrap();
    let cells = [0.0035, 0.003, 0.0025, 0.002, 0.00175];
    let largest = |u: &[Vector3]| u.iter().map(|d| d.norm()).fold(0.0, Real::max);
    for (label, pulls, case) in [
        ("tendon 0 pulled 2 mm", vec![0.002], None),
        (
            "0.1 N tip press, tendons held at zero pull",
            vec![],
            Some(press),
        ),
    ] {
        let runs: Vec<Vec<Vector3>> = cells
            .iter()
            .map(|&h| with_tendons(&reference, h, &pulls, case))
            .collect();
        eprintln!("{label}");
        for (k, (h, u)) in cells.iter().zip(&runs).enumerate() {
            let change = runs.get(k + 1).map(|v| {
                u.iter()
                    .zip(v)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, Real::max)
                    / largest(v)
            });
            eprintln!(
                "  cell {:.2} mm: largest marker displacement {:.3} mm; change to the next finer mesh {}",
                h * 1e3,
                largest(u) * 1e3,
                change.map_or("-".into(), |c| format!("{:.1} %", 100.0 * c))
            );
        }
    }
    let free: Vec<Vector3> = reference
        .marker_vertices
        .iter()
        .map(|&m| Vector3::from(press.displacement_m[m]))
        .collect();
    eprintln!(
        "the same press in the reference, without tendons (linear): {:.3} mm",
        largest(&free) * 1e3
    );
}
