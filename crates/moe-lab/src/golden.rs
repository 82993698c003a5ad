//! Golden fixtures: small committed files holding reference results of the numerical stages
//! (hand presets, a short simulator run, SR-ARAP, the shipped network and the physics
//! estimator on the committed held-out frames, small surface, patting and grasping runs, the
//! paper's scenes). Each [`Fixture`](crate::golden::Fixture) recomputes its content; a check
//! compares it with the committed file (numbers within a relative tolerance, everything else
//! exactly), an update rewrites the file. They are never edited by hand.

use std::path::{Path, PathBuf};

use moe_io::{DatasetReader, IoError, SplitFractions};
use moe_physics::PhysicsConfig;
use serde_json::Value;

use crate::error::LabError;

/// The committed held-out frames of the golden regression (a data set directory, relative to
/// the workspace root).
pub const HELDOUT_DIR: &str = "fixtures/contact/heldout";
/// The shipped contact model, relative to the workspace root.
pub const SHIPPED_MODEL: &str = "models/contact-two-finger.safetensors";

/// The source checkout this crate was built in (fixtures, scenes and models are found there).
pub fn workspace_root() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest
        .ancestors()
        .nth(2)
        .map_or_else(|| manifest.to_owned(), Path::to_path_buf)
}

/// How a fixture's content is recomputed; long ones say how far they are with one line at a
/// time.
type Generate = fn(&mut dyn FnMut(&str)) -> Result<Value, LabError>;

/// One golden fixture: where it lives, how to recompute it, and how close numbers must be.
#[derive(Debug, Clone, Copy)]
pub struct Fixture {
    /// Path relative to the workspace root.
    pub path: &'static str,
    /// Allowed relative difference of numbers (the same value is also the absolute floor).
    pub tolerance: f64,
    /// Recomputes the fixture's content.
    generate: Generate,
}

/// Every golden fixture of the workspace, in the order they are checked.
pub const FIXTURES: &[Fixture] = &[
    Fixture {
        path: "fixtures/golden/hand_presets.json",
        generate: |_| hand_presets(),
        tolerance: 1e-9,
    },
    Fixture {
        path: "fixtures/golden/eval_surface_small.json",
        generate: |_| crate::without_keys(&crate::surface_eval::surface_fixture()?, &[]),
        tolerance: 1e-3,
    },
    Fixture {
        path: "fixtures/golden/arap_heldout_small.json",
        generate: |_| arap_heldout(),
        tolerance: 1e-7,
    },
    Fixture {
        path: "fixtures/golden/contact_heldout_small.json",
        generate: |_| contact_heldout(),
        tolerance: 1e-4,
    },
    Fixture {
        path: "fixtures/golden/physics_heldout_small.json",
        generate: |_| {
            physics_heldout(&moe_io::read_config(
                &workspace_root().join("fixtures/physics/exact-markers.toml"),
            )?)
        },
        tolerance: 1e-4,
    },
    Fixture {
        path: "fixtures/golden/physics_default_heldout_small.json",
        generate: |_| physics_heldout(&PhysicsConfig::default()),
        tolerance: 1e-4,
    },
    Fixture {
        path: "fixtures/golden/eval_patting_small.json",
        generate: patting_small,
        tolerance: 1e-3,
    },
    Fixture {
        path: "fixtures/golden/eval_grasp_small.json",
        generate: grasp_small,
        tolerance: 1e-3,
    },
    Fixture {
        path: "fixtures/golden/sim_short_scene.json",
        generate: |_| sim_short_scene(),
        tolerance: 1e-6,
    },
    Fixture {
        path: "fixtures/scenes/head_patting.toml",
        generate: |_| scene(&moe_tendon_sim::paper_scenes::head_patting()?),
        tolerance: 1e-12,
    },
    Fixture {
        path: "fixtures/scenes/arm_patting.toml",
        generate: |_| scene(&moe_tendon_sim::paper_scenes::arm_patting()?),
        tolerance: 1e-12,
    },
    Fixture {
        path: "fixtures/scenes/inclined_plate_00.toml",
        generate: |_| scene(&moe_tendon_sim::paper_scenes::inclined_plate(0.0)?),
        tolerance: 1e-12,
    },
    Fixture {
        path: "fixtures/scenes/inclined_plate_30.toml",
        generate: |_| scene(&moe_tendon_sim::paper_scenes::inclined_plate(30.0)?),
        tolerance: 1e-12,
    },
    Fixture {
        path: "fixtures/scenes/inclined_plate_45.toml",
        generate: |_| scene(&moe_tendon_sim::paper_scenes::inclined_plate(45.0)?),
        tolerance: 1e-12,
    },
];

