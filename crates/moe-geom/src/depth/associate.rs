//! Which depth pixels see which finger, predicted from an estimated shape.
//!
//! The estimated finger meshes are drawn through the camera into a [`ZBuffer`]: a pixel whose
//! nearest predicted surface is finger `f` is a candidate observation of `f`, never chosen by
//! colour. It is kept when it lies on the sampling grid, away from the predicted silhouettes
//! (a band of pixels around every place where the nearest surface changes finger or ends: depth
//! there mixes finger and background, the flying pixels of stereo cameras), holds a depth, and
//! its depth lies within a gate of the predicted one (a pixel that sees something in front of
//! the finger, such as the object that presses it, or a wild value, is counted apart). Each
//! kept pixel gives a point-to-plane residual: the measured point's distance from the plane of
//! the predicted face, along the face's outward normal.

use crate::depth::DepthImage;
use crate::error::GeomError;
use crate::hand::HandModel;
use crate::instant::HandShape;
use crate::math::{Point3, Real, Vector3};
use crate::zbuffer::ZBuffer;

/// How pixels are sampled and gated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AssociationOptions {
    /// Sample every `stride_px`-th pixel in both directions (1: every pixel). Default 4.
    pub stride_px: u32,
    /// Pixels this close to a predicted silhouette are left out. Default 2.
    pub edge_band_px: u32,
    /// Largest depth by which a pixel may see the finger behind its predicted surface, metres.
    /// Default 3 mm.
    pub gate_m: Real,
    /// Largest depth by which a pixel may see the finger in front of its predicted surface,
    /// metres: an object touching the finger lies in front of it, within millimetres, about the
    /// contact. Default 3 mm.
    pub front_gate_m: Real,
}

impl Default for AssociationOptions {
    fn default() -> Self {
        Self {
            stride_px: 4,
            edge_band_px: 2,
            gate_m: 0.003,
            front_gate_m: 0.003,
        }
    }
}

impl AssociationOptions {
    /// Checks every option.
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] for a zero stride or a gate that is not positive, named
    /// as in a `[depth]` settings table (`depth.stride_px`, `depth.gate_m`,
    /// `depth.front_gate_m`).
    pub fn validate(&self) -> Result<(), GeomError> {
        if self.stride_px == 0 {
            return Err(GeomError::InvalidParameter {
                name: "depth.stride_px",
                value: 0.0,
                reason: "must be at least 1",
            });
        }
        for (name, v) in [
            ("depth.gate_m", self.gate_m),
            ("depth.front_gate_m", self.front_gate_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GeomError::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be finite and positive",
                });
            }
        }
        Ok(())
    }
}

/// One depth pixel associated with a finger's predicted surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthPoint {
    /// The pixel (column, row).
    pub pixel: [u32; 2],
    /// The face of the finger's mesh the pixel's ray meets first.
    pub face: u32,
    /// The measured point, hand frame.
    pub measured_in_hand: Point3,
    /// Where the ray meets the predicted surface, hand frame.
    pub predicted_in_hand: Point3,
    /// The face's outward unit normal, hand frame.
    pub normal_in_hand: Vector3,
    /// The measured point's signed distance from the face's plane, along the normal, metres
    /// (positive outside the predicted surface).
    pub residual_m: Real,
}

/// What one finger's pixels gave.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FingerDepth {
    /// The pixels kept.
    pub points: Vec<DepthPoint>,
    /// Sampled pixels whose nearest predicted surface is this finger.
    pub predicted: usize,
    /// Of those, left out near a silhouette.
    pub edge: usize,
    /// Left out for holding no depth.
    pub holes: usize,
    /// Left out for a depth outside the gates (something in front of the finger, or far off).
    pub gated: usize,
}

