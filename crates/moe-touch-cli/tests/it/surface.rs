//! `moe-touch surface`.

use moe_geom::SeededRng;
use moe_geom::shapes::icosphere;
use moe_geom::{Point3, TriMesh, Vector3};

use crate::common::{assert_one_line_error, run, run_json, run_ok, scratch, stable};

fn sphere_points(r: f64, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = SeededRng::new(seed);
    (0..n)
        .map(|_| {
            let d = Vector3::new(rng.normal(), rng.normal(), rng.normal()).normalize() * r;
            vec![d.x, d.y, d.z]
        })
        .collect()
}

/// Writes the prior most tests use, a 9 cm level-3 icosphere, as `dir/prior.obj`.
fn sphere_prior(dir: &std::path::Path) -> std::path::PathBuf {
    let prior = dir.join("prior.obj");
    moe_io::write_mesh(&prior, &icosphere(3, 0.09)).unwrap();
    prior
}

#[test]
fn sphere_method_reconstructs_a_sphere_and_reports_fitted_hyper_parameters() {
    let dir = scratch("surface-sphere");
    let contacts = dir.join("contacts.csv");
    moe_io::write_csv(&contacts, &["x", "y", "z"], &sphere_points(0.05, 200, 1)).unwrap();
    let out_path = dir.join("surface.obj");
    let report = run_json(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--method",
        "sphere",
        "--grid",
        "40",
        "--out",
        out_path.to_str().unwrap(),
        "--json",
    ]);
    insta::assert_json_snapshot!("surface_sphere", stable(report.clone(), &dir));
    assert_eq!(report["contacts"], 200);
    assert_eq!(report["hyper"]["fitted"], true);
    assert!(
        report["log_marginal_likelihood"]
            .as_f64()
            .unwrap()
            .is_finite()
    );
    let mesh = moe_io::read_mesh(&out_path).unwrap();
    mesh.require_closed().unwrap();
    let worst = mesh
        .vertices()
        .iter()
        .map(|p| (p.coords.norm() - 0.05).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-3, "{worst}");
}

#[test]
fn prior_method_writes_variance_and_answers_queries_in_order() {
    let dir = scratch("surface-prior");
    let prior = sphere_prior(&dir);
    let contacts = dir.join("contacts.csv");
    // The body is 10 mm larger than the prior on the patted cap.
    let pts: Vec<Vec<f64>> = sphere_points(0.1, 300, 2)
        .into_iter()
        .filter(|p| p[2] > 0.03)
        .collect();
    moe_io::write_csv(&contacts, &["x", "y", "z"], &pts).unwrap();
    let queries = dir.join("q.csv");
    moe_io::write_csv(
        &queries,
        &["x", "y", "z"],
        &[
            vec![0.0, 0.0, 0.1],
            vec![0.0, 0.0, 0.0],
            vec![0.3, 0.0, 0.0],
        ],
    )
    .unwrap();
    let (out_path, var_path, q_out) = (dir.join("s.obj"), dir.join("v.ply"), dir.join("qv.csv"));
    let report = run_json(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--prior",
        prior.to_str().unwrap(),
        "--grid",
        "40",
        "--out",
        out_path.to_str().unwrap(),
        "--variance-out",
        var_path.to_str().unwrap(),
        "--query",
        queries.to_str().unwrap(),
        "--query-out",
        q_out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(report["queries"], 3);
    let ply = moe_io::read_ply(&var_path).unwrap();
    let std = ply.scalar("std").expect("std scalar");
    assert_eq!(std.len(), ply.points.len());
    // Standard deviation: small on the patted top, larger on the unobserved bottom.
    let top: Vec<f32> = ply
        .points
        .iter()
        .zip(std)
        .filter(|(p, _)| p.z > 0.07)
        .map(|(_, s)| *s)
        .collect();
    let bottom: Vec<f32> = ply
        .points
        .iter()
        .zip(std)
        .filter(|(p, _)| p.z < -0.07)
        .map(|(_, s)| *s)
        .collect();
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    assert!(
        mean(&top) < mean(&bottom),
        "{} vs {}",
        mean(&top),
        mean(&bottom)
    );
    let table = moe_io::read_csv(&q_out).unwrap();
    assert_eq!(
        table.header.as_deref(),
        Some(&["mean".to_owned(), "std".to_owned()][..])
    );
    assert_eq!(table.rows.len(), 3);
    assert!(
        table.rows[0][0].abs() < 2e-3,
        "on the contacts: {:?}",
        table.rows[0]
    );
    assert!(table.rows[1][0] < -0.05, "inside: {:?}", table.rows[1]);
    // Outside, 0.21 m from the prior: the (uniform 10 mm) correction is long-range here.
    assert!(
        (table.rows[2][0] - 0.21).abs() < 0.015,
        "far outside: {:?}",
        table.rows[2]
    );
    let mesh = moe_io::read_mesh(&out_path).unwrap();
    let top_r = mesh
        .vertices()
        .iter()
        .filter(|p| p.z > 0.08)
        .map(|p| p.coords.norm())
        .fold(0.0, f64::max);
    assert!(
        (top_r - 0.1).abs() < 2e-3,
        "top follows the contacts: {top_r}"
    );
}

#[test]
fn nonprob_baseline_writes_a_closed_mesh() {
    let dir = scratch("surface-nonprob");
    let prior = sphere_prior(&dir);
    let contacts = dir.join("contacts.csv");
    moe_io::write_csv(&contacts, &[], &sphere_points(0.095, 50, 3)).unwrap();
    let out_path = dir.join("np.obj");
    run_ok(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--prior",
        prior.to_str().unwrap(),
        "--method",
        "nonprob",
        "--out",
        out_path.to_str().unwrap(),
    ]);
    moe_io::read_mesh(&out_path)
        .unwrap()
        .require_closed()
        .unwrap();
}

