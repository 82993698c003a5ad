//! The shipped scene files (paper Fig. 5: a thin plate touching the tip, the middle and the base
//! of a finger, from the front and from the side) parse and run.

use std::path::PathBuf;

use moe_geom::Real;
use moe_tendon_sim::{Scene, SceneConfig};

fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes")
}

fn load(name: &str) -> SceneConfig {
    let path = scenes_dir().join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    toml::from_str(&text).unwrap_or_else(|e| panic!("{name}: {e}"))
}

const SCENES: [&str; 6] = [
    "plate_tip_front.toml",
    "plate_tip_side.toml",
    "plate_middle_front.toml",
    "plate_middle_side.toml",
    "plate_base_front.toml",
    "plate_base_side.toml",
];

#[test]
fn every_fig5_scene_parses_and_runs_a_few_steps() {
    for name in SCENES {
        let mut scene = Scene::new(load(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut state = scene.initial_state();
        for _ in 0..3 {
            scene
                .step(&mut state)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        assert_eq!(scene.num_steps(), 120, "{name}");
    }
}

#[test]
fn the_middle_front_scene_labels_the_front_of_finger_0_only() {
    let config = load("plate_middle_front.toml");
    let mut scene = Scene::new(config).unwrap();
    let mut state = scene.initial_state();
    // Run to the end of the press (t = 0.6 s).
    for _ in 0..60 {
        scene.step(&mut state).unwrap();
    }
    let frame = scene.frame(&state);
    let finger = scene.hand().fingers()[0].model.clone();
    let labels = &frame.fingers[0].labels;
    let ids: Vec<usize> = (0..labels.len()).filter(|&i| labels[i]).collect();
    assert!(ids.len() >= 3, "{} labelled", ids.len());
    assert!(frame.fingers[1].labels.iter().all(|&l| !l));
    for &i in &ids {
        let rest = finger.mesh().vertices()[i];
        assert!(rest.x > 0.0, "vertex {i} at {rest} is not on the front");
        assert!(
            (0.025..0.055).contains(&rest.z),
            "vertex {i} at {rest} outside the plate's band"
        );
    }
    let penetration = -frame.fingers[0]
        .distances_m
        .iter()
        .copied()
        .fold(Real::INFINITY, Real::min);
    assert!(penetration < 0.0005, "penetration {penetration}");
}
