//! Config files: the shipped hand configs, JSON/TOML round trips and their errors.

use moe_geom::{FingerParams, HandPreset};
use moe_io::{
    FingerConfig, HandConfig, IoError, TendonConfig, load_hand_config, read_config, read_json,
    write_json, write_toml,
};

use crate::{fixture_configs, scratch};

#[test]
fn shipped_preset_config_loads_with_its_finger_parameters() {
    let hand = load_hand_config(&fixture_configs().join("preset-long-fingers.toml")).unwrap();
    assert_eq!(hand.num_fingers(), 2);
    for f in hand.fingers() {
        let top = f
            .model
            .mesh()
            .vertices()
            .iter()
            .map(|p| p.z)
            .fold(f64::MIN, f64::max);
        assert!((top - 0.095).abs() < 1e-12, "finger length {top}");
        assert_eq!(f.model.marker_vertices().len(), 7);
    }
}

#[test]
fn shipped_custom_mesh_config_loads_the_mesh_and_its_ids() {
    let dir = fixture_configs();
    let hand = load_hand_config(&dir.join("custom-mesh-finger.toml")).unwrap();
    assert_eq!(hand.num_fingers(), 2);
    let mesh_finger = &hand.fingers()[0];
    let mesh = moe_io::read_obj(&dir.join("tiny-finger.obj")).unwrap();
    assert_eq!(mesh_finger.model.mesh(), &mesh);
    assert_eq!(mesh_finger.model.marker_vertices(), &[7, 13, 19]);
    assert_eq!(mesh_finger.model.base_vertices(), &[0, 1, 2, 3, 4, 5, 6]);
    assert_eq!(mesh_finger.model.tendon_routes().len(), 2);
    // Markers are on the +x side in the finger frame, and base vertices at z = 0.
    for &m in mesh_finger.model.marker_vertices() {
        assert!(mesh.vertices()[m as usize].x > 0.0 || m == 19);
    }
    for &b in mesh_finger.model.base_vertices() {
        assert_eq!(mesh.vertices()[b as usize].z, 0.0);
    }
    // The pose turns +x toward the palm centre: the base centre sits at (0.025, 0, 0) and the
    // finger's +x axis maps to -x of the hand.
    let iso = mesh_finger.hand_from_finger.iso();
    let c = iso * moe_geom::Point3::origin();
    assert!((c - moe_geom::Point3::new(0.025, 0.0, 0.0)).norm() < 1e-15);
    let x = iso * moe_geom::Vector3::x();
    assert!((x + moe_geom::Vector3::x()).norm() < 1e-12, "{x}");
}

#[test]
fn hand_config_round_trips_through_json_and_toml() {
    let dir = scratch("hand-config");
    std::fs::copy(
        fixture_configs().join("tiny-finger.obj"),
        dir.join("tiny-finger.obj"),
    )
    .unwrap();
    let config = HandConfig {
        preset: None,
        finger: None,
        fingers: vec![
            FingerConfig {
                params: None,
                mesh: Some("tiny-finger.obj".into()),
                marker_vertices: vec![7, 13],
                base_vertices: vec![0, 1, 2],
                tendons: vec![TendonConfig {
                    points_in_finger: vec![[0.001, 0.0, 0.0], [0.001, 0.0, 0.03]],
                    antagonist: 0,
                }],
                position_m: [0.1, 0.2, 0.3],
                rotation_axis_angle_rad: [0.0, 0.5, 0.0],
            },
            FingerConfig {
                params: Some(FingerParams {
                    vertex_budget: 200,
                    ..FingerParams::default()
                }),
                mesh: None,
                marker_vertices: vec![],
                base_vertices: vec![],
                tendons: vec![],
                position_m: [0.0; 3],
                rotation_axis_angle_rad: [0.0; 3],
            },
        ],
    };
    write_json(&dir.join("hand.json"), &config).unwrap();
    write_toml(&dir.join("hand.toml"), &config).unwrap();
    let from_json: HandConfig = read_json(&dir.join("hand.json")).unwrap();
    let from_toml: HandConfig = read_config(&dir.join("hand.toml")).unwrap();
    assert_eq!(from_json, config);
    assert_eq!(from_toml, config);
    let a = load_hand_config(&dir.join("hand.json")).unwrap();
    let b = load_hand_config(&dir.join("hand.toml")).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.fingers()[0].model.marker_vertices(), &[7, 13]);

    let preset = HandConfig {
        preset: Some(HandPreset::FiveFinger),
        finger: None,
        fingers: vec![],
    };
    write_json(&dir.join("p.json"), &preset).unwrap();
    assert_eq!(
        load_hand_config(&dir.join("p.json")).unwrap().num_fingers(),
        5
    );
}

#[test]
fn config_errors_name_the_file_and_place() {
    let dir = scratch("config-errors");
    std::fs::write(
        dir.join("bad.toml"),
        "preset = \"two-finger\"\n[finger]\nlength = 0.1\n",
    )
    .unwrap();
    let e = load_hand_config(&dir.join("bad.toml")).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: Some(3), .. }), "{e}");
    assert!(e.to_string().contains("bad.toml:3:"), "{e}");

    std::fs::write(dir.join("bad.json"), "{\"preset\": \"four-finger\"}").unwrap();
    let e = load_hand_config(&dir.join("bad.json")).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: Some(1), .. }), "{e}");

    std::fs::write(
        dir.join("ids.toml"),
        "[[fingers]]\nmesh = \"m.obj\"\nmarker_vertices = [99]\nbase_vertices = [0]\n",
    )
    .unwrap();
    std::fs::copy(fixture_configs().join("tiny-finger.obj"), dir.join("m.obj")).unwrap();
    let e = load_hand_config(&dir.join("ids.toml")).unwrap_err();
    assert!(
        e.to_string().contains("fingers[0]") && e.to_string().contains("99"),
        "{e}"
    );

    std::fs::write(dir.join("h.yaml"), "preset: two-finger\n").unwrap();
    assert!(matches!(
        load_hand_config(&dir.join("h.yaml")),
        Err(IoError::UnsupportedExtension { .. })
    ));
}
