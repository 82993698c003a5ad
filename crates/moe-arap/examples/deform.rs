//! Deform a mesh with SR-ARAP: keep its base where it is, pull one vertex, and read the
//! smoothly bent result.
//!
//! `cargo run -p moe-arap --example deform [MESH.obj|.ply|.stl]` — without a file, the default
//! finger of the two-finger hand. The base is the vertices within 2 mm of the lowest z; the
//! handle, the highest vertex, is pulled 15 mm along +x.

use moe_arap::{ArapConfig, ArapSolver, Start};
use moe_geom::{FingerModel, FingerParams, Point3, TriMesh, Vector3};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mesh: TriMesh = match std::env::args().nth(1) {
        Some(path) => moe_io::read_mesh(path.as_ref())?,
        None => FingerModel::from_params(&FingerParams::default())?
            .mesh()
            .clone(),
    };
    let z = |v: &u32| mesh.vertices()[*v as usize].z;
    let ids: Vec<u32> = (0..mesh.num_vertices() as u32).collect();
    let bottom = ids.iter().map(z).fold(f64::INFINITY, f64::min);
    let base: Vec<u32> = ids
        .iter()
        .copied()
        .filter(|v| z(v) < bottom + 0.002)
        .collect();
    let tip = *ids
        .iter()
        .max_by(|a, b| z(a).total_cmp(&z(b)))
        .ok_or("an empty mesh")?;

    // The lines that matter: build (factorise once), then solve for any targets.
    let solver = ArapSolver::new(&mesh, &ArapConfig::default(), &base, &[tip])?;
    let base_targets: Vec<Point3> = base.iter().map(|&v| mesh.vertices()[v as usize]).collect();
    let pulled = mesh.vertices()[tip as usize] + Vector3::new(0.015, 0.0, 0.0);
    let solution = solver.solve(&base_targets, &[Some(pulled)], Start::Rest)?;

    let moved = |v: usize| (solution.vertices[v] - mesh.vertices()[v]).norm();
    let max = (0..mesh.num_vertices()).map(moved).fold(0.0, f64::max);
    println!(
        "{} vertices, {} fixed, tip pulled 15 mm: largest displacement {:.1} mm, energy {:.3e} \
         after {} iterations",
        mesh.num_vertices(),
        base.len(),
        1e3 * max,
        solution.info.energy.last().copied().unwrap_or(f64::NAN),
        solution.info.energy.len()
    );
    Ok(())
}
