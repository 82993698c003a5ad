//! Contact from physics on the command line: `contact --method physics` on one frame of
//! markers, `run --contact physics` over an episode (forces in the report and in the result
//! file), `calibrate` from contact-free frames; each refusing bad input in one line, writing
//! nothing.

use std::path::{Path, PathBuf};

use moe_geom::{FingerParams, HandModel, HandPreset, Point3};
use moe_geom::{HandEstimator as _, Observation};
use moe_io::DatasetFrame;
use moe_record::EpisodeFrame;

use crate::common::{assert_one_line_error, fixtures, run, run_json, scratch};

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn episode_path() -> PathBuf {
    fixtures().join("episodes/plate_tip_front_small.mcap")
}

fn episode() -> moe_record::Episode {
    moe_record::read_episode(&episode_path()).unwrap()
}

/// The plate-at-the-tip frame 4 (the plate presses finger 0's tip; one marker of finger 1
/// unseen).
fn pressed_keypoints() -> PathBuf {
    fixtures().join("keypoints/plate_tip_front_frame4.json")
}

/// The true markers of an episode frame as a `--keypoints` file.
fn keypoints_file(dir: &Path, name: &str, frame: &EpisodeFrame) -> PathBuf {
    let p = dir.join(name);
    let fingers: Vec<Vec<Option<Point3>>> = frame
        .markers_in_hand
        .iter()
        .map(|m| m.iter().copied().map(Some).collect())
        .collect();
    moe_io::write_json(&p, &serde_json::json!({ "fingers": fingers })).unwrap();
    p
}

/// `moe-touch contact --method physics` on the two-finger hand with pulls at rest.
fn physics_contact(keypoints: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    physics_contact_pulling(keypoints, "0,0,0,0;0,0,0,0", out, extra)
}

/// `moe-touch contact --method physics` on the two-finger hand with `pulls`.
fn physics_contact_pulling(
    keypoints: &Path,
    pulls: &str,
    out: &Path,
    extra: &[&str],
) -> std::process::Output {
    let mut args = vec![
        "contact",
        "--method",
        "physics",
        "--hand",
        "two-finger",
        "--keypoints",
        path(keypoints),
        "--tendon-pulls",
        pulls,
        "--out",
        path(out),
    ];
    args.extend_from_slice(extra);
    run(&args)
}

fn ok_json(o: &std::process::Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("one JSON object on stdout")
}

fn vector(v: &serde_json::Value) -> [f64; 3] {
    let a = v.as_array().unwrap();
    [0, 1, 2].map(|i| a[i].as_f64().unwrap())
}

