//! The factorised static tangent: its solves are the body's linear response, and by reciprocity
//! one solve per observed coordinate gives that coordinate's response to a load anywhere.

use faer::Mat;
use moe_geom::{FingerModel, FingerParams, Point3, Real, Vector3};
use moe_tendon_sim::mechanics::{FemInputs, FingerBody, Integrator, PointTerm, StepContext, Terms};
use moe_tendon_sim::{BodyState, Material, TendonCommand, TendonParams, VoxelParams};

fn finger() -> (FingerModel, FingerBody) {
    let model = FingerModel::from_params(&FingerParams {
        vertex_budget: 400,
        ..FingerParams::default()
    })
    .unwrap();
    let mut body = FingerBody::new(
        &model,
        &Material::default(),
        &VoxelParams { cell_size_m: 0.005 },
    )
    .unwrap();
    body.fem_mut().set_exact_static_tangent(true);
    (model, body)
}

/// The static shape under `pulls`, gravity along −x and a point force `load` at surface vertex
/// `at`.
fn static_shape(
    body: &FingerBody,
    start: &[Point3],
    pulls: &[Real],
    at: u32,
    load: Vector3,
) -> Vec<Point3> {
    let params = TendonParams::default();
    let commands: Vec<TendonCommand> = pulls
        .iter()
        .map(|&pull_m| TendonCommand::Displacement { pull_m })
        .collect();
    let point = body.surface().points()[at as usize];
    let mut ws = body.workspace(0);
    let mut state = BodyState {
        x: start.to_vec(),
        v: vec![Vector3::zeros(); start.len()],
    };
    let rest = body.fem().mesh().nodes().to_vec();
    body.fem()
        .step(
            &mut ws,
            StepContext::default(),
            Integrator::Static {
                tolerance_m: 1e-11,
                max_iterations: 200,
            },
            &mut state,
            FemInputs {
                targets: &rest,
                gravity: Vector3::new(-9.81, 0.0, 0.0),
                terms: &mut |x: &[Point3], _: &[Vector3], t: &mut Terms| {
                    for (tendon, &c) in body.tendons().iter().zip(&commands) {
                        tendon.add_terms(x, c, &params, t);
                    }
                    t.point_energy_j -= load.dot(&point.position(x).coords);
                    t.points.push(PointTerm {
                        point,
                        force: load,
                        stiffness: Default::default(),
                        damping: Default::default(),
                        target_velocity: Vector3::zeros(),
                    });
                },
            },
        )
        .unwrap();
    state.x
}

#[test]
fn the_compliance_by_reciprocity_equals_finite_differences_of_the_static_solve() {
    let (model, body) = finger();
    // A bent finger (one tendon taut, its antagonist slack) under gravity.
    let pulls = [0.003, -0.003, 0.0, 0.0];
    let rest = body.fem().mesh().nodes().to_vec();
    let x0 = static_shape(&body, &rest, &pulls, 0, Vector3::zeros());
    // The tangent at the bent shape, with the tendons' terms there.
    let params = TendonParams::default();
    let mut terms = Terms::default();
    for (tendon, &p) in body.tendons().iter().zip(&pulls) {
        tendon.add_terms(
            &x0,
            TendonCommand::Displacement { pull_m: p },
            &params,
            &mut terms,
        );
    }
    let fem = body.fem();
    let mut tangent = fem.tangent();
    fem.factor_tangent(
        &mut tangent,
        &x0,
        &terms,
        &Vector3::new(-9.81, 0.0, 0.0),
        StepContext::default(),
    )
    .unwrap();
    assert_eq!(tangent.num_active_rank_ones(), 1, "one taut tendon");
    // One solve per observed coordinate: markers 2 and 6, every axis.
    let observed: Vec<(u32, usize)> = [2usize, 6]
        .iter()
        .flat_map(|&m| (0..3).map(move |d| (m, d)))
        .map(|(m, d)| (model.marker_vertices()[m], d))
        .collect();
    let mut fields = Mat::<Real>::zeros(tangent.num_rows(), observed.len());
    for (j, &(v, d)) in observed.iter().enumerate() {
        let e = body.surface().points()[v as usize];
        for k in 0..4 {
            if let Some(i) = fem.free_index(e.nodes[k]) {
                fields[(3 * i + d, j)] += e.weights[k];
            }
        }
    }
    tangent.solve_in_place(fem, fields.as_mut()).unwrap();
    // Loads at three places (back, side, near the tip), each along every axis.
    let n = model.mesh().num_vertices() as u32;
    let far_side = (0..n)
        .find(|&v| {
            let p = model.mesh().vertices()[v as usize];
            p.x < -0.007 && (p.z - 0.04).abs() < 0.004
        })
        .unwrap();
    let side = (0..n)
        .find(|&v| {
            let p = model.mesh().vertices()[v as usize];
            p.y > 0.007 && (p.z - 0.025).abs() < 0.004
        })
        .unwrap();
    let tip = (0..n)
        .find(|&v| model.mesh().vertices()[v as usize].z > 0.075)
        .unwrap();
    let eps = 1e-4; // newtons: far inside the linear range
    let mut worst: Real = 0.0;
    for at in [far_side, side, tip] {
        let e = body.surface().points()[at as usize];
        for axis in 0..3 {
            let mut f = Vector3::zeros();
            f[axis] = eps;
            let plus = static_shape(&body, &x0, &pulls, at, f);
            let minus = static_shape(&body, &x0, &pulls, at, -f);
            for (j, &(v, d)) in observed.iter().enumerate() {
                let ev = body.surface().points()[v as usize];
                let fd = (ev.position(&plus)[d] - ev.position(&minus)[d]) / (2.0 * eps);
                // Reciprocity: the field of coordinate j at the load point, along the load.
                let mut recip = 0.0;
                for k in 0..4 {
                    if let Some(i) = fem.free_index(e.nodes[k]) {
                        recip += e.weights[k] * fields[(3 * i + axis, j)];
                    }
                }
                let scale = fd.abs().max(1e-3);
                worst = worst.max((fd - recip).abs() / scale);
                assert!(
                    (fd - recip).abs() <= 2e-3 * scale,
                    "load at {at} along {axis}, coordinate {j}: finite differences {fd:e} m/N, \
                     reciprocity {recip:e} m/N"
                );
            }
        }
    }
    eprintln!("largest relative difference {worst:.2e}");
}

#[test]
fn a_tangent_solve_needs_a_factorisation_and_the_right_rows() {
    let (_, body) = finger();
    let fem = body.fem();
    let mut tangent = fem.tangent();
    let mut b = Mat::<Real>::zeros(tangent.num_rows(), 1);
    moe_geom::assert_err!(
        tangent.solve_in_place(fem, b.as_mut()),
        moe_tendon_sim::SimError::InvalidParameter {
            name: "tangent",
            ..
        }
    );
    let rest = fem.mesh().nodes().to_vec();
    fem.factor_tangent(
        &mut tangent,
        &rest,
        &Terms::default(),
        &Vector3::zeros(),
        StepContext::default(),
    )
    .unwrap();
    let mut wrong = Mat::<Real>::zeros(tangent.num_rows() + 3, 1);
    moe_geom::assert_err!(
        tangent.solve_in_place(fem, wrong.as_mut()),
        moe_tendon_sim::SimError::LengthMismatch { .. }
    );
    tangent.solve_in_place(fem, b.as_mut()).unwrap();
    assert!(
        b.col(0).iter().all(|&v| v == 0.0),
        "zero load, zero displacement"
    );
}
