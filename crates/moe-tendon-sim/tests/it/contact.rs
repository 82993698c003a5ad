//! Contact of the default finger with a plate and a sphere (finger frame, dynamic steps at the
//! default time step, gravity off so that only the obstacle loads the finger).

use moe_geom::{FingerParams, Point3, Real, Topology, Vector3};
use moe_tendon_sim::mechanics::{
    FingerBody, FingerInputs, Integrator, PosedObstacles, StepContext,
};
use moe_tendon_sim::{
    BodyState, ContactParams, Obstacle, ObstacleConfig, ObstacleShape, PoseKeyframe,
    PoseTrajectory, TendonCommand, TendonParams, contact_labels, surface_contact,
};

use crate::tendons::default_finger;

const DT: Real = 0.01;

/// Runs `steps` dynamic steps against `obstacle`; returns the deformed surface, its signed
/// distances to the obstacle and the labels at the end.
fn press(
    body: &FingerBody,
    obstacle: &Obstacle,
    steps: u64,
) -> (Vec<Point3>, Vec<Real>, Vec<bool>) {
    press_with(body, obstacle, steps, &ContactParams::default())
}

/// As [`press`] with the given contact model.
fn press_with(
    body: &FingerBody,
    obstacle: &Obstacle,
    steps: u64,
    contact: &ContactParams,
) -> (Vec<Point3>, Vec<Real>, Vec<bool>) {
    let rest = body.fem().mesh().nodes().to_vec();
    let mut state = BodyState {
        x: rest.clone(),
        v: vec![Vector3::zeros(); rest.len()],
    };
    let commands = [TendonCommand::Displacement { pull_m: 0.0 }; 4];
    let tendon = TendonParams::default();
    let obstacles = std::slice::from_ref(obstacle);
    let mut ws = body.fem().workspace();
    for step in 0..steps {
        let t0 = step as Real * DT;
        let posed = PosedObstacles::new(obstacles, t0, t0 + DT);
        let inputs = FingerInputs {
            targets: &rest,
            gravity: Vector3::zeros(),
            commands: &commands,
            tendon: &tendon,
            obstacles: &posed,
            contact,
        };
        body.step(
            &mut ws,
            StepContext { step, finger: 0 },
            Integrator::Dynamic { dt_secs: DT },
            &mut state,
            &inputs,
        )
        .unwrap();
    }
    let surface = body.surface().positions(&state.x);
    let t_end = steps as Real * DT;
    let c = surface_contact(
        &surface,
        obstacles,
        &[obstacle.pose_at(t_end)],
        contact.stiffness_n_per_m,
    );
    let labels = contact_labels(&c, body.movable_surface_vertices(), contact);
    (surface, c.distances_m, labels)
}

fn moving(shape: ObstacleShape, from: [Real; 3], to: [Real; 3], t_press: Real) -> Obstacle {
    Obstacle::new(
        0,
        &ObstacleConfig {
            shape,
            trajectory: PoseTrajectory {
                keyframes: vec![PoseKeyframe::at(0.0, from), PoseKeyframe::at(t_press, to)],
            },
        },
    )
    .unwrap()
}

#[test]
fn plate_pressed_5mm_penetrates_less_than_half_a_millimetre_on_the_facing_side_only() {
    let (model, body) = default_finger();
    let p = FingerParams::default();
    // A 2 mm thick plate parallel to the finger axis, facing its +x side over z ∈ [3, 7] cm,
    // approaching from 1 mm away and pressing 5 mm past the rest surface.
    let half = [0.001, 0.03, 0.02];
    let r = p.radius_at(0.03);
    let from = [r + 0.001 + half[0], 0.0, 0.05];
    let to = [r - 0.005 + half[0], 0.0, 0.05];
    let plate = moving(
        ObstacleShape::Cuboid {
            half_extents_m: half,
        },
        from,
        to,
        0.6,
    );
    let (_, d, labels) = press(&body, &plate, 100);
    let penetration = -d.iter().copied().fold(Real::INFINITY, Real::min);
    let labelled = labels.iter().filter(|&&l| l).count();
    eprintln!(
        "plate: penetration {:.4} mm, {labelled} labelled vertices",
        penetration * 1e3
    );
    assert!(penetration < 0.0005, "penetration {penetration} m");
    assert!(labelled >= 5, "only {labelled} vertices labelled");
    let normals = model.mesh().vertex_normals();
    for (i, &l) in labels.iter().enumerate() {
        if l {
            let rest = model.mesh().vertices()[i];
            assert!(
                rest.x > 0.0 && normals[i].x > 0.3,
                "vertex {i} at {rest} (normal {}) labelled but not facing the plate",
                normals[i]
            );
        }
    }
}