#[test]
fn physics_contact_writes_the_dented_shape_the_loads_and_the_finger_forces() {
    let dir = scratch("physics-contact");
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let out = dir.join("pressed");
    let report = ok_json(&physics_contact(&pressed_keypoints(), &out, &["--json"]));
    let written: serde_json::Value = moe_io::read_json(&out.join("contact.json")).unwrap();
    assert_eq!(written, report);
    assert_eq!(report["method"], "physics");
    assert_eq!(report["frame"], "hand");
    assert_eq!(report["threshold"], 0.5);
    // Without --world-from-hand: the identity (fingers up).
    assert_eq!(
        report["world_from_hand"],
        serde_json::json!([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    );

    // The plate presses finger 0: one load or more there, none on finger 1.
    let loads: serde_json::Value = moe_io::read_json(&out.join("loads.json")).unwrap();
    assert_eq!(loads["frame"], "hand");
    let loads = loads["loads"].as_array().unwrap();
    assert!(!loads.is_empty(), "a press, no load");
    assert_eq!(report["loads"], loads.len());
    assert!(loads.iter().all(|l| l["finger"] == 0), "{loads:?}");
    let fingers = report["fingers"].as_array().unwrap();
    assert_eq!(fingers[1]["loads"], 0);
    assert_eq!(fingers[1]["force_magnitude_n"], 0.0);
    for l in loads {
        let m = l["magnitude_n"].as_f64().unwrap();
        let f = vector(&l["force_n"]);
        assert!((f.iter().map(|x| x * x).sum::<f64>().sqrt() - m).abs() < 1e-12);
        // Tens of millinewtons, resolved to a few percent; at the tip (the top 30 mm).
        assert!((0.01..1.0).contains(&m), "{m} N");
        assert!(l["magnitude_sd_n"].as_f64().unwrap() < 0.5 * m, "{l}");
        assert!(vector(&l["location_rest_m"])[2] > 0.05, "{l}");
        let along = l["location_sd_along_m"].as_f64().unwrap();
        assert!((0.0..0.05).contains(&along), "{l}");
    }
    // The finger's force is the sum of its loads'.
    let sum = loads.iter().fold([0.0; 3], |acc, l| {
        let f = vector(&l["force_n"]);
        [acc[0] + f[0], acc[1] + f[1], acc[2] + f[2]]
    });
    let finger0 = vector(&fingers[0]["force_n"]);
    for k in 0..3 {
        assert!((finger0[k] - sum[k]).abs() < 1e-12, "{finger0:?} {sum:?}");
    }
    assert!(fingers[0]["pressed_probability"].as_f64().unwrap() > 0.5);

    // The meshes: the dented surface with probability and per-vertex force, coloured.
    let contacts = moe_io::read_csv(&out.join("contacts.csv")).unwrap();
    assert_eq!(
        contacts.header.unwrap(),
        ["finger", "vertex", "x", "y", "z", "probability"]
    );
    assert_eq!(report["contact_vertices"], contacts.rows.len());
    assert!(!contacts.rows.is_empty());
    for (i, f) in fingers.iter().enumerate() {
        let ply = moe_io::read_ply(&out.join(f["mesh"].as_str().unwrap())).unwrap();
        assert_eq!(ply.points.len(), 1024);
        assert!(ply.colors.is_some());
        let probability = ply.scalar("contact_probability").unwrap();
        let force = ply.scalar("force_n").unwrap();
        let force_sum: f64 = force.iter().map(|&v| f64::from(v)).sum();
        let magnitude = f["force_magnitude_n"].as_f64().unwrap();
        // Per-vertex magnitudes add up to at least the net force (1e-6: f32 in the file).
        assert!(force_sum >= magnitude * (1.0 - 1e-6) - 1e-9, "finger {i}");
        if i == 1 {
            assert!(force.iter().all(|&v| v == 0.0));
        }
        let rows: Vec<&Vec<f64>> = contacts.rows.iter().filter(|r| r[0] == i as f64).collect();
        assert_eq!(f["contact_vertices"], rows.len());
        for r in rows {
            let v = r[1] as usize;
            assert!(r[5] >= 0.5 && f64::from(probability[v]) >= 0.5 - 1e-6);
            assert_eq!(
                [r[2], r[3], r[4]],
                [ply.points[v].x, ply.points[v].y, ply.points[v].z]
            );
        }
        // Finger 0 is dented: its tip moved from rest by more than a millimetre.
        let rest = hand.rest_vertices_in_hand(i);
        let moved = ply
            .points
            .iter()
            .zip(&rest)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        if i == 0 {
            assert!(moved > 1e-3, "finger 0 moved {moved} m");
        }
    }

    // Nothing presses in frame 0 of the episode: no load, no contact, and the same files.
    let free = dir.join("free");
    let kp = keypoints_file(&dir, "frame0.json", &episode().frames[0]);
    let report = ok_json(&physics_contact(&kp, &free, &["--json"]));
    let loads: serde_json::Value = moe_io::read_json(&free.join("loads.json")).unwrap();
    assert_eq!(loads["loads"].as_array().unwrap().len(), 0);
    assert_eq!(report["loads"], 0);
    assert_eq!(report["contact_vertices"], 0);
    for name in [
        "finger_0.ply",
        "finger_1.ply",
        "contacts.csv",
        "contact.json",
    ] {
        assert!(free.join(name).exists(), "{name}");
    }

    // The hand's pose sets gravity: fingers held sideways bend otherwise.
    let sideways = dir.join("sideways");
    let report = ok_json(&physics_contact(
        &kp,
        &sideways,
        &[
            "--world-from-hand",
            "0.1,-0.2,0.3,0.7071067811865476,0,0,0.7071067811865476",
            "--json",
        ],
    ));
    assert_eq!(report["world_from_hand"][0], 0.1);
    let a = moe_io::read_ply(&free.join("finger_0.ply")).unwrap();
    let b = moe_io::read_ply(&sideways.join("finger_0.ply")).unwrap();
    assert_ne!(a.points, b.points);
}

/// Every committed settings file of the physics estimator loads, is named in the report and
/// finds the press on finger 0 only.
#[test]
fn the_committed_physics_settings_load_and_find_the_press() {
    let dir = scratch("physics-settings");
    let mut n = 0;
    for entry in std::fs::read_dir(fixtures().join("physics")).unwrap() {
        let config = entry.unwrap().path();
        if config.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let out = dir.join(format!("out-{n}"));
        let report = ok_json(&physics_contact(
            &pressed_keypoints(),
            &out,
            &["--physics-config", path(&config), "--json"],
        ));
        assert_eq!(report["physics_config"], path(&config));
        let fingers = report["fingers"].as_array().unwrap();
        assert!(
            fingers[0]["loads"].as_u64().unwrap() >= 1,
            "{}",
            config.display()
        );
        assert_eq!(fingers[1]["loads"], 0, "{}", config.display());
        n += 1;
    }
    assert!(n >= 1, "the committed settings are found");
}

/// The application studies take the physics estimator's settings, and refuse a file they
/// cannot read, or one given to the other pipeline, before any trial runs.
#[test]
fn the_studies_refuse_physics_settings_they_cannot_use_before_any_trial() {
    let dir = scratch("study-settings");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "marker_sigma_m = -1.0\n").unwrap();
    let depth = fixtures().join("physics/depth.toml");
    for (args, needle) in [
        (
            vec![
                "eval",
                "grasp",
                "--contact",
                "dgcnn",
                "--physics-config",
                path(&depth),
            ],
            "--physics-config is for --contact physics",
        ),
        (
            vec!["eval", "grasp", "--physics-config", path(&bad)],
            "marker_sigma_m",
        ),
        (
            vec!["eval", "patting", "--physics-config", path(&bad)],
            "marker_sigma_m",
        ),
    ] {
        let line = assert_one_line_error(&run(&args));
        assert!(line.contains(needle), "{args:?}: {line}");
        assert!(line.contains("--physics-config"), "{args:?}: {line}");
    }
    // SR-ARAP's settings of the paper's pipeline, checked before any trajectory is simulated.
    let bad_shape = dir.join("bad-shape.toml");
    std::fs::write(&bad_shape, "[depth]\npasses = 1000\n").unwrap();
    let bad = path(&bad_shape);
    let model = fixtures().join("../models/contact-two-finger.safetensors");
    for args in [
        vec![
            "eval",
            "physics",
            "--trajectories",
            "1",
            "--model",
            path(&model),
            "--shape-config",
            bad,
        ],
        vec!["eval", "patting", "--shape-config", bad],
        vec!["eval", "grasp", "--contact", "dgcnn", "--shape-config", bad],
    ] {
        let line = assert_one_line_error(&run(&args));
        assert!(
            line.contains("depth.passes") && line.contains("--shape-config"),
            "{args:?}: {line}"
        );
    }
    let line = assert_one_line_error(&run(&[
        "eval",
        "grasp",
        "--contact",
        "physics",
        "--shape-config",
        bad,
    ]));
    assert!(line.contains("--shape-config is for"), "{line}");
    let line = assert_one_line_error(&run(&["eval", "physics", "--shape-config", bad]));
    assert!(line.contains("needs --model"), "{line}");
    // A rendering camera, checked before any trajectory or scene is simulated.
    let bad_camera = dir.join("bad-camera.toml");
    std::fs::write(&bad_camera, "[noise]\nflying_pixel_fraction = 2.0\n").unwrap();
    let bad = path(&bad_camera);
    for args in [
        vec!["eval", "physics", "--perceived", "--camera", bad],
        vec!["eval", "markers", "--camera", bad],
    ] {
        let line = assert_one_line_error(&run(&args));
        assert!(
            line.contains("flying_pixel_fraction") && line.contains("--camera"),
            "{args:?}: {line}"
        );
    }
    // The detector's settings for perceived frames, checked before any trajectory.
    let bad_detector = dir.join("bad-detector.toml");
    std::fs::write(&bad_detector, "dbscan_min_points = 1\n").unwrap();
    let bad = path(&bad_detector);
    let line = assert_one_line_error(&run(&[
        "eval",
        "physics",
        "--perceived",
        "--detector-config",
        bad,
    ]));
    assert!(
        line.contains("dbscan_min_points") && line.contains("--detector-config"),
        "{line}"
    );
}

#[test]
fn physics_contact_refuses_bad_input_in_one_line_and_writes_nothing() {
    let dir = scratch("physics-contact-errors");
    let out = dir.join("never");
    let refused_pulling = |keypoints: &Path, pulls: &str, extra: &[&str], needles: &[&str]| {
        let o = physics_contact_pulling(keypoints, pulls, &out, extra);
        let line = assert_one_line_error(&o);
        for needle in needles {
            assert!(line.contains(needle), "{extra:?}: {line} lacks {needle}");
        }
        assert!(!out.exists(), "{extra:?}: something was written");
    };
    let refused = |keypoints: &Path, extra: &[&str], needles: &[&str]| {
        refused_pulling(keypoints, "0,0,0,0;0,0,0,0", extra, needles);
    };
    let good = pressed_keypoints();
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };

    // Keypoints: malformed, NaN, out of range, wrong counts.
    let text = std::fs::read_to_string(&good).unwrap();
    let truncated = write("truncated.json", &text[..text.len() / 2]);
    refused(&truncated, &[], &["truncated.json"]);
    let nan = write("nan.json", &text.replacen("0.014550319258956598", "NaN", 1));
    refused(&nan, &[], &["nan.json"]);
    let huge = write(
        "huge.json",
        &text.replacen("0.014550319258956598", "1e999", 1),
    );
    refused(&huge, &[], &["huge.json"]);
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    value["fingers"][1].as_array_mut().unwrap().pop();
    let short = write("short.json", &value.to_string());
    refused(&short, &[], &["short.json", "finger 1 has 6 markers"]);
    value["fingers"].as_array_mut().unwrap().pop();
    let one = write("one.json", &value.to_string());
    refused(&one, &[], &["one.json", "1 fingers, the hand has 2"]);

    // Tendon pulls of the wrong length or not numbers.
    refused_pulling(
        &good,
        "0,0,0;0,0,0,0",
        &[],
        &["finger 0 has 3 tendon pulls"],
    );
    refused_pulling(&good, "0,0,0,0", &[], &["1 fingers of tendon pulls"]);
    refused_pulling(
        &good,
        "0,0,nan,0;0,0,0,0",
        &[],
        &["finger 0, tendon 2", "not finite"],
    );
    refused_pulling(&good, "0,0,0,0;0,0,0,0;0,0,0,0", &[], &["3 fingers"]);

    // A material that is not physical, or has fields the material does not have.
    for (name, body, needle) in [
        (
            "negative-e.toml",
            "[material]\nyoungs_modulus_pa = -5.0\n",
            "youngs_modulus_pa",
        ),
        (
            "zero-e.toml",
            "[material]\nyoungs_modulus_pa = 0.0\n",
            "youngs_modulus_pa",
        ),
        (
            "poisson.toml",
            "[material]\npoisson_ratio = 0.5\n",
            "poisson_ratio",
        ),
        (
            "poisson-low.json",
            r#"{"material": {"poisson_ratio": -1.0}}"#,
            "poisson_ratio",
        ),
        ("unknown.toml", "[material]\nyoung = 1.0\n", "young"),
        ("top.toml", "stiffness = 1.0\n", "stiffness"),
    ] {
        let m = write(name, body);
        refused(&good, &["--material", path(&m)], &[name, needle]);
    }
    for (name, body, needle) in [
        ("sigma.toml", "marker_sigma_m = 0.0\n", "marker_sigma_m"),
        ("extra.toml", "marker_sigma = 1e-4\n", "marker_sigma"),
    ] {
        let c = write(name, body);
        refused(&good, &["--physics-config", path(&c)], &[name, needle]);
    }

    // A pose that is not one.
    refused(
        &good,
        &["--world-from-hand", "0,0,0,0,0,1"],
        &["6 values, expected 7"],
    );
    refused(
        &good,
        &["--world-from-hand", "0,0,0,0,0,0,2"],
        &["quaternion", "norm"],
    );
    refused(
        &good,
        &["--world-from-hand", "0,0,0,0,0,x,1"],
        &["'x' is not a number"],
    );

    // Options that mean nothing for physics, and physics options for the DGCNN.
    let model = fixtures().join("../models/contact-two-finger.safetensors");
    refused(
        &good,
        &["--model", path(&model)],
        &["--model is for --method dgcnn"],
    );
    refused(
        &good,
        &["--shape", path(&dir)],
        &["--shape is for --method dgcnn"],
    );
    refused(
        &good,
        &["--dtype", "f64"],
        &["--dtype is for --method dgcnn"],
    );
    let o = run(&[
        "contact",
        "--method",
        "physics",
        "--hand",
        "two-finger",
        "--keypoints",
        path(&good),
        "--out",
        path(&out),
    ]);
    let line = assert_one_line_error(&o);
    assert!(line.contains("--tendon-pulls"), "{line}");
    assert!(!out.exists());
    let o = run(&[
        "contact",
        "--hand",
        "two-finger",
        "--keypoints",
        path(&good),
        "--model",
        path(&model),
        "--out",
        path(&out),
    ]);
    let line = assert_one_line_error(&o);
    assert!(
        line.contains("--keypoints is for --method physics"),
        "{line}"
    );
    assert!(!out.exists());
}