/// The depth pixels of `depth` that see each finger of `hand` as `shape` predicts it (finger
/// vertices in the hand frame).
///
/// # Errors
/// [`GeomError::LengthMismatch`] when `shape` has another number of fingers than `hand`,
/// [`GeomError::FingerLengthMismatch`] when a finger has another number of vertices,
/// [`GeomError::NonFiniteFingerPoint`] for a vertex with a NaN or infinite coordinate, or
/// [`GeomError::InvalidParameter`] for a zero stride or a gate that is not positive.
pub fn associate_depth(
    hand: &HandModel,
    shape: &HandShape,
    depth: &DepthImage<'_>,
    options: &AssociationOptions,
) -> Result<Vec<FingerDepth>, GeomError> {
    check(hand, shape, options)?;
    let camera_from_hand = depth.hand_from_camera().inverse();
    let mut zbuffer = ZBuffer::new(*depth.intrinsics())?;
    let mut normals: Vec<Vec<Vector3>> = Vec::with_capacity(shape.fingers.len());
    for (f, vertices) in shape.fingers.iter().enumerate() {
        let faces = hand.fingers()[f].model.mesh().faces();
        let in_camera = camera_from_hand.transform_points(vertices);
        let mut finger_normals = Vec::with_capacity(faces.len());
        for (k, face) in faces.iter().enumerate() {
            let [a, b, c] = face.map(|i| vertices[i as usize]);
            finger_normals.push(
                (b - a)
                    .cross(&(c - a))
                    .try_normalize(0.0)
                    .unwrap_or_default(),
            );
            zbuffer.draw(&face.map(|i| in_camera[i as usize]), f as u32, k as u32);
        }
        normals.push(finger_normals);
    }
    let hand_from_camera = depth.hand_from_camera();
    let k = depth.intrinsics();
    let mut out = vec![FingerDepth::default(); shape.fingers.len()];
    let band = options.edge_band_px;
    for j in (0..k.height).step_by(options.stride_px as usize) {
        for i in (0..k.width).step_by(options.stride_px as usize) {
            let Some(hit) = zbuffer.hit(i, j) else {
                continue;
            };
            let finger = &mut out[hit.item as usize];
            finger.predicted += 1;
            if near_silhouette(&zbuffer, i, j, band, hit.item) {
                finger.edge += 1;
                continue;
            }
            let Some(measured) = depth.point_in_camera(i, j) else {
                finger.holes += 1;
                continue;
            };
            let ahead = hit.z - measured.z;
            if ahead > options.front_gate_m || -ahead > options.gate_m {
                finger.gated += 1;
                continue;
            }
            let normal = normals[hit.item as usize][hit.face as usize];
            let measured_in_hand = hand_from_camera.transform_point(&measured);
            let predicted_in_hand = hand_from_camera.transform_point(&hit.point);
            finger.points.push(DepthPoint {
                pixel: [i, j],
                face: hit.face,
                measured_in_hand,
                predicted_in_hand,
                normal_in_hand: normal,
                residual_m: normal.dot(&(measured_in_hand - predicted_in_hand)),
            });
        }
    }
    Ok(out)
}

/// Whether a pixel within `band` of `(i, j)` (on the square's border, and inside the image)
/// sees nothing or another item than `item`.
fn near_silhouette(zbuffer: &ZBuffer, i: u32, j: u32, band: u32, item: u32) -> bool {
    if band == 0 {
        return false;
    }
    let k = zbuffer.intrinsics();
    let (w, h) = (i64::from(k.width), i64::from(k.height));
    let (i, j, b) = (i64::from(i), i64::from(j), i64::from(band));
    for dj in -b..=b {
        for di in -b..=b {
            if dj.abs() != b && di.abs() != b {
                continue;
            }
            let (x, y) = (i + di, j + dj);
            if !(0..w).contains(&x) || !(0..h).contains(&y) {
                continue;
            }
            // In range by the check above.
            let other = zbuffer.hit(x as u32, y as u32);
            if other.is_none_or(|o| o.item != item) {
                return true;
            }
        }
    }
    false
}

