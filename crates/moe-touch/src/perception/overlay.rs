//! Pictures of a detection: the colour image with the markers found and their ids drawn on it.

use image::{Rgb, RgbImage};
use moe_geom::{HandFromCamera, HandKeypoints, Point3, Real};
use moe_tendon_sim::camera::CameraIntrinsics;

use super::{ClusterFate, MarkerDetection, MarkerDetector};
use crate::TouchError;

/// Colour of a found marker's ring and label.
const FOUND: Rgb<u8> = Rgb([40, 255, 60]);
/// Colour of a rejected cluster's cross.
const REJECTED: Rgb<u8> = Rgb([255, 220, 0]);
/// Colour of a contact point.
const CONTACT: Rgb<u8> = Rgb([255, 30, 200]);

/// 3 × 5 pixel glyphs of `0`–`9` and `.`, one row per entry, bit 2 on the left.
const GLYPHS: [[u8; 5]; 11] = [
    [0b111, 0b101, 0b101, 0b101, 0b111],
    [0b010, 0b110, 0b010, 0b010, 0b111],
    [0b111, 0b001, 0b111, 0b100, 0b111],
    [0b111, 0b001, 0b111, 0b001, 0b111],
    [0b101, 0b101, 0b111, 0b001, 0b001],
    [0b111, 0b100, 0b111, 0b001, 0b111],
    [0b111, 0b100, 0b111, 0b101, 0b111],
    [0b111, 0b001, 0b010, 0b010, 0b010],
    [0b111, 0b101, 0b111, 0b101, 0b111],
    [0b111, 0b101, 0b111, 0b001, 0b111],
    [0b000, 0b000, 0b000, 0b000, 0b010],
];

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
    for (f, markers) in keypoints.fingers.iter().enumerate() {
        for (m, p) in markers.iter().enumerate() {
            let Some(p) = p else { continue };
            let Some((u, v)) = k.project(&camera_from_hand.transform_point(p)) else {
                continue;
            };
            ring(&mut img, u, v, 7.0, FOUND);
            text(&mut img, u + 9.0, v - 5.0, &format!("{f}.{m}"), FOUND);
        }
    }
    Ok(img)
}

fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && x < i64::from(img.width()) && y < i64::from(img.height()) {
        img.put_pixel(x as u32, y as u32, c);
    }
}

fn ring(img: &mut RgbImage, u: Real, v: Real, r: Real, c: Rgb<u8>) {
    let steps = (2.0 * std::f64::consts::PI * r * 2.0).ceil() as usize;
    for s in 0..steps {
        let a = s as Real / steps as Real * std::f64::consts::TAU;
        for dr in [0.0, 1.0] {
            put(
                img,
                (u + (r + dr) * a.cos()).round() as i64,
                (v + (r + dr) * a.sin()).round() as i64,
                c,
            );
        }
    }
}

fn cross(img: &mut RgbImage, u: Real, v: Real, half: i64, c: Rgb<u8>) {
    let (x, y) = (u.round() as i64, v.round() as i64);
    for d in -half..=half {
        put(img, x + d, y + d, c);
        put(img, x + d, y - d, c);
    }
}

/// Digits and dots at 2× scale, top-left corner at `(u, v)`.
fn text(img: &mut RgbImage, u: Real, v: Real, s: &str, c: Rgb<u8>) {
    let (x0, y0) = (u.round() as i64, v.round() as i64);
    for (n, ch) in s.chars().enumerate() {
        let glyph = match ch {
            '0'..='9' => GLYPHS[ch as usize - '0' as usize],
            '.' => GLYPHS[10],
            _ => continue,
        };
        let gx = x0 + 8 * n as i64;
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..3 {
                if bits & (0b100 >> col) != 0 {
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        put(img, gx + 2 * col + dx, y0 + 2 * row as i64 + dy, c);
                    }
                }
            }
        }
    }
}
