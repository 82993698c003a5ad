//! Quasi-static presses of a frictionless ball on the default (round, tapered, capped) finger:
//! 13 places — four heights on three sides and the apex along the axis — at four depths, 52
//! presses, each a sequence of static equilibria as the ball moves in.

use moe_geom::{FingerParams, Real, Vector3};
use moe_tendon_sim::mechanics::{
    FingerBody, FingerInputs, Integrator, PosedObstacles, StepContext,
};
use moe_tendon_sim::{
    BodyState, ContactParams, Obstacle, ObstacleConfig, ObstacleShape, PoseKeyframe,
    PoseTrajectory, SimError, TendonCommand, TendonParams,
};

use crate::tendons::default_finger;

/// The ball's radius, metres.
const BALL_M: Real = 0.008;
/// Static equilibria from first touch to the full depth.
const STEPS: u64 = 8;

/// One press: where the ball starts (just clear of the surface) and where it ends.
#[derive(Debug, Clone, Copy)]
struct Press {
    name: &'static str,
    from: [Real; 3],
    to: [Real; 3],
}

/// The 52 presses: heights 15, 30, 45 and 60 mm on the +x, +y and −x sides, and the apex from
/// above, each 1, 2, 3 and 4 mm deep (the ball's centre moved that far past first touch).
fn presses() -> Vec<Press> {
    let p = FingerParams::default();
    let mut out = Vec::new();
    for depth in [0.001, 0.002, 0.003, 0.004] {
        for (side, dir) in [
            ("+x", Vector3::x()),
            ("+y", Vector3::y()),
            ("-x", -Vector3::x()),
        ] {
            for z in [0.015, 0.030, 0.045, 0.060] {
                let touch = p.radius_at(z) + BALL_M;
                let at = |r: Real| {
                    let c = dir * r + Vector3::z() * z;
                    [c.x, c.y, c.z]
                };
                out.push(Press {
                    name: leak(format!(
                        "{side} z {:.0} mm, {:.0} mm deep",
                        z * 1e3,
                        depth * 1e3
                    )),
                    from: at(touch + 0.0005),
                    to: at(touch - depth),
                });
            }
        }
        let top = p.length_m + BALL_M;
        out.push(Press {
            name: leak(format!("apex, {:.0} mm deep", depth * 1e3)),
            from: [0.0, 0.0, top + 0.0005],
            to: [0.0, 0.0, top - depth],
        });
    }
    out
}

fn leak(s: String) -> &'static str {
    Box::leak(s.into_boxed_str())
}

/// Runs `press` as `STEPS` static equilibria; the Newton iterations of each, or the error.
fn run(body: &FingerBody, press: &Press) -> Result<Vec<usize>, SimError> {
    let rest = body.fem().mesh().nodes().to_vec();
    let mut state = BodyState {
        x: rest.clone(),
        v: vec![Vector3::zeros(); rest.len()],
    };
    let obstacle = Obstacle::new(
        0,
        &ObstacleConfig {
            shape: ObstacleShape::Ball { radius_m: BALL_M },
            trajectory: PoseTrajectory {
                keyframes: vec![
                    PoseKeyframe::at(0.0, press.from),
                    PoseKeyframe::at(STEPS as Real, press.to),
                ],
            },
        },
    )
    .unwrap();
    let commands = [TendonCommand::Displacement { pull_m: 0.0 }; 4];
    let (tendon, contact) = (TendonParams::default(), ContactParams::default());
    let obstacles = std::slice::from_ref(&obstacle);
    let mut ws = body.fem().workspace();
    let mut iterations = Vec::new();
    for step in 0..STEPS {
        let t = step as Real;
        let posed = PosedObstacles::new(obstacles, t, t + 1.0);
        let inputs = FingerInputs {
            targets: &rest,
            gravity: Vector3::zeros(),
            commands: &commands,
            tendon: &tendon,
            obstacles: &posed,
            contact: &contact,
        };
        let report = body.step(
            &mut ws,
            StepContext { step, finger: 0 },
            Integrator::Static {
                tolerance_m: 1e-8,
                max_iterations: 100,
            },
            &mut state,
            &inputs,
        )?;
        iterations.push(report.iterations);
    }
    Ok(iterations)
}

#[test]
fn every_static_ball_press_converges() {
    let (_, body) = default_finger();
    let all = presses();
    assert_eq!(all.len(), 52);
    let mut failed = Vec::new();
    let mut most = 0;
    for press in &all {
        match run(&body, press) {
            Ok(iterations) => most = most.max(iterations.iter().copied().max().unwrap_or(0)),
            Err(e) => failed.push(format!("{}: {e}", press.name)),
        }
    }
    eprintln!(
        "static ball presses: {} of {} converged (at most {most} Newton iterations a step)",
        all.len() - failed.len(),
        all.len()
    );
    assert!(
        failed.is_empty(),
        "{} failed:\n{}",
        failed.len(),
        failed.join("\n")
    );
}