fn check(
    hand: &HandModel,
    shape: &HandShape,
    options: &AssociationOptions,
) -> Result<(), GeomError> {
    if shape.fingers.len() != hand.num_fingers() {
        return Err(GeomError::LengthMismatch {
            what: "fingers of the shape (fingers of the hand)",
            expected: hand.num_fingers(),
            got: shape.fingers.len(),
        });
    }
    for (f, (vertices, hf)) in shape.fingers.iter().zip(hand.fingers()).enumerate() {
        let expected = hf.model.mesh().num_vertices();
        if vertices.len() != expected {
            return Err(GeomError::FingerLengthMismatch {
                what: "shape vertices",
                finger: f,
                expected,
                got: vertices.len(),
            });
        }
        if let Some(index) = vertices
            .iter()
            .position(|p| !p.coords.iter().all(|c| c.is_finite()))
        {
            return Err(GeomError::NonFiniteFingerPoint {
                what: "shape vertex",
                finger: f,
                index,
            });
        }
    }
    options.validate()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::FingerParams;
    use crate::camera::CameraIntrinsics;
    use crate::hand::HandPreset;
    use crate::math::Iso3;
    use crate::transform::HandFromCamera;

    fn hand() -> HandModel {
        HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap()
    }

    fn mount() -> HandFromCamera {
        HandFromCamera::new(Iso3::translation(0.0, 0.0, -0.02))
    }

    /// An exact depth image of `shape` (and of `extra` triangles, hand frame, in front of it).
    fn render(hand: &HandModel, shape: &HandShape, extra: &[[Point3; 3]]) -> Vec<f32> {
        crate::depth::render_hand(hand, shape, extra, CameraIntrinsics::default(), mount())
            .unwrap()
            .view()
            .pixels()
            .to_vec()
    }

    /// The depth image of the predicted shape itself: every kept pixel lies on its face's
    /// plane (to the image's f32 rounding), both fingers get hundreds of pixels, and the
    /// silhouettes' bands are left out.
    #[test]
    fn the_predicted_shape_explains_its_own_depth_image() {
        let hand = hand();
        let shape = HandShape::rest(&hand);
        let pixels = render(&hand, &shape, &[]);
        let image = DepthImage::new(&pixels, CameraIntrinsics::default(), mount()).unwrap();
        let out = associate_depth(&hand, &shape, &image, &AssociationOptions::default()).unwrap();
        for (f, d) in out.iter().enumerate() {
            assert!(
                d.points.len() > 200,
                "finger {f}: {} points",
                d.points.len()
            );
            assert!(
                d.edge > 0 && d.holes == 0 && d.gated == 0,
                "finger {f}: {d:?}"
            );
            assert_eq!(d.points.len() + d.edge, d.predicted);
            for p in &d.points {
                assert!(p.residual_m.abs() < 1e-7, "finger {f}: {p:?}");
                assert!((p.normal_in_hand.norm() - 1.0).abs() < 1e-12);
            }
        }
    }

    /// A finger moved by `d` is seen, pixel by pixel, at about the distance n·d from its
    /// predicted faces' planes.
    #[test]
    fn a_moved_finger_gives_the_normal_component_of_its_move() {
        let hand = hand();
        let predicted = HandShape::rest(&hand);
        let d = Vector3::new(0.0005, -0.0003, 0.0);
        let mut moved = predicted.clone();
        moved.fingers[0].iter_mut().for_each(|p| *p += d);
        let pixels = render(&hand, &moved, &[]);
        let image = DepthImage::new(&pixels, CameraIntrinsics::default(), mount()).unwrap();
        let out =
            associate_depth(&hand, &predicted, &image, &AssociationOptions::default()).unwrap();
        let points = &out[0].points;
        let mut errs: Vec<Real> = points
            .iter()
            .map(|p| (p.residual_m - p.normal_in_hand.dot(&d)).abs())
            .collect();
        errs.sort_by(Real::total_cmp);
        let q = |x: Real| errs[((errs.len() - 1) as Real * x) as usize];
        // Exact where the ray meets the moved copy of its own face; elsewhere off by the
        // surface's curvature between the two faces (most at grazing views).
        assert!(points.len() > 1000, "{} pixels", points.len());
        assert!(
            q(0.5) < 0.05 * d.norm() && q(0.9) < 0.25 * d.norm(),
            "errors from n·d: median {} m, 90th percentile {} m",
            q(0.5),
            q(0.9)
        );
        // The other finger did not move.
        assert!(out[1].points.iter().all(|p| p.residual_m.abs() < 1e-7));
    }

    /// An object in front of a finger is not the finger: its pixels are gated out, and what is
    /// kept still lies on the finger. A frame of holes gives no points and no error.
    #[test]
    fn an_occluder_is_gated_and_holes_are_counted() {
        let hand = hand();
        let shape = HandShape::rest(&hand);
        let opts = AssociationOptions::default();
        // A plate facing the camera 2 cm in front of the palm, between the camera and finger 0
        // (on the +x side) but clear of the finger's body.
        let corner = |x: Real, y: Real| Point3::new(x, y, 0.02);
        let plate = [
            [
                corner(-0.002, -0.03),
                corner(0.012, -0.03),
                corner(0.012, 0.03),
            ],
            [
                corner(-0.002, -0.03),
                corner(0.012, 0.03),
                corner(-0.002, 0.03),
            ],
        ];
        let pixels = render(&hand, &shape, &plate);
        let image = DepthImage::new(&pixels, CameraIntrinsics::default(), mount()).unwrap();
        let out = associate_depth(&hand, &shape, &image, &opts).unwrap();
        assert!(out[0].gated > 100, "{:?}", out[0].gated);
        assert_eq!(out[1].gated, 0, "finger 1 is not behind the plate");
        assert!(out[0].points.iter().all(|p| p.residual_m.abs() < 1e-7));
        // The gates are one-sided: with a front gate wider than the plate's distance the
        // plate's pixels are kept (as the finger's), with a wide back gate they still are not.
        let wide = |front_gate_m, gate_m| {
            let o = AssociationOptions {
                front_gate_m,
                gate_m,
                ..opts
            };
            associate_depth(&hand, &shape, &image, &o).unwrap()[0].gated
        };
        assert_eq!(wide(1.0, opts.gate_m), 0);
        assert_eq!(wide(opts.front_gate_m, 1.0), out[0].gated);
        let holes = vec![f32::NAN; pixels.len()];
        let image = DepthImage::new(&holes, CameraIntrinsics::default(), mount()).unwrap();
        for d in associate_depth(&hand, &shape, &image, &opts).unwrap() {
            assert!(d.points.is_empty() && d.holes > 100, "{d:?}");
        }
    }

    /// A shape that does not fit the hand, a non-finite vertex, or bad options are refused.
    #[test]
    fn bad_shapes_and_options_are_refused() {
        let hand = hand();
        let shape = HandShape::rest(&hand);
        let pixels = vec![0.05f32; 640 * 480];
        let image = DepthImage::new(&pixels, CameraIntrinsics::default(), mount()).unwrap();
        let opts = AssociationOptions::default();
        let one = HandShape {
            fingers: vec![shape.fingers[0].clone()],
        };
        crate::assert_err!(
            associate_depth(&hand, &one, &image, &opts),
            GeomError::LengthMismatch { .. }
        );
        let mut nan = shape.clone();
        nan.fingers[1][5].x = Real::NAN;
        crate::assert_err!(
            associate_depth(&hand, &nan, &image, &opts),
            GeomError::NonFiniteFingerPoint {
                finger: 1,
                index: 5,
                ..
            }
        );
        for bad in [
            AssociationOptions {
                stride_px: 0,
                ..opts
            },
            AssociationOptions {
                gate_m: Real::NAN,
                ..opts
            },
        ] {
            crate::assert_err!(
                associate_depth(&hand, &shape, &image, &bad),
                GeomError::InvalidParameter { .. }
            );
        }
    }
}
