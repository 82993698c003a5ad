//! Golden fixtures: small committed JSON files holding reference results of the numerical stages.
//! `--check` recomputes each and compares it with the committed file (numbers within a relative
//! tolerance, everything else exactly); `--update` rewrites them. Never edit them by hand.

use std::path::Path;

use anyhow::{Context, Result, bail};
use clap::Args;
use serde_json::Value;

use crate::ci::workspace_root;

/// Arguments of `cargo xtask fixtures`.
#[derive(Debug, Args)]
pub(crate) struct FixturesArgs {
    /// Recompute every golden fixture and fail on any difference.
    #[arg(long, conflicts_with = "update", required_unless_present = "update")]
    pub(crate) check: bool,
    /// Recompute every golden fixture and overwrite the committed files.
    #[arg(long)]
    pub(crate) update: bool,
}

/// One golden fixture: where it lives, how to recompute it, and how close numbers must be.
struct Fixture {
    /// Path relative to the workspace root.
    path: &'static str,
    /// Recomputes the fixture's content.
    generate: fn() -> Result<Value>,
    /// Allowed relative difference of numbers (plus the same value as an absolute floor).
    tolerance: f64,
}

/// Every golden fixture of the workspace.
const FIXTURES: &[Fixture] = &[
    Fixture {
        path: "fixtures/golden/hand_presets.json",
        generate: golden_hand_presets,
        tolerance: 1e-9,
    },
    Fixture {
        path: "fixtures/golden/eval_surface_small.json",
        generate: crate::eval::surface_fixture,
        tolerance: 1e-3,
    },
];

pub(crate) fn run(args: &FixturesArgs) -> Result<()> {
    let root = workspace_root();
    let mut failures = Vec::new();
    for fixture in FIXTURES {
        let path = root.join(fixture.path);
        let fresh = (fixture.generate)().with_context(|| format!("computing {}", fixture.path))?;
        if args.update {
            write_json(&path, &fresh)?;
            eprintln!("fixtures: wrote {}", fixture.path);
            continue;
        }
        let text = std::fs::read_to_string(&path).with_context(|| {
            format!(
                "reading {} (run `cargo xtask fixtures --update` to create it)",
                fixture.path
            )
        })?;
        let committed: Value =
            serde_json::from_str(&text).with_context(|| format!("parsing {}", fixture.path))?;
        match first_difference(&committed, &fresh, fixture.tolerance, "$") {
            None => eprintln!("fixtures: {} ok", fixture.path),
            Some(diff) => {
                eprintln!("fixtures: {} differs: {diff}", fixture.path);
                failures.push(fixture.path);
            }
        }
    }
    if !failures.is_empty() {
        bail!(
            "{} golden fixture(s) differ: {}",
            failures.len(),
            failures.join(", ")
        );
    }
    Ok(())
}

fn write_json(path: &Path, value: &Value) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, serde_json::to_string_pretty(value)? + "\n")?;
    std::fs::rename(&tmp, path)?;
    Ok(())
}

/// The first place where `a` and `b` differ, as a JSON path with both values.
fn first_difference(a: &Value, b: &Value, tol: f64, at: &str) -> Option<String> {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64()?, y.as_f64()?);
            let scale = x.abs().max(y.abs()).max(1.0);
            ((x - y).abs() > tol * scale).then(|| format!("{at}: committed {x}, computed {y}"))
        }
        (Value::Array(x), Value::Array(y)) => {
            if x.len() != y.len() {
                return Some(format!(
                    "{at}: committed {} items, computed {}",
                    x.len(),
                    y.len()
                ));
            }
            x.iter()
                .zip(y)
                .enumerate()
                .find_map(|(i, (u, v))| first_difference(u, v, tol, &format!("{at}[{i}]")))
        }
        (Value::Object(x), Value::Object(y)) => {
            let keys_x: Vec<_> = x.keys().collect();
            let keys_y: Vec<_> = y.keys().collect();
            if keys_x != keys_y {
                return Some(format!(
                    "{at}: committed keys {keys_x:?}, computed {keys_y:?}"
                ));
            }
            x.iter()
                .find_map(|(k, u)| first_difference(u, &y[k], tol, &format!("{at}.{k}")))
        }
        _ => (a != b).then(|| format!("{at}: committed {a}, computed {b}")),
    }
}

/// The built-in hands: counts, vertex ids and integral measures of every preset's finger.
fn golden_hand_presets() -> Result<Value> {
    use moe_geom::{FingerParams, HandModel, HandPreset, Topology};
    let mut out = serde_json::Map::new();
    for preset in HandPreset::ALL {
        let hand = HandModel::preset(preset, &FingerParams::default())?;
        let f = &hand.fingers()[0].model;
        let mesh = f.mesh();
        let centroid = mesh
            .vertices()
            .iter()
            .fold(moe_geom::Vector3::zeros(), |s, p| s + p.coords)
            / mesh.num_vertices() as f64;
        let poses: Vec<Value> = hand
            .fingers()
            .iter()
            .map(|f| {
                let t = f.hand_from_finger.iso().translation.vector;
                serde_json::json!([t.x, t.y, t.z, f.hand_from_finger.iso().rotation.angle()])
            })
            .collect();
        out.insert(
            preset.name().to_owned(),
            serde_json::json!({
                "num_fingers": hand.num_fingers(),
                "vertices_per_finger": mesh.num_vertices(),
                "faces_per_finger": mesh.num_faces(),
                "edges_per_finger": Topology::new(mesh).edges().len(),
                "marker_vertices": f.marker_vertices(),
                "num_base_vertices": f.base_vertices().len(),
                "surface_area_m2": mesh.surface_area(),
                "volume_m3": mesh.signed_volume(),
                "centroid_m": [centroid.x, centroid.y, centroid.z],
                "finger_poses_xyz_angle": poses,
            }),
        );
    }
    Ok(Value::Object(out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_are_found_and_located() {
        let a = serde_json::json!({"x": [1.0, 2.0], "n": "a"});
        assert_eq!(first_difference(&a, &a, 1e-9, "$"), None);
        let b = serde_json::json!({"x": [1.0, 2.001], "n": "a"});
        assert_eq!(
            first_difference(&a, &b, 1e-9, "$").as_deref(),
            Some("$.x[1]: committed 2, computed 2.001")
        );
        assert_eq!(first_difference(&a, &b, 1e-2, "$"), None);
        let c = serde_json::json!({"x": [1.0, 2.0], "n": "b"});
        assert!(first_difference(&a, &c, 1.0, "$").is_some());
    }
}