#[test]
fn sphere_pressed_into_the_side_gives_one_compact_patch_at_the_contact_point() {
    let (model, body) = default_finger();
    let p = FingerParams::default();
    let (radius, zc) = (0.01, 0.05);
    let r = p.radius_at(zc);
    let from = [0.0, r + radius + 0.001, zc];
    let to = [0.0, r + radius - 0.004, zc];
    let ball = moving(ObstacleShape::Ball { radius_m: radius }, from, to, 0.5);
    let (surface, _, labels) = press(&body, &ball, 80);
    let ids: Vec<usize> = (0..labels.len()).filter(|&i| labels[i]).collect();
    assert!(ids.len() >= 3, "{} labelled vertices", ids.len());
    // One connected patch over the surface mesh's edges.
    let topo = Topology::new(model.mesh());
    let mut seen = vec![false; labels.len()];
    let mut stack = vec![ids[0]];
    seen[ids[0]] = true;
    while let Some(v) = stack.pop() {
        for &n in topo.neighbors(v) {
            let n = n as usize;
            if labels[n] && !seen[n] {
                seen[n] = true;
                stack.push(n);
            }
        }
    }
    assert!(
        ids.iter().all(|&i| seen[i]),
        "the labelled set is not one connected patch"
    );
    // Patch centre vs the geometric contact point: the point of the sphere facing the deformed
    // finger's axis at the contact height.
    let centre = ids
        .iter()
        .fold(Vector3::zeros(), |a, &i| a + surface[i].coords)
        / ids.len() as Real;
    let ring: Vec<usize> = (0..surface.len())
        .filter(|&i| (model.mesh().vertices()[i].z - zc).abs() < 0.002)
        .collect();
    let axis = ring
        .iter()
        .fold(Vector3::zeros(), |a, &i| a + surface[i].coords)
        / ring.len() as Real;
    let c = Vector3::from(to);
    let geometric = c + (axis - c).normalize() * radius;
    let err = (centre - geometric).norm();
    let extent = ids
        .iter()
        .map(|&i| (surface[i].coords - centre).norm())
        .fold(0.0, Real::max);
    eprintln!(
        "sphere: {} labelled, centre error {:.3} mm, patch radius {:.2} mm",
        ids.len(),
        err * 1e3,
        extent * 1e3
    );
    assert!(
        err < 0.003,
        "patch centre {:.2} mm from the contact point",
        err * 1e3
    );
    assert!(extent < radius, "patch is not compact: radius {extent}");
}

#[test]
fn friction_drags_the_surface_along_a_sliding_plate() {
    let (model, body) = default_finger();
    let p = FingerParams::default();
    let half = [0.001, 0.03, 0.015];
    let r = p.radius_at(0.035);
    let x_in = r - 0.003 + half[0];
    let plate = Obstacle::new(
        0,
        &ObstacleConfig {
            shape: ObstacleShape::Cuboid {
                half_extents_m: half,
            },
            trajectory: PoseTrajectory {
                keyframes: vec![
                    PoseKeyframe::at(0.0, [r + 0.0005 + half[0], 0.0, 0.05]),
                    PoseKeyframe::at(0.3, [x_in, 0.0, 0.05]),
                    PoseKeyframe::at(0.6, [x_in, 0.005, 0.05]),
                ],
            },
        },
    )
    .unwrap();
    let drag = |friction: Real| {
        let contact = ContactParams {
            friction,
            ..ContactParams::default()
        };
        let (surface, _, labels) = press_with(&body, &plate, 60, &contact);
        let ids: Vec<usize> = (0..labels.len()).filter(|&i| labels[i]).collect();
        assert!(!ids.is_empty());
        ids.iter()
            .map(|&i| surface[i].y - model.mesh().vertices()[i].y)
            .sum::<Real>()
            / ids.len() as Real
    };
    let (slip, stick) = (drag(0.0), drag(1.0));
    eprintln!("mean tangential displacement of the patch: mu = 0: {slip:e} m, mu = 1: {stick:e} m");
    assert!(
        slip.abs() < 2e-4,
        "frictionless contact dragged the surface by {slip}"
    );
    assert!(
        stick > 5e-4,
        "friction should drag the surface along, got {stick}"
    );
}
