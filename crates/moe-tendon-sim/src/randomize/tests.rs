//! Tests of the scene randomisation: seeded draws, regions and fingers, pressed apexes, parameter
//! checks, material and mesh parameters, and a simulated sample.

use super::*;

#[test]
fn same_seed_same_scene_and_families_all_place() {
    let params = RandomSceneParams::default();
    assert_eq!(
        sample_scene(&params, 7, 3).unwrap(),
        sample_scene(&params, 7, 3).unwrap()
    );
    assert_ne!(
        sample_scene(&params, 7, 3).unwrap(),
        sample_scene(&params, 7, 4).unwrap()
    );
    for family in ObjectFamily::ALL {
        let params = RandomSceneParams {
            families: vec![family],
            ..RandomSceneParams::default()
        };
        for t in 0..3 {
            let s = sample_scene(&params, 11, t).unwrap();
            assert_eq!(s.family, family);
            // The object starts a gap away from the target, along the normal.
            let obstacle = Obstacle::new(0, &s.config.obstacles[0]).unwrap();
            let pose = s.config.obstacles[0].trajectory.pose_at(0.0);
            let probe = s.target_in_hand + s.normal_in_hand * params.gap_m;
            let d = obstacle
                .signed_distance(&pose, &probe)
                .map_or(0.0, |d| d.distance_m);
            assert!(d.abs() < 1.5e-3, "{family:?}: {d}");
        }
    }
}

#[test]
fn regions_and_fingers_are_all_drawn() {
    let params = RandomSceneParams {
        preset: HandPreset::ThreeFinger,
        ..RandomSceneParams::default()
    };
    let scenes: Vec<SampledScene> = (0..60)
        .map(|t| sample_scene(&params, 1, t).unwrap())
        .collect();
    for region in [FingerRegion::Tip, FingerRegion::Middle, FingerRegion::Base] {
        assert!(scenes.iter().any(|s| s.region == region));
    }
    for f in 0..3 {
        assert!(scenes.iter().any(|s| s.finger == f));
    }
}

#[test]
fn the_apex_is_pressed_along_the_finger_and_labelled_at_its_end() {
    let params = RandomSceneParams {
        regions: vec![FingerRegion::Apex],
        families: vec![ObjectFamily::Sphere, ObjectFamily::ThinPlate],
        ..quick()
    };
    let hand = HandModel::preset(params.preset, &params.finger).unwrap();
    for t in 0..4 {
        let (sampled, _, frames) = simulate_trajectory(&params, 3, t).unwrap();
        assert_eq!(sampled.region, FingerRegion::Apex);
        let finger = &hand.fingers()[sampled.finger];
        let n = finger
            .hand_from_finger
            .inverse()
            .transform_vector(&sampled.normal_in_hand);
        // 45–90° above the cap's equator: the normal is within 45° of the finger's axis.
        assert!(n.z >= std::f64::consts::FRAC_1_SQRT_2 - 1e-12, "{n}");
        // At full press the labelled vertices are on the rounded end.
        let pressed = frames
            .iter()
            .min_by(|a, b| {
                (a.time_secs - params.press_secs)
                    .abs()
                    .total_cmp(&(b.time_secs - params.press_secs).abs())
            })
            .unwrap();
        let rest = finger.model.mesh().vertices();
        let labels = &pressed.fingers[sampled.finger].labels;
        let labelled: Vec<usize> = (0..labels.len()).filter(|&v| labels[v]).collect();
        assert!(
            !labelled.is_empty(),
            "trajectory {t}: no label at full press"
        );
        for v in labelled {
            assert!(rest[v].z > params.finger.cap_start_z() - 1e-3, "vertex {v}");
        }
    }
    let none = RandomSceneParams {
        regions: vec![],
        ..RandomSceneParams::default()
    };
    assert!(matches!(
        sample_scene(&none, 0, 0),
        Err(SimError::InvalidParameter {
            name: "regions",
            ..
        })
    ));
}

