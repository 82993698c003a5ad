//! SR-ARAP registered to a depth image: a press that only the depth image sees.

use moe_arap::{MultiShapeEstimator, ShapeConfig, ShapeDepth};
use moe_geom::depth::{AssociationOptions, DepthImage, associate_depth};
use moe_geom::transform::HandFromCamera;
use moe_geom::{CameraIntrinsics, HandModel, HandShape, Iso3, Point3, Real, Vector3};

use crate::two_finger_hand;

fn mount() -> HandFromCamera {
    HandFromCamera::new(Iso3::translation(0.0, 0.0, -0.02))
}

/// An exact depth image of `shape` (and of `extra` triangles, hand frame) through the default
/// camera at [`mount`].
fn render(hand: &HandModel, shape: &HandShape, extra: &[[Point3; 3]]) -> Vec<f32> {
    moe_geom::depth::render_hand(hand, shape, extra, CameraIntrinsics::default(), mount())
        .unwrap()
        .view()
        .pixels()
        .to_vec()
}

/// The rest hand with finger 0 dented by `depth_m` (inwards along the surface normal, a smooth
/// bump 5 mm in radius) at the visible surface point nearest the middle of its markers, and
/// that point.
fn dented(hand: &HandModel, depth_m: Real) -> (HandShape, Point3, Vector3) {
    let rest = HandShape::rest(hand);
    let pixels = render(hand, &rest, &[]);
    let image = DepthImage::new(&pixels, CameraIntrinsics::default(), mount()).unwrap();
    let seen = associate_depth(hand, &rest, &image, &AssociationOptions::default()).unwrap();
    let markers = hand.rest_keypoints();
    let m = &markers.fingers[0];
    let middle = Point3::from((m[2].unwrap().coords + m[3].unwrap().coords) / 2.0);
    let seen = seen[0]
        .points
        .iter()
        .min_by(|a, b| {
            (a.predicted_in_hand - middle)
                .norm()
                .total_cmp(&(b.predicted_in_hand - middle).norm())
        })
        .unwrap();
    let (centre, inwards) = (seen.predicted_in_hand, -seen.normal_in_hand);
    let mut shape = rest.clone();
    for p in &mut shape.fingers[0] {
        let d = (*p - centre).norm() / 0.005;
        if d < 1.0 {
            *p += inwards * depth_m * (1.0 - d * d).powi(2);
        }
    }
    (shape, centre, -inwards)
}

/// Largest distance from the true shape over finger 0's vertices within 3 mm of `centre`.
fn dent_error(estimate: &HandShape, truth: &HandShape, centre: &Point3) -> Real {
    estimate.fingers[0]
        .iter()
        .zip(&truth.fingers[0])
        .filter(|(_, t)| (*t - centre).norm() < 0.003)
        .map(|(e, t)| (e - t).norm())
        .fold(0.0, Real::max)
}

/// A 1 mm dent between the markers, seen by the depth image only: SR-ARAP from the markers
/// leaves the surface where it was; registered to the depth image as well it follows the dent
/// to a fraction of its depth, and the fingers away from it stay where the markers put them.
#[test]
fn a_dent_only_the_depth_image_sees_is_followed() {
    let hand = two_finger_hand();
    let (truth, centre, _) = dented(&hand, 0.001);
    let keypoints = hand.keypoints_on(&truth.fingers);
    let pixels = render(&hand, &truth, &[]);
    let image = DepthImage::new(&pixels, CameraIntrinsics::default(), mount()).unwrap();
    let mut markers_only = MultiShapeEstimator::new(hand.clone(), ShapeConfig::default()).unwrap();
    let without = markers_only
        .estimate_with(&keypoints, Some(&image))
        .unwrap();
    let with_depth = ShapeConfig {
        depth: ShapeDepth {
            enabled: true,
            ..ShapeDepth::default()
        },
        ..ShapeConfig::default()
    };
    let mut registered = MultiShapeEstimator::new(hand.clone(), with_depth).unwrap();
    let with = registered.estimate_with(&keypoints, Some(&image)).unwrap();
    let off_without = dent_error(&without.shape, &truth, &centre);
    let off_with = dent_error(&with.shape, &truth, &centre);
    assert!(off_without > 0.0008, "markers alone: {off_without:e} m");
    assert!(
        off_with < 0.5 * off_without,
        "with depth {off_with:e} m, markers alone {off_without:e} m"
    );
    let r = &with.reports[0];
    assert!(r.depth_patches > 10 && r.depth_pixels > 100, "{r:?}");
    assert_eq!(without.reports[0].depth_patches, 0);
    // Visible markers stay on their keypoints.
    for (m, v) in registered.handle_vertices(0).iter().enumerate() {
        let err =
            (with.shape.fingers[0][v.unwrap() as usize] - keypoints.fingers[0][m].unwrap()).norm();
        assert!(err < 1e-9, "marker {m}: {err:e}");
    }
    // The untouched finger is not pulled away from its true (rest) shape.
    let other = with.shape.fingers[1]
        .iter()
        .zip(&truth.fingers[1])
        .map(|(e, t)| (e - t).norm())
        .fold(0.0, Real::max);
    assert!(other < 1e-4, "finger 1 moved {other:e} m");
    // Through the seam as well: the observation's depth image is used.
    let observation = moe_geom::Observation::from_keypoints(&keypoints).with_depth(image);
    let shape = moe_geom::ShapeEstimator::estimate_shape(&mut registered, &observation).unwrap();
    assert!(dent_error(&shape, &truth, &centre) < 0.5 * off_without);
}

/// An object just in front of the finger (as the one pressing it is) does not pull the surface
/// out towards it: its pixels are left out by the front gate, and a patch that still lies in
/// front weighs little. With the physics estimator's front gate (3 mm) and a quadratic loss,
/// the surface is pulled out.
#[test]
fn an_object_just_in_front_does_not_pull_the_surface_out() {
    let hand = two_finger_hand();
    let rest = HandShape::rest(&hand);
    let (_, centre, _) = dented(&hand, 0.0);
    // A 6 mm square facing the camera, 1.5 mm in front of the surface along the ray.
    let eye = Point3::from(mount().iso().translation.vector);
    let towards = (eye - centre).normalize();
    let u = towards.cross(&Vector3::y()).normalize() * 0.003;
    let v = towards.cross(&u).normalize() * 0.003;
    let c = centre + towards * 0.0015;
    let plate = [
        [c - u - v, c + u - v, c + u + v],
        [c - u - v, c + u + v, c - u + v],
    ];
    let pixels = render(&hand, &rest, &plate);
    let image = DepthImage::new(&pixels, CameraIntrinsics::default(), mount()).unwrap();
    let keypoints = hand.rest_keypoints();
    let off = |front_gate_m, front_loss_sigma| {
        let settings = ShapeConfig {
            depth: ShapeDepth {
                enabled: true,
                front_gate_m,
                front_loss_sigma,
                ..ShapeDepth::default()
            },
            ..ShapeConfig::default()
        };
        let mut est = MultiShapeEstimator::new(hand.clone(), settings).unwrap();
        let out = est.estimate_with(&keypoints, Some(&image)).unwrap();
        dent_error(&out.shape, &rest, &centre)
    };
    let d = ShapeDepth::default();
    let robust = off(d.front_gate_m, d.front_loss_sigma);
    let quadratic = off(0.003, 0.0);
    assert!(
        quadratic > 0.0004,
        "quadratic loss: pulled out {quadratic:e} m"
    );
    assert!(
        robust < 0.1 * quadratic,
        "robust {robust:e} m against {quadratic:e} m"
    );
}
