//! Tests of the RGB-D camera: depth of planes, noise, grazing surfaces, markers and what hides them.

use super::*;
use moe_geom::{FingerParams, HandModel, HandPreset, Vector3};

/// A square of side `size` centred on the camera axis at depth `z` in the camera frame,
/// expressed in the hand frame for `camera`.
fn plane_facing(
    camera: &RgbdCamera,
    z: Real,
    size: Real,
    tilt_rad: Real,
) -> (Vec<Point3>, Vec<[u32; 3]>) {
    let rot = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), tilt_rad);
    let s = 0.5 * size;
    let v = [(-s, -s), (s, -s), (s, s), (-s, s)].map(|(x, y)| {
        camera
            .hand_from_camera
            .transform_point(&(Point3::new(0.0, 0.0, z) + rot * Vector3::new(x, y, 0.0)))
    });
    (v.to_vec(), vec![[0, 1, 2], [0, 2, 3]])
}

/// The default camera with an ideal (noise-free) sensor.
fn ideal_camera() -> RgbdCamera {
    RgbdCamera {
        noise: NoiseModel::ideal(),
        ..RgbdCamera::default()
    }
}

fn item<'a>(v: &'a [Point3], f: &'a [[u32; 3]], markers: &'a [Point3]) -> RenderItem<'a> {
    RenderItem {
        vertices_in_hand: v,
        faces: f,
        albedo: [200, 200, 200],
        markers_in_hand: markers,
        marker_radius_m: 0.003,
    }
}

#[test]
fn ideal_depth_of_a_fronto_parallel_plane_is_exact() {
    let camera = ideal_camera();
    let (v, f) = plane_facing(&camera, 0.5, 2.0, 0.0);
    let img = camera.render(&[item(&v, &f, &[])], 1).unwrap();
    assert!(
        img.depth_m
            .iter()
            .all(|&d| (Real::from(d) - 0.5).abs() < 1e-6)
    );
}

#[test]
fn tilted_plane_depth_matches_ray_plane_intersection() {
    let camera = ideal_camera();
    let tilt = 0.4;
    let (v, f) = plane_facing(&camera, 0.4, 2.0, tilt);
    let img = camera.render(&[item(&v, &f, &[])], 1).unwrap();
    let n = Vector3::new(tilt.sin(), 0.0, tilt.cos()); // plane normal in the camera frame
    let k = &camera.intrinsics;
    for (i, j) in [(10, 10), (320, 240), (600, 50), (200, 470)] {
        let ray = Vector3::new(
            (Real::from(i) - k.cx) / k.fx,
            (Real::from(j) - k.cy) / k.fy,
            1.0,
        );
        let t = 0.4 * n.z / n.dot(&ray); // point on the plane: (0, 0, 0.4)
        let expected = t * ray.z;
        let got = Real::from(img.depth(i, j));
        assert!(
            (got - expected).abs() < 1e-5 * expected,
            "pixel ({i},{j}): {got} vs {expected}"
        );
    }
}

#[test]
fn noisy_depth_stays_within_the_noise_model() {
    let camera = RgbdCamera::default();
    let z = 0.5;
    let (v, f) = plane_facing(&camera, z, 2.0, 0.0);
    let img = camera.render(&[item(&v, &f, &[])], 7).unwrap();
    let sigma = camera.noise.depth_std(z);
    let n = img.depth_m.len() as Real;
    let mean = img.depth_m.iter().map(|&d| Real::from(d)).sum::<Real>() / n;
    let var = img
        .depth_m
        .iter()
        .map(|&d| (Real::from(d) - mean).powi(2))
        .sum::<Real>()
        / n;
    assert!(
        img.depth_m
            .iter()
            .all(|&d| (Real::from(d) - z).abs() < 6.0 * sigma)
    );
    assert!((mean - z).abs() < 0.05 * sigma, "mean {mean}");
    assert!(
        (var.sqrt() / sigma - 1.0).abs() < 0.02,
        "std {} vs {sigma}",
        var.sqrt()
    );
    // Same seed, same bytes; another seed, another image.
    assert_eq!(img, camera.render(&[item(&v, &f, &[])], 7).unwrap());
    assert_ne!(img, camera.render(&[item(&v, &f, &[])], 8).unwrap());
}