#[test]
fn bad_ranges_are_rejected() {
    let p = RandomSceneParams {
        families: vec![],
        ..RandomSceneParams::default()
    };
    moe_geom::assert_err!(
        sample_scene(&p, 0, 0),
        SimError::InvalidParameter {
            name: "families",
            ..
        }
    );
    let p = RandomSceneParams {
        press_depth_m: [0.005, 0.001],
        ..RandomSceneParams::default()
    };
    moe_geom::assert_err!(
        sample_scene(&p, 0, 0),
        SimError::InvalidParameter {
            name: "press_depth_m",
            ..
        }
    );
    for e in [0.0, -1e5, Real::NAN] {
        let p = RandomSceneParams {
            material: Material {
                youngs_modulus_pa: e,
                ..Material::default()
            },
            ..RandomSceneParams::default()
        };
        moe_geom::assert_err!(
            sample_scene(&p, 0, 0),
            SimError::InvalidParameter {
                name: "youngs_modulus_pa",
                ..
            }
        );
    }
    let p = RandomSceneParams {
        material: Material {
            poisson_ratio: 0.5,
            ..Material::default()
        },
        ..RandomSceneParams::default()
    };
    moe_geom::assert_err!(
        sample_scene(&p, 0, 0),
        SimError::InvalidParameter {
            name: "poisson_ratio",
            ..
        }
    );
    for h in [0.0, -0.001, Real::INFINITY] {
        let p = RandomSceneParams {
            voxel: VoxelParams { cell_size_m: h },
            ..RandomSceneParams::default()
        };
        moe_geom::assert_err!(
            sample_scene(&p, 0, 0),
            SimError::InvalidParameter {
                name: "voxel cell_size_m",
                ..
            }
        );
    }
    let p = RandomSceneParams {
        hand_rotation_rad: [0.0, Real::NAN, 0.0],
        ..RandomSceneParams::default()
    };
    moe_geom::assert_err!(
        sample_scene(&p, 0, 0),
        SimError::InvalidParameter {
            name: "hand_rotation_rad",
            ..
        }
    );
}

/// `params` with Young's modulus times `factor` and cells of `cell_size_m`.
fn with_material(factor: Real, cell_size_m: Real) -> RandomSceneParams {
    let default = RandomSceneParams::default();
    RandomSceneParams {
        material: Material {
            youngs_modulus_pa: factor * default.material.youngs_modulus_pa,
            ..Material::default()
        },
        voxel: VoxelParams { cell_size_m },
        ..default
    }
}

#[test]
fn material_and_mesh_are_parameters_that_draw_nothing() {
    let default = RandomSceneParams::default();
    let other = with_material(1.25, 0.0025);
    for t in 0..6 {
        let a = sample_scene(&default, 5, t).unwrap();
        let b = sample_scene(&other, 5, t).unwrap();
        // The default parameters give the scene configuration of before they existed.
        assert_eq!(a.config.material, SceneConfig::default().material);
        assert_eq!(a.config.voxel, SceneConfig::default().voxel);
        assert_eq!(b.config.material, other.material);
        assert_eq!(b.config.voxel, other.voxel);
        // Nothing else differs: the parameters draw no random number.
        let mut b = b;
        b.config.material = a.config.material.clone();
        b.config.voxel = a.config.voxel.clone();
        assert_eq!(a, b, "trajectory {t}");
    }
    // A parameter file sets them by section; an empty one is the default.
    let parsed: RandomSceneParams =
        toml::from_str("[material]\nyoungs_modulus_pa = 125000.0\n[voxel]\ncell_size_m = 0.0025\n")
            .unwrap();
    assert_eq!(parsed, other);
    assert_eq!(
        toml::from_str::<RandomSceneParams>("").unwrap(),
        RandomSceneParams::default()
    );
    assert!(toml::from_str::<RandomSceneParams>("[material]\nyoungs = 1.0\n").is_err());
    // And they are recorded where the parameters are (a data set's card).
    let json = serde_json::to_value(&other).unwrap();
    assert_eq!(json["material"]["youngs_modulus_pa"], 125000.0);
    assert_eq!(json["voxel"]["cell_size_m"], 0.0025);
}

