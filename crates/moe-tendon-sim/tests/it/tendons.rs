//! Tendon actuation of the default finger (finger frame, no gravity, quasi-static).

use moe_geom::{FingerModel, FingerParams, Point3, Real, Vector3};
use moe_tendon_sim::mechanics::{
    FingerBody, FingerInputs, Integrator, PosedObstacles, StepContext,
};
use moe_tendon_sim::{
    BodyState, ContactParams, Material, TendonCommand, TendonParams, VoxelParams,
};

pub(crate) fn default_finger() -> (FingerModel, FingerBody) {
    let model = FingerModel::from_params(&FingerParams::default()).unwrap();
    let body = FingerBody::new(&model, &Material::default(), &VoxelParams::default()).unwrap();
    (model, body)
}

/// Static equilibrium under tendon displacements `pulls` (metres, one per tendon).
fn solve(body: &FingerBody, pulls: [Real; 4]) -> Vec<Point3> {
    solve_commands(
        body,
        pulls.map(|pull_m| TendonCommand::Displacement { pull_m }),
    )
}

/// Static equilibrium under tendon `commands`.
fn solve_commands(body: &FingerBody, commands: [TendonCommand; 4]) -> Vec<Point3> {
    solve_with(body, commands, &TendonParams::default())
}

/// Static equilibrium under tendon `commands` with cables of `params`.
fn solve_with(
    body: &FingerBody,
    commands: [TendonCommand; 4],
    params: &TendonParams,
) -> Vec<Point3> {
    let rest = body.fem().mesh().nodes().to_vec();
    let mut state = BodyState {
        x: rest.clone(),
        v: vec![Vector3::zeros(); rest.len()],
    };
    let posed = PosedObstacles::new(&[], 0.0, 0.0);
    let inputs = FingerInputs {
        targets: &rest,
        gravity: Vector3::zeros(),
        commands: &commands,
        tendon: params,
        obstacles: &posed,
        contact: &ContactParams::default(),
    };
    let mut ws = body.fem().workspace();
    body.step(
        &mut ws,
        StepContext::default(),
        Integrator::Static {
            tolerance_m: 1e-9,
            max_iterations: 200,
        },
        &mut state,
        &inputs,
    )
    .unwrap();
    state.x
}

/// Mean displacement of the surface vertices in the top 5 % of the finger.
fn tip_displacement(model: &FingerModel, body: &FingerBody, x: &[Point3]) -> Vector3 {
    let len = FingerParams::default().length_m;
    let rest = model.mesh().vertices();
    let now = body.surface().positions(x);
    let (mut sum, mut n) = (Vector3::zeros(), 0);
    for (r, p) in rest.iter().zip(&now) {
        if r.z > 0.95 * len {
            sum += p - r;
            n += 1;
        }
    }
    sum / n as Real
}

#[test]
fn pulling_a_tendon_bends_toward_its_side_monotonically_with_a_slack_antagonist() {
    let (model, body) = default_finger();
    let params = TendonParams::default();
    // +x tendon pulled; its antagonist (−x) is released by the same length, as by a pulley.
    let mut last = 0.0;
    for d in [0.001, 0.002, 0.003, 0.004] {
        let x = solve(&body, [d, -d, 0.0, 0.0]);
        let tip = tip_displacement(&model, &body, &x);
        eprintln!("pull {d} m: tip {tip:?}");
        assert!(tip.x > last, "pull {d}: tip x {} not beyond {last}", tip.x);
        assert!(
            tip.y.abs() < 0.05 * tip.x,
            "pull {d}: out-of-plane {}",
            tip.y
        );
        last = tip.x;
        let t_pulled =
            body.tendons()[0].tension(&x, TendonCommand::Displacement { pull_m: d }, &params);
        let t_antagonist =
            body.tendons()[1].tension(&x, TendonCommand::Displacement { pull_m: -d }, &params);
        assert!(t_pulled > 0.0);
        assert_eq!(t_antagonist, 0.0, "antagonist must be slack");
        // The pulled tendon's path is (nearly) its rest length minus the pull.
        let len = body.tendons()[0].length(&x);
        let target = body.tendons()[0].rest_length_m() - d;
        assert!((len - target).abs() < 0.02 * d, "length {len} vs {target}");
    }
    assert!(
        last > 0.005,
        "4 mm of pull should bend the tip by several mm, got {last}"
    );
}

