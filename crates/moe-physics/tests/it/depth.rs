//! The depth image as observation: a press that only the depth image shows, a free hand seen
//! in depth, and depth images that are broken.

use moe_geom::zbuffer::ZBuffer;
use moe_geom::{
    CameraIntrinsics, HandEstimator as _, HandFromCamera, HandKeypoints, HandShape, Iso3,
    Observation, OwnedDepthImage, Real, SeededRng, WorldFromHand,
};
use moe_physics::testing::{render_depth, static_hand};
use moe_physics::{HandMaterial, PhysicsConfig, PhysicsEstimate, PhysicsEstimator};

use crate::common::{hand, no_pulls, press};

/// The wrist camera of the default hand: 2 cm behind the palm, looking along the fingers.
fn camera() -> (CameraIntrinsics, HandFromCamera) {
    (
        CameraIntrinsics::default(),
        HandFromCamera::new(Iso3::translation(0.0, 0.0, -0.02)),
    )
}

fn with_depth() -> PhysicsConfig {
    let mut config = PhysicsConfig::default();
    config.depth.enabled = true;
    config
}

fn estimate(
    config: &PhysicsConfig,
    markers: &HandKeypoints,
    depth: Option<&OwnedDepthImage>,
) -> PhysicsEstimate {
    let hand = hand();
    let pulls = no_pulls(&hand);
    let mut est = PhysicsEstimator::new(&hand, &HandMaterial::default(), config).unwrap();
    let mut obs = Observation::from_keypoints(markers)
        .with_tendon_pulls(&pulls)
        .with_world_from_hand(WorldFromHand::identity());
    if let Some(d) = depth {
        obs = obs.with_depth(d.view());
    }
    est.estimate(&obs).unwrap()
}

/// A vertex of finger 0 that the camera sees face-on, nearest `z_m` along the finger.
fn seen_vertex(shape: &HandShape, z_m: Real) -> u32 {
    let hand = hand();
    let (k, mount) = camera();
    let mut zbuffer = ZBuffer::new(k).unwrap();
    let camera_from_hand = mount.iso().inverse();
    let mesh = hand.fingers()[0].model.mesh();
    for (i, face) in mesh.faces().iter().enumerate() {
        zbuffer.draw(
            &face.map(|v| camera_from_hand * shape.fingers[0][v as usize]),
            0,
            i as u32,
        );
    }
    let rest = mesh.vertices();
    zbuffer
        .hits()
        .iter()
        .flatten()
        .filter(|h| h.cos_view > 0.3)
        .flat_map(|h| mesh.faces()[h.face as usize])
        .min_by(|&a, &b| {
            (rest[a as usize].z - z_m)
                .abs()
                .total_cmp(&(rest[b as usize].z - z_m).abs())
        })
        .expect("the camera sees finger 0")
}

/// Finger 0's markers with all but the three nearest its base hidden.
fn base_markers_only(markers: &HandKeypoints) -> HandKeypoints {
    let hand = hand();
    let rest = hand.fingers()[0].model.marker_positions();
    let mut order: Vec<usize> = (0..rest.len()).collect();
    order.sort_by(|&a, &b| rest[a].z.total_cmp(&rest[b].z));
    let mut out = markers.clone();
    for &m in &order[3..] {
        out.fingers[0][m] = None;
    }
    out
}