impl Fixture {
    /// Recomputes the fixture's content; `progress` is told, one line at a time, how far a long
    /// one is (patting and grasping, per pair and per incline).
    ///
    /// # Errors
    /// Whatever the stage that makes the content fails with.
    pub fn compute(&self, progress: &mut dyn FnMut(&str)) -> Result<Value, LabError> {
        (self.generate)(progress)
    }

    /// Whether the fixture is stored as TOML (the paper's scene files) rather than JSON.
    pub fn is_toml(&self) -> bool {
        self.path.ends_with(".toml")
    }

    /// The first place where the `committed` content and the `fresh` one differ beyond the
    /// fixture's tolerance, as a JSON path (`$.x[1]`) with both values; `None` when they agree.
    pub fn first_difference(&self, committed: &Value, fresh: &Value) -> Option<String> {
        first_difference(committed, fresh, self.tolerance, "$")
    }

    /// Writes `value` as the fixture's file under `root`, creating its directory: pretty JSON,
    /// or TOML under a header that says where it comes from.
    ///
    /// # Errors
    /// [`IoError`] when the directory or the file cannot be written, or the value cannot be
    /// written as TOML.
    pub fn write(&self, root: &Path, value: &Value) -> Result<(), IoError> {
        let path = root.join(self.path);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
        }
        if self.is_toml() {
            let header = "# Generated by `cargo xtask fixtures --update` from moe_tendon_sim::paper_scenes;\n\
                          # do not edit by hand. SI units.\n";
            let body = toml::to_string(value).map_err(|e| IoError::Serialize {
                path: path.clone(),
                message: e.to_string(),
            })?;
            moe_io::write_atomic(&path, format!("{header}{body}").as_bytes())
        } else {
            moe_io::write_json(&path, value)
        }
    }
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

/// Rounds every float of `v` to 1e-3 (fixtures of long studies compare across machines).
fn round3(v: &mut Value) {
    match v {
        Value::Number(n) => {
            if let Some(f) = n.as_f64()
                && n.is_f64()
            {
                *v = Value::from((f * 1e3).round() / 1e3);
            }
        }
        Value::Array(a) => a.iter_mut().for_each(round3),
        Value::Object(o) => o.values_mut().for_each(round3),
        _ => {}
    }
}