/// One static step of the scene sampled with `params` (trajectory 0 of seed 5) without its
/// object and wrist motion, under `actuation` of finger 0: the largest displacement of a
/// vertex of finger 0 from rest (hand frame, metres) and the tension of tendon 0 (N).
fn bend(params: &RandomSceneParams, actuation: ActuationSchedule) -> (Real, Real) {
    let mut config = sample_scene(params, 5, 0).unwrap().config;
    config.obstacles.clear();
    config.wrist = PoseTrajectory::default();
    config.solver.mode = crate::scene::SolverMode::Static;
    config.duration_secs = config.solver.dt_secs;
    config.actuation = vec![actuation];
    let mut scene = Scene::new(config).unwrap();
    let mut state = scene.initial_state();
    let rest = scene.frame(&state);
    let info = scene.step(&mut state).unwrap();
    let bent = scene.frame(&state);
    let deflection = rest.fingers[0]
        .vertices_in_hand
        .iter()
        .zip(&bent.fingers[0].vertices_in_hand)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, Real::max);
    (deflection, info.tendons[0][0].tension_n)
}

#[test]
fn a_stiffer_finger_bends_less_under_the_same_pull() {
    let schedule = |mode, value: Real| ActuationSchedule {
        mode,
        keyframes: vec![ActuationKeyframe {
            time_secs: 0.0,
            values: vec![value, 0.0, 0.0, 0.0],
        }],
    };
    let default = RandomSceneParams::default();
    let stiff = with_material(1.25, default.voxel.cell_size_m);
    // The same tension: the bend scales with 1/E in the linear range.
    let force = schedule(crate::trajectory::ActuationMode::Force, 0.3);
    let (soft_bend, _) = bend(&default, force.clone());
    let (stiff_bend, _) = bend(&stiff, force);
    assert!(soft_bend > 1e-3, "the pull bends the finger: {soft_bend} m");
    let ratio = stiff_bend / soft_bend;
    assert!((0.7..0.9).contains(&ratio), "bend ratio {ratio}");
    // The same pulled length: the bend is nearly the cable's, and the tension it takes grows
    // with E.
    let pull = schedule(crate::trajectory::ActuationMode::Displacement, 0.003);
    let (soft_bend, soft_tension) = bend(&default, pull.clone());
    let (stiff_bend, stiff_tension) = bend(&stiff, pull);
    assert!(stiff_bend < soft_bend, "{stiff_bend} ≥ {soft_bend}");
    let ratio = stiff_tension / soft_tension;
    assert!((1.15..1.4).contains(&ratio), "tension ratio {ratio}");
}

/// A short schedule so that the test runs quickly in the dev profile.
fn quick() -> RandomSceneParams {
    RandomSceneParams {
        press_secs: 0.25,
        hold_secs: 0.05,
        retract_secs: 0.05,
        press_depth_m: [0.004, 0.006],
        save_every_steps: 5,
        ..RandomSceneParams::default()
    }
}

