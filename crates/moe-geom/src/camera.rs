//! The pinhole camera: intrinsics in pixels and the projection convention every crate shares.
//!
//! The optical frame is OpenCV's (x right, y down, z forward); a point `(x, y, z)` projects to the
//! pixel `(u, v) = (fx·x/z + cx, fy·y/z + cy)`, pixel `(i, j)` having its centre at `(u, v) = (i, j)`.

use serde::{Deserialize, Serialize};

use crate::{GeomError, Point3, Real, Vector3};

/// Pinhole intrinsics in pixels (no distortion).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraIntrinsics {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: Real,
    /// Focal length along y, pixels.
    pub fy: Real,
    /// Principal point x, pixels.
    pub cx: Real,
    /// Principal point y, pixels.
    pub cy: Real,
}

impl Default for CameraIntrinsics {
    /// 640 × 480 with a 380-pixel focal length (≈ 80° horizontal field of view), like a
    /// short-range RealSense (D405-class) at that resolution: wide enough to see the markers
    /// near the finger bases from a wrist mount.
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            fx: 380.0,
            fy: 380.0,
            cx: 319.5,
            cy: 239.5,
        }
    }
}

impl CameraIntrinsics {
    /// Checks the intrinsics.
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] for a zero or huge image size or a non-positive focal
    /// length.
    pub fn validate(&self) -> Result<(), GeomError> {
        for (name, v) in [("camera width", self.width), ("camera height", self.height)] {
            if !(1..=8192).contains(&v) {
                return Err(GeomError::InvalidParameter {
                    name,
                    value: Real::from(v),
                    reason: "must be in 1..=8192 pixels",
                });
            }
        }
        for (name, v) in [("camera fx", self.fx), ("camera fy", self.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GeomError::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be positive",
                });
            }
        }
        for (name, v) in [("camera cx", self.cx), ("camera cy", self.cy)] {
            if !v.is_finite() {
                return Err(GeomError::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be finite",
                });
            }
        }
        Ok(())
    }

    /// Pixel coordinates of a point in the camera frame, `None` behind the camera.
    pub fn project(&self, p_in_camera: &Point3) -> Option<(Real, Real)> {
        (p_in_camera.z > 0.0).then(|| {
            (
                self.fx * p_in_camera.x / p_in_camera.z + self.cx,
                self.fy * p_in_camera.y / p_in_camera.z + self.cy,
            )
        })
    }
}

/// Distance along the unit ray `dir` from the origin to triangle `q`, `None` if it misses
/// (Möller–Trumbore, both faces). With the camera at the origin, a point is hidden by a
/// triangle whose distance along the point's ray is shorter than the point's.
pub fn ray_triangle(dir: &Vector3, q: &[Point3; 3]) -> Option<Real> {
    let e1 = q[1] - q[0];
    let e2 = q[2] - q[0];
    let p = dir.cross(&e2);
    let det = e1.dot(&p);
    if det.abs() < 1e-18 {
        return None;
    }
    let inv = 1.0 / det;
    let s = -q[0].coords;
    let u = s.dot(&p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = s.cross(&e1);
    let v = dir.dot(&qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(&qv) * inv;
    (t > 0.0).then_some(t)
}