#[test]
fn poisson_mesher_writes_a_closed_sphere_and_reports_its_time() {
    let dir = scratch("surface-poisson");
    let contacts = dir.join("contacts.csv");
    moe_io::write_csv(&contacts, &["x", "y", "z"], &sphere_points(0.05, 200, 1)).unwrap();
    let out_path = dir.join("surface.ply");
    let report = run_json(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--method",
        "sphere",
        "--grid",
        "32",
        "--mesher",
        "poisson",
        "--poisson-depth",
        "4",
        "--out",
        out_path.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(report["mesher"], "poisson");
    assert!(report["timings"]["poisson_secs"].as_f64().unwrap() > 0.0);
    let mesh = moe_io::read_mesh(&out_path).unwrap();
    mesh.require_closed().unwrap();
    assert!(mesh.signed_volume() > 0.0, "outward oriented");
    let worst = mesh
        .vertices()
        .iter()
        .map(|p| (p.coords.norm() - 0.05).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1.5e-3, "{worst}");
    // The depth option belongs to the Poisson mesher.
    let err = assert_one_line_error(&run(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--method",
        "sphere",
        "--poisson-depth",
        "4",
        "--out",
        out_path.to_str().unwrap(),
    ]));
    assert!(err.contains("--mesher poisson"), "{err}");
}