/// Data sanity on a simulated sample (one trajectory per family): the pressed frames carry
/// labels, labels lie on the side of the finger that faces the object, the contact ratio of
/// contact frames lies in the documented range, and nothing penetrates beyond 0.5 mm.
#[test]
fn simulated_sample_is_sane() {
    let mut contact_vertices = 0usize;
    let mut vertices_in_contact_frames = 0usize;
    for (t, family) in ObjectFamily::ALL.into_iter().enumerate() {
        let params = RandomSceneParams {
            families: vec![family],
            ..quick()
        };
        let (sampled, _, frames) = simulate_trajectory(&params, 5, t as u64).unwrap();
        let scene = Scene::new(sampled.config.clone()).unwrap();
        let obstacle = &scene.obstacles()[0];
        // At the end of the press the hand is pushed past first touch.
        let pressed = frames
            .iter()
            .filter(|f| {
                (f.time_secs - params.press_secs).abs()
                    < 0.5 * params.dt_secs * params.save_every_steps as Real
            })
            .collect::<Vec<_>>();
        assert!(!pressed.is_empty());
        for f in &pressed {
            let labelled: usize = f
                .fingers
                .iter()
                .map(|g| g.labels.iter().filter(|&&l| l).count())
                .sum();
            assert!(labelled > 0, "{family:?}: no label at full press");
            // The object pushes the pressed finger back against the press.
            let force = f.fingers[sampled.finger].force_in_hand_n;
            assert!(
                force.dot(&sampled.normal_in_hand) < 0.0,
                "{family:?}: net force {force} along the press normal"
            );
        }
        // A finger's net force is the vector sum of its vertices' forces: no longer than the
        // sum of their magnitudes.
        for f in &frames {
            for g in &f.fingers {
                let magnitudes: Real = g.contact_force_n.iter().sum();
                let net = g.force_in_hand_n.norm();
                assert!(net <= magnitudes * (1.0 + 1e-12), "{net} > {magnitudes}");
                assert_eq!(net == 0.0, magnitudes == 0.0);
            }
        }
        for f in &frames {
            let pose = obstacle.pose_at(f.time_secs);
            let mut any = false;
            for (i, g) in f.fingers.iter().enumerate() {
                let min = g
                    .distances_m
                    .iter()
                    .copied()
                    .fold(Real::INFINITY, Real::min);
                assert!(min > -5e-4, "{family:?}: penetration {min} m");
                let mesh = scene.hand().fingers()[i]
                    .model
                    .mesh()
                    .with_vertices(g.vertices_in_world.clone())
                    .unwrap();
                let normals = mesh.vertex_normals();
                for (v, &l) in g.labels.iter().enumerate() {
                    if !l {
                        continue;
                    }
                    any = true;
                    let s = obstacle.signed_distance(&pose, &g.vertices_in_world[v]);
                    if let Some(s) = s {
                        // The obstacle's outward normal at the closest point faces the
                        // finger: the finger's own outward normal opposes it.
                        let c = normals[v].dot(&s.normal);
                        assert!(c < 0.3, "{family:?}: label on the far side ({c:.2})");
                    }
                }
                if g.labels.iter().any(|&l| l) {
                    contact_vertices += g.labels.iter().filter(|&&l| l).count();
                }
            }
            if any {
                vertices_in_contact_frames +=
                    f.fingers.iter().map(|g| g.labels.len()).sum::<usize>();
            }
        }
    }
    let ratio = contact_vertices as Real / vertices_in_contact_frames as Real;
    assert!((0.001..0.15).contains(&ratio), "contact ratio {ratio}");
}

/// Finger bodies built once for a data set give every trajectory the frames it gets from bodies
/// of its own, bit for bit, and a scene of another material or resolution refuses them.
#[test]
fn shared_finger_bodies_give_the_same_frames_and_refuse_another_material() {
    let params = quick();
    let bodies = hand_bodies(&params).unwrap();
    for t in 0..2 {
        let (sampled, _, own) = simulate_trajectory(&params, 11, t).unwrap();
        let (again, _, shared) = simulate_trajectory_with(&params, &bodies, 11, t).unwrap();
        assert_eq!(sampled, again);
        assert_eq!(own, shared, "trajectory {t}");
    }
    let sampled = sample_scene(&params, 11, 0).unwrap();
    let mut softer = sampled.config.clone();
    softer.material.youngs_modulus_pa *= 0.5;
    assert!(matches!(
        Scene::with_bodies(softer, &bodies),
        Err(SimError::InvalidParameter {
            name: "material",
            ..
        })
    ));
    let mut finer = sampled.config;
    finer.voxel.cell_size_m *= 0.5;
    assert!(matches!(
        Scene::with_bodies(finer, &bodies),
        Err(SimError::InvalidParameter {
            name: "voxel cell_size_m",
            ..
        })
    ));
}