/// The harsher depth: whole millimetres, twice the white noise, and an error shared by
/// neighbouring pixels (nearby pixels' errors correlate, far ones' do not); the defaults write
/// no new field.
#[test]
fn harsher_depth_is_quantised_and_correlated_between_neighbours() {
    let camera = RgbdCamera {
        noise: NoiseModel::ideal().harsher(),
        ..RgbdCamera::default()
    };
    assert_eq!(
        camera.noise.depth_std_base_m, 0.0,
        "no white noise in this one"
    );
    let z = 0.05;
    let (v, f) = plane_facing(&camera, z, 0.2, 0.0);
    let img = camera.render(&[item(&v, &f, &[])], 3).unwrap();
    for &d in &img.depth_m {
        let mm = Real::from(d) * 1e3;
        assert!(
            (mm - mm.round()).abs() < 1e-3,
            "{d} is not whole millimetres"
        );
    }
    // Without quantisation, the shared error alone: its spread and its correlation.
    let shared = RgbdCamera {
        noise: NoiseModel {
            depth_quantum_m: 0.0,
            ..camera.noise
        },
        ..camera
    };
    let img = shared.render(&[item(&v, &f, &[])], 3).unwrap();
    let e = |i: u32, j: u32| Real::from(img.depth(i, j)) - z;
    let pairs = |di: u32| -> (Real, Real, Real) {
        let (mut xy, mut xx, mut yy) = (0.0, 0.0, 0.0);
        for j in (0..480).step_by(7) {
            for i in (0..600).step_by(7) {
                let (a, b) = (e(i, j), e(i + di, j));
                xy += a * b;
                xx += a * a;
                yy += b * b;
            }
        }
        (xy / (xx * yy).sqrt(), xx, yy)
    };
    let (near, xx, _) = pairs(1);
    let (far, _, _) = pairs(40);
    let n = (0..480).step_by(7).count() * (0..600).step_by(7).count();
    let sd = (xx / n as Real).sqrt();
    assert!(near > 0.9, "neighbours correlate: {near}");
    assert!(far.abs() < 0.2, "pixels 40 apart hardly do: {far}");
    assert!(sd > 0.5 * 2e-4 && sd < 1.5 * 2e-4, "spread {sd}");
    // The defaults write no new field (scene files written before them stay the same).
    let toml = toml::to_string(&RgbdCamera::default().noise).unwrap();
    assert!(
        !toml.contains("correlat") && !toml.contains("quantum"),
        "{toml}"
    );
}

#[test]
fn grazing_surfaces_and_out_of_range_have_no_depth() {
    let camera = RgbdCamera::default();
    // Tilted 87° about y: along the centre column the rays meet the plane at 87° or more
    // from its normal; toward the left edge the angle opens up to well below the cut-off.
    let (v, f) = plane_facing(&camera, 0.5, 8.0, 87f64.to_radians());
    let img = camera.render(&[item(&v, &f, &[])], 3).unwrap();
    let centre = camera.intrinsics.cx.round() as u32;
    let mut centre_hits = 0;
    for j in 0..img.height {
        if img.rgb(centre, j) != BACKGROUND {
            centre_hits += 1;
            assert_eq!(
                img.depth(centre, j),
                0.0,
                "grazing pixel ({centre},{j}) has depth"
            );
        }
    }
    assert!(
        centre_hits > 0,
        "the plane is visible along the centre column"
    );
    let right = camera.intrinsics.width - 1;
    assert!(
        img.depth(right, camera.intrinsics.cy as u32) > 0.0,
        "oblique but not grazing"
    );
    let (v, f) = plane_facing(&camera, 5.0, 40.0, 0.0);
    let img = camera.render(&[item(&v, &f, &[])], 3).unwrap();
    assert!(img.depth_m.iter().all(|&d| d == 0.0), "beyond max depth");
}

