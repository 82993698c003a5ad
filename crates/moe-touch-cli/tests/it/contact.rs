//! `moe-touch contact`: on a point cloud against the PyTorch reference, on a hand shape with
//! its meshes, contact points and summary, and refusing bad models and inputs with one line.

use std::path::{Path, PathBuf};

use moe_contact::{DgcnnConfig, FeatureFrame, InputFeature, ModelCard, ModelWeights, PointSet};
use moe_geom::{FingerModel, FingerParams};
use safetensors::SafeTensors;

use crate::common::{assert_one_line_error, fixtures, run, run_json, run_ok, scratch};

fn reference(name: &str) -> Vec<f64> {
    let bytes = std::fs::read(fixtures().join("contact/reference_io.safetensors")).unwrap();
    let st = SafeTensors::deserialize(&bytes).unwrap();
    st.tensor(name)
        .unwrap()
        .data()
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

fn reference_model() -> PathBuf {
    fixtures().join("contact/reference_weights.safetensors")
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The reference input as a CSV file (shortest round-trip decimals: the same f64 values).
fn reference_points(dir: &Path) -> PathBuf {
    let input = reference("input");
    let rows: Vec<Vec<f64>> = input.chunks(3).map(<[f64]>::to_vec).collect();
    let p = dir.join("points.csv");
    moe_io::write_csv(&p, &["x", "y", "z"], &rows).unwrap();
    p
}

#[test]
fn contact_on_points_reproduces_the_pytorch_logits() {
    let dir = scratch("contact-points");
    let points = reference_points(&dir);
    for (aggregation, tolerance) in [("max", 1e-9), ("sum", 1e-10 * 64.4)] {
        let out_csv = dir.join(format!("{aggregation}.csv"));
        let report = run_json(&[
            "contact",
            "--points",
            path(&points),
            "--model",
            path(&reference_model()),
            "--aggregation",
            aggregation,
            "--dtype",
            "f64",
            "--out",
            path(&out_csv),
            "--json",
        ]);
        assert_eq!(report["points"], 2048);
        assert_eq!(report["card"], false);
        let table = moe_io::read_csv(&out_csv).unwrap();
        assert_eq!(
            table.header.unwrap(),
            vec!["logit0", "logit1", "probability"]
        );
        let want = reference(&format!("logits_{aggregation}_f64"));
        assert_eq!(table.rows.len(), 2048);
        for (row, w) in table.rows.iter().zip(want.chunks(2)) {
            assert!((row[0] - w[0]).abs() <= tolerance && (row[1] - w[1]).abs() <= tolerance);
            let p = 1.0 / (1.0 + (row[0] - row[1]).exp());
            assert!((row[2] - p).abs() < 1e-12);
        }
    }
}

/// A seeded model of the shipped form (per-finger sets in the finger frame) taking xyz and
/// `second`, written under `dir` by the feature's name.
fn per_finger_model(dir: &Path, second: InputFeature) -> PathBuf {
    let mut config = DgcnnConfig::default();
    config.input.point_set = PointSet::PerFinger;
    config.input.frame = FeatureFrame::Finger;
    config.input.features.push(second);
    let mut card = ModelCard::new(config.clone());
    card.threshold = 0.5;
    let weights = ModelWeights::seeded(&config, 6, 3).unwrap();
    let p = dir.join(format!("{}.safetensors", second.name()));
    moe_io::write_model_files(
        &p,
        &weights.to_bytes().unwrap(),
        Some(&card.to_json().unwrap()),
    )
    .unwrap();
    p
}

fn shape_dir(dir: &Path) -> PathBuf {
    let shape = dir.join("shape");
    run_ok(&[
        "shape",
        "--hand",
        "two-finger",
        "--keypoints",
        path(&fixtures().join("keypoints/plate_tip_front_frame4.json")),
        "--iterations",
        "10",
        "--out",
        path(&shape),
    ]);
    shape
}

/// `moe-touch contact` on a two-finger hand shape.
fn contact_on_shape(
    shape: &Path,
    model: &Path,
    out_dir: &Path,
    extra: &[&str],
) -> std::process::Output {
    let mut args = vec![
        "contact",
        "--hand",
        "two-finger",
        "--shape",
        path(shape),
        "--model",
        path(model),
        "--out",
        path(out_dir),
    ];
    args.extend_from_slice(extra);
    run(&args)
}

#[test]
fn contact_on_a_hand_shape_writes_coloured_meshes_contacts_and_a_summary() {
    let dir = scratch("contact-shape");
    let model = per_finger_model(&dir, InputFeature::RestXyz);
    let shape = shape_dir(&dir);
    let out_dir = dir.join("out");
    let out = contact_on_shape(&shape, &model, &out_dir, &["--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["card"], true);
    assert_eq!(report["threshold"], 0.5);
    let written: serde_json::Value = moe_io::read_json(&out_dir.join("contact.json")).unwrap();
    assert_eq!(written, report);
    let contacts = moe_io::read_csv(&out_dir.join("contacts.csv")).unwrap();
    let mut total = 0;
    for (i, f) in report["fingers"].as_array().unwrap().iter().enumerate() {
        let ply = moe_io::read_ply(&out_dir.join(f["mesh"].as_str().unwrap())).unwrap();
        let probs = ply.scalar("contact_probability").unwrap();
        assert_eq!(probs.len(), 1024, "finger {i}");
        let above: Vec<usize> = (0..probs.len())
            .filter(|&v| f64::from(probs[v]) >= 0.5)
            .collect();
        assert_eq!(f["contact_vertices"], above.len());
        // The colour ramp follows the probability: red grows with it.
        let colors = ply.colors.clone().unwrap();
        let (lo, hi) = (0..probs.len()).fold((0, 0), |(lo, hi), v| {
            (
                if probs[v] < probs[lo] { v } else { lo },
                if probs[v] > probs[hi] { v } else { hi },
            )
        });
        assert!(colors[hi][0] >= colors[lo][0]);
        // contacts.csv lists exactly those vertices, at the shape's positions.
        let mesh = moe_io::read_mesh(&shape.join(format!("finger_{i}.obj"))).unwrap();
        let rows: Vec<&Vec<f64>> = contacts.rows.iter().filter(|r| r[0] == i as f64).collect();
        assert_eq!(rows.len(), above.len());
        for (r, &v) in rows.iter().zip(&above) {
            assert_eq!(r[1], v as f64);
            let p = mesh.vertices()[v];
            assert_eq!([r[2], r[3], r[4]], [p.x, p.y, p.z]);
        }
        total += above.len();
    }
    assert_eq!(report["contact_vertices"], total);
}

/// A model that takes the tendon pulls runs on a shape given `--tendon-pulls`, its
/// probabilities depend on them, and it refuses a shape without them (or with pulls that do not
/// fit the hand) in one line, writing nothing.
#[test]
fn contact_on_a_shape_takes_the_tendon_pulls_a_model_needs() {
    let dir = scratch("contact-pulls");
    let model = per_finger_model(&dir, InputFeature::TendonPull);
    let shape = shape_dir(&dir);
    let probabilities = |pulls: &str, out: &Path| {
        let o = contact_on_shape(&shape, &model, out, &["--tendon-pulls", pulls]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let ply = moe_io::read_ply(&out.join("finger_0.ply")).unwrap();
        ply.scalar("contact_probability").unwrap().to_vec()
    };
    let bent = probabilities("0.004,-0.004,0,0;0,0,0.002,-0.002", &dir.join("bent"));
    let free = probabilities("0,0,0,0;0,0,0,0", &dir.join("free"));
    assert_ne!(bent, free);
    for (extra, needle) in [
        (&[][..], "tendon pulls"),
        (&["--tendon-pulls", "0,0,0;0,0,0,0"][..], "tendon pulls"),
        (
            &["--tendon-pulls", "0,0,x,0;0,0,0,0"][..],
            "'x' is not a number",
        ),
        (
            &["--tendon-pulls", "0,,0,0;0,0,0,0"][..],
            "finger 0, tendon 1",
        ),
        (
            &["--tendon-pulls", "0,0,0,0"][..],
            "fingers of the tendon pulls",
        ),
    ] {
        let out = dir.join("never");
        let o = contact_on_shape(&shape, &model, &out, extra);
        assert!(!o.status.success(), "{extra:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(needle), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?}");
    }
    // Pulls given to a model that does not take them are refused, not ignored.
    let plain = per_finger_model(&dir, InputFeature::RestXyz);
    let out = dir.join("never");
    let o = contact_on_shape(&shape, &plain, &out, &["--tendon-pulls", "0,0,0,0;0,0,0,0"]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("does not take them"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!out.exists());
}

fn write_reference_card(dir: &Path, edit: impl FnOnce(&mut ModelCard)) -> PathBuf {
    let p = dir.join("ref.safetensors");
    std::fs::copy(reference_model(), &p).unwrap();
    let mut card = ModelCard::new(DgcnnConfig::default());
    edit(&mut card);
    std::fs::write(dir.join("ref.json"), card.to_json().unwrap()).unwrap();
    p
}

#[test]
fn contact_refuses_bad_models_and_inputs_with_one_line_and_writes_nothing() {
    let dir = scratch("contact-errors");
    let points = reference_points(&dir);
    let out_csv = dir.join("never.csv");
    let on_points = |model: &Path, points: &Path, extra: &[&str]| {
        let mut args = vec![
            "contact",
            "--points",
            path(points),
            "--model",
            path(model),
            "--out",
            path(&out_csv),
        ];
        args.extend_from_slice(extra);
        let out = run(&args);
        let line = assert_one_line_error(&out);
        assert!(!out_csv.exists(), "nothing written after: {line}");
        line
    };

    // A weights file with a missing tensor.
    let weights = ModelWeights::parse(&std::fs::read(reference_model()).unwrap()).unwrap();
    let mut tensors: Vec<(String, Vec<usize>, Vec<u8>)> = weights
        .names()
        .filter(|n| *n != "edge3.phi.bias")
        .map(|n| {
            let (s, v) = weights.get(n).unwrap();
            (
                n.to_string(),
                s.to_vec(),
                v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            )
        })
        .collect();
    tensors.sort();
    let views: Vec<(String, safetensors::tensor::TensorView<'_>)> = tensors
        .iter()
        .map(|(n, s, b)| {
            (
                n.clone(),
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, s.clone(), b)
                    .unwrap(),
            )
        })
        .collect();
    let broken = dir.join("broken.safetensors");
    std::fs::write(&broken, safetensors::serialize(views, None).unwrap()).unwrap();
    assert!(on_points(&broken, &points, &[]).contains("edge3.phi.bias"));

    // A card that contradicts the weights, and one whose features a point cloud cannot give.
    let contradicting = write_reference_card(&dir, |c| c.architecture.edge_widths = [64, 64, 256]);
    assert!(on_points(&contradicting, &points, &[]).contains("edge_widths"));
    let rest = write_reference_card(&dir, |c| {
        c.architecture.input.features.push(InputFeature::RestXyz)
    });
    assert!(on_points(&rest, &points, &[]).contains("input.features"));
    std::fs::remove_file(dir.join("ref.json")).unwrap();

    // Fewer points than k, a non-finite point, a device this build does not have.
    let few = dir.join("few.csv");
    moe_io::write_csv(&few, &[], &vec![vec![0.0, 0.0, 0.01]; 5]).unwrap();
    assert!(on_points(&reference_model(), &few, &[]).contains("fewer than k = 30"));
    let nan = dir.join("nan.csv");
    std::fs::write(&nan, "0,0,0\nNaN,0,0\n").unwrap();
    let _ = on_points(&reference_model(), &nan, &[]);
    assert!(on_points(&reference_model(), &points, &["--device", "cuda"]).contains("cuda"));

    // A shape whose vertex count does not match the hand.
    let model = per_finger_model(&dir, InputFeature::RestXyz);
    let shape = shape_dir(&dir);
    let small = FingerModel::from_params(&FingerParams {
        vertex_budget: 300,
        ..FingerParams::default()
    })
    .unwrap();
    moe_io::write_mesh(&shape.join("finger_1.obj"), small.mesh()).unwrap();
    let out_dir = dir.join("out");
    let out = contact_on_shape(&shape, &model, &out_dir, &[]);
    let line = assert_one_line_error(&out);
    assert!(line.contains("finger 1"), "{line}");
    assert!(!out_dir.exists(), "nothing written");
}
