//! The wrist camera's depth image as an observation: the pixels, borrowed, with the camera that
//! took them (intrinsics and where it is mounted on the hand).
//!
//! A pixel holds the depth along the optical axis in metres. Cameras mark a missing depth as 0
//! (RealSense, ROS 2) or NaN; both, and any other value that is not a finite positive number,
//! are holes: [`DepthImage::depth`] gives `None` there, so a frame of holes is a frame without
//! depth, never an error. Only an image whose size does not fit the camera is refused.
//!
//! [`associate_depth`](crate::depth::associate_depth) tells which pixels see which finger,
//! predicted from an estimated shape (a z-buffer of its meshes, not colour), and gives each a
//! point-to-plane residual; [`pool_pixels`](crate::depth::pool_pixels) pools a surface's pixels
//! into observations of patches of it, with their variance under the camera's noise
//! ([`DepthNoise`](crate::depth::DepthNoise)); [`render_hand`](crate::depth::render_hand) draws
//! a hand's noise-free depth image.

use serde::{Deserialize, Serialize};

mod associate;
mod pool;

pub use associate::{AssociationOptions, DepthPoint, FingerDepth, associate_depth};
pub use pool::{
    DepthNoise, PooledPatch, SurfacePatches, SurfacePixel, barycentric, check_depth_settings,
    pool_pixels, surface_pixels,
};

use crate::camera::CameraIntrinsics;
use crate::error::GeomError;
use crate::math::{Point3, Real};
use crate::transform::HandFromCamera;

/// The depth image, without noise and with holes where nothing is seen, that a camera with
/// `intrinsics` at `hand_from_camera` takes of the fingers of `hand` with surfaces `shape`
/// (hand frame) and of `occluders` (triangles, hand frame): what tests and examples give an
/// estimator that reads depth.
///
/// # Errors
/// Invalid intrinsics, or a shape that does not fit the hand.
pub fn render_hand(
    hand: &crate::hand::HandModel,
    shape: &crate::instant::HandShape,
    occluders: &[[Point3; 3]],
    intrinsics: CameraIntrinsics,
    hand_from_camera: HandFromCamera,
) -> Result<OwnedDepthImage, GeomError> {
    shape.check_against(hand)?;
    let mut zbuffer = crate::zbuffer::ZBuffer::new(intrinsics)?;
    let camera_from_hand = hand_from_camera.inverse();
    let fingers = hand.fingers().iter().zip(&shape.fingers);
    for (f, (hf, surface)) in fingers.enumerate() {
        let in_camera = camera_from_hand.transform_points(surface);
        for (k, face) in hf.model.mesh().faces().iter().enumerate() {
            zbuffer.draw(&face.map(|i| in_camera[i as usize]), f as u32, k as u32);
        }
    }
    let item = shape.fingers.len() as u32;
    for (k, t) in occluders.iter().enumerate() {
        let q = t.map(|p| camera_from_hand.transform_point(&p));
        zbuffer.draw(&q, item, k as u32);
    }
    let depth = zbuffer
        .hits()
        .iter()
        .map(|h| h.map_or(0.0, |h| h.z as f32))
        .collect();
    OwnedDepthImage::new(depth, intrinsics, hand_from_camera)
}

/// A depth image with its camera, borrowed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthImage<'a> {
    depth_m: &'a [f32],
    intrinsics: CameraIntrinsics,
    hand_from_camera: HandFromCamera,
}

impl<'a> DepthImage<'a> {
    /// `depth_m` (row-major, metres along the optical axis) seen by a camera with `intrinsics`
    /// mounted at `hand_from_camera`.
    ///
    /// # Errors
    /// Invalid intrinsics, or [`GeomError::LengthMismatch`] when the image does not have
    /// `width × height` pixels.
    pub fn new(
        depth_m: &'a [f32],
        intrinsics: CameraIntrinsics,
        hand_from_camera: HandFromCamera,
    ) -> Result<Self, GeomError> {
        intrinsics.validate()?;
        let expected = intrinsics.width as usize * intrinsics.height as usize;
        if depth_m.len() != expected {
            return Err(GeomError::LengthMismatch {
                what: "depth image pixels (camera width × height)",
                expected,
                got: depth_m.len(),
            });
        }
        Ok(Self {
            depth_m,
            intrinsics,
            hand_from_camera,
        })
    }

    /// The pixels, row-major.
    pub fn pixels(&self) -> &'a [f32] {
        self.depth_m
    }

    /// The camera's intrinsics.
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// Where the camera is on the hand.
    pub fn hand_from_camera(&self) -> &HandFromCamera {
        &self.hand_from_camera
    }

    /// The depth at pixel `(i, j)` (column, row), metres; `None` for a hole or outside the
    /// image.
    pub fn depth(&self, i: u32, j: u32) -> Option<Real> {
        if i >= self.intrinsics.width || j >= self.intrinsics.height {
            return None;
        }
        // `get`: an owned image read from a file reaches here unchecked ([`OwnedDepthImage::check`]).
        let d = *self
            .depth_m
            .get(j as usize * self.intrinsics.width as usize + i as usize)?;
        (d.is_finite() && d > 0.0).then_some(Real::from(d))
    }

    /// The point pixel `(i, j)` sees, camera frame; `None` for a hole.
    pub fn point_in_camera(&self, i: u32, j: u32) -> Option<Point3> {
        let z = self.depth(i, j)?;
        let k = &self.intrinsics;
        Some(Point3::new(
            (Real::from(i) - k.cx) * z / k.fx,
            (Real::from(j) - k.cy) * z / k.fy,
            z,
        ))
    }

    /// Pixels that hold a depth.
    pub fn valid_pixels(&self) -> usize {
        self.depth_m
            .iter()
            .filter(|d| d.is_finite() && **d > 0.0)
            .count()
    }

    /// The same image, owned.
    pub fn to_owned_image(&self) -> OwnedDepthImage {
        OwnedDepthImage {
            depth_m: self.depth_m.to_vec(),
            intrinsics: self.intrinsics,
            hand_from_camera: self.hand_from_camera,
        }
    }
}