#[test]
fn registration_moves_a_displaced_prior_onto_the_contacts() {
    let dir = scratch("surface-register");
    // An egg-like prior, and contacts all over the same egg shifted by 6 mm.
    let egg = moe_geom::shapes::star_shaped(3, Point3::origin(), |d| {
        0.06 + 0.012 * d.x + 0.01 * d.y * d.y
    })
    .unwrap();
    let prior = dir.join("prior.obj");
    moe_io::write_mesh(&prior, &egg).unwrap();
    let shift = Vector3::new(0.006, -0.002, 0.001);
    let pts: Vec<Vec<f64>> = egg
        .vertices()
        .iter()
        .step_by(3)
        .map(|p| {
            let q = p + shift;
            vec![q.x, q.y, q.z]
        })
        .collect();
    let contacts = dir.join("contacts.csv");
    moe_io::write_csv(&contacts, &["x", "y", "z"], &pts).unwrap();
    let out_path = dir.join("surface.obj");
    let registered = |extra: &[&str]| {
        let mut args = vec![
            "surface",
            "--contacts",
            contacts.to_str().unwrap(),
            "--prior",
            prior.to_str().unwrap(),
            "--register",
            "--lengthscale",
            "0.03",
            "--signal-variance",
            "1e-5",
            "--noise-variance",
            "1e-8",
            "--grid",
            "24",
            "--out",
            out_path.to_str().unwrap(),
            "--json",
        ];
        args.extend_from_slice(extra);
        let report = run_json(&args);
        let icp = report["registration"].clone();
        let t = &icp["prior_to_contacts"]["translation"];
        let found = Vector3::new(
            t[0].as_f64().unwrap(),
            t[1].as_f64().unwrap(),
            t[2].as_f64().unwrap(),
        );
        (icp["rms_after_m"].as_f64().unwrap(), found)
    };
    // Contacts all around the body pin the pose: plain ICP recovers the shift exactly.
    let (rms, found) = registered(&["--no-pose-prior"]);
    assert!(rms < 1e-6, "{rms}");
    assert!((found - shift).norm() < 1e-5, "{found}");
    // The pose prior (σ 20 mm) pulls a little towards the given pose; a tight one (1 mm) more.
    let (rms_map, found_map) = registered(&[]);
    let (_, found_tight) = registered(&["--pose-sd-mm", "1"]);
    assert!(
        rms_map < 1e-3 && (found_map - shift).norm() < 1e-3,
        "{found_map}"
    );
    assert!(
        found_tight.norm() < 0.5 * found_map.norm(),
        "{found_tight} vs {found_map}"
    );
    // The pose prior's options need --register.
    let out = run(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--prior",
        prior.to_str().unwrap(),
        "--no-pose-prior",
        "--grid",
        "24",
        "--out",
        out_path.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--register"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `--prior-gate`: contacts 10 mm outside a prior are left out by a 5 mm gate and kept by a
/// 20 mm one, for the GP and the baseline; a gate that is not a positive distance, or one for
/// a method without a prior, is refused.
#[test]
fn the_prior_gate_leaves_out_contacts_far_from_the_prior() {
    let dir = scratch("surface-gate");
    let prior = sphere_prior(&dir);
    let contacts = dir.join("contacts.csv");
    let mut pts: Vec<Vec<f64>> = sphere_points(0.09, 200, 2)
        .into_iter()
        .filter(|p| p[2] > 0.03)
        .collect();
    let near = pts.len();
    pts.extend([vec![0.0, 0.1, 0.0], vec![0.1, 0.0, 0.0]]);
    moe_io::write_csv(&contacts, &["x", "y", "z"], &pts).unwrap();
    let out_path = dir.join("s.obj");
    let (c, p, o) = (
        contacts.to_str().unwrap(),
        prior.to_str().unwrap(),
        out_path.to_str().unwrap(),
    );
    // Every call is `surface --contacts C --out O` and its own options.
    let base = ["surface", "--contacts", c, "--out", o];
    for method in ["prior", "nonprob"] {
        let gated = |gate| {
            let extra = [
                "--prior",
                p,
                "--method",
                method,
                "--grid",
                "24",
                "--prior-gate",
                gate,
                "--json",
            ];
            run_json(&[&base[..], &extra].concat())
        };
        let report = gated("0.005");
        assert_eq!(report["contacts"], near + 2, "{method}");
        assert_eq!(report["gated_contacts"], 2, "{method}");
        assert_eq!(gated("0.02")["gated_contacts"], 0, "{method}");
    }
    // A method without a prior has nothing to gate against.
    let extra = ["--method", "sphere", "--prior-gate", "0.005"];
    let err = assert_one_line_error(&run(&[&base[..], &extra].concat()));
    assert!(err.contains("needs a method with a prior"), "{err}");
    for bad in ["--prior-gate=0", "--prior-gate=-0.01"] {
        let err = assert_one_line_error(&run(&[&base[..], &["--prior", p, bad]].concat()));
        assert!(err.contains("prior_gate_m"), "{bad}: {err}");
    }
}

/// `--noise-floor` holds the fitted noise at its floor where the contacts alone would fit
/// less, and a bad floor is refused in one line, writing nothing.
#[test]
fn the_noise_floor_bounds_the_fitted_noise() {
    let dir = scratch("surface-noise-floor");
    let contacts = dir.join("contacts.csv");
    moe_io::write_csv(&contacts, &["x", "y", "z"], &sphere_points(0.05, 200, 1)).unwrap();
    let (good, bad) = (dir.join("s.obj"), dir.join("never.obj"));
    let args = |out: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "surface".to_string(),
            "--contacts".into(),
            contacts.display().to_string(),
            "--method".into(),
            "sphere".into(),
            "--grid".into(),
            "16".into(),
            "--out".into(),
            out.display().to_string(),
            "--json".into(),
        ];
        args.extend(extra.iter().map(|e| e.to_string()));
        args
    };
    let noise = |extra: &[&str]| {
        let a = args(&good, extra);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        run_json(&a)["hyper"]["noise_variance_m2"].as_f64().unwrap()
    };
    let free = noise(&[]);
    let floored = noise(&["--noise-floor", "0.003"]);
    assert!(free < 1e-8, "{free}");
    assert!((floored / 9e-6 - 1.0).abs() < 1e-6, "{floored}");
    let a = args(&bad, &["--noise-floor=-0.001"]);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let err = assert_one_line_error(&run(&a));
    assert!(err.contains("--noise-floor"), "{err}");
    // The baseline fits no GP.
    let prior = sphere_prior(&dir);
    let mut a = args(
        &bad,
        &["--noise-floor", "0.003", "--prior", prior.to_str().unwrap()],
    );
    a[4] = "nonprob".into();
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let err = assert_one_line_error(&run(&a));
    assert!(err.contains("GP methods only"), "{err}");
    assert!(!bad.exists());
}