fn is_marker_red(c: [u8; 3]) -> bool {
    c[0] > 50 && u16::from(c[0]) > 2 * u16::from(c[1]) && u16::from(c[0]) > 2 * u16::from(c[2])
}

/// Centroid of the red pixels within `radius_px` of `(u, v)`.
fn red_centroid(img: &RgbdImage, u: Real, v: Real, radius_px: Real) -> Option<(Real, Real, usize)> {
    let (mut su, mut sv, mut n) = (0.0, 0.0, 0usize);
    for j in 0..img.height {
        for i in 0..img.width {
            let (du, dv) = (Real::from(i) - u, Real::from(j) - v);
            let c = img.rgb(i, j);
            if du * du + dv * dv <= radius_px * radius_px && is_marker_red(c) {
                su += Real::from(i);
                sv += Real::from(j);
                n += 1;
            }
        }
    }
    (n > 0).then(|| (su / n as Real, sv / n as Real, n))
}

/// Vertices in the hand frame, faces and marker centres of one finger.
type FingerData = (Vec<Point3>, Vec<[u32; 3]>, Vec<Point3>);

fn hand_items(hand: &HandModel) -> Vec<FingerData> {
    (0..hand.num_fingers())
        .map(|i| {
            let f = &hand.fingers()[i];
            let markers = f
                .hand_from_finger
                .transform_points(&f.model.marker_positions());
            (
                hand.rest_vertices_in_hand(i),
                f.model.mesh().faces().to_vec(),
                markers,
            )
        })
        .collect()
}

#[test]
fn a_marker_seen_head_on_is_centred_on_its_projection() {
    let camera = ideal_camera();
    let (v, f) = plane_facing(&camera, 0.3, 1.0, 0.0);
    // Off-centre markers, in the hand frame, on the plane.
    let markers: Vec<Point3> = [(0.02, -0.01), (-0.05, 0.04)]
        .iter()
        .map(|&(x, y)| {
            camera
                .hand_from_camera
                .transform_point(&Point3::new(x, y, 0.3))
        })
        .collect();
    let img = camera.render(&[item(&v, &f, &markers)], 0).unwrap();
    let camera_from_hand = camera.hand_from_camera.inverse();
    for m in &markers {
        let p = camera_from_hand.transform_point(m);
        let (u, v) = camera.intrinsics.project(&p).unwrap();
        let r_px = 0.003 * camera.intrinsics.fx / p.z;
        let (cu, cv, n) = red_centroid(&img, u, v, 1.5 * r_px).unwrap();
        let area = std::f64::consts::PI * r_px * r_px;
        assert!(
            (n as Real / area - 1.0).abs() < 0.1,
            "{n} pixels for a disc of {area:.0}"
        );
        assert!(
            (cu - u).abs() < 0.3 && (cv - v).abs() < 0.3,
            "({cu},{cv}) vs ({u},{v})"
        );
    }
}