/// A hand held another way is the upright scene turned: without gravity its frames are the
/// upright ones turned by the hand's rotation, and with gravity the free fingers sag along the
/// gravity the turned hand feels.
#[test]
fn a_turned_hand_is_the_upright_scene_turned_and_sags_its_own_way() {
    let upright = quick();
    let turned = RandomSceneParams {
        hand_rotation_rad: [0.5 * PI, 0.0, 0.0],
        ..quick()
    };
    let rotation = hand_rotation(&turned);
    let run = |params: &RandomSceneParams, gravity: [Real; 3]| {
        let sampled = sample_scene(params, 5, 1).unwrap();
        let mut config = sampled.config.clone();
        config.gravity_m_s2 = gravity;
        let mut scene = Scene::new(config).unwrap();
        let steps = scene.num_steps();
        (sampled, run_saving(&mut scene, steps).unwrap())
    };
    let (a, up) = run(&upright, [0.0; 3]);
    let (b, turn) = run(&turned, [0.0; 3]);
    // The draws are the same: only the placement in the world turns.
    assert_eq!(
        (a.family, a.finger, a.region),
        (b.family, b.finger, b.region)
    );
    assert_eq!(a.target_in_hand, b.target_in_hand);
    let mut largest: Real = 0.0;
    let mut moved: Real = 0.0;
    for (f, g) in up.iter().zip(&turn) {
        assert!(g.world_from_hand.rotation.angle_to(&rotation) < 1e-12);
        for (i, (p, q)) in f.fingers.iter().zip(&g.fingers).enumerate() {
            assert_eq!(p.labels, q.labels, "t = {}", f.time_secs);
            for (x, y) in p.vertices_in_world.iter().zip(&q.vertices_in_world) {
                largest = largest.max((rotation * x - y).norm());
            }
            moved = moved.max(
                p.vertices_in_world
                    .iter()
                    .zip(&up[0].fingers[i].vertices_in_world)
                    .map(|(x, y)| (x - y).norm())
                    .fold(0.0, Real::max),
            );
        }
    }
    assert!(moved > 1e-3, "the scene does not move ({moved} m)");
    assert!(largest < 1e-6, "turned frames differ by {largest} m");
    // With gravity and no pull: the scene starts settled, its free finger's tip already moved
    // from the rest shape along the gravity of the hand frame (across the fingers for the
    // turned hand).
    let still = |p: &RandomSceneParams| RandomSceneParams {
        max_pull_m: 0.0,
        ..p.clone()
    };
    let gravity = [0.0, 0.0, -9.81];
    let hand = HandModel::preset(upright.preset, &upright.finger).unwrap();
    let sag = |params: &RandomSceneParams| -> Vector3 {
        let (sampled, frames) = run(&still(params), gravity);
        let free = 1 - sampled.finger;
        let rest = hand.rest_vertices_in_hand(free);
        let in_hand = |f: &SimFrame, v: usize| {
            f.world_from_hand.inverse() * f.fingers[free].vertices_in_world[v]
        };
        let tip = (0..rest.len())
            .max_by(|&u, &v| rest[u].z.total_cmp(&rest[v].z))
            .unwrap();
        in_hand(&frames[0], tip) - rest[tip]
    };
    let g_turned = rotation.inverse() * Vector3::from(gravity);
    let (s_up, s_turn) = (sag(&upright), sag(&turned));
    assert!(
        s_turn.dot(&g_turned.normalize()) > 0.9 * s_turn.norm(),
        "{s_turn}"
    );
    assert!(s_turn.norm() > 5.0 * s_up.norm(), "{s_turn} vs {s_up}");
}
