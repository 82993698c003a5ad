//! The plane rule: which fingers are loaded, their tips, the plane through them or through the
//! contact points.

use moe_geom::{RansacConfig, SeededRng};

use super::*;

fn angle_deg(a: &Vector3, b: &Vector3) -> Real {
    (a.dot(b) / (a.norm() * b.norm()))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// A finger is loaded when it has moved more than the threshold from rest in some hold
/// frame, and its tip (the vertex farthest along the press) is averaged over exactly the
/// frames in which it is loaded and its tip seen.
#[test]
fn loaded_fingers_are_the_deformed_ones_and_their_tips_average_the_seen_loaded_frames() {
    let options = GraspOptions::default();
    let axis = Vector3::new(0.0, 0.0, -1.0);
    let rest = [Point3::new(0.0, 0.0, 0.0), Point3::new(0.0, 0.0, -0.05)];
    let finger = |moved: [Real; 2], tip_seen: bool| {
        let at: Vec<Point3> = rest
            .iter()
            .zip(moved)
            .map(|(p, dx)| Point3::new(p.x + dx, p.y, p.z))
            .collect();
        FingerView {
            displacement_m: largest_displacement(&at, &rest),
            vertices_in_world: at,
            tip_seen,
        }
    };
    let m = options.loaded_finger_m;
    let frames = [
        // Finger 0 loaded (its tip moved 2 thresholds), 1 just below the threshold, 2 at
        // rest, 3 loaded with its tip hidden.
        vec![
            finger([0.0, 2.0 * m], true),
            finger([0.0, 0.9 * m], true),
            finger([0.0; 2], true),
            finger([0.0, 2.0 * m], false),
        ],
        // Finger 0 loaded again (tip 4 thresholds), 2 loaded at its base only.
        vec![
            finger([0.0, 4.0 * m], true),
            finger([0.0, 0.5 * m], true),
            finger([1.5 * m, 0.0], true),
            finger([0.0, 2.0 * m], false),
        ],
        // Finger 0 loaded with its tip hidden: not in its average.
        vec![
            finger([0.0, 9.0 * m], false),
            finger([0.0; 2], true),
            finger([0.0; 2], true),
            finger([0.0; 2], true),
        ],
    ];
    let (loaded, tips) = loaded_fingertips(&frames, &axis, &options);
    assert_eq!(loaded, [0, 2, 3]);
    // A non-finite vertex is neither a displacement nor a tip.
    let mut broken = finger([0.0, 2.0 * m], true);
    broken
        .vertices_in_world
        .push(Point3::new(Real::NAN, 0.0, 1.0));
    let mut at_rest = rest.to_vec();
    at_rest.push(Point3::origin());
    assert_eq!(
        largest_displacement(&broken.vertices_in_world, &at_rest),
        2.0 * m
    );
    assert_eq!(broken.tip(&axis), Some(Point3::new(2.0 * m, 0.0, -0.05)));
    assert_eq!(tips.len(), 2, "finger 3's tip was never seen");
    // Finger 0: the tip (z = −0.05) of frames 0 and 1, x averaged; finger 2: frame 1's.
    let close = |a: Point3, b: Point3| (a - b).norm() < 1e-12;
    assert!(
        close(tips[0], Point3::new(3.0 * m, 0.0, -0.05)),
        "{}",
        tips[0]
    );
    assert!(close(tips[1], Point3::new(0.0, 0.0, -0.05)), "{}", tips[1]);
}

/// Through three seen tips the plane is theirs; through two, it contains them with the
/// normal nearest the prior; with fewer the prior itself; fewer than three loaded fingers
/// give none.
#[test]
fn the_fingertip_plane_is_through_three_tips_or_two_and_the_axis() {
    let ransac = RansacConfig::default();
    let prior = Vector3::z();
    let tips = [
        Point3::new(0.03, 0.0, 0.0),
        Point3::new(-0.015, 0.026, 0.0),
        Point3::new(-0.015, -0.026, 0.01),
    ];
    let plane_normal = (tips[1] - tips[0]).cross(&(tips[2] - tips[0])).normalize();
    let (source, n) = fingertip_plane(3, 3, &tips, &prior, &ransac).unwrap();
    assert_eq!(source, PlaneSource::LoadedFingertips);
    assert!(n.dot(&prior) > 0.0);
    assert!(n.dot(&plane_normal).abs() > 1.0 - 1e-12, "{n}");
    // Two tips: the normal is perpendicular to their line, in the plane of the line's normal
    // and the prior, and tilted away from the prior only as far as the line demands.
    let two = [Point3::new(0.0, 0.0, 0.0), Point3::new(0.03, 0.0, 0.01)];
    let (source, n) = fingertip_plane(3, 3, &two, &prior, &ransac).unwrap();
    assert_eq!(source, PlaneSource::TwoFingertipsAndAxis);
    let line = (two[1] - two[0]).normalize();
    assert!(n.dot(&line).abs() < 1e-12);
    assert!(n.y.abs() < 1e-12);
    assert!((angle_deg(&n, &prior) - (0.01_f64 / 0.03).atan().to_degrees()).abs() < 1e-9);
    assert!(fingertip_plane(2, 3, &tips, &prior, &ransac).is_none());
    for seen in [&tips[..1], &[]] {
        let (source, n) = fingertip_plane(3, 3, seen, &prior, &ransac).unwrap();
        assert_eq!(source, PlaneSource::LoadedFingersAxis);
        assert_eq!(n, prior);
    }
    // A non-finite tip gives no plane, never a non-finite normal.
    let nan = Point3::new(Real::NAN, 0.0, 0.0);
    assert!(fingertip_plane(3, 3, &[two[0], nan], &prior, &ransac).is_none());
    assert!(fingertip_plane(3, 3, &[tips[0], tips[1], nan], &prior, &ransac).is_none());
}

/// The unit normal of a plate inclined by `incline_deg` about the world's x axis.
fn inclined(incline_deg: Real) -> Vector3 {
    let a = incline_deg.to_radians();
    Vector3::new(0.0, -a.sin(), a.cos())
}

/// Two unit vectors spanning the plane of unit normal `n`.
fn in_plane(n: &Vector3) -> (Vector3, Vector3) {
    let u = Vector3::x().cross(n).cross(n).normalize();
    (u, n.cross(&u))
}

/// A finger of five vertices from `base` to `tip`, displaced `displacement_m` from rest.
fn finger_to(base: Point3, tip: Point3, displacement_m: Real, tip_seen: bool) -> FingerView {
    FingerView {
        vertices_in_world: (0..5)
            .map(|k| base + (tip - base) * (Real::from(k) / 4.0))
            .collect(),
        displacement_m,
        tip_seen,
    }
}

/// Three loaded fingers whose tips rest on a known plane give that plane, toward the hand,
/// whatever the contact points say (here: none).
#[test]
fn three_loaded_fingertips_on_a_plane_give_that_plane() {
    let options = GraspOptions::default();
    let normal = inclined(20.0);
    let (u, v) = in_plane(&normal);
    let centre = Point3::new(0.01, -0.02, 0.3);
    // The hand 8° off the normal, pressing along its axis (toward the plane).
    let axis = -(moe_geom::math::UnitQuat::from_axis_angle(&Vector3::x_axis(), 8f64.to_radians())
        * normal);
    let wrist = centre - axis * 0.12;
    let loaded = 2.0 * options.loaded_finger_m;
    let frame: Vec<FingerView> = [0.0, 120.0, 240.0]
        .iter()
        .map(|deg: &Real| {
            let a = deg.to_radians();
            let tip = centre + (u * a.cos() + v * a.sin()) * 0.03;
            finger_to(tip - axis * 0.08, tip, loaded, true)
        })
        .collect();
    let fit = fit_grasp_plane(&[], &[frame.clone(), frame], &axis, &wrist, &options);
    assert_eq!(fit.loaded_fingers, [0, 1, 2]);
    assert_eq!(fit.tips.len(), 3);
    let plane = fit.plane.unwrap();
    assert_eq!(plane.source, PlaneSource::LoadedFingertips);
    assert!(plane.inliers.is_empty());
    assert!((plane.normal - normal).norm() < 1e-9, "{}", plane.normal);
}

/// With no finger loaded, RANSAC through the contact points gives the plane: points on a plate
/// inclined 30° (±0.5 mm of noise, and a few far off it) give its normal within 1°, toward the
/// wrist, with the outliers left out.
#[test]
fn contact_points_on_a_30_degree_plate_give_its_normal() {
    let options = GraspOptions::default();
    let normal = inclined(30.0);
    let (u, v) = in_plane(&normal);
    let mut rng = SeededRng::new(7);
    let mut contacts: Vec<ContactPoint> = (0..60)
        .map(|k| ContactPoint {
            finger: k % 3,
            vertex: k as u32,
            point: Point3::origin()
                + u * rng.uniform_range(-0.03, 0.03)
                + v * rng.uniform_range(-0.03, 0.03)
                + normal * rng.uniform_range(-5e-4, 5e-4),
            probability: 0.9,
        })
        .collect();
    let outliers = [60, 61, 62];
    for (k, offset) in outliers.iter().zip([0.02, 0.03, -0.025]) {
        contacts.push(ContactPoint {
            finger: 0,
            vertex: *k as u32,
            point: Point3::origin() + u * 0.01 + normal * offset,
            probability: 0.9,
        });
    }
    // A level hand: its axis straight down, 30° off the plate's normal; its fingers at rest.
    let axis = -Vector3::z();
    let wrist = Point3::new(0.0, 0.0, 0.1);
    let at_rest = finger_to(
        Point3::new(0.0, 0.0, 0.08),
        Point3::new(0.0, 0.0, 0.0),
        0.0,
        true,
    );
    let fit = fit_grasp_plane(
        &contacts,
        &[vec![at_rest.clone(), at_rest.clone(), at_rest]],
        &axis,
        &wrist,
        &options,
    );
    assert!(fit.loaded_fingers.is_empty());
    let plane = fit.plane.unwrap();
    assert_eq!(plane.source, PlaneSource::ContactPoints);
    let error = angle_deg(&plane.normal, &normal);
    assert!(error < 1.0, "{error}°");
    assert!(plane.normal.dot(&(wrist - Point3::origin())) > 0.0);
    assert!(outliers.iter().all(|k| !plane.inliers.contains(k)));
    assert!(plane.inliers.len() >= 55, "{}", plane.inliers.len());
    // Too few contact points and no loaded fingers: no plane, and the reason.
    let none = fit_grasp_plane(&contacts[..2], &[], &axis, &wrist, &options);
    assert!(matches!(
        none.plane,
        Err(GeomError::TooFewPoints { got: 2, .. })
    ));
}

/// Without [`GraspOptions::fingertip_plane`] the contact points give the plane even when three
/// fingers are loaded.
#[test]
fn without_the_fingertip_plane_the_contacts_give_it() {
    let options = GraspOptions {
        fingertip_plane: false,
        ..GraspOptions::default()
    };
    let loaded = 2.0 * options.loaded_finger_m;
    let tips = [
        Point3::new(0.03, 0.0, 0.0),
        Point3::new(-0.015, 0.026, 0.0),
        Point3::new(-0.015, -0.026, 0.0),
    ];
    let frame: Vec<FingerView> = tips
        .iter()
        .map(|t| finger_to(t + Vector3::z() * 0.08, *t, loaded, true))
        .collect();
    let contacts: Vec<ContactPoint> = (0..9)
        .map(|k| ContactPoint {
            finger: 0,
            vertex: k,
            point: Point3::new(0.01 * Real::from(k % 3), 0.01 * Real::from(k / 3), 0.0),
            probability: 1.0,
        })
        .collect();
    let fit = fit_grasp_plane(
        &contacts,
        &[frame],
        &-Vector3::z(),
        &Point3::new(0.0, 0.0, 0.1),
        &options,
    );
    assert_eq!(fit.loaded_fingers, [0, 1, 2]);
    let plane = fit.plane.unwrap();
    assert_eq!(plane.source, PlaneSource::ContactPoints);
    assert!((plane.normal - Vector3::z()).norm() < 1e-9);
    assert_eq!(plane.inliers.len(), 9);
}
