//! `moe-touch sim` on the shipped Fig. 5 scenes.

use crate::common::{assert_one_line_error, fixtures, run, run_json, run_ok, scratch, stable};

#[test]
fn sim_writes_ply_frames_with_contact_labels_and_a_summary() {
    let out = scratch("sim-ply");
    let scene = fixtures().join("scenes/plate_middle_front.toml");
    let summary = run_json(&[
        "sim",
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--steps",
        "30",
        "--json",
    ]);
    assert_eq!(summary["steps"], 30);
    insta::assert_json_snapshot!("sim_plate_middle_front", stable(summary.clone(), &out));
    let frames = summary["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 4, "frames at steps 0, 10, 20, 30");
    let on_disk: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(on_disk["frames"], summary["frames"]);
    let last = frames.last().unwrap();
    let name = last["files"][0].as_str().unwrap();
    let ply = moe_io::read_ply(&out.join(name)).unwrap();
    assert_eq!(ply.points.len(), 1024);
    let contact = &ply.scalars.iter().find(|(n, _)| n == "contact").unwrap().1;
    let labelled = contact.iter().filter(|&&c| c == 1.0).count();
    assert!(labelled > 0, "the plate touches finger 0 by step 30");
    assert_eq!(last["contact_vertices"][0], labelled);
    assert_eq!(last["contact_vertices"][1], 0);
}

#[test]
fn sim_writes_obj_frames() {
    let out = scratch("sim-obj");
    let scene = fixtures().join("scenes/plate_tip_side.toml");
    run_ok(&[
        "sim",
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--steps",
        "2",
        "--format",
        "obj",
    ]);
    for name in ["frame_000000_finger_0.obj", "frame_000002_finger_1.obj"] {
        let mesh = moe_io::read_mesh(&out.join(name)).unwrap();
        assert_eq!(mesh.num_vertices(), 1024, "{name}");
    }
}

#[test]
fn bad_scene_is_one_line_error_and_writes_nothing() {
    let dir = scratch("sim-bad");
    let scene = dir.join("bad.toml");
    std::fs::write(&scene, "[solver]\ndt_secs = 0.0\n").unwrap();
    let err = refused(&scene, &dir.join("out"), &[]);
    assert!(err.contains("dt_secs"), "{err}");
}

#[test]
fn diverging_scene_names_the_step_and_leaves_no_output() {
    let dir = scratch("sim-diverge");
    let scene = dir.join("diverge.toml");
    let base = std::fs::read_to_string(fixtures().join("scenes/plate_middle_front.toml")).unwrap();
    // A kinetic-energy limit far below the first step's energy counts as divergence.
    let text = base.replace(
        "mode = \"dynamic\"",
        "mode = \"dynamic\"\nmax_kinetic_energy_j = 1e-15",
    );
    assert_ne!(text, base);
    std::fs::write(&scene, text).unwrap();
    let out = dir.join("out");
    let o = run(&[
        "sim",
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    let last = stderr.trim_end().lines().last().unwrap();
    assert!(
        last.starts_with("error:") && last.contains("step 0"),
        "{stderr}"
    );
    assert!(!out.exists(), "partial output left behind");
}

#[test]
fn steps_beyond_the_scene_and_scenes_beyond_the_step_limit_are_refused() {
    let dir = scratch("sim-limits");
    let scene = fixtures().join("scenes/plate_tip_side.toml");
    let out = dir.join("out");
    let err = refused(&scene, &out, &["--steps", "100000000000"]);
    assert!(
        err.contains("100000000000 steps asked") && err.contains("covers"),
        "{err}"
    );
    // A duration of 10^7 steps and one more.
    let long = dir.join("long.toml");
    std::fs::write(
        &long,
        "duration_secs = 10000.001\n[solver]\ndt_secs = 0.001\n",
    )
    .unwrap();
    let err = refused(&long, &out, &[]);
    assert!(err.contains("at most 10,000,000 steps"), "{err}");
}

/// Runs `moe-touch sim` on `scene` into `out` with `extra` arguments, asserts a one-line error
/// and that nothing was written, and returns the error.
fn refused(scene: &std::path::Path, out: &std::path::Path, extra: &[&str]) -> String {
    let mut args = vec![
        "sim",
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let err = assert_one_line_error(&run(&args));
    assert!(!out.exists(), "output left behind after: {err}");
    err
}
