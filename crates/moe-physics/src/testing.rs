//! Markers of a hand under known loads, for tests, benchmarks and studies: each finger's static
//! equilibrium under its pulls, gravity and point loads, simulated by the data generator's
//! model (`moe-tendon-sim` at its default 3.5 mm mesh and the nominal material), not the
//! estimator's.

use moe_geom::{
    CameraIntrinsics, HandFromCamera, HandKeypoints, HandModel, HandShape, OwnedDepthImage, Point3,
    Real, Vector3, WorldFromHand,
};
use moe_tendon_sim::mechanics::{FemInputs, FingerBody, Integrator, PointTerm, StepContext, Terms};
use moe_tendon_sim::{BodyState, Material, TendonCommand, TendonParams, VoxelParams};

use crate::error::PhysicsError;

/// A known point load: a force on one surface vertex of one finger, finger frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLoad {
    /// Finger index.
    pub finger: usize,
    /// Surface vertex of that finger's mesh.
    pub vertex: u32,
    /// The force, newtons, finger frame.
    pub force: Vector3,
}

/// The markers (hand frame, all seen) of `hand` at `world_from_hand` in static equilibrium
/// under `pulls` (metres, per finger and tendon), gravity (0, 0, −9.81) m/s² in the world and
/// `loads`.
///
/// # Errors
/// Pulls or loads that do not fit the hand (naming the finger), or a static solve that does
/// not converge.
pub fn static_markers(
    hand: &HandModel,
    pulls: &[Vec<Real>],
    world_from_hand: &WorldFromHand,
    loads: &[PointLoad],
) -> Result<HandKeypoints, PhysicsError> {
    Ok(static_hand(hand, pulls, world_from_hand, loads)?.0)
}

/// As [`static_markers`], with every finger's surface (hand frame).
///
/// # Errors
/// As [`static_markers`].
pub fn static_hand(
    hand: &HandModel,
    pulls: &[Vec<Real>],
    world_from_hand: &WorldFromHand,
    loads: &[PointLoad],
) -> Result<(HandKeypoints, HandShape), PhysicsError> {
    if pulls.len() != hand.num_fingers() {
        return Err(PhysicsError::LengthMismatch {
            what: "fingers of the tendon pulls",
            expected: hand.num_fingers(),
            got: pulls.len(),
        });
    }
    let model_error = |finger: usize| move |source| PhysicsError::Model { finger, source };
    let gravity_in_hand = world_from_hand
        .iso()
        .inverse_transform_vector(&Vector3::new(0.0, 0.0, -9.81));
    let mut fingers = Vec::with_capacity(hand.num_fingers());
    let mut surfaces = Vec::with_capacity(hand.num_fingers());
    for (f, hf) in hand.fingers().iter().enumerate() {
        let body = FingerBody::new(&hf.model, &Material::default(), &VoxelParams::default())
            .map_err(model_error(f))?;
        let n = hf.model.mesh().num_vertices();
        if let Some(l) = loads
            .iter()
            .find(|l| l.finger >= hand.num_fingers() || (l.finger == f && l.vertex as usize >= n))
        {
            return Err(PhysicsError::FingerLengthMismatch {
                what: "load vertex (vertices of the finger)",
                finger: l.finger,
                expected: n,
                got: l.vertex as usize,
            });
        }
        if pulls[f].len() != body.tendons().len() {
            return Err(PhysicsError::FingerLengthMismatch {
                what: "tendon pulls",
                finger: f,
                expected: body.tendons().len(),
                got: pulls[f].len(),
            });
        }
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
                StepContext { step: 0, finger: f },
                Integrator::Static {
                    tolerance_m: 1e-10,
                    max_iterations: 200,
                },
                &mut state,
                FemInputs {
                    targets: &rest,
                    gravity: finger_from_hand * gravity_in_hand,
                    terms: &mut |x: &[Point3], _: &[Vector3], t: &mut Terms| {
                        for (tendon, &c) in body.tendons().iter().zip(&commands) {
                            tendon.add_terms(x, c, &params, t);
                        }
                        for l in loads.iter().filter(|l| l.finger == f) {
                            let point = body.surface().points()[l.vertex as usize];
                            t.point_energy_j -= l.force.dot(&point.position(x).coords);
                            t.points.push(PointTerm {
                                point,
                                force: l.force,
                                stiffness: Default::default(),
                                damping: Default::default(),
                                target_velocity: Vector3::zeros(),
                            });
                        }
                    },
                },
            )
            .map_err(model_error(f))?;
        let hand_from_finger = hf.hand_from_finger.iso();
        let surface: Vec<Point3> = body
            .surface()
            .points()
            .iter()
            .map(|e| hand_from_finger * e.position(&state.x))
            .collect();
        fingers.push(
            hf.model
                .marker_vertices()
                .iter()
                .map(|&v| Some(surface[v as usize]))
                .collect(),
        );
        surfaces.push(surface);
    }
    Ok((HandKeypoints { fingers }, HandShape { fingers: surfaces }))
}

/// The depth image (no noise, holes where nothing is seen) that a camera with `intrinsics` at
/// `hand_from_camera` takes of the fingers of `hand` with surfaces `shape` (hand frame).
///
/// # Errors
/// Invalid intrinsics.
pub fn render_depth(
    hand: &HandModel,
    shape: &HandShape,
    intrinsics: CameraIntrinsics,
    hand_from_camera: HandFromCamera,
) -> Result<OwnedDepthImage, PhysicsError> {
    Ok(moe_geom::depth::render_hand(
        hand,
        shape,
        &[],
        intrinsics,
        hand_from_camera,
    )?)
}
