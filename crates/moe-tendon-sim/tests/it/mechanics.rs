//! Corotational FEM against analytic solutions on structured box meshes.

use moe_geom::{Matrix3, Point3, Real, Vector3};
use moe_tendon_sim::mechanics::{FemInputs, FemModel, Integrator, StepContext, Terms, TetMesh};
use moe_tendon_sim::{BodyState, Material};

const E: Real = 1e5;
const NU: Real = 0.1;

fn material() -> Material {
    Material {
        youngs_modulus_pa: E,
        poisson_ratio: NU,
        ..Material::default()
    }
}

/// A bar `[0, w]² × [0, len]` with `n × n × m` cells, fixed at z = 0.
fn bar(w: Real, len: Real, n: usize, m: usize) -> FemModel {
    let mesh = TetMesh::box_grid(Point3::origin(), Point3::new(w, w, len), [n, n, m]).unwrap();
    let fixed = mesh.nodes().iter().map(|p| p.z <= 1e-12).collect();
    FemModel::new(mesh, material(), fixed, &[], 0).unwrap()
}

fn static_solve(model: &FemModel, loads: Vec<(u32, Vector3)>) -> Vec<Point3> {
    let x = model.mesh().nodes().to_vec();
    let v = vec![Vector3::zeros(); x.len()];
    let targets = x.clone();
    let mut state = BodyState { x, v };
    let mut ws = model.workspace();
    let report = model
        .step(
            &mut ws,
            StepContext::default(),
            Integrator::Static {
                tolerance_m: 1e-10,
                max_iterations: 100,
            },
            &mut state,
            FemInputs {
                targets: &targets,
                gravity: Vector3::zeros(),
                terms: &mut |_, _, t: &mut Terms| t.nodal_forces.clone_from(&loads),
            },
        )
        .unwrap();
    assert!(report.iterations < 100);
    state.x
}

/// Consistent nodal loads of a uniform traction `t` on the top face z = len of a Kuhn box
/// (triangles (4,5,7) and (4,6,7) of each top cell).
fn top_traction(model: &FemModel, len: Real, t: Vector3) -> Vec<(u32, Vector3)> {
    let nodes = model.mesh().nodes();
    let mut load = vec![Vector3::zeros(); nodes.len()];
    for tet in model.mesh().tets() {
        for skip in 0..4 {
            let face: Vec<u32> = (0..4).filter(|&k| k != skip).map(|k| tet[k]).collect();
            if face
                .iter()
                .all(|&i| (nodes[i as usize].z - len).abs() < 1e-12)
            {
                let p = face.iter().map(|&i| nodes[i as usize]).collect::<Vec<_>>();
                let area = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
                for &i in &face {
                    load[i as usize] += t * (area / 3.0);
                }
            }
        }
    }
    load.into_iter()
        .enumerate()
        .filter(|(_, f)| f.norm() > 0.0)
        .map(|(i, f)| (i as u32, f))
        .collect()
}

fn mean_over(
    x: &[Point3],
    rest: &[Point3],
    pick: impl Fn(&Point3) -> bool,
    f: impl Fn(&Point3) -> Real,
) -> Real {
    let vals: Vec<Real> = x
        .iter()
        .zip(rest)
        .filter(|(_, r)| pick(r))
        .map(|(p, _)| f(p))
        .collect();
    vals.iter().sum::<Real>() / vals.len() as Real
}

#[test]
fn axial_stretch_recovers_youngs_modulus_and_poisson_ratio() {
    let (w, len) = (0.01, 0.06);
    let model = bar(w, len, 3, 18);
    let sigma = 0.01 * E; // 1 % strain
    let x = static_solve(
        &model,
        top_traction(&model, len, Vector3::new(0.0, 0.0, sigma)),
    );
    let rest = model.mesh().nodes();
    let (z1, z2) = (len / 3.0, 2.0 * len / 3.0);
    let at = |z: Real| move |p: &Point3| (p.z - z).abs() < 1e-9;
    let u1 = mean_over(&x, rest, at(z1), |p| p.z) - z1;
    let u2 = mean_over(&x, rest, at(z2), |p| p.z) - z2;
    let axial = (u2 - u1) / (z2 - z1);
    let e_est = sigma / axial;
    let zm = len / 2.0;
    let mid = |side: Real| move |p: &Point3| (p.z - zm).abs() < 1e-9 && (p.x - side).abs() < 1e-9;
    let width = mean_over(&x, rest, mid(w), |p| p.x) - mean_over(&x, rest, mid(0.0), |p| p.x);
    let lateral = (width - w) / w;
    let nu_est = -lateral / axial;
    eprintln!("E estimate {e_est:.1} Pa, nu estimate {nu_est:.4}");
    assert!((e_est - E).abs() / E < 0.02, "E {e_est}");
    assert!((nu_est - NU).abs() < 0.005, "nu {nu_est}");
}