#[test]
fn visible_markers_project_to_their_ground_truth_positions() {
    // The wrist camera sees the fingers' inner sides obliquely, so the visible part of a
    // marker patch is foreshortened and partly behind the finger's curvature: its pixel
    // centroid lies within a fraction of the marker's projected radius of the projected
    // centre, and the centre pixel itself is red.
    let camera = ideal_camera();
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let data = hand_items(&hand);
    let camera_from_hand = camera.hand_from_camera.inverse();
    let mut checked = 0;
    for (f, (_, _, markers)) in data.iter().enumerate() {
        for m in markers {
            // Paint this marker alone: neighbouring markers can overlap it in the image.
            let items: Vec<RenderItem<'_>> = data
                .iter()
                .enumerate()
                .map(|(g, (v, fc, _))| {
                    item(v, fc, if g == f { std::slice::from_ref(m) } else { &[] })
                })
                .collect();
            let img = camera.render(&items, 0).unwrap();
            let p = camera_from_hand.transform_point(m);
            let (u, v) = camera.intrinsics.project(&p).unwrap();
            assert!(
                is_marker_red(img.rgb(u.round() as u32, v.round() as u32)),
                "centre of marker at ({u:.1},{v:.1}) is not red"
            );
            let r_px = 0.003 * camera.intrinsics.fx / p.z;
            let (cu, cv, n) = red_centroid(&img, u, v, Real::INFINITY).expect("marker visible");
            assert!(n >= 20, "marker at ({u:.1},{v:.1}) covers {n} pixels");
            let err = ((cu - u).powi(2) + (cv - v).powi(2)).sqrt();
            assert!(
                err < 0.5 * r_px,
                "marker at ({u:.1},{v:.1}) seen at ({cu:.1},{cv:.1}), radius {r_px:.1} px"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 14, "all markers of both fingers face the camera");
}

#[test]
fn an_object_in_front_of_a_marker_hides_it() {
    let camera = ideal_camera();
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let data = hand_items(&hand);
    let camera_from_hand = camera.hand_from_camera.inverse();
    // A small plate on the ray to the third marker of finger 0, halfway to it, wide enough to
    // cover the whole marker patch.
    let m = camera_from_hand.transform_point(&data[0].2[2]);
    let mid = Point3::from(m.coords * 0.5);
    let s = 0.004;
    let plate: Vec<Point3> = [(-s, -s), (s, -s), (s, s), (-s, s)]
        .iter()
        .map(|&(x, y)| {
            camera
                .hand_from_camera
                .transform_point(&(mid + Vector3::new(x, y, 0.0)))
        })
        .collect();
    let plate_faces = vec![[0, 1, 2], [0, 2, 3]];
    let mut items: Vec<RenderItem<'_>> = data.iter().map(|(v, f, mk)| item(v, f, mk)).collect();
    let (u, v) = camera.intrinsics.project(&m).unwrap();
    let before = camera.render(&items, 0).unwrap();
    assert!(
        red_centroid(&before, u, v, 3.0).is_some(),
        "visible without the plate"
    );
    items.push(item(&plate, &plate_faces, &[]));
    let img = camera.render(&items, 0).unwrap();
    assert!(
        red_centroid(&img, u, v, 3.0).is_none(),
        "hidden marker must not be red"
    );
    // The same marker of the other finger stays visible.
    let m2 = camera_from_hand.transform_point(&data[1].2[2]);
    let (u2, v2) = camera.intrinsics.project(&m2).unwrap();
    assert!(red_centroid(&img, u2, v2, 3.0).is_some());
}

#[test]
fn visibility_is_the_line_of_sight() {
    let camera = RgbdCamera::default();
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
    let data = hand_items(&hand);
    let items: Vec<RenderItem<'_>> = data.iter().map(|(v, f, mk)| item(v, f, mk)).collect();
    let markers: Vec<Point3> = data.iter().flat_map(|d| d.2.clone()).collect();
    // Every marker faces the camera (see the test above) ...
    let seen = camera.visible(&items, &markers, 2e-4).unwrap();
    assert!(seen.iter().all(|&s| s), "{seen:?}");
    // ... and the same points moved through to the far side of their finger are hidden by
    // it; a point behind the camera or outside the image is not seen at all.
    let far: Vec<Point3> = hand
        .fingers()
        .iter()
        .flat_map(|f| {
            f.model.marker_positions().into_iter().map(|p| {
                f.hand_from_finger
                    .transform_point(&Point3::new(-p.x, -p.y, p.z))
            })
        })
        .collect();
    let seen = camera.visible(&items, &far, 2e-4).unwrap();
    assert!(seen.iter().all(|&s| !s), "{seen:?}");
    let outside = [Point3::new(0.0, 0.0, -0.1), Point3::new(1.0, 0.0, 0.05)];
    assert_eq!(
        camera.visible(&[], &outside, 0.0).unwrap(),
        vec![false, false]
    );
    assert_eq!(
        camera
            .visible(&[], &[Point3::new(0.0, 0.0, 0.05)], 0.0)
            .unwrap(),
        vec![true]
    );
}

#[test]
fn bad_intrinsics_are_rejected() {
    let camera = RgbdCamera {
        intrinsics: CameraIntrinsics {
            fx: 0.0,
            ..CameraIntrinsics::default()
        },
        ..RgbdCamera::default()
    };
    assert!(matches!(
        camera.render(&[], 0),
        Err(GeomError::InvalidParameter {
            name: "camera fx",
            ..
        })
    ));
}

/// A noise-free D405-class camera with only the given stereo and flying-pixel settings.
fn stereo_camera(baseline_m: Real, flying: Real) -> RgbdCamera {
    RgbdCamera {
        noise: NoiseModel {
            stereo_baseline_m: baseline_m,
            flying_pixel_fraction: flying,
            ..NoiseModel::ideal()
        },
        ..RgbdCamera::d405_wrist()
    }
}

/// The depth along the image's centre row.
fn centre_row(img: &RgbdImage) -> Vec<f32> {
    let j = img.height / 2;
    (0..img.width).map(|i| img.depth(i, j)).collect()
}

#[test]
fn the_second_imager_leaves_the_band_and_the_occlusion_shadow_a_stereo_camera_leaves() {
    // A wall 10 cm away filling the view, and a 1 cm wide strip 6 cm away on the axis.
    let (z_wall, z_strip) = (0.10, 0.06);
    let camera = stereo_camera(D405_BASELINE_M, 0.0);
    let (wall, wf) = plane_facing(&camera, z_wall, 1.0, 0.0);
    let strip: Vec<Point3> = [(-0.005, -0.5), (0.005, -0.5), (0.005, 0.5), (-0.005, 0.5)]
        .iter()
        .map(|&(x, y)| {
            camera
                .hand_from_camera
                .transform_point(&Point3::new(x, y, z_strip))
        })
        .collect();
    let sf = vec![[0, 1, 2], [0, 2, 3]];
    let items = [item(&wall, &wf, &[]), item(&strip, &sf, &[])];
    let fx = camera.intrinsics.fx;
    let disparity = |z: Real| fx * D405_BASELINE_M / z;

    let row = centre_row(&camera.render(&items, 3).unwrap());
    // The band: the columns whose wall point falls left of the second image.
    let band = row.iter().take_while(|&&d| d == 0.0).count() as Real;
    assert!(
        (band - disparity(z_wall)).abs() <= 1.0,
        "band {band} px, disparity {:.1} px",
        disparity(z_wall)
    );
    // The shadow: wall columns beside the strip that only the first imager sees; its width is
    // the difference of the two surfaces' disparities.
    let strip_start = row
        .iter()
        .position(|&d| (Real::from(d) - z_strip).abs() < 1e-4)
        .unwrap();
    let shadow = row[..strip_start]
        .iter()
        .rev()
        .take_while(|&&d| d == 0.0)
        .count() as Real;
    let expected = disparity(z_strip) - disparity(z_wall);
    assert!(
        (shadow - expected).abs() <= 1.5,
        "shadow {shadow} px, expected {expected:.1} px"
    );
    // To the right of the strip the wall is seen by both imagers.
    let after = row
        .iter()
        .rposition(|&d| (Real::from(d) - z_strip).abs() < 1e-4)
        .unwrap();
    assert!((Real::from(row[after + 1]) - z_wall).abs() < 1e-4);

    // Without a second imager: neither band nor shadow.
    let plain = centre_row(&stereo_camera(0.0, 0.0).render(&items, 3).unwrap());
    assert!(plain.iter().all(|&d| d > 0.0));
}

#[test]
fn flying_pixels_lie_between_the_surfaces_of_a_depth_step_and_only_there() {
    let (z_wall, z_strip) = (0.10, 0.06);
    let render = |flying: Real| {
        let camera = stereo_camera(0.0, flying);
        let (wall, wf) = plane_facing(&camera, z_wall, 1.0, 0.0);
        let (strip, sf) = plane_facing(&camera, z_strip, 0.01, 0.0);
        camera
            .render(&[item(&wall, &wf, &[]), item(&strip, &sf, &[])], 5)
            .unwrap()
    };
    let clean = render(0.0);
    let flying = render(1.0);
    let on = |d: f32, z: Real| (Real::from(d) - z).abs() < 1e-6;
    let mut between = 0;
    for (k, (&c, &f)) in clean.depth_m.iter().zip(&flying.depth_m).enumerate() {
        assert!(on(c, z_wall) || on(c, z_strip), "pixel {k}: {c}");
        if c != f {
            // Only pixels with a neighbour across the step move, and only between the two.
            let (i, j) = (k as u32 % clean.width, k as u32 / clean.width);
            let neighbours = [
                i.checked_sub(1).map(|a| (a, j)),
                (i + 1 < clean.width).then_some((i + 1, j)),
                j.checked_sub(1).map(|b| (i, b)),
                (j + 1 < clean.height).then_some((i, j + 1)),
            ];
            assert!(
                neighbours
                    .iter()
                    .flatten()
                    .any(|&(a, b)| clean.depth(a, b) != c),
                "pixel ({i},{j}) moved away from the step"
            );
            let f = Real::from(f);
            assert!(f > z_strip && f < z_wall, "pixel ({i},{j}): {f}");
            between += 1;
        }
    }
    // Every pixel on either side of the strip's outline: 2 × 4 sides × about its 37 px.
    assert!(between > 200, "{between} flying pixels");
}

#[test]
fn the_d405_camera_file_is_the_preset_and_its_noise_is_documented() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/cameras/d405-wrist.toml"
    ))
    .unwrap();
    let camera: RgbdCamera = toml::from_str(&text).unwrap();
    assert_eq!(camera, RgbdCamera::d405_wrist());
    camera.validate().unwrap();
    // σ(z) = z² · s / (f · B): 0.12 mm at 5 cm, 0.50 mm at 10 cm.
    assert!((camera.noise.depth_std(0.05) - 1.2434e-4).abs() < 1e-8);
    assert!((camera.noise.depth_std(0.10) - 4.9736e-4).abs() < 1e-8);
}

