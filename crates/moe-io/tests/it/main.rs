//! Integration tests of `moe-io`: round trips through real files, fixture configs, fuzzing of
//! every reader, and the atomic-write guarantees.

mod atomic_writes;
mod configs;
mod fuzz;
mod harness;
mod round_trips;
mod stl;

use std::path::{Path, PathBuf};

use moe_geom::{FingerModel, FingerParams, Point3, TriMesh};

/// A fresh, empty scratch directory for one test.
pub(crate) fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("moe-io-it-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

/// Names of the entries of a directory, sorted.
pub(crate) fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("read dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// The workspace's `fixtures/configs` directory.
pub(crate) fn fixture_configs() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/configs")
}

/// A small parametric finger mesh (closed, a few hundred vertices).
pub(crate) fn finger_mesh(budget: usize) -> TriMesh {
    let params = FingerParams {
        vertex_budget: budget,
        ..FingerParams::default()
    };
    FingerModel::from_params(&params)
        .expect("valid params")
        .mesh()
        .clone()
}

/// A regular octahedron of circumradius `r`, outward-oriented.
pub(crate) fn octahedron(r: f64) -> TriMesh {
    moe_geom::shapes::octahedron(r)
}

/// Asserts two point lists are bit-identical.
pub(crate) fn assert_bit_exact(a: &[Point3], b: &[Point3]) {
    assert_eq!(a.len(), b.len());
    for (i, (p, q)) in a.iter().zip(b).enumerate() {
        for k in 0..3 {
            assert_eq!(
                p[k].to_bits(),
                q[k].to_bits(),
                "vertex {i} coordinate {k}: {p} vs {q}"
            );
        }
    }
}
