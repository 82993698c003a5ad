//! Hand-level scenes: determinism (golden digest), wrist following, divergence and bad input.

use moe_geom::{FingerModel, FingerParams, Point3, TendonRoute, Vector3};
use moe_tendon_sim::{
    ActuationKeyframe, ActuationMode, ActuationSchedule, FemModel, FingerBody, Integrator,
    Material, ObstacleConfig, ObstacleShape, PoseKeyframe, PoseTrajectory, Scene, SceneConfig,
    SimError, StepContext, TetMesh, VoxelParams,
};

/// Golden [`moe_tendon_sim::SimState::rounded_digest`] (positions rounded to 1e-9 m) of
/// [`short_scene`] after 8 steps. Produced by running
/// `MOE_PRINT_DIGEST=1 cargo test -p moe-tendon-sim --test it golden -- --nocapture` on the
/// reference machine and pasting the printed value; it changes whenever the physics or the
/// default parameters change on purpose (then regenerate it the same way and say why in the
/// commit).
const GOLDEN_DIGEST: u64 = 0xbf56_735d_3b25_0f81;

/// Two-finger hand: finger 0 pulls its +x tendon, a plate presses finger 1's outer side, the
/// wrist moves up slowly.
pub(crate) fn short_scene() -> SceneConfig {
    let p = FingerParams::default();
    SceneConfig {
        duration_secs: 0.08,
        wrist: PoseTrajectory {
            keyframes: vec![
                PoseKeyframe::at(0.0, [0.0, 0.0, 0.0]),
                PoseKeyframe::at(1.0, [0.0, 0.0, 0.01]),
            ],
        },
        actuation: vec![ActuationSchedule {
            mode: ActuationMode::Displacement,
            keyframes: vec![
                ActuationKeyframe {
                    time_secs: 0.0,
                    values: vec![0.0; 4],
                },
                ActuationKeyframe {
                    time_secs: 0.1,
                    values: vec![0.002, -0.002, 0.0, 0.0],
                },
            ],
        }],
        obstacles: vec![ObstacleConfig {
            shape: ObstacleShape::Cuboid {
                half_extents_m: [0.001, 0.03, 0.02],
            },
            // Finger 1 sits at x = −0.025 with its +x side facing the palm axis; its outer side
            // is at x ≈ −0.025 − r.
            trajectory: PoseTrajectory {
                keyframes: vec![
                    PoseKeyframe::at(0.0, [-0.025 - p.radius_at(0.03) - 0.0015, 0.0, 0.05]),
                    PoseKeyframe::at(0.08, [-0.025 - p.radius_at(0.03) + 0.002, 0.0, 0.05]),
                ],
            },
        }],
        ..SceneConfig::default()
    }
}

fn run(config: SceneConfig) -> (Scene, moe_tendon_sim::SimState) {
    let mut scene = Scene::new(config).unwrap();
    let mut state = scene.initial_state();
    for _ in 0..scene.num_steps() {
        scene.step(&mut state).unwrap();
    }
    (scene, state)
}

#[test]
fn golden_digest_of_a_short_scene_is_reproduced() {
    let (scene, a) = run(short_scene());
    let (_, b) = run(short_scene());
    assert_eq!(a.step, 8);
    assert_eq!(a, b, "two runs of the same scene differ");
    assert_eq!(a.digest(), b.digest());
    let digest = a.rounded_digest(1e-9);
    if std::env::var_os("MOE_PRINT_DIGEST").is_some() {
        println!("digest = {digest:#018x}");
    }
    assert_eq!(digest, GOLDEN_DIGEST, "digest {digest:#018x}");
    // The plate touches finger 1 only.
    let frame = scene.frame(&a);
    let labelled: Vec<usize> = frame
        .fingers
        .iter()
        .map(|f| f.labels.iter().filter(|&&l| l).count())
        .collect();
    assert_eq!(labelled[0], 0);
    assert!(labelled[1] > 0, "{labelled:?}");
}

#[test]
fn base_nodes_follow_the_wrist_exactly() {
    let mut config = short_scene();
    config.obstacles.clear();
    config.wrist = PoseTrajectory {
        keyframes: vec![
            PoseKeyframe::at(0.0, [0.0; 3]),
            PoseKeyframe {
                time_secs: 0.05,
                translation_m: [0.01, -0.02, 0.03],
                rotation_rad: [0.0, 0.3, 0.0],
            },
        ],
    };
    config.duration_secs = 0.05;
    let (scene, state) = run(config);
    let pose = scene.config().wrist.pose_at(state.time_secs);
    for (i, body) in scene.bodies().iter().enumerate() {
        let world_from_finger = pose * scene.hand().fingers()[i].hand_from_finger.iso();
        for (n, rest) in body.fem().mesh().nodes().iter().enumerate() {
            if body.fem().fixed()[n] {
                let err = (state.fingers[i].x[n] - world_from_finger * rest).norm();
                assert!(err < 1e-12, "finger {i} node {n} off by {err}");
            }
        }
    }
}