#[test]
fn every_tendon_bends_toward_its_own_side() {
    let (model, body) = default_finger();
    let sides = [Vector3::x(), -Vector3::x(), Vector3::y(), -Vector3::y()];
    for (k, side) in sides.iter().enumerate() {
        let mut pulls = [0.0; 4];
        pulls[k] = 0.002;
        pulls[[1, 0, 3, 2][k]] = -0.002;
        let tip = tip_displacement(&model, &body, &solve(&body, pulls));
        let lateral = Vector3::new(tip.x, tip.y, 0.0);
        assert!(
            lateral.dot(side) > 0.98 * lateral.norm(),
            "tendon {k}: {tip:?}"
        );
    }
}

#[test]
fn equal_pulls_on_an_antagonistic_pair_keep_the_finger_straight() {
    let (model, body) = default_finger();
    let single = tip_displacement(&model, &body, &solve(&body, [0.002, -0.002, 0.0, 0.0]));
    let both = tip_displacement(&model, &body, &solve(&body, [0.002, 0.002, 0.0, 0.0]));
    eprintln!("single {single:?} both {both:?}");
    let lateral = (both.x * both.x + both.y * both.y).sqrt();
    assert!(
        lateral < 0.02 * single.x,
        "lateral {lateral} vs single-pull {}",
        single.x
    );
    assert!(
        both.z < -0.0005,
        "equal pulls compress the finger: {both:?}"
    );
}

#[test]
fn force_drive_with_the_displacement_tension_reproduces_the_displacement_shape() {
    let (model, body) = default_finger();
    let d = 0.002;
    let x_disp = solve(&body, [d, -d, 0.0, 0.0]);
    let tension = body.tendons()[0].tension(
        &x_disp,
        TendonCommand::Displacement { pull_m: d },
        &TendonParams::default(),
    );
    let force = |tension_n| TendonCommand::Force { tension_n };
    let x_force = solve_commands(&body, [force(tension), force(0.0), force(0.0), force(0.0)]);
    let a = tip_displacement(&model, &body, &x_disp);
    let b = tip_displacement(&model, &body, &x_force);
    eprintln!("tension {tension:.3} N: displacement-driven tip {a:?}, force-driven tip {b:?}");
    assert!(tension > 0.0);
    assert!((a - b).norm() < 0.01 * a.norm(), "{a:?} vs {b:?}");
    // A cable cannot push: a negative tension does nothing.
    let x_neg = solve_commands(&body, [force(-5.0), force(0.0), force(0.0), force(0.0)]);
    let max = x_neg
        .iter()
        .zip(body.fem().mesh().nodes())
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, Real::max);
    assert!(max < 1e-12, "moved by {max}");
}

/// The zero-pull state as the cable parameters state it. Slack is taken up before a cable pulls:
/// with 1 mm of slack, pulls 1 mm longer give the taut cables' shape, and a pull within the
/// slack leaves the finger at rest. Pre-tension (negative slack) on all four cables stretches
/// them at rest: the finger shortens along its axis without bending, each cable in tension.
#[test]
fn slack_is_taken_up_before_a_cable_pulls_and_pretension_shortens_the_finger() {
    let (model, body) = default_finger();
    let taut = TendonParams::default();
    let slack = TendonParams {
        slack_m: 0.001,
        ..TendonParams::default()
    };
    let pulls = |p: [Real; 4]| p.map(|pull_m| TendonCommand::Displacement { pull_m });
    let bent = solve_with(&body, pulls([0.002, -0.002, 0.0, 0.0]), &taut);
    let same = solve_with(&body, pulls([0.003, -0.001, 0.001, 0.001]), &slack);
    let largest = bent
        .iter()
        .zip(&same)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, Real::max);
    assert!(
        largest < 1e-9,
        "slack and longer pulls differ by {largest} m"
    );
    let tip = tip_displacement(&model, &body, &bent);
    assert!(tip.norm() > 1e-3, "a 2 mm pull moves the tip {tip:?}");

    let within = solve_with(&body, pulls([0.0005, 0.0, 0.0, 0.0]), &slack);
    let rest = body.fem().mesh().nodes();
    let moved = within
        .iter()
        .zip(rest)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, Real::max);
    assert!(
        moved < 1e-12,
        "a pull within the slack moves the finger {moved} m"
    );

    let pretension = TendonParams {
        slack_m: -0.0002,
        ..TendonParams::default()
    };
    let zero = pulls([0.0; 4]);
    let x = solve_with(&body, zero, &pretension);
    let tip = tip_displacement(&model, &body, &x);
    assert!(
        tip.z < -1e-5,
        "pre-tension does not shorten the finger: {tip:?}"
    );
    assert!(
        tip.xy().norm() < 0.05 * tip.z.abs(),
        "pre-tension bends the finger: {tip:?}"
    );
    for (j, tendon) in body.tendons().iter().enumerate() {
        let t = tendon.tension(&x, zero[j], &pretension);
        assert!(t > 0.0, "cable {j} is slack under pre-tension");
    }
}
