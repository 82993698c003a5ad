//! Markers of a hand whose fingers carry known point loads, simulated statically by the data
//! generator's own model (its 3.5 mm voxel mesh; the estimator models the finger with its own).

use moe_geom::{FingerParams, HandKeypoints, HandModel, HandPreset, Point3, Real, Vector3};
use moe_tendon_sim::mechanics::{FemInputs, FingerBody, Integrator, PointTerm, StepContext, Terms};
use moe_tendon_sim::{BodyState, Material, TendonCommand, TendonParams, VoxelParams};

/// Gravity in the world and in the hand frame (the hand held fingers-down at identity).
pub(crate) const GRAVITY: [Real; 3] = [0.0, 0.0, -9.81];

pub(crate) fn hand() -> HandModel {
    HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap()
}

/// A point load: finger, surface vertex, force in the finger frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PointLoad {
    pub(crate) finger: usize,
    pub(crate) vertex: u32,
    pub(crate) force: Vector3,
}

/// The surface vertex of finger `f` nearest `p` (finger frame).
pub(crate) fn vertex_near(hand: &HandModel, f: usize, p: Point3) -> u32 {
    let v = hand.fingers()[f].model.mesh().vertices();
    (0..v.len())
        .min_by(|&a, &b| (v[a] - p).norm().total_cmp(&(v[b] - p).norm()))
        .unwrap() as u32
}

/// The outward normal of finger `f` at vertex `v`, finger frame.
pub(crate) fn normal_at(hand: &HandModel, f: usize, v: u32) -> Vector3 {
    hand.fingers()[f].model.mesh().vertex_normals()[v as usize]
}

/// The static markers (hand frame) of every finger under `pulls` and `loads`, by the data
/// generator's model.
pub(crate) fn simulate(
    hand: &HandModel,
    pulls: &[Vec<Real>],
    loads: &[PointLoad],
) -> HandKeypoints {
    let g = Vector3::from(GRAVITY);
    let fingers = hand
        .fingers()
        .iter()
        .enumerate()
        .map(|(f, hf)| {
            let body =
                FingerBody::new(&hf.model, &Material::default(), &VoxelParams::default()).unwrap();
            let rest = body.fem().mesh().nodes().to_vec();
            let mut state = BodyState {
                x: rest.clone(),
                v: vec![Vector3::zeros(); rest.len()],
            };
            let commands: Vec<TendonCommand> = pulls[f]
                .iter()
                .map(|&pull_m| TendonCommand::Displacement { pull_m })
                .collect();
            let finger_from_hand = hf.hand_from_finger.iso().inverse();
            let params = TendonParams::default();
            let mut ws = body.workspace(0);
            body.fem()
                .step(
                    &mut ws,
                    StepContext::default(),
                    Integrator::Static {
                        tolerance_m: 1e-10,
                        max_iterations: 200,
                    },
                    &mut state,
                    FemInputs {
                        targets: &rest,
                        gravity: finger_from_hand * g,
                        terms: &mut |x: &[Point3], _: &[Vector3], t: &mut Terms| {
                            for (tendon, &c) in body.tendons().iter().zip(&commands) {
                                tendon.add_terms(x, c, &params, t);
                            }
                            for l in loads.iter().filter(|l| l.finger == f) {
                                t.points.push(PointTerm {
                                    point: body.surface().points()[l.vertex as usize],
                                    force: l.force,
                                    stiffness: Default::default(),
                                    damping: Default::default(),
                                    target_velocity: Vector3::zeros(),
                                });
                            }
                        },
                    },
                )
                .unwrap();
            let hand_from_finger = hf.hand_from_finger.iso();
            hf.model
                .marker_vertices()
                .iter()
                .map(|&v| {
                    Some(hand_from_finger * body.surface().points()[v as usize].position(&state.x))
                })
                .collect()
        })
        .collect();
    HandKeypoints { fingers }
}

/// Zero pulls for every tendon of `hand`.
pub(crate) fn no_pulls(hand: &HandModel) -> Vec<Vec<Real>> {
    hand.fingers()
        .iter()
        .map(|f| vec![0.0; f.model.tendon_routes().len()])
        .collect()
}

/// Vertices of finger `f` within one ring of `v` (edge neighbours, `v` included).
pub(crate) fn ring(hand: &HandModel, f: usize, v: u32) -> Vec<u32> {
    let mut out = vec![v];
    for face in hand.fingers()[f].model.mesh().faces() {
        if face.contains(&v) {
            for &u in face {
                if !out.contains(&u) {
                    out.push(u);
                }
            }
        }
    }
    out
}