#[test]
fn bad_inputs_give_one_line_errors() {
    let dir = scratch("surface-bad");
    let contacts = dir.join("c.csv");
    moe_io::write_csv(&contacts, &[], &sphere_points(0.05, 3, 4)).unwrap();
    let out_path = dir.join("s.obj");
    let o = out_path.to_str().unwrap();
    // Too few contacts for a sphere.
    let err = assert_one_line_error(&run(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--method",
        "sphere",
        "--out",
        o,
    ]));
    assert!(err.contains("at least 4"), "{err}");
    // A prior method without a prior.
    let err = assert_one_line_error(&run(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--out",
        o,
    ]));
    assert!(err.contains("--prior"), "{err}");
    // A grid that would not fit in memory is refused before anything is read or allocated.
    for grid in ["1", "257", "100000"] {
        let err = assert_one_line_error(&run(&[
            "surface",
            "--contacts",
            contacts.to_str().unwrap(),
            "--method",
            "sphere",
            "--grid",
            grid,
            "--out",
            o,
        ]));
        assert!(err.contains("between 2 and 256"), "{grid}: {err}");
    }
    assert!(!out_path.exists());
    // A non-watertight prior.
    let (v, mut f) = icosphere(2, 0.05).into_parts();
    f.pop();
    let open = dir.join("open.obj");
    moe_io::write_mesh(&open, &TriMesh::new(v, f).unwrap()).unwrap();
    let err = assert_one_line_error(&run(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--prior",
        open.to_str().unwrap(),
        "--out",
        o,
    ]));
    assert!(err.contains("watertight"), "{err}");
    // A NaN coordinate.
    let nan = dir.join("nan.csv");
    std::fs::write(&nan, "x,y,z\n0,0,0.05\n0,nan,0.05\n").unwrap();
    let err = assert_one_line_error(&run(&[
        "surface",
        "--contacts",
        nan.to_str().unwrap(),
        "--method",
        "sphere",
        "--out",
        o,
    ]));
    assert!(
        err.contains("nan") || err.contains("finite") || err.contains("number"),
        "{err}"
    );
    // Nothing to do.
    let err = assert_one_line_error(&run(&[
        "surface",
        "--contacts",
        contacts.to_str().unwrap(),
        "--method",
        "sphere",
    ]));
    assert!(err.contains("--out"), "{err}");
    let _ = Point3::origin();
}