#[test]
fn run_with_physics_reports_forces_and_draws_them_as_arrows_and_a_plot() {
    let dir = scratch("physics-run");
    let out = dir.join("result.mcap");
    let report_path = dir.join("report.json");
    let summary = run_json(&[
        "run",
        "--contact",
        "physics",
        "--episode",
        path(&episode_path()),
        "--out",
        path(&out),
        "--report",
        path(&report_path),
        "--json",
    ]);
    assert_eq!(summary["frames"], 7);
    assert!(summary.get("per_frame").is_none());
    let forces = summary["forces"]["fingers"].as_array().unwrap();
    assert_eq!(forces.len(), 2);
    let report: serde_json::Value = moe_io::read_json(&report_path).unwrap();
    let episode = episode();
    let per_frame = report["per_frame"].as_array().unwrap();
    assert_eq!(per_frame.len(), 7);
    let mut pressed_frames = 0;
    for (k, (r, frame)) in per_frame.iter().zip(&episode.frames).enumerate() {
        let fingers = r["finger_forces"].as_array().unwrap();
        assert_eq!(fingers.len(), 2, "frame {k}");
        let loads = r["loads"].as_array().unwrap();
        for (f, x) in fingers.iter().enumerate() {
            let on_finger: Vec<_> = loads.iter().filter(|l| l["finger"] == f).collect();
            assert_eq!(x["loads"], on_finger.len(), "frame {k} finger {f}");
            let sum = on_finger
                .iter()
                .fold(0.0, |s, l| s + vector(&l["force_n"])[0]);
            assert!((vector(&x["force_n"])[0] - sum).abs() < 1e-12, "frame {k}");
        }
        // Where the plate presses finger 0 (the ground truth), the estimate finds force there.
        if !frame.contact_vertices[0].is_empty() {
            pressed_frames += 1;
            let m = fingers[0]["magnitude_n"].as_f64().unwrap();
            assert!(m > 0.01, "frame {k}: {m} N on the pressed finger");
        }
        // Before the plate arrives, nothing.
        if k == 0 {
            assert!(loads.is_empty(), "frame 0: {loads:?}");
        }
    }
    assert_eq!(pressed_frames, 3);

    // The result file: the force topics beside the others, one arrow per load, the plotted
    // magnitudes the report's.
    let bytes = std::fs::read(&out).unwrap();
    let mut arrows = Vec::new();
    let mut plotted = Vec::new();
    let mut info = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        match m.channel.topic.as_str() {
            "/run/info" => {
                info = Some(serde_json::from_slice::<moe_record::RunInfo>(&m.data).unwrap())
            }
            "/estimate/forces" => {
                let u = <foxglove::messages::SceneUpdate as foxglove::Decode>::decode(&m.data[..])
                    .unwrap();
                arrows.push(u.entities.iter().map(|e| e.arrows.len()).sum::<usize>());
            }
            "/estimate/finger_force" => plotted
                .push(serde_json::from_slice::<moe_record::FingerForcesMessage>(&m.data).unwrap()),
            _ => {}
        }
    }
    assert_eq!(info.unwrap().force_arrow_m_per_n, Some(0.2));
    assert_eq!(arrows.len(), 7);
    assert_eq!(plotted.len(), 7);
    for (k, r) in per_frame.iter().enumerate() {
        assert_eq!(arrows[k], r["loads"].as_array().unwrap().len(), "frame {k}");
        for (f, x) in r["finger_forces"].as_array().unwrap().iter().enumerate() {
            let m = plotted[k].fingers[f].magnitude_n;
            assert!((m - x["magnitude_n"].as_f64().unwrap()).abs() < 1e-12);
        }
    }

    // Options of the other method, or a bad material: one line, nothing written.
    let never = dir.join("never.mcap");
    let ep = episode_path();
    let model = fixtures().join("../models/contact-two-finger.safetensors");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[material]\npoisson_ratio = 0.7\n").unwrap();
    let bad_shape = dir.join("bad-shape.toml");
    std::fs::write(&bad_shape, "[depth]\nenabled = true\nweight = -1.0\n").unwrap();
    // A material fitted to a hand of three fingers.
    let other_hand = dir.join("other-hand.toml");
    std::fs::write(
        &other_hand,
        "[hand]\nvertices_per_finger = [1024, 1024, 1024]\nmarkers_per_finger = [7, 7, 7]\n\
         tendons_per_finger = [4, 4, 4]\n",
    )
    .unwrap();
    for (extra, needle) in [
        (
            vec!["--contact", "physics", "--model", path(&model)],
            "--model is for --contact dgcnn",
        ),
        (
            vec!["--contact", "physics", "--iterations", "5"],
            "--iterations is for --contact dgcnn",
        ),
        (
            vec!["--contact", "physics", "--shape-config", path(&bad_shape)],
            "--shape-config is for --contact dgcnn",
        ),
        (
            vec![
                "--contact",
                "dgcnn",
                "--model",
                path(&model),
                "--shape-config",
                path(&bad_shape),
            ],
            "depth.weight",
        ),
        (
            vec!["--contact", "dgcnn", "--material", path(&bad)],
            "--material is for --contact physics",
        ),
        (
            vec!["--contact", "physics", "--material", path(&bad)],
            "poisson_ratio",
        ),
        (
            vec!["--contact", "physics", "--force-scale", "0"],
            "--force-scale",
        ),
        (
            vec!["--material", path(&other_hand)],
            "calibrate on this hand",
        ),
    ] {
        let mut args = vec!["run", "--episode", path(&ep), "--out", path(&never)];
        args.extend(extra.iter().copied());
        let line = assert_one_line_error(&run(&args));
        assert!(line.contains(needle), "{extra:?}: {line}");
        assert!(!never.exists());
    }
}

