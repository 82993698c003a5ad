//! `moe-touch arap` and `moe-touch shape`.

use moe_geom::{FingerModel, FingerParams, HandKeypoints, HandModel, HandPreset, Vector3};

use crate::common::{assert_one_line_error, run, run_json, run_ok, scratch, stable};

fn finger() -> FingerModel {
    FingerModel::from_params(&FingerParams {
        vertex_budget: 300,
        ..FingerParams::default()
    })
    .unwrap()
}

#[test]
fn arap_translates_a_mesh_whose_handles_all_move_together() {
    let dir = scratch("arap-translate");
    let finger = finger();
    let mesh_path = dir.join("rest.obj");
    moe_io::write_mesh(&mesh_path, finger.mesh()).unwrap();
    let shift = Vector3::new(0.01, -0.02, 0.005);
    let handles: Vec<serde_json::Value> = finger
        .base_vertices()
        .iter()
        .chain(finger.marker_vertices())
        .map(|&v| {
            let t = finger.mesh().vertices()[v as usize] + shift;
            serde_json::json!({"vertex": v, "target": [t.x, t.y, t.z]})
        })
        .collect();
    let c_path = dir.join("c.json");
    moe_io::write_json(&c_path, &serde_json::json!({ "handles": handles })).unwrap();
    let (out_path, log_path) = (dir.join("deformed.obj"), dir.join("energy.csv"));
    let out = run_ok(&[
        "arap",
        "--mesh",
        mesh_path.to_str().unwrap(),
        "--constraints",
        c_path.to_str().unwrap(),
        "--iterations",
        "5",
        "--out",
        out_path.to_str().unwrap(),
        "--energy-log",
        log_path.to_str().unwrap(),
        "--json",
    ]);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(summary["iterations"], 5);
    assert_eq!(summary["num_handles"], handles.len());
    let deformed = moe_io::read_mesh(&out_path).unwrap();
    let err = deformed
        .vertices()
        .iter()
        .zip(finger.mesh().vertices())
        .map(|(d, r)| (d - (r + shift)).norm())
        .fold(0.0, f64::max);
    assert!(err < 1e-9, "{err:e}");
    let log = std::fs::read_to_string(&log_path).unwrap();
    assert_eq!(
        log.lines().count(),
        6,
        "header and one row per iteration:\n{log}"
    );
}

#[test]
fn arap_rejects_bad_constraints_and_meshes_with_one_line() {
    let dir = scratch("arap-bad");
    let mesh_path = dir.join("rest.obj");
    moe_io::write_mesh(&mesh_path, finger().mesh()).unwrap();
    let out_path = dir.join("out.obj");
    let attempt = |mesh: &std::path::Path, constraints: serde_json::Value| {
        let c_path = dir.join("c.json");
        moe_io::write_json(&c_path, &constraints).unwrap();
        run(&[
            "arap",
            "--mesh",
            mesh.to_str().unwrap(),
            "--constraints",
            c_path.to_str().unwrap(),
            "--out",
            out_path.to_str().unwrap(),
        ])
    };
    let conflicting = serde_json::json!({"handles": [
        {"vertex": 5, "target": [0.0, 0.0, 0.0]},
        {"vertex": 5, "target": [0.0, 0.0, 1.0]}
    ]});
    let msg = assert_one_line_error(&attempt(&mesh_path, conflicting));
    assert!(msg.contains("vertex 5"), "{msg}");
    let out_of_range =
        serde_json::json!({"handles": [{"vertex": 100000, "target": [0.0, 0.0, 0.0]}]});
    let msg = assert_one_line_error(&attempt(&mesh_path, out_of_range));
    assert!(msg.contains("100000"), "{msg}");
    // Three triangles share the edge 0–1: not a manifold mesh.
    let bad_mesh = dir.join("nonmanifold.obj");
    std::fs::write(
        &bad_mesh,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n",
    )
    .unwrap();
    let one = serde_json::json!({"handles": [{"vertex": 0, "target": [0.0, 0.0, 0.0]}]});
    assert_one_line_error(&attempt(&bad_mesh, one));
    assert!(!out_path.exists(), "no output after an error");
}

#[test]
fn shape_writes_every_finger_and_flags_a_fully_occluded_one() {
    let dir = scratch("shape");
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let mut kp: HandKeypoints = hand.rest_keypoints();
    kp.fingers[0][2] = None;
    kp.fingers[1] = vec![None; kp.fingers[1].len()];
    let kp_path = dir.join("kp.json");
    moe_io::write_json(&kp_path, &kp).unwrap();
    let out_dir = dir.join("out");
    let report = run_json(&[
        "shape",
        "--hand",
        "two-finger",
        "--keypoints",
        kp_path.to_str().unwrap(),
        "--iterations",
        "10",
        "--out",
        out_dir.to_str().unwrap(),
        "--json",
    ]);
    let fingers = report["fingers"].as_array().unwrap();
    insta::assert_json_snapshot!("shape_occluded_finger", stable(report.clone(), &dir));
    assert_eq!(fingers[0]["missing_markers"], serde_json::json!([2]));
    assert_eq!(fingers[0]["all_markers_missing"], false);
    assert_eq!(fingers[1]["all_markers_missing"], true);
    for (i, f) in fingers.iter().enumerate() {
        let mesh = moe_io::read_mesh(&out_dir.join(f["mesh"].as_str().unwrap())).unwrap();
        // Rest keypoints give back the rest hand.
        let err = mesh
            .vertices()
            .iter()
            .zip(hand.rest_vertices_in_hand(i))
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "finger {i}: {err:e}");
    }
    let written: serde_json::Value = moe_io::read_json(&out_dir.join("shape.json")).unwrap();
    assert_eq!(written, report);

    // A keypoint file for the wrong number of fingers.
    kp.fingers.pop();
    moe_io::write_json(&kp_path, &kp).unwrap();
    let out = run(&[
        "shape",
        "--hand",
        "two-finger",
        "--keypoints",
        kp_path.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert_one_line_error(&out);
    let out = run(&[
        "shape",
        "--hand",
        "four-finger",
        "--keypoints",
        "x.json",
        "--out",
        "y",
    ]);
    let msg = assert_one_line_error(&out);
    assert!(msg.contains("four-finger"), "{msg}");
}
