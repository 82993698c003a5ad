//! Contact on a finger mesh of your own: a model trained for that finger, the finger's rest mesh
//! and its deformed vertices in, a contact probability per vertex out. No hand model, markers or
//! base vertices are needed.
//!
//! `cargo run -p moe-contact --example own_finger [MODEL REST_MESH [DEFORMED_MESH]]`, `MODEL`
//! without extension (`NAME.safetensors` and its card `NAME.json`), meshes in the finger frame
//! (metres; OBJ, PLY or STL; the deformed one with the rest mesh's vertices in the same order).
//! Without arguments: the shipped two-finger model on that hand's finger, pressed in at the tip.

use std::path::{Path, PathBuf};

use moe_contact::DgcnnEstimator;
use moe_geom::{FingerModel, FingerParams, Point3, TriMesh};

/// Contact probability of every vertex of `rest` deformed to `deformed`: all a user writes.
fn contact_on(
    model: &Path,
    rest: &TriMesh,
    deformed: &[Point3],
) -> Result<Vec<f64>, Box<dyn std::error::Error>> {
    let weights = std::fs::read(model.with_extension("safetensors"))?;
    let card = std::fs::read_to_string(model.with_extension("json"))?;
    let estimator = DgcnnEstimator::finger_from_bytes(&weights, &card, rest)?;
    Ok(estimator.finger_map(deformed)?)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (model, rest, deformed) = match args.as_slice() {
        [model, rest, rest_of @ ..] => {
            let rest = moe_io::read_mesh(rest.as_ref())?;
            let deformed = match rest_of.first() {
                Some(path) => moe_io::read_mesh(path.as_ref())?.vertices().to_vec(),
                None => rest.vertices().to_vec(),
            };
            (PathBuf::from(model), rest, deformed)
        }
        _ => {
            let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
            let rest = FingerModel::from_params(&FingerParams::default())?
                .mesh()
                .clone();
            let deformed = pressed_at_the_tip(&rest);
            (root.join("models/contact-two-finger"), rest, deformed)
        }
    };
    let p = contact_on(&model, &rest, &deformed)?;
    let touching = p.iter().filter(|&&p| p >= 0.5).count();
    let top = p.iter().copied().fold(0.0, f64::max);
    println!(
        "{} vertices: {touching} at contact probability >= 0.5 (highest {top:.2})",
        p.len()
    );
    Ok(())
}

/// The finger dented up to 2 mm (along +x) within 8 mm of a point 5 mm below its tip on its -x
/// side, the back of the finger (+x faces the hand's axis): a stand-in for a deformed shape.
fn pressed_at_the_tip(rest: &TriMesh) -> Vec<Point3> {
    let v = rest.vertices();
    let top = v.iter().map(|p| p.z).fold(f64::MIN, f64::max);
    let side = v.iter().map(|p| p.x).fold(f64::MAX, f64::min);
    let centre = Point3::new(side, 0.0, top - 0.005);
    v.iter()
        .map(|p| {
            let d = (p - centre).norm();
            let depth = 0.002 * (1.0 - d / 0.008).max(0.0);
            Point3::new(p.x + depth, p.y, p.z)
        })
        .collect()
}