/// A data set of two trajectories made of the episode's frames (the plate touches finger 0
/// from frame 2 on), with the default simulator parameters on its card; `contact_everywhere`
/// labels every frame in contact.
fn dataset(dir: &Path, contact_everywhere: bool) -> PathBuf {
    use moe_lab::datagen::{GenPlan, generate, simulated_layout};
    let params = moe_tendon_sim::randomize::RandomSceneParams::default();
    let layout = simulated_layout(&params).unwrap();
    let episode = episode();
    let to32 = |p: &Point3| [p.x as f32, p.y as f32, p.z as f32];
    let frames = move |t: u64| -> Result<Vec<DatasetFrame>, moe_lab::LabError> {
        Ok(episode
            .frames
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let mut contact: Vec<u8> = f
                    .contact_vertices
                    .iter()
                    .zip(&episode.info.finger_num_vertices)
                    .flat_map(|(ids, &n)| {
                        let mut l = vec![0u8; n];
                        ids.iter().for_each(|&i| l[i as usize] = 1);
                        l
                    })
                    .collect();
                if contact_everywhere {
                    contact[0] = 1;
                }
                let iso = f.world_from_hand;
                let (x, q) = (iso.translation.vector, iso.rotation.quaternion());
                DatasetFrame {
                    trajectory_id: t,
                    frame_index: k as u32,
                    vertices: f
                        .finger_vertices_in_hand
                        .iter()
                        .flatten()
                        .map(to32)
                        .collect(),
                    contact_force_n: contact.iter().map(|&c| 0.05 * f32::from(c)).collect(),
                    obstacle_distance_m: vec![f32::INFINITY; contact.len()],
                    contact,
                    finger_force_n: Some(vec![[0.0; 3]; 2]),
                    markers: f.markers_in_hand.iter().flatten().map(to32).collect(),
                    world_from_hand: [x.x, x.y, x.z, q.i, q.j, q.k, q.w],
                    tendon_pull_m: f
                        .tendon_pull_m
                        .iter()
                        .flatten()
                        .map(|&v| v as f32)
                        .collect(),
                    object_family: 0,
                    object_params: vec![0.0; layout_object_params()],
                }
            })
            .collect())
    };
    let out = dir.join(if contact_everywhere {
        "touched"
    } else {
        "data"
    });
    std::fs::create_dir_all(&out).unwrap();
    let plan = GenPlan {
        trajectories: 2,
        trajectories_per_shard: 2,
        seed: 1,
        machine: 1,
        machines: 1,
    };
    let generator = serde_json::json!({ "simulator": "moe-tendon-sim", "params": params });
    generate(&plan, &out, &layout, generator, &frames, &|_, _| {}).unwrap();
    out
}