#[test]
fn divergence_is_reported_with_step_and_element() {
    // Exploding energy: a limit below the first step's kinetic energy.
    let mut config = short_scene();
    config.solver.max_kinetic_energy_j = 1e-15;
    let mut scene = Scene::new(config).unwrap();
    let mut state = scene.initial_state();
    assert!(matches!(
        scene.step(&mut state),
        Err(SimError::ExplodingEnergy {
            step: 0,
            finger: 0,
            ..
        })
    ));
    // Inverted elements: a step that starts from a mirrored (inside-out) configuration.
    let mesh =
        TetMesh::box_grid(Point3::origin(), Point3::new(0.01, 0.01, 0.01), [1, 1, 2]).unwrap();
    let fixed: Vec<bool> = mesh.nodes().iter().map(|p| p.z < 1e-9).collect();
    let model = FemModel::new(mesh, Material::default(), fixed, &[], 0).unwrap();
    let mut x: Vec<Point3> = model
        .mesh()
        .nodes()
        .iter()
        .map(|p| Point3::new(p.x, p.y, -p.z))
        .collect();
    let targets = x.clone();
    let mut v = vec![Vector3::zeros(); x.len()];
    let mut ws = model.workspace();
    let err = model.step(
        &mut ws,
        StepContext { step: 7, finger: 1 },
        Integrator::Dynamic { dt_secs: 0.01 },
        &mut x,
        &mut v,
        &targets,
        &Vector3::zeros(),
        &mut |_, _, _| {},
    );
    assert!(
        matches!(
            err,
            Err(SimError::InvertedElement {
                step: 7,
                finger: 1,
                element: 0,
                ..
            })
        ),
        "{err:?}"
    );
}

#[test]
fn bad_scene_input_gives_typed_errors() {
    let check = |config: SceneConfig, name: &str| match Scene::new(config) {
        Err(SimError::InvalidParameter { name: got, .. }) => assert_eq!(got, name),
        other => panic!("{name}: {other:?}"),
    };
    let mut c = SceneConfig::default();
    c.solver.dt_secs = 0.0;
    check(c, "dt_secs");
    let mut c = SceneConfig::default();
    c.solver.dt_secs = -0.01;
    check(c, "dt_secs");
    let mut c = SceneConfig::default();
    c.material.youngs_modulus_pa = -1.0;
    check(c, "youngs_modulus_pa");
    let mut c = SceneConfig::default();
    c.material.poisson_ratio = 0.5;
    check(c, "poisson_ratio");
    let mut c = SceneConfig::default();
    c.voxel.cell_size_m = 0.0;
    check(c, "cell_size_m");
    let c = SceneConfig {
        actuation: vec![ActuationSchedule {
            mode: ActuationMode::Displacement,
            keyframes: vec![ActuationKeyframe {
                time_secs: 0.0,
                values: vec![0.0; 3],
            }],
        }],
        ..SceneConfig::default()
    };
    let err = Scene::new(c).unwrap_err();
    assert!(
        matches!(&err, SimError::Actuation { finger: 0, source }
            if matches!(**source, SimError::LengthMismatch { expected: 4, got: 3, .. })),
        "{err}"
    );
    assert!(
        err.to_string().starts_with("actuation of finger 0"),
        "{err}"
    );
    let c = SceneConfig {
        obstacles: vec![ObstacleConfig {
            shape: ObstacleShape::Ball { radius_m: 0.0 },
            trajectory: PoseTrajectory::default(),
        }],
        ..SceneConfig::default()
    };
    assert!(matches!(
        Scene::new(c),
        Err(SimError::InvalidObstacle { obstacle: 0, .. })
    ));
}

