//! `moe-touch hand`.

use crate::common::{assert_one_line_error, fixtures, run, run_json, run_ok, scratch, stable};

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

/// Median of a region's bound from the `--json` summary.
fn region_median(summary: &serde_json::Value, region: &str, key: &str) -> f64 {
    summary["bound"]["regions"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["region"] == region)
        .unwrap_or_else(|| panic!("region {region}"))[key]["median"]
        .as_f64()
        .unwrap()
}

#[test]
fn marker_layouts_give_their_counts() {
    for (layout, count) in [
        ("camera-row", 7),
        ("two-rows", 14),
        ("sides", 21),
        ("tip-ring", 13),
    ] {
        let dir = scratch(&format!("hand-layout-{layout}"));
        let summary = run_json(&[
            "hand",
            "--marker-layout",
            layout,
            "--vertex-budget",
            "512",
            "--out",
            dir.to_str().unwrap(),
            "--json",
        ]);
        assert!(summary.get("bound").is_none(), "no bound unless asked");
        for f in summary["fingers"].as_array().unwrap() {
            let ids = f["marker_vertices"].as_array().unwrap();
            assert_eq!(ids.len(), count, "{layout}");
            let mut distinct: Vec<u64> = ids.iter().map(|v| v.as_u64().unwrap()).collect();
            distinct.sort_unstable();
            distinct.dedup();
            assert_eq!(distinct.len(), count, "{layout}: distinct vertices");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// `--bound` prints the three regions, writes finger 0's map with the bound per vertex, and the
/// bound of N frames is that of one over √N.
#[test]
fn bound_reports_the_regions_and_writes_the_map() {
    let dir = scratch("hand-bound");
    let out = run_ok(&[
        "hand",
        "--marker-layout",
        "two-rows",
        "--out",
        dir.to_str().unwrap(),
        "--bound",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    for line in [
        "Cramér–Rao bound of a press on finger 0 (14 markers, layout two-rows)",
        "tip (0.80–1.00)",
        "middle (0.40–0.70)",
        "base (0.12–0.35)",
        "bound_finger_0.ply",
    ] {
        assert!(text.contains(line), "'{line}' missing from:\n{text}");
    }
    let map = moe_io::read_ply(&dir.join("bound_finger_0.ply")).unwrap();
    let mesh = moe_io::read_mesh(&dir.join("finger_0.obj")).unwrap();
    assert_eq!(
        map.points,
        mesh.vertices(),
        "the map is finger 0 in the hand frame"
    );
    let colors = map.colors.as_ref().expect("a colour ramp");
    assert_eq!(colors.len(), map.points.len());
    let along = map.scalar("bound_along_mm").unwrap();
    let around = map.scalar("bound_around_mm").unwrap();
    let movable = map.scalar("movable").unwrap();
    let markers = map.scalar("marker").unwrap();
    assert_eq!(markers.iter().filter(|&&m| m == 1.0).count(), 14);
    let moving: Vec<usize> = (0..along.len()).filter(|&v| movable[v] == 1.0).collect();
    assert!(moving.len() > 800, "{} movable vertices", moving.len());
    for &v in &moving {
        assert!(along[v] > 0.0 && around[v] > 0.0, "vertex {v}");
    }
    // The summary: finite medians, the base (far from where the finger bends) worst.
    let dir1 = scratch("hand-bound-json");
    let bound_json = |frames: &str, dir: &std::path::Path| {
        run_json(&[
            "hand",
            "--marker-layout",
            "two-rows",
            "--out",
            dir.to_str().unwrap(),
            "--bound",
            "--bound-frames",
            frames,
            "--json",
        ])
    };
    let one = bound_json("1", &dir1);
    assert_eq!(one["bound"]["markers"], 14);
    assert_eq!(one["bound"]["map"], "bound_finger_0.ply");
    let written: serde_json::Value = moe_io::read_json(&dir1.join("hand.json")).unwrap();
    assert_eq!(written, one, "hand.json holds the printed summary");
    for region in ["tip", "middle", "base"] {
        for key in ["along_mm", "around_mm", "force_sd_n"] {
            let m = region_median(&one, region, key);
            assert!(m.is_finite() && m > 0.0, "{region} {key}: {m}");
        }
    }
    assert!(region_median(&one, "base", "along_mm") > region_median(&one, "tip", "along_mm"));
    let four = bound_json("4", &dir1);
    for region in ["tip", "middle", "base"] {
        let ratio =
            region_median(&one, region, "along_mm") / region_median(&four, region, "along_mm");
        assert!(
            (ratio - 2.0).abs() < 1e-3,
            "{region}: 1 frame / 4 frames = {ratio}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::remove_dir_all(&dir1).unwrap();
}

#[test]
fn bound_options_need_bound_and_bad_layouts_are_named() {
    let dir = scratch("hand-bound-bad");
    let out_dir = dir.join("out");
    // A bound option without --bound is a usage error.
    let out = run(&[
        "hand",
        "--out",
        out_dir.to_str().unwrap(),
        "--bound-frames",
        "5",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--bound"));
    // An unknown layout name on the command line.
    let out = run(&[
        "hand",
        "--marker-layout",
        "four-rows",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("two-rows"));
    // Markers that would share vertices: one line naming the layout field, nothing written.
    let config = dir.join("crowded.toml");
    std::fs::write(
        &config,
        "preset = \"two-finger\"\n[finger]\nmarker_layout = { rows = [{ angle_deg = 0 }, { angle_deg = 2 }] }\n",
    )
    .unwrap();
    let out = run(&[
        "hand",
        "--config",
        config.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--bound",
    ]);
    let msg = assert_one_line_error(&out);
    assert!(msg.contains("marker_layout.rows"), "{msg}");
    assert!(!out_dir.exists(), "nothing written");
    // An unknown layout name in a config: the file, line and the presets.
    std::fs::write(
        &config,
        "preset = \"two-finger\"\n[finger]\nmarker_layout = \"two-row\"\n",
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
    assert!(
        msg.contains("crowded.toml:3") && msg.contains("two-rows"),
        "{msg}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--bound-observe` adds the wrist camera's depth image: the report says what it sees, every
/// region's median bound with the markers and depth is below the markers' alone, the harsher
/// depth noise gives a larger one, and the harsher noise without depth is refused.
#[test]
fn the_bound_with_depth_reports_what_the_camera_sees() {
    let dir = scratch("hand-bound-depth");
    let bound = |extra: &[&str]| {
        let mut args = vec![
            "hand",
            "--vertex-budget",
            "512",
            "--out",
            dir.to_str().unwrap(),
            "--bound",
            "--json",
        ];
        args.extend_from_slice(extra);
        run_json(&args)
    };
    let markers = bound(&[]);
    let both = bound(&["--bound-observe", "both"]);
    let harsher = bound(&["--bound-observe", "both", "--bound-harsher-depth"]);
    assert_eq!(markers["bound"]["observed"], "markers");
    assert!(markers["bound"].get("depth").is_none());
    assert_eq!(both["bound"]["observed"], "markers and depth");
    let seen = &both["bound"]["depth_coverage"];
    let (vertices, total) = (
        seen["vertices"].as_u64().unwrap(),
        seen["surface_vertices"].as_u64().unwrap(),
    );
    assert!(vertices > 20 && vertices < total / 2, "{seen}");
    assert!(seen["pixels"].as_f64().unwrap() > 1000.0, "{seen}");
    for region in ["tip", "middle", "base"] {
        for key in ["along_mm", "around_mm"] {
            let (m, b, h) = (
                region_median(&markers, region, key),
                region_median(&both, region, key),
                region_median(&harsher, region, key),
            );
            assert!(
                b < m && b < h,
                "{region} {key}: markers {m}, both {b}, harsher {h}"
            );
        }
    }
    let out = run(&[
        "hand",
        "--out",
        dir.to_str().unwrap(),
        "--bound",
        "--bound-harsher-depth",
    ]);
    let line = assert_one_line_error(&out);
    assert!(line.contains("--bound-harsher-depth"), "{line}");
    // Another camera from a file: the committed D405-class wrist camera, mounted farther back, sees
    // fewer pixels and bounds less tightly than the default camera, still far below the markers
    // alone at the base.
    let d405 = fixtures().join("cameras/d405-wrist.toml");
    let other = bound(&[
        "--bound-observe",
        "both",
        "--bound-camera",
        d405.to_str().unwrap(),
    ]);
    assert_eq!(other["bound"]["depth"]["intrinsics"]["width"], 424);
    let pixels = |v: &serde_json::Value| v["bound"]["depth_coverage"]["pixels"].as_f64().unwrap();
    assert!(
        pixels(&other) < pixels(&both),
        "{} vs {}",
        pixels(&other),
        pixels(&both)
    );
    let base = |v: &serde_json::Value| region_median(v, "base", "along_mm");
    assert!(base(&both) < base(&other) && base(&other) < base(&markers));
    // A rendering camera's file is told from the bound's own by its noise fields: a file with
    // only intrinsics stays a bound model (its assumed correlated part kept).
    let intrinsics_only = dir.join("intrinsics-only.toml");
    std::fs::write(
        &intrinsics_only,
        "[intrinsics]\nwidth = 424\nheight = 240\nfx = 223.4\nfy = 216.5\ncx = 211.5\ncy = 119.5\n",
    )
    .unwrap();
    let model = bound(&[
        "--bound-observe",
        "both",
        "--bound-camera",
        intrinsics_only.to_str().unwrap(),
    ]);
    assert_eq!(model["bound"]["depth"]["noise"]["correlated_sigma_m"], 1e-4);
    assert_eq!(other["bound"]["depth"]["noise"]["quantum_m"], 1e-4);
    // A bad file of either kind is refused naming the file and the field, writing nothing.
    for (name, text, field) in [
        (
            "bad-camera.toml",
            "min_range_m = 0.5\nmax_range_m = 0.1\n",
            "max_range_m",
        ),
        (
            "bad-rgbd.toml",
            "[noise]\nflying_pixel_fraction = 2.0\n",
            "flying_pixel_fraction",
        ),
    ] {
        let bad = dir.join(name);
        std::fs::write(&bad, text).unwrap();
        let out = run(&[
            "hand",
            "--out",
            dir.join("never").to_str().unwrap(),
            "--bound",
            "--bound-observe",
            "depth",
            "--bound-camera",
            bad.to_str().unwrap(),
        ]);
        let line = assert_one_line_error(&out);
        assert!(line.contains(name) && line.contains(field), "{line}");
        assert!(!dir.join("never").exists());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