#[test]
fn cantilever_tip_deflection_approaches_euler_bernoulli_under_refinement() {
    let (w, len): (Real, Real) = (0.01, 0.1);
    let p = 1e-3; // N: tip deflection ≈ 1 % of the length
    let inertia = w.powi(4) / 12.0;
    let analytic = p * len.powi(3) / (3.0 * E * inertia);
    let mut errors = Vec::new();
    for n in [2, 4, 6] {
        let model = bar(w, len, n, 10 * n);
        let area = w * w;
        let x = static_solve(
            &model,
            top_traction(&model, len, Vector3::new(p / area, 0.0, 0.0)),
        );
        let rest = model.mesh().nodes();
        let tip = mean_over(&x, rest, |r| (r.z - len).abs() < 1e-9, |q| q.x)
            - mean_over(rest, rest, |r| (r.z - len).abs() < 1e-9, |q| q.x);
        let err = (tip - analytic).abs() / analytic;
        eprintln!("n = {n}: tip {tip:e} m vs Euler-Bernoulli {analytic:e} m, error {err:.4}");
        errors.push(err);
    }
    assert!(errors.windows(2).all(|e| e[1] < e[0]), "{errors:?}");
    assert!(*errors.last().unwrap() < 0.10, "{errors:?}");
}

#[test]
fn rigid_motion_of_the_rest_shape_has_zero_elastic_force() {
    let model = bar(0.01, 0.03, 2, 6);
    let q = nalgebra::Rotation3::from_euler_angles(0.7, -1.2, 2.5).into_inner();
    let t = Vector3::new(0.3, -0.1, 0.05);
    let moved: Vec<Point3> = model
        .mesh()
        .nodes()
        .iter()
        .map(|p| Point3::from(q * p.coords + t))
        .collect();
    let f = model.elastic_forces(&moved).unwrap();
    let max = f.iter().map(|f| f.norm()).fold(0.0, Real::max);
    // Force scale of a 1 % strain on one element: E · h² · 0.01 ≈ 0.03 N.
    assert!(max < 1e-10, "max force {max:e} N");
    // A stretched configuration does produce forces, so the check above is not vacuous.
    let stretched: Vec<Point3> = moved
        .iter()
        .map(|p| Point3::from(p.coords * 1.01))
        .collect();
    let f = model.elastic_forces(&stretched).unwrap();
    assert!(f.iter().map(|f| f.norm()).fold(0.0, Real::max) > 1e-3);
}

#[test]
fn linear_displacement_patch_test_is_reproduced_exactly() {
    let (lo, hi) = (Point3::origin(), Point3::new(0.02, 0.03, 0.025));
    let mesh = TetMesh::box_grid(lo, hi, [4, 4, 4]).unwrap();
    let on_boundary =
        |p: &Point3| (0..3).any(|k| (p[k] - lo[k]).abs() < 1e-12 || (p[k] - hi[k]).abs() < 1e-12);
    let fixed: Vec<bool> = mesh.nodes().iter().map(on_boundary).collect();
    let a = Matrix3::new(1.05, 0.02, -0.03, 0.01, 0.97, 0.04, 0.02, -0.01, 1.03);
    let rot = nalgebra::Rotation3::from_euler_angles(0.2, 0.1, -0.3).into_inner();
    let a = rot * a;
    let c = Vector3::new(0.001, -0.002, 0.003);
    let exact = |p: &Point3| Point3::from(a * p.coords + c);
    let model = FemModel::new(mesh, material(), fixed, &[], 0).unwrap();
    let targets: Vec<Point3> = model.mesh().nodes().iter().map(exact).collect();
    let x = model.mesh().nodes().to_vec();
    let v = vec![Vector3::zeros(); x.len()];
    let mut state = BodyState { x, v };
    let mut ws = model.workspace();
    model
        .step(
            &mut ws,
            StepContext::default(),
            Integrator::Static {
                tolerance_m: 1e-14,
                max_iterations: 200,
            },
            &mut state,
            FemInputs {
                targets: &targets,
                gravity: Vector3::zeros(),
                terms: &mut |_, _, _| {},
            },
        )
        .unwrap();
    let interior = model.fixed().iter().filter(|&&f| !f).count();
    assert!(interior >= 27);
    let err = state
        .x
        .iter()
        .zip(&targets)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    assert!(err < 1e-12, "max deviation {err:e} m");
}