fn layout_object_params() -> usize {
    moe_lab::datagen::simulated_layout(&Default::default())
        .unwrap()
        .object_param_len
}

#[test]
fn calibrate_fits_the_material_from_contact_free_frames_and_refuses_what_it_cannot_use() {
    let dir = scratch("physics-calibrate");
    let calibrate = |source: &[&str], out: &Path, extra: &[&str]| {
        let mut args = vec!["calibrate"];
        args.extend_from_slice(source);
        args.extend_from_slice(&["--out", path(out), "--max-evaluations", "3"]);
        args.extend_from_slice(extra);
        run(&args)
    };
    let ep = episode_path();
    let episode_src = ["--episode", path(&ep)];

    // The episode: its 3 frames with contact left out, the 4 others in two streams.
    let toml = dir.join("material.toml");
    let r = ok_json(&calibrate(&episode_src, &toml, &["--json"]));
    assert_eq!(r["frames_read"], 7);
    assert_eq!(r["frames_with_contact"], 3);
    assert_eq!(r["streams"], 2);
    assert_eq!(r["frames"], 4);
    assert_eq!(r["markers"], "detected");
    assert_eq!(r["initial"]["youngs_modulus_pa"], 1e5);
    let e = r["fitted"]["youngs_modulus_pa"].as_f64().unwrap();
    assert!(e > 0.0 && e.is_finite());
    assert!(r["rms_fitted_m"].as_f64().unwrap() <= r["rms_initial_m"].as_f64().unwrap());
    // The file is a material the estimator reads, with the fitted values.
    let material: moe_physics::HandMaterial = moe_io::read_config(&toml).unwrap();
    assert_eq!(material.material.youngs_modulus_pa, e);
    assert_eq!(
        material.material.rayleigh_stiffness,
        r["fitted"]["rayleigh_stiffness"].as_f64().unwrap()
    );
    let o = physics_contact(
        &pressed_keypoints(),
        &dir.join("with-material"),
        &["--material", path(&toml), "--json"],
    );
    assert_eq!(ok_json(&o)["material"], path(&toml));
    // The ground-truth markers on request, the damping kept, JSON out.
    let json = dir.join("material.json");
    let r = ok_json(&calibrate(
        &episode_src,
        &json,
        &["--markers", "truth", "--keep-damping", "--json"],
    ));
    assert_eq!(r["markers"], "ground truth");
    let kept = r["fitted"]["rayleigh_stiffness"].as_f64().unwrap();
    assert!((kept - r["initial"]["rayleigh_stiffness"].as_f64().unwrap()).abs() < 1e-12);
    let _: moe_physics::HandMaterial = moe_io::read_config(&json).unwrap();

    // A data set: each trajectory's frames before its first contact.
    let data = dataset(&dir, false);
    let data_src = ["--data", path(&data)];
    let r = ok_json(&calibrate(&data_src, &dir.join("d.toml"), &["--json"]));
    assert_eq!(r["trajectories"], 2);
    assert_eq!(r["frames_read"], 14);
    assert_eq!(r["frames"], 4);
    assert_eq!(r["streams"], 2);
    assert_eq!(r["hand"], "two-finger");
    let r = ok_json(&calibrate(
        &data_src,
        &dir.join("d1.toml"),
        &["--max-trajectories", "1", "--hand", "two-finger", "--json"],
    ));
    assert_eq!(
        (r["trajectories"].as_u64(), r["frames"].as_u64()),
        (Some(1), Some(2))
    );

    // Refused in one line, nothing written.
    let never = dir.join("never.toml");
    let refused = |source: &[&str], out: &Path, extra: &[&str], needle: &str| {
        let line = assert_one_line_error(&calibrate(source, out, extra));
        assert!(line.contains(needle), "{extra:?}: {line}");
        assert!(!out.exists(), "{extra:?}");
    };
    let touched = dataset(&dir, true);
    refused(
        &["--data", path(&touched)],
        &never,
        &[],
        "no contact-free frames",
    );
    // An episode whose every frame has contact.
    let mut all = episode();
    for f in &mut all.frames {
        f.contact_vertices[1] = vec![0];
    }
    let all_path = dir.join("all-contact.mcap");
    moe_record::write_episode(&all_path, &all.info, &all.frames).unwrap();
    refused(
        &["--episode", path(&all_path)],
        &never,
        &[],
        "no contact-free frames",
    );
    refused(
        &data_src,
        &never,
        &["--hand", "three-finger"],
        "another hand",
    );
    // Another mesh, and the same number of vertices on a longer finger.
    let long = fixtures().join("configs/preset-long-fingers.toml");
    refused(&data_src, &never, &["--hand", path(&long)], "another hand");
    let custom = dir.join("long.toml");
    std::fs::write(
        &custom,
        "preset = \"two-finger\"\n[finger]\nlength_m = 0.09\n",
    )
    .unwrap();
    refused(
        &data_src,
        &never,
        &["--hand", path(&custom)],
        "another hand",
    );
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[material]\nyoungs_modulus_pa = -1.0\n").unwrap();
    refused(
        &episode_src,
        &never,
        &["--material", path(&bad)],
        "youngs_modulus_pa",
    );
    refused(&episode_src, &dir.join("m.txt"), &[], ".toml or .json");
    refused(
        &episode_src,
        &never,
        &["--max-trajectories", "1"],
        "--max-trajectories is for --data",
    );
    refused(&[], &never, &[], "--episode");
    refused(
        &episode_src,
        &never,
        &["--hand", "three-finger"],
        "three-finger",
    );
}

