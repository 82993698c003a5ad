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

/// [`with_depth`] without the evidence of the space seen empty.
fn without_seen_through() -> PhysicsConfig {
    let mut config = with_depth();
    config.depth.seen_through_prior = 1.0;
    config
}

fn estimator(config: &PhysicsConfig) -> PhysicsEstimator {
    PhysicsEstimator::new(&hand(), &HandMaterial::default(), config).unwrap()
}

/// `est`'s estimate of the unpulled hand, held upright, with `markers`, `depth` and `time`.
fn observe(
    est: &mut PhysicsEstimator,
    markers: &HandKeypoints,
    depth: Option<&OwnedDepthImage>,
    time: Option<Real>,
) -> PhysicsEstimate {
    let pulls = no_pulls(&hand());
    let mut obs = Observation::from_keypoints(markers)
        .with_tendon_pulls(&pulls)
        .with_world_from_hand(WorldFromHand::identity());
    if let Some(d) = depth {
        obs = obs.with_depth(d.view());
    }
    if let Some(t) = time {
        obs = obs.with_time(t);
    }
    est.estimate(&obs).unwrap()
}

/// A lone frame's estimate.
fn estimate(
    config: &PhysicsConfig,
    markers: &HandKeypoints,
    depth: Option<&OwnedDepthImage>,
) -> PhysicsEstimate {
    observe(&mut estimator(config), markers, depth, None)
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
    // The image shows the fingers alone, without the object that presses: the evidence of
    // the space seen empty would rightly find nothing to press there, so the depth rows are
    // weighed here without it (it is tested where the toucher is in view, in moe-lab's
    // patting tests).
    let config = without_seen_through();
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

/// A two-frame stream of finger 0: the free hand with every marker seen, then `markers` and
/// `depth` 50 ms later; the second frame's estimate.
fn second_frame(
    config: &PhysicsConfig,
    markers: &HandKeypoints,
    depth: &OwnedDepthImage,
) -> PhysicsEstimate {
    let (free_markers, free_depth) = free_hand_seen();
    let mut est = estimator(config);
    observe(&mut est, &free_markers, Some(&free_depth), Some(0.0));
    observe(&mut est, markers, Some(depth), Some(0.05))
}

#[test]
fn an_object_in_front_of_lost_markers_places_the_press_it_hides() {
    let hand = hand();
    let pulls = no_pulls(&hand);
    let finger = &hand.fingers()[0];
    let rest = finger.model.mesh().vertices();
    let slots = finger.model.marker_vertices();
    let mut by_height: Vec<usize> = (0..slots.len()).collect();
    by_height.sort_by(|&a, &b| {
        rest[slots[a] as usize]
            .z
            .total_cmp(&rest[slots[b] as usize].z)
    });
    // A light press on the fourth marker from the base; the pressing object hides it and the
    // next one up.
    let hidden = &by_height[3..5];
    let v = slots[hidden[0]];
    let (mut markers, shape) = static_hand(
        &hand,
        &pulls,
        &WorldFromHand::identity(),
        &[press(&hand, v, 0.05)],
    )
    .unwrap();
    let (k, mount) = camera();
    let image = render_depth(&hand, &shape, k, mount).unwrap();
    // The object: 5 mm in front of each hidden marker, 30 pixels across.
    let camera_from_hand = mount.iso().inverse();
    let mut pixels = image.view().pixels().to_vec();
    for &slot in hidden {
        let p = camera_from_hand * markers.fingers[0][slot].unwrap();
        let (u, w) = k.project(&p).unwrap();
        for j in 0..k.height {
            for i in 0..k.width {
                if (Real::from(i) - u).hypot(Real::from(j) - w) < 15.0 {
                    pixels[(j * k.width + i) as usize] = (p.z - 0.005) as f32;
                }
            }
        }
        markers.fingers[0][slot] = None;
    }
    let depth = OwnedDepthImage::new(pixels, k, mount).unwrap();
    let off = |config: &PhysicsConfig| {
        let e = second_frame(config, &markers, &depth);
        let hand_from_finger = finger.hand_from_finger.iso();
        e.details
            .loads
            .iter()
            .filter(|l| l.finger == 0)
            .map(|l| (l.location_rest - hand_from_finger * rest[v as usize]).norm())
            .fold(Real::INFINITY, Real::min)
    };
    // The object is a disc painted into the image, not a body reaching the finger: the
    // covered markers are weighed here without the evidence of the space seen empty.
    let with = off(&without_seen_through());
    let mut config = without_seen_through();
    config.depth.covered_marker_prior = 0.0;
    let without = off(&config);
    // The lost markers with the object just in front of them place the press; without that
    // evidence the markers left and the depth image about the object place it a ring or two
    // off.
    assert!(with < 0.0015, "placed {:.2} mm off", with * 1e3);
    assert!(without > 0.003, "placed {:.2} mm off", without * 1e3);
}

/// The shape `free + k · (pressed − free)`, per finger and vertex.
fn blend(free: &HandShape, pressed: &HandShape, k: Real) -> HandShape {
    HandShape {
        fingers: free
            .fingers
            .iter()
            .zip(&pressed.fingers)
            .map(|(f, p)| f.iter().zip(p).map(|(a, b)| a + (b - a) * k).collect())
            .collect(),
    }
}

#[test]
fn a_release_only_the_depth_image_shows_is_reported_in_its_frame_with_the_lag_taken_out() {
    let hand = hand();
    let pulls = no_pulls(&hand);
    let (k, mount) = camera();
    let (_, free) = static_hand(&hand, &pulls, &WorldFromHand::identity(), &[]).unwrap();
    let v = seen_vertex(&free, 0.05);
    let newtons = 0.2;
    let (_, pressed) = static_hand(
        &hand,
        &pulls,
        &WorldFromHand::identity(),
        &[press(&hand, v, newtons)],
    )
    .unwrap();
    // The body follows its static response with the damping time β (first-order lag): pressed
    // from t = 0 to t = 0.05 s, released then; seen at 0, 0.05 and 0.1 s.
    let beta = HandMaterial::default().material.rayleigh_stiffness;
    let a = (-0.05 / beta).exp();
    let frames = [(0.0, 0.0), (0.05, 1.0 - a), (0.1, a * (1.0 - a))];
    let markers_of = |shape: &HandShape| base_markers_only(&hand.keypoints_on(&shape.fingers));
    // As in the press only the depth image shows, the image has no object pressing.
    let run = |gain: Real| {
        let mut config = without_seen_through();
        config.contact_lag_gain = gain;
        let mut est = estimator(&config);
        frames
            .iter()
            .map(|&(t, k_dent)| {
                let shape = blend(&free, &pressed, k_dent);
                let depth = render_depth(&hand, &shape, k, mount).unwrap();
                let e = observe(&mut est, &markers_of(&shape), Some(&depth), Some(t));
                e.details
                    .loads
                    .iter()
                    .filter(|l| l.finger == 0)
                    .map(|l| l.magnitude_n)
                    .sum::<Real>()
            })
            .collect::<Vec<_>>()
    };
    let taken_out = run(1.0);
    let as_seen = run(0.0);
    // With the lag taken out of the markers and the depth patches, the press is weighed at its
    // static force at the onset and released in the release's frame.
    assert_eq!(taken_out[0], 0.0, "{taken_out:?}");
    assert!(
        (taken_out[1] - newtons).abs() < 0.2 * newtons,
        "{taken_out:?}"
    );
    assert_eq!(taken_out[2], 0.0, "released: {taken_out:?}");
    // As seen, the dent that lingers is read as a press a frame after the release, and the
    // onset as a fraction of the force.
    assert!(as_seen[2] > 0.0, "{as_seen:?}");
    assert!(as_seen[1] < 0.6 * newtons, "{as_seen:?}");
}