#[test]
fn a_press_only_the_depth_image_shows_is_found_with_it_and_missed_without() {
    let hand = hand();
    let pulls = no_pulls(&hand);
    let (_, rest_shape) = static_hand(&hand, &pulls, &WorldFromHand::identity(), &[]).unwrap();
    let v = seen_vertex(&rest_shape, 0.05);
    let (markers, shape) = static_hand(
        &hand,
        &pulls,
        &WorldFromHand::identity(),
        &[press(&hand, v, 0.1)],
    )
    .unwrap();
    let markers = base_markers_only(&markers);
    let (k, mount) = camera();
    let depth = render_depth(&hand, &shape, k, mount).unwrap();
    let config = with_depth();
    // The markers near the base alone do not show the press.
    let blind = estimate(&config, &markers, None);
    assert!(
        blind.details.loads.iter().all(|l| l.finger != 0),
        "markers alone: {:?}",
        blind.details.loads
    );
    assert_eq!(blind.details.fingers[0].depth_rows, 0);
    // The depth image does.
    let seen = estimate(&config, &markers, Some(&depth));
    let loads: Vec<_> = seen
        .details
        .loads
        .iter()
        .filter(|l| l.finger == 0)
        .collect();
    assert_eq!(loads.len(), 1, "{:?}", seen.details.loads);
    let rest = hand.fingers()[0].model.mesh().vertices();
    let hand_from_finger = hand.fingers()[0].hand_from_finger.iso();
    let off = (loads[0].location_rest - hand_from_finger * rest[v as usize]).norm();
    assert!(off < 0.005, "placed {:.2} mm off", off * 1e3);
    assert!(
        (loads[0].magnitude_n - 0.1).abs() < 0.05,
        "{} N of 0.1 N",
        loads[0].magnitude_n
    );
    assert!(seen.details.fingers[0].depth_rows > 0);
}

/// The free hand's markers and its depth image.
fn free_hand_seen() -> (HandKeypoints, OwnedDepthImage) {
    let hand = hand();
    let pulls = no_pulls(&hand);
    let (markers, shape) = static_hand(&hand, &pulls, &WorldFromHand::identity(), &[]).unwrap();
    let (k, mount) = camera();
    (markers, render_depth(&hand, &shape, k, mount).unwrap())
}

#[test]
fn a_free_hand_seen_in_depth_raises_no_press() {
    let (markers, depth) = free_hand_seen();
    let e = estimate(&with_depth(), &markers, Some(&depth));
    assert!(e.details.loads.is_empty(), "{:?}", e.details.loads);
    assert!(e.details.fingers.iter().all(|f| f.depth_rows > 0));
}

#[test]
fn broken_depth_images_give_a_frame_without_depth_or_a_typed_error_never_a_panic() {
    let (markers, good) = free_hand_seen();
    let (k, mount) = camera();
    let n = good.view().pixels().len();
    let config = with_depth();
    let without = estimate(&config, &markers, None);
    // All holes, in every spelling: the frame is estimated from its markers alone.
    for (name, value) in [
        ("zeros", 0.0),
        ("NaN", f32::NAN),
        ("negative", -1.0),
        ("infinite", f32::INFINITY),
    ] {
        let image = OwnedDepthImage::new(vec![value; n], k, mount).unwrap();
        let e = estimate(&config, &markers, Some(&image));
        assert!(
            e.details.fingers.iter().all(|f| f.depth_rows == 0),
            "{name}"
        );
        assert_eq!(e.details.loads, without.details.loads, "{name}");
        assert_eq!(e.shape, without.shape, "{name}");
    }
    // Garbage: the good image with a third of its pixels replaced by wild values.
    let mut rng = SeededRng::new(38);
    for trial in 0..4 {
        let mut pixels = good.view().pixels().to_vec();
        for p in pixels.iter_mut() {
            if rng.uniform() < 0.33 {
                *p = match (rng.uniform() * 5.0) as u32 {
                    0 => f32::NAN,
                    1 => 0.0,
                    2 => -*p,
                    3 => *p * 1e6,
                    _ => *p + (rng.normal() * 0.01) as f32,
                };
            }
        }
        let image = OwnedDepthImage::new(pixels, k, mount).unwrap();
        let e = estimate(&config, &markers, Some(&image));
        assert!(
            e.shape
                .fingers
                .iter()
                .flatten()
                .all(|p| p.coords.iter().all(|c| c.is_finite())),
            "trial {trial}"
        );
    }
    // A wrong size never reaches the estimator: the image is refused where it is made.
    assert!(OwnedDepthImage::new(vec![0.5; n - 1], k, mount).is_err());
}