/// The physics estimator's shapes as a training input: every frame kept in order with its
/// labels, its shape the estimator's on its trajectory's stream (the same, bit for bit, as one
/// estimator run over each trajectory in turn), whatever the threads.
#[test]
fn physics_shapes_for_training_are_each_trajectorys_stream() {
    use moe_lab::physics_eval::with_physics_shapes;
    let reader = moe_io::DatasetReader::open(&fixtures().join("contact/heldout")).unwrap();
    let frames: Vec<moe_geom::LabelledFrame> = reader
        .labelled_frames(None, moe_io::SplitFractions::default())
        .collect::<Result<_, _>>()
        .unwrap();
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let (material, config) = (
        moe_physics::HandMaterial::default(),
        moe_physics::PhysicsConfig::default(),
    );
    let frame_secs = 0.05;
    let out = with_physics_shapes(&hand, &frames, frame_secs, &material, &config, None).unwrap();
    assert_eq!(out.len(), frames.len());
    let mut estimator = moe_physics::PhysicsEstimator::new(&hand, &material, &config).unwrap();
    let mut previous = None;
    let mut dented = 0;
    for (a, b) in out.iter().zip(&frames) {
        assert_eq!(
            (a.trajectory_id, a.frame_index, &a.contact, &a.markers),
            (b.trajectory_id, b.frame_index, &b.contact, &b.markers)
        );
        if previous != Some(b.trajectory_id) {
            estimator.reset();
            previous = Some(b.trajectory_id);
        }
        let e = estimator
            .estimate(
                &Observation::from_keypoints(&b.markers)
                    .with_tendon_pulls(&b.tendon_pull_m)
                    .with_world_from_hand(b.world_from_hand)
                    .with_time(f64::from(b.frame_index) * frame_secs),
            )
            .unwrap();
        assert_eq!(a.shape, e.shape);
        dented += usize::from(!e.details.loads.is_empty());
    }
    assert!(dented > 0, "the held-out frames have presses");
    let err = with_physics_shapes(&hand, &frames, 0.0, &material, &config, None).unwrap_err();
    assert!(err.to_string().contains("frame_secs"), "{err}");
}
