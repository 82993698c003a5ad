//! `moe-touch hand`.

use crate::common::{assert_one_line_error, fixtures, run, run_json, scratch, stable};

#[test]
fn presets_write_closed_meshes_and_matching_ids() {
    for (preset, fingers) in [("two-finger", 2), ("three-finger", 3), ("five-finger", 5)] {
        let dir = scratch(&format!("hand-{preset}"));
        let summary = run_json(&[
            "hand",
            "--preset",
            preset,
            "--out",
            dir.to_str().unwrap(),
            "--json",
        ]);
        assert_eq!(summary["num_fingers"], fingers);
        insta::assert_json_snapshot!(format!("hand_{preset}"), stable(summary.clone(), &dir));
        let written: serde_json::Value = moe_io::read_json(&dir.join("hand.json")).unwrap();
        assert_eq!(written, summary, "hand.json holds the printed summary");
        for f in summary["fingers"].as_array().unwrap() {
            let mesh = moe_io::read_mesh(&dir.join(f["mesh"].as_str().unwrap())).unwrap();
            mesh.require_closed().unwrap();
            assert_eq!(
                mesh.num_vertices(),
                f["num_vertices"].as_u64().unwrap() as usize
            );
            let markers: Vec<usize> = f["marker_vertices"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_u64().unwrap() as usize)
                .collect();
            assert_eq!(markers.len(), 7);
            assert!(markers.iter().all(|&m| m < mesh.num_vertices()));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn the_rest_mesh_matches_the_library_model() {
    let dir = scratch("hand-library");
    let out = run(&[
        "hand",
        "--out",
        dir.to_str().unwrap(),
        "--vertex-budget",
        "512",
    ]);
    assert!(out.status.success());
    let hand = moe_geom::HandModel::preset(
        moe_geom::HandPreset::TwoFinger,
        &moe_geom::FingerParams {
            vertex_budget: 512,
            ..Default::default()
        },
    )
    .unwrap();
    for i in 0..2 {
        let mesh = moe_io::read_mesh(&dir.join(format!("finger_{i}.obj"))).unwrap();
        assert_eq!(
            mesh.vertices(),
            hand.rest_vertices_in_hand(i).as_slice(),
            "bit-exact OBJ"
        );
        assert_eq!(mesh.faces(), hand.fingers()[i].model.mesh().faces());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn example_configs_load() {
    let configs = std::fs::read_dir(fixtures().join("configs")).unwrap();
    let mut n = 0;
    for entry in configs {
        let path = entry.unwrap().path();
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        if !matches!(ext, "toml" | "json") {
            continue;
        }
        let dir = scratch(&format!("hand-config-{n}"));
        let out = run(&[
            "hand",
            "--config",
            path.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}: {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(dir.join("hand.json").exists());
        std::fs::remove_dir_all(&dir).unwrap();
        n += 1;
    }
    assert!(n >= 2, "the example configs are found");
}

#[test]
fn bad_input_gives_one_line_and_writes_nothing() {
    let dir = scratch("hand-bad");
    let out_dir = dir.join("out");
    // A config with a malformed value.
    let config = dir.join("bad.toml");
    std::fs::write(
        &config,
        "preset = \"two-finger\"\n[finger]\nlength_m = -0.05\n",
    )
    .unwrap();
    let out = run(&[
        "hand",
        "--config",
        config.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let msg = assert_one_line_error(&out);
    assert!(msg.contains("length_m"), "{msg}");
    assert!(!out_dir.exists(), "nothing written");
    // A truncated config.
    std::fs::write(&config, "preset = \"two-fin").unwrap();
    let out = run(&[
        "hand",
        "--config",
        config.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let msg = assert_one_line_error(&out);
    assert!(msg.contains("bad.toml"), "{msg}");
    assert!(!out_dir.exists());
    // An unknown preset is a usage error.
    let out = run(&[
        "hand",
        "--preset",
        "four-finger",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("four-finger"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_closed_stdout_is_not_a_panic() {
    // `moe-touch hand --json | head -c 0`: the reader is gone before the summary is printed.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let dir = scratch("hand-pipe");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_moe-touch"))
        .args(["hand", "--out", dir.to_str().unwrap(), "--json"])
        .env("RUST_BACKTRACE", "0")
        .stdout(writer)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}