/// A depth image with its camera, owned (to store it or send it to another thread).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OwnedDepthImage {
    depth_m: Vec<f32>,
    intrinsics: CameraIntrinsics,
    hand_from_camera: HandFromCamera,
}

impl OwnedDepthImage {
    /// As [`DepthImage::new`], owning the pixels.
    ///
    /// # Errors
    /// As [`DepthImage::new`].
    pub fn new(
        depth_m: Vec<f32>,
        intrinsics: CameraIntrinsics,
        hand_from_camera: HandFromCamera,
    ) -> Result<Self, GeomError> {
        DepthImage::new(&depth_m, intrinsics, hand_from_camera)?;
        Ok(Self {
            depth_m,
            intrinsics,
            hand_from_camera,
        })
    }

    /// The image, borrowed. Checked when it was made (or read: see [`OwnedDepthImage::check`]).
    pub fn view(&self) -> DepthImage<'_> {
        DepthImage {
            depth_m: &self.depth_m,
            intrinsics: self.intrinsics,
            hand_from_camera: self.hand_from_camera,
        }
    }

    /// Checks an image read from a file, whose size nothing has checked yet.
    ///
    /// # Errors
    /// As [`DepthImage::new`].
    pub fn check(&self) -> Result<(), GeomError> {
        DepthImage::new(&self.depth_m, self.intrinsics, self.hand_from_camera).map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Iso3;

    fn camera() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 4,
            height: 3,
            fx: 100.0,
            fy: 100.0,
            cx: 1.5,
            cy: 1.0,
        }
    }

    /// Holes of every kind read as no depth; the rest back-project through the pinhole.
    #[test]
    fn holes_are_missing_depth_and_pixels_back_project() {
        let mut pixels = vec![0.05f32; 12];
        pixels[0] = 0.0;
        pixels[1] = f32::NAN;
        pixels[2] = -0.01;
        pixels[3] = f32::INFINITY;
        let mount = HandFromCamera::new(Iso3::translation(0.0, 0.0, -0.02));
        let image = DepthImage::new(&pixels, camera(), mount).unwrap();
        assert_eq!(image.valid_pixels(), 8);
        for i in 0..4 {
            assert_eq!(image.depth(i, 0), None, "pixel {i}");
        }
        assert_eq!(image.depth(4, 0), None, "outside the image");
        let p = image.point_in_camera(3, 2).unwrap();
        let z = Real::from(0.05f32);
        assert_eq!(p, Point3::new(1.5 * z / 100.0, z / 100.0, z));
        let k = image.intrinsics();
        let (u, v) = k.project(&p).unwrap();
        assert!((u - 3.0).abs() < 1e-12 && (v - 2.0).abs() < 1e-12);
        // A frame of holes is a frame without depth, not an error.
        let empty = vec![f32::NAN; 12];
        assert_eq!(
            DepthImage::new(&empty, camera(), mount)
                .unwrap()
                .valid_pixels(),
            0
        );
        // Owned and back, and through serde.
        let owned = image.to_owned_image();
        let bits = |d: &[f32]| d.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(owned.view().pixels()), bits(image.pixels()));
        assert_eq!(owned.view().hand_from_camera(), image.hand_from_camera());
        let clean = OwnedDepthImage::new(vec![0.05; 12], camera(), mount).unwrap();
        let back: OwnedDepthImage =
            serde_json::from_str(&serde_json::to_string(&clean).unwrap()).unwrap();
        assert_eq!(back, clean);
    }

    /// An image of another size than the camera's, or a camera that cannot be, is refused.
    #[test]
    fn a_wrong_size_or_camera_is_an_error() {
        let mount = HandFromCamera::new(Iso3::identity());
        for n in [0, 11, 13] {
            let pixels = vec![0.05f32; n];
            crate::assert_err!(
                DepthImage::new(&pixels, camera(), mount),
                GeomError::LengthMismatch { expected: 12, .. }
            );
        }
        let bad = CameraIntrinsics {
            fx: Real::NAN,
            ..camera()
        };
        assert!(DepthImage::new(&[0.05; 12], bad, mount).is_err());
        let read = OwnedDepthImage {
            depth_m: vec![0.05; 5],
            intrinsics: camera(),
            hand_from_camera: mount,
        };
        assert!(read.check().is_err());
        // Unchecked, it still answers without a panic: the missing pixels are holes.
        assert_eq!(read.view().depth(3, 2), None);
        assert_eq!(read.view().depth(0, 0), Some(Real::from(0.05f32)));
    }
}
