//! Golden fixtures: small committed JSON files holding reference results of the numerical stages.
//! `--check` recomputes each and compares it with the committed file (numbers within a relative
//! tolerance, everything else exactly); `--update` rewrites them. Never edit them by hand.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde_json::Value;

/// The source checkout this crate was built in (fixtures, scenes and models are found there).
pub fn workspace_root() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest
        .ancestors()
        .nth(2)
        .map_or_else(|| manifest.to_owned(), Path::to_path_buf)
}

/// What [`run`] does with each fixture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Recompute every golden fixture and fail on any difference.
    Check,
    /// Recompute every golden fixture and overwrite the committed files.
    Update,
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

/// Whether a fixture is stored as TOML (scene files) rather than JSON, by its extension.
fn is_toml(path: &str) -> bool {
    path.ends_with(".toml")
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
        generate: crate::cli::eval::surface_fixture,
        tolerance: 1e-3,
    },
    Fixture {
        path: "fixtures/golden/arap_heldout_small.json",
        generate: crate::cli::eval::contact::golden_arap,
        tolerance: 1e-7,
    },
    Fixture {
        path: "fixtures/golden/contact_heldout_small.json",
        generate: crate::cli::eval::contact::golden_table1,
        tolerance: 1e-4,
    },
    Fixture {
        path: "fixtures/golden/physics_heldout_small.json",
        generate: crate::cli::eval::physics::golden_physics,
        tolerance: 1e-4,
    },
    Fixture {
        path: "fixtures/golden/physics_default_heldout_small.json",
        generate: crate::cli::eval::physics::golden_physics_default,
        tolerance: 1e-4,
    },
    Fixture {
        path: "fixtures/golden/eval_patting_small.json",
        generate: crate::cli::eval::patting::patting_fixture,
        tolerance: 1e-3,
    },
    Fixture {
        path: "fixtures/golden/eval_grasp_small.json",
        generate: crate::cli::eval::grasp::grasp_fixture,
        tolerance: 1e-3,
    },
    Fixture {
        path: "fixtures/golden/sim_short_scene.json",
        generate: golden_sim_short_scene,
        tolerance: 1e-6,
    },
    Fixture {
        path: "fixtures/scenes/head_patting.toml",
        generate: scene_head_patting,
        tolerance: 1e-12,
    },
    Fixture {
        path: "fixtures/scenes/arm_patting.toml",
        generate: || scene_value(&moe_tendon_sim::paper_scenes::arm_patting()?),
        tolerance: 1e-12,
    },
    Fixture {
        path: "fixtures/scenes/inclined_plate_00.toml",
        generate: || scene_inclined_plate(0.0),
        tolerance: 1e-12,
    },
    Fixture {
        path: "fixtures/scenes/inclined_plate_30.toml",
        generate: || scene_inclined_plate(30.0),
        tolerance: 1e-12,
    },
    Fixture {
        path: "fixtures/scenes/inclined_plate_45.toml",
        generate: || scene_inclined_plate(45.0),
        tolerance: 1e-12,
    },
];

/// The simulator's regression scene: its state digest (positions rounded to 1 nm) after all
/// steps, and the contact labels and penetration of its last frame.
fn golden_sim_short_scene() -> Result<Value> {
    let mut scene = moe_tendon_sim::Scene::new(moe_tendon_sim::testing::golden_short_scene())?;
    let mut state = scene.initial_state();
    for _ in 0..scene.num_steps() {
        scene.step(&mut state)?;
    }
    let frame = scene.frame(&state);
    let contacts: Vec<usize> = frame
        .fingers
        .iter()
        .map(|f| f.labels.iter().filter(|&&l| l).count())
        .collect();
    let penetration_mm: Vec<f64> = frame
        .fingers
        .iter()
        .map(|f| (-1e3 * f.distances_m.iter().copied().fold(0.0_f64, f64::min)).max(0.0))
        .collect();
    Ok(serde_json::json!({
        "steps": state.step,
        "rounded_digest_1nm": format!("{:#018x}", state.rounded_digest(1e-9)),
        "contact_vertices": contacts,
        "max_penetration_mm": penetration_mm,
    }))
}

fn scene_value(config: &moe_tendon_sim::SceneConfig) -> Result<Value> {
    Ok(serde_json::to_value(config)?)
}

/// The paper's head-patting scene (§5.3).
fn scene_head_patting() -> Result<Value> {
    scene_value(&moe_tendon_sim::paper_scenes::head_patting()?)
}

/// The paper's inclined-plate scene (§6.2).
fn scene_inclined_plate(deg: f64) -> Result<Value> {
    scene_value(&moe_tendon_sim::paper_scenes::inclined_plate(deg)?)
}

/// Recomputes every golden fixture of the workspace and checks it against the committed file
/// (numbers within the fixture's relative tolerance, everything else exactly), or rewrites it.
///
/// # Errors
/// A fixture that cannot be computed, read or written, or (checking) that differs.
pub fn run(mode: Mode) -> Result<()> {
    let root = workspace_root();
    let mut failures = Vec::new();
    for fixture in FIXTURES {
        let path = root.join(fixture.path);
        let fresh = (fixture.generate)().with_context(|| format!("computing {}", fixture.path))?;
        if mode == Mode::Update {
            write_fixture(&path, &fresh)?;
            eprintln!("fixtures: wrote {}", fixture.path);
            continue;
        }
        let text = std::fs::read_to_string(&path).with_context(|| {
            format!(
                "reading {} (run `cargo xtask fixtures --update` to create it)",
                fixture.path
            )
        })?;
        let committed: Value = if is_toml(fixture.path) {
            toml::from_str(&text).with_context(|| format!("parsing {}", fixture.path))?
        } else {
            serde_json::from_str(&text).with_context(|| format!("parsing {}", fixture.path))?
        };
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

fn write_fixture(path: &Path, value: &Value) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    if path.extension().is_some_and(|e| e == "toml") {
        let header = "# Generated by `cargo xtask fixtures --update` from moe_tendon_sim::paper_scenes;\n\
                      # do not edit by hand. SI units.\n";
        let body = toml::to_string(value)?;
        moe_io::write_atomic(path, format!("{header}{body}").as_bytes())?;
    } else {
        moe_io::write_json(path, value)?;
    }
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