#[test]
fn damped_dynamics_settle_to_the_static_gravity_sag() {
    // A short bar under gravity: backward Euler with Rayleigh damping must come to rest at the
    // static equilibrium of the same model.
    let model = bar(0.01, 0.04, 2, 8);
    let g = Vector3::new(-9.81, 0.0, 0.0);
    let rest = model.mesh().nodes().to_vec();
    let mut ws = model.workspace();
    let mut statics = BodyState {
        x: rest.clone(),
        v: vec![Vector3::zeros(); rest.len()],
    };
    model
        .step(
            &mut ws,
            StepContext::default(),
            Integrator::Static {
                tolerance_m: 1e-10,
                max_iterations: 100,
            },
            &mut statics,
            FemInputs {
                targets: &rest,
                gravity: g,
                terms: &mut |_, _, _| {},
            },
        )
        .unwrap();
    let mut dynamic = BodyState {
        x: rest.clone(),
        v: vec![Vector3::zeros(); rest.len()],
    };
    for step in 0..400 {
        model
            .step(
                &mut ws,
                StepContext { step, finger: 0 },
                Integrator::Dynamic { dt_secs: 0.01 },
                &mut dynamic,
                FemInputs {
                    targets: &rest,
                    gravity: g,
                    terms: &mut |_, _, _| {},
                },
            )
            .unwrap();
    }
    let sag = statics
        .x
        .iter()
        .zip(&rest)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, Real::max);
    let err = dynamic
        .x
        .iter()
        .zip(&statics.x)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, Real::max);
    assert!(sag > 1e-4, "sag {sag:e}");
    assert!(
        err < 1e-3 * sag,
        "dynamic end state off by {err:e} m (sag {sag:e} m)"
    );
    // Time step must be positive.
    let err = model.step(
        &mut ws,
        StepContext::default(),
        Integrator::Dynamic { dt_secs: 0.0 },
        &mut dynamic,
        FemInputs {
            targets: &rest,
            gravity: g,
            terms: &mut |_, _, _| {},
        },
    );
    assert!(matches!(
        err,
        Err(moe_tendon_sim::SimError::InvalidParameter {
            name: "dt_secs",
            ..
        })
    ));
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]
    #[test]
    fn any_rigid_motion_has_zero_elastic_force(
        a in -3.2..3.2f64, b in -1.5..1.5f64, c in -3.2..3.2f64,
        tx in -1.0..1.0f64, ty in -1.0..1.0f64, tz in -1.0..1.0f64,
    ) {
        let model = bar(0.01, 0.02, 2, 4);
        let q = nalgebra::Rotation3::from_euler_angles(a, b, c).into_inner();
        let t = Vector3::new(tx, ty, tz);
        let moved: Vec<Point3> = model.mesh().nodes().iter().map(|p| Point3::from(q * p.coords + t)).collect();
        let f = model.elastic_forces(&moved).unwrap();
        let max = f.iter().map(|f| f.norm()).fold(0.0, Real::max);
        proptest::prop_assert!(max < 1e-10, "max force {max:e} N");
    }
}

/// Convergence is judged on the full Newton step: a tolerance below the round-off floor of the
/// solve cannot be met, and the static solver must say so rather than report success after a
/// line search that shrank the step to nothing.
#[test]
fn an_unreachable_static_tolerance_is_reported() {
    let model = bar(0.01, 0.1, 2, 20);
    let area = 0.01 * 0.01;
    let loads = top_traction(&model, 0.1, Vector3::new(1e-3 / area, 0.0, 0.0));
    let x = model.mesh().nodes().to_vec();
    let v = vec![Vector3::zeros(); x.len()];
    let targets = x.clone();
    let mut state = BodyState { x, v };
    let mut ws = model.workspace();
    let result = model.step(
        &mut ws,
        StepContext::default(),
        Integrator::Static {
            tolerance_m: 1e-18,
            max_iterations: 20,
        },
        &mut state,
        FemInputs {
            targets: &targets,
            gravity: Vector3::zeros(),
            terms: &mut |_, _, t: &mut Terms| t.nodal_forces.clone_from(&loads),
        },
    );
    assert!(
        matches!(
            result,
            Err(moe_tendon_sim::SimError::StaticNotConverged { .. })
        ),
        "{result:?}"
    );
}