#[test]
fn bad_geometry_gives_typed_errors() {
    let finger = FingerModel::from_params(&FingerParams::default()).unwrap();
    // A tendon route leaving the body.
    let mut routes = finger.tendon_routes().to_vec();
    routes[2] = TendonRoute {
        points_in_finger: vec![Point3::new(0.0, 0.005, 0.0), Point3::new(0.0, 0.02, 0.04)],
        antagonist: 3,
    };
    let outside = FingerModel::from_parts(
        finger.mesh().clone(),
        finger.marker_vertices().to_vec(),
        finger.base_vertices().to_vec(),
        routes,
    )
    .unwrap();
    let err = FingerBody::new(&outside, &Material::default(), &VoxelParams::default());
    assert!(
        matches!(
            err,
            Err(SimError::TendonOutsideBody {
                tendon: 2,
                point: 1,
                ..
            })
        ),
        "{err:?}"
    );
    // An open surface.
    let mesh = finger.mesh();
    let open =
        moe_geom::TriMesh::new(mesh.vertices().to_vec(), mesh.faces()[1..].to_vec()).unwrap();
    assert!(matches!(
        moe_tendon_sim::voxelize(&open, &VoxelParams::default()),
        Err(SimError::Geometry(moe_geom::GeomError::OpenMesh { .. }))
    ));
    // A non-manifold surface is rejected when the mesh is built; the error converts.
    let v = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
        Point3::new(0.0, -1.0, 0.0),
        Point3::new(0.0, 0.0, 1.0),
    ];
    let geom = moe_geom::TriMesh::new(v, vec![[0, 1, 2], [0, 1, 3], [0, 1, 4]]).unwrap_err();
    let sim: SimError = geom.into();
    assert!(matches!(
        sim,
        SimError::Geometry(moe_geom::GeomError::NonManifoldEdge { .. })
    ));
}

#[test]
fn static_mode_follows_the_schedule_through_equilibria() {
    let mut config = short_scene();
    config.solver.mode = moe_tendon_sim::SolverMode::Static;
    config.gravity_m_s2 = [0.0; 3];
    config.duration_secs = 0.03;
    let (scene, state) = run(config);
    assert_eq!(state.step, 3);
    for f in &state.fingers {
        assert!(f.v.iter().all(|v| v.norm() == 0.0));
    }
    // Finger 0's +x tendon is being pulled: its tip moved toward the finger's +x side.
    let body = &scene.bodies()[0];
    let hand_from_finger = scene.hand().fingers()[0].hand_from_finger.iso();
    let world_from_finger = scene.config().wrist.pose_at(state.time_secs) * hand_from_finger;
    let tip_rest = body
        .fem()
        .mesh()
        .nodes()
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.z.total_cmp(&b.1.z))
        .unwrap();
    let moved = world_from_finger.inverse() * state.fingers[0].x[tip_rest.0] - tip_rest.1;
    assert!(moved.x > 1e-4, "tip moved by {moved:?}");
}

#[test]
fn a_rigidly_moving_hand_is_not_deformed_once_it_stops() {
    // No gravity, no obstacles, no actuation: the wrist turns by 1 rad and moves 5 cm, then
    // holds. Corotation must leave the fingers undeformed in the hand frame after the motion.
    let config = SceneConfig {
        gravity_m_s2: [0.0; 3],
        duration_secs: 1.5,
        wrist: PoseTrajectory {
            keyframes: vec![
                PoseKeyframe::at(0.0, [0.0; 3]),
                PoseKeyframe {
                    time_secs: 0.5,
                    translation_m: [0.05, 0.0, 0.02],
                    rotation_rad: [0.6, 0.0, 0.8],
                },
            ],
        },
        ..SceneConfig::default()
    };
    let (scene, state) = run(config);
    let frame = scene.frame(&state);
    let mut worst: moe_geom::Real = 0.0;
    for (i, f) in frame.fingers.iter().enumerate() {
        let rest = scene.hand().rest_vertices_in_hand(i);
        for (p, q) in f.vertices_in_hand.iter().zip(&rest) {
            worst = worst.max((p - q).norm());
        }
    }
    eprintln!("largest deviation from the rest shape after the motion: {worst:e} m");
    assert!(
        worst < 5e-5,
        "fingers deformed by {worst} m after a rigid motion"
    );
}

#[test]
fn three_and_five_finger_hands_step() {
    for preset in [
        moe_geom::HandPreset::ThreeFinger,
        moe_geom::HandPreset::FiveFinger,
    ] {
        let config = SceneConfig {
            hand: moe_tendon_sim::HandConfig {
                preset,
                finger: FingerParams {
                    vertex_budget: 256,
                    ..FingerParams::default()
                },
            },
            voxel: VoxelParams { cell_size_m: 0.005 },
            duration_secs: 0.02,
            ..SceneConfig::default()
        };
        let (scene, state) = run(config);
        assert_eq!(state.fingers.len(), preset.num_fingers());
        let frame = scene.frame(&state);
        assert!(
            frame.fingers.iter().all(|f| f.vertices_in_hand.len()
                == scene.hand().fingers()[0].model.mesh().num_vertices())
        );
    }
}

#[test]
fn scenes_and_states_can_move_between_threads() {
    fn assert_send<T: Send>() {}
    fn assert_sync<T: Sync>() {}
    assert_send::<Scene>();
    assert_send::<moe_tendon_sim::SimState>();
    assert_sync::<moe_tendon_sim::SimState>();
    assert_sync::<moe_tendon_sim::FingerBody>();
}
