//! Pictures of a detection: the colour image with the markers found and their ids drawn on it.

use image::{Rgb, RgbImage};
use moe_geom::CameraIntrinsics;
use moe_geom::{HandFromCamera, HandKeypoints, Point3, Real};

use crate::draw::{cross, line, place_labels, put, ring, text, text_size};
use moe_touch::TouchError;
use moe_touch::perception::{ClusterFate, MarkerDetection, MarkerDetector};

/// Colour of a found marker's ring and label.
const FOUND: Rgb<u8> = Rgb([40, 255, 60]);
/// Colour of a rejected cluster's cross.
const REJECTED: Rgb<u8> = Rgb([255, 220, 0]);
/// Colour of a contact point.
const CONTACT: Rgb<u8> = Rgb([255, 30, 200]);
/// Colour of the line from a marker to a label placed away from it.
const LEADER: Rgb<u8> = Rgb([20, 150, 40]);
/// Radius of a found marker's ring, pixels.
const RING_PX: Real = 7.0;

/// The colour image (`color_rgb8`, the detector's size) with every found marker ringed and
/// labelled `finger.marker`, and every rejected cluster crossed.
///
/// # Errors
/// [`TouchError::ImageSize`] when the image does not have the detector's size.
pub fn draw_detection(
    detector: &MarkerDetector,
    color_rgb8: &[u8],
    detection: &MarkerDetection,
) -> Result<RgbImage, TouchError> {
    let mut img = draw_keypoints(
        detector.intrinsics(),
        detector.hand_from_camera(),
        color_rgb8,
        &detection.keypoints,
        &[],
    )?;
    for c in &detection.diagnostics.clusters {
        if !matches!(c.fate, ClusterFate::Assigned { .. })
            && c.centre_px.iter().all(|x| x.is_finite())
        {
            cross(&mut img, c.centre_px[0], c.centre_px[1], 4, REJECTED);
        }
    }
    Ok(img)
}

/// The colour image of a camera with `intrinsics` at `hand_from_camera`, with the markers
/// `keypoints` (hand frame) ringed and labelled and the contact points `contacts_in_hand`
/// dotted in red.
///
/// # Errors
/// [`TouchError::ImageSize`] when the image does not have the intrinsics' size.
pub fn draw_keypoints(
    intrinsics: &CameraIntrinsics,
    hand_from_camera: HandFromCamera,
    color_rgb8: &[u8],
    keypoints: &HandKeypoints,
    contacts_in_hand: &[Point3],
) -> Result<RgbImage, TouchError> {
    let k = intrinsics;
    let expected = 3 * k.width as usize * k.height as usize;
    let mut img = RgbImage::from_raw(k.width, k.height, color_rgb8.to_vec()).ok_or(
        TouchError::ImageSize {
            what: "colour image bytes",
            expected,
            got: color_rgb8.len(),
        },
    )?;
    let camera_from_hand = hand_from_camera.inverse();
    for p in contacts_in_hand {
        if let Some((u, v)) = k.project(&camera_from_hand.transform_point(p)) {
            let (x, y) = (u.round() as i64, v.round() as i64);
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (-1, 0), (0, -1)] {
                put(&mut img, x + dx, y + dy, CONTACT);
            }
        }
    }
    let mut anchors = Vec::new();
    let mut labels = Vec::new();
    for (f, markers) in keypoints.fingers.iter().enumerate() {
        for (m, p) in markers.iter().enumerate() {
            let Some(p) = p else { continue };
            let Some((u, v)) = k.project(&camera_from_hand.transform_point(p)) else {
                continue;
            };
            anchors.push((u, v));
            labels.push(format!("{f}.{m}"));
        }
    }
    // Labels where they overlap neither each other nor a marker, joined to their marker by a
    // thin line when pushed away from it.
    let sizes: Vec<(i64, i64)> = labels.iter().map(|l| text_size(l)).collect();
    let corners = place_labels(
        &anchors,
        &sizes,
        RING_PX,
        i64::from(k.width),
        i64::from(k.height),
    );
    for (((u, v), label), ((x0, y0), (w, h))) in
        anchors.iter().zip(&labels).zip(corners.iter().zip(&sizes))
    {
        ring(&mut img, *u, *v, RING_PX, FOUND);
        let centre = ((x0 + w / 2) as Real, (y0 + h / 2) as Real);
        let d = (centre.0 - u).hypot(centre.1 - v);
        if d > RING_PX + 12.0 + (w.max(h) / 2) as Real {
            let s = (RING_PX + 1.0) / d;
            line(
                &mut img,
                (u + s * (centre.0 - u), v + s * (centre.1 - v)),
                centre,
                1,
                LEADER,
            );
        }
        text(&mut img, *x0 as Real, *y0 as Real, label, FOUND);
    }
    Ok(img)
}
