//! `moe-touch plane`.

use moe_geom::SeededRng;

use crate::common::{assert_one_line_error, run, run_ok, scratch, stable};

/// 60 points on the plane z = 0.1 + 0.5 y (normal ∝ (0, −0.5, 1)) with 0.2 mm noise, and 20
/// points scattered above it.
fn incline_points() -> Vec<Vec<f64>> {
    let mut rng = SeededRng::new(3);
    let mut rows = Vec::new();
    for _ in 0..60 {
        let (x, y) = (
            rng.uniform_range(-0.05, 0.05),
            rng.uniform_range(-0.05, 0.05),
        );
        rows.push(vec![x, y, 0.1 + 0.5 * y + 2e-4 * rng.normal()]);
    }
    for _ in 0..20 {
        let (x, y) = (
            rng.uniform_range(-0.05, 0.05),
            rng.uniform_range(-0.05, 0.05),
        );
        rows.push(vec![x, y, 0.1 + 0.5 * y + rng.uniform_range(0.01, 0.05)]);
    }
    rows
}

#[test]
fn fits_an_incline_and_reports_normal_offset_inliers_and_rms() {
    let dir = scratch("plane-incline");
    let points = dir.join("points.csv");
    moe_io::write_csv(&points, &["x", "y", "z"], &incline_points()).unwrap();
    let args = [
        "plane",
        "--points",
        points.to_str().unwrap(),
        "--threshold",
        "0.001",
        "--seed",
        "4",
        "--json",
    ];
    let out = run_ok(&args);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    insta::assert_json_snapshot!("plane_incline", stable(v.clone(), &dir));
    let n: Vec<f64> = v["normal"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let truth = [0.0, -0.5, 1.0].map(|c: f64| c / 1.25f64.sqrt());
    let cos: f64 = n.iter().zip(truth).map(|(a, b)| a * b).sum();
    assert!(cos.abs() > 0.9999, "{n:?}");
    // n·x + d = 0 through (0, 0, 0.1).
    let d = v["offset_m"].as_f64().unwrap();
    assert!((n[2] * 0.1 + d).abs() < 5e-4, "{d}");
    let inliers: Vec<u64> = v["inliers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_u64().unwrap())
        .collect();
    assert_eq!(inliers, (0..60).collect::<Vec<u64>>());
    let rms = v["rms_m"].as_f64().unwrap();
    assert!(rms > 5e-5 && rms < 4e-4, "{rms}");
    // The same seed, the same output.
    assert_eq!(run(&args).stdout, out.stdout);
}

#[test]
fn too_few_collinear_and_non_numeric_points_are_one_line_errors() {
    let dir = scratch("plane-bad");
    let two = dir.join("two.csv");
    moe_io::write_csv(&two, &["x", "y", "z"], &[vec![0.0; 3], vec![1.0, 0.0, 0.0]]).unwrap();
    let err = assert_one_line_error(&run(&["plane", "--points", two.to_str().unwrap()]));
    assert!(err.contains("at least 3"), "{err}");
    let line = dir.join("line.csv");
    let rows: Vec<Vec<f64>> = (0..5).map(|k| vec![k as f64, 0.0, 0.0]).collect();
    moe_io::write_csv(&line, &["x", "y", "z"], &rows).unwrap();
    let err = assert_one_line_error(&run(&["plane", "--points", line.to_str().unwrap()]));
    assert!(err.contains("collinear"), "{err}");
    let nan = dir.join("nan.csv");
    std::fs::write(&nan, "x,y,z\n0,0,0\n1,0,0\n0,1,nan\n").unwrap();
    let err = assert_one_line_error(&run(&["plane", "--points", nan.to_str().unwrap()]));
    assert!(err.contains("nan") || err.contains("non-finite"), "{err}");
    let err = assert_one_line_error(&run(&[
        "plane",
        "--points",
        line.to_str().unwrap(),
        "--threshold=-1",
    ]));
    assert!(err.contains("distance_threshold_m"), "{err}");
}