#[test]
fn a_camera_with_a_bad_stereo_setting_is_named() {
    for (noise, name) in [
        (
            NoiseModel {
                stereo_baseline_m: -0.01,
                ..NoiseModel::default()
            },
            "stereo_baseline_m",
        ),
        (
            NoiseModel {
                flying_pixel_fraction: 1.5,
                ..NoiseModel::default()
            },
            "flying_pixel_fraction",
        ),
        (
            NoiseModel {
                flying_pixel_step_m: Real::NAN,
                ..NoiseModel::default()
            },
            "flying_pixel_step_m",
        ),
    ] {
        let camera = RgbdCamera {
            noise,
            ..RgbdCamera::default()
        };
        let err = camera.validate().unwrap_err().to_string();
        assert!(err.contains(name), "{err}");
        assert!(camera.render(&[], 0).is_err());
    }
    // A mount whose rotation is not a unit quaternion would scale the scene.
    let mut camera = RgbdCamera::d405_wrist();
    let mut iso = *camera.hand_from_camera.iso();
    iso.rotation = nalgebra::Unit::new_unchecked(iso.rotation.into_inner() * 2.0);
    camera.hand_from_camera = Transform::new(iso);
    let err = camera.validate().unwrap_err().to_string();
    assert!(err.contains("hand_from_camera.rotation"), "{err}");
}