/// The built-in hands: counts, vertex ids and integral measures of every preset's finger.
fn hand_presets() -> Result<Value, LabError> {
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

/// The simulator's regression scene: its state digest (positions rounded to 1 nm) after all
/// steps, and the contact labels and penetration of its last frame.
fn sim_short_scene() -> Result<Value, LabError> {
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

/// A paper scene's settings, as its TOML file holds them.
fn scene(config: &moe_tendon_sim::SceneConfig) -> Result<Value, LabError> {
    crate::without_keys(config, &[])
}

/// The committed held-out frames with their hand and contact-label rule.
fn heldout_frames() -> Result<(moe_geom::HandModel, Vec<moe_geom::LabelledFrame>, String), LabError>
{
    let reader = DatasetReader::open(&workspace_root().join(HELDOUT_DIR))?;
    let hand = crate::datagen::dataset_hand(&reader)?;
    let frames = reader
        .labelled_frames(None, SplitFractions::default())
        .collect::<Result<Vec<_>, _>>()?;
    Ok((hand, frames, crate::datagen::label_rule(reader.card())))
}

/// SR-ARAP shapes of the held-out frames' keypoints (all markers and the seeded 4 of 7): per
/// frame the BCD and per-vertex errors against the true surface and a sample of estimated
/// vertices (mm).
fn arap_heldout() -> Result<Value, LabError> {
    let (hand, frames, _) = heldout_frames()?;
    crate::without_keys(&crate::contact_eval::arap_golden(&hand, &frames)?, &[])
}

/// Table 1 of the shipped model on the held-out frames (no KNN rows, no timings), plus the
/// network's summed contact probability per frame on the true shape.
fn contact_heldout() -> Result<Value, LabError> {
    let (hand, frames, rule) = heldout_frames()?;
    let dgcnn = crate::physics_study::load_model_on(&workspace_root().join(SHIPPED_MODEL), &hand)?;
    let table = crate::contact_eval::table1_golden(&hand, &frames, &rule, &dgcnn)?;
    crate::without_keys(&table, &[])
}

/// The physics estimator with `config` on the held-out frames.
fn physics_heldout(config: &PhysicsConfig) -> Result<Value, LabError> {
    let dir = workspace_root().join(HELDOUT_DIR);
    crate::without_keys(&crate::physics_study::physics_golden(&dir, config)?, &[])
}

/// `eval patting --size small`: every figure rounded to µm; what depends on the machine
/// (timings, vertex counts of meshes) left out.
fn patting_small(progress: &mut dyn FnMut(&str)) -> Result<Value, LabError> {
    use crate::patting::{
        DEFAULT_ESTIMATED_NOISE_FLOOR_M, DEFAULT_PRIOR_GATE_M, PattingSize, PattingStudyOptions,
        pair_progress, run_patting_study,
    };
    let options = PattingStudyOptions {
        size: PattingSize::Small,
        pairs: None,
        bodies: Vec::new(),
        model: workspace_root().join(SHIPPED_MODEL),
        camera_seed: 0,
        out: None,
        prior_gate_m: DEFAULT_PRIOR_GATE_M,
        estimated_noise_floor_m: DEFAULT_ESTIMATED_NOISE_FLOOR_M,
        physics: moe_physics::PhysicsConfig::default(),
        shape: moe_arap::ShapeConfig::default(),
    };
    let knn = crate::contact_eval::build_knn_index(
        &DatasetReader::open(&workspace_root().join(HELDOUT_DIR))?,
        None,
        false,
    )?;
    let mut started = std::time::Instant::now();
    let report = run_patting_study(&options, &knn, |body, k, pair| -> Result<(), LabError> {
        progress(&pair_progress(
            body,
            k,
            pair,
            started.elapsed().as_secs_f64(),
        ));
        started = std::time::Instant::now();
        Ok(())
    })?;
    let mut v = crate::without_keys(&report, &["secs", "variance_secs", "vertices"])?;
    round3(&mut v);
    Ok(v)
}

/// The grasp study of the golden fixture: one trial per incline, the paper's pipeline with the
/// shipped model, the default settings.
pub fn grasp_fixture_options() -> crate::grasp::GraspStudyOptions {
    use crate::grasp::{GraspOptions, GraspStudyOptions, GraspStudySource};
    GraspStudyOptions {
        trials: 1,
        model: workspace_root().join(SHIPPED_MODEL),
        camera_seed: 0,
        source: GraspStudySource::Pipeline,
        threshold: None,
        grasp: GraspOptions::default(),
        physics: moe_physics::PhysicsConfig::default(),
        shape: moe_arap::ShapeConfig::default(),
    }
}

/// `eval grasp` with [`grasp_fixture_options`], rounded to 1e-3.
fn grasp_small(progress: &mut dyn FnMut(&str)) -> Result<Value, LabError> {
    use crate::grasp::GraspInclineRow;
    let options = grasp_fixture_options();
    let mut started = std::time::Instant::now();
    let report =
        crate::grasp::run_grasp_study(&options, |row: &GraspInclineRow| -> Result<(), LabError> {
            progress(&row.progress(started.elapsed().as_secs_f64()));
            started = std::time::Instant::now();
            Ok(())
        })?;
    let mut v = crate::without_keys(&report, &[])?;
    round3(&mut v);
    Ok(v)
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

    #[test]
    fn rounding_keeps_integers_and_rounds_floats_to_a_thousandth() {
        let mut v = serde_json::json!({"a": [1.23456, 7], "b": {"c": -0.0004}, "d": "x"});
        round3(&mut v);
        assert_eq!(
            v,
            serde_json::json!({"a": [1.235, 7], "b": {"c": -0.0}, "d": "x"})
        );
    }

    /// Every fixture's file is committed, under a distinct path; the quick ones recompute to
    /// what is committed (the long ones are checked by the tool's golden test).
    #[test]
    fn every_fixture_is_committed_and_the_quick_ones_match() {
        let root = workspace_root();
        let mut paths: Vec<_> = FIXTURES.iter().map(|f| f.path).collect();
        paths.sort_unstable();
        paths.dedup();
        assert_eq!(paths.len(), FIXTURES.len());
        for fixture in FIXTURES {
            let text = std::fs::read_to_string(root.join(fixture.path)).unwrap();
            if fixture.path.ends_with("hand_presets.json") || fixture.is_toml() {
                let committed: Value = if fixture.is_toml() {
                    toml::from_str(&text).unwrap()
                } else {
                    serde_json::from_str(&text).unwrap()
                };
                let fresh = fixture.compute(&mut |_| {}).unwrap();
                assert_eq!(
                    fixture.first_difference(&committed, &fresh),
                    None,
                    "{}",
                    fixture.path
                );
            }
        }
    }
}
