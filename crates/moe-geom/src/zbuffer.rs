//! Z-buffer rasterisation through the pinhole camera: for every pixel, the nearest surface
//! along its ray, which item and face it belongs to, and where. The virtual camera renders its
//! frames with it; a runtime predicts which pixel sees which finger with it.
//!
//! Pixel `(i, j)` is covered by a triangle when its centre `(u, v) = (i, j)` lies inside the
//! triangle's projection; depth is interpolated perspective-correctly (1/z is affine in the
//! image). Triangles are clipped at a near plane 1 mm in front of the camera.

use crate::{CameraIntrinsics, GeomError, Point3, Real, Vector3};

/// The nearest surface seen through one pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZHit {
    /// Its depth (z in the camera frame), metres.
    pub z: Real,
    /// The item it belongs to (as drawn).
    pub item: u32,
    /// Its face within the item (as drawn).
    pub face: u32,
    /// Cosine between the viewing ray and the face's normal (absolute value).
    pub cos_view: Real,
    /// The surface point, camera frame.
    pub point: Point3,
}

/// A z-buffer the size of a camera's image.
#[derive(Debug, Clone)]
pub struct ZBuffer {
    intrinsics: CameraIntrinsics,
    hits: Vec<Option<ZHit>>,
}

impl ZBuffer {
    /// An empty buffer for `intrinsics`.
    ///
    /// # Errors
    /// Invalid intrinsics ([`CameraIntrinsics::validate`]).
    pub fn new(intrinsics: CameraIntrinsics) -> Result<Self, GeomError> {
        intrinsics.validate()?;
        let n = intrinsics.width as usize * intrinsics.height as usize;
        Ok(Self {
            intrinsics,
            hits: vec![None; n],
        })
    }

    /// The camera.
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// Every pixel's nearest surface, row-major.
    pub fn hits(&self) -> &[Option<ZHit>] {
        &self.hits
    }

    /// The nearest surface at pixel `(i, j)` (column, row); `None` outside the image or where
    /// nothing was drawn.
    pub fn hit(&self, i: u32, j: u32) -> Option<&ZHit> {
        if i >= self.intrinsics.width || j >= self.intrinsics.height {
            return None;
        }
        self.hits[j as usize * self.intrinsics.width as usize + i as usize].as_ref()
    }

    /// Draws triangle `q` (camera frame) of item `item`, face `face`: clipped at the near plane,
    /// each pixel whose centre it covers keeps the nearest surface. A triangle with a NaN or
    /// infinite corner is not drawn.
    pub fn draw(&mut self, q: &[Point3; 3], item: u32, face: u32) {
        const NEAR: Real = 1e-3;
        // A triangle with a non-finite corner covers nothing (and would not clip).
        if !q.iter().all(|p| p.coords.iter().all(|c| c.is_finite())) {
            return;
        }
        let normal = (q[1] - q[0]).cross(&(q[2] - q[0]));
        let len = normal.norm();
        if len <= 0.0 {
            return;
        }
        let normal = normal / len;
        // Sutherland–Hodgman against z >= NEAR.
        let mut poly: Vec<Point3> = Vec::with_capacity(4);
        for k in 0..3 {
            let (a, b) = (q[k], q[(k + 1) % 3]);
            if a.z >= NEAR {
                poly.push(a);
            }
            if (a.z >= NEAR) != (b.z >= NEAR) {
                let t = (NEAR - a.z) / (b.z - a.z);
                poly.push(a + (b - a) * t);
            }
        }
        for k in 1..poly.len().saturating_sub(1) {
            self.draw_clipped(&[poly[0], poly[k], poly[k + 1]], &normal, item, face);
        }
    }

    fn draw_clipped(&mut self, q: &[Point3; 3], normal: &Vector3, item: u32, face: u32) {
        let cam = self.intrinsics;
        let uv = q.map(|p| cam.project(&p).expect("clipped to z >= near"));
        let edge = |a: (Real, Real), b: (Real, Real), p: (Real, Real)| {
            (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)
        };
        let area = edge(uv[0], uv[1], uv[2]);
        if area.abs() < 1e-12 {
            return;
        }
        let (w, h) = (cam.width as Real, cam.height as Real);
        let min_u = uv
            .iter()
            .map(|p| p.0)
            .fold(Real::INFINITY, Real::min)
            .ceil()
            .max(0.0);
        let max_u = uv
            .iter()
            .map(|p| p.0)
            .fold(Real::NEG_INFINITY, Real::max)
            .floor()
            .min(w - 1.0);
        let min_v = uv
            .iter()
            .map(|p| p.1)
            .fold(Real::INFINITY, Real::min)
            .ceil()
            .max(0.0);
        let max_v = uv
            .iter()
            .map(|p| p.1)
            .fold(Real::NEG_INFINITY, Real::max)
            .floor()
            .min(h - 1.0);
        if min_u > max_u || min_v > max_v {
            return;
        }
        let inv_z = q.map(|p| 1.0 / p.z);
        for j in min_v as usize..=max_v as usize {
            for i in min_u as usize..=max_u as usize {
                let p = (i as Real, j as Real);
                let l0 = edge(uv[1], uv[2], p) / area;
                let l1 = edge(uv[2], uv[0], p) / area;
                let l2 = 1.0 - l0 - l1;
                if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
                    continue;
                }
                // Perspective-correct interpolation: 1/z is affine in screen space.
                let iz = l0 * inv_z[0] + l1 * inv_z[1] + l2 * inv_z[2];
                let z = 1.0 / iz;
                let slot = &mut self.hits[j * cam.width as usize + i];
                if slot.is_some_and(|hit| hit.z <= z) {
                    continue;
                }
                let point = Point3::from(
                    (q[0].coords * (l0 * inv_z[0])
                        + q[1].coords * (l1 * inv_z[1])
                        + q[2].coords * (l2 * inv_z[2]))
                        * z,
                );
                let cos_view = normal.dot(&point.coords.normalize()).abs();
                *slot = Some(ZHit {
                    z,
                    item,
                    face,
                    cos_view,
                    point,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 64,
            height: 48,
            fx: 40.0,
            fy: 40.0,
            cx: 31.5,
            cy: 23.5,
        }
    }

    /// A triangle in the plane z = `z` that covers the image centre.
    fn facing(z: Real) -> [Point3; 3] {
        [
            Point3::new(-0.5 * z, -0.5 * z, z),
            Point3::new(0.5 * z, -0.5 * z, z),
            Point3::new(0.0, 0.5 * z, z),
        ]
    }

    /// A plane facing the camera is seen at its depth with its item and face; the nearer of two
    /// surfaces wins whatever the order they are drawn in; what lies behind the camera, or
    /// outside the triangle, is not drawn.
    #[test]
    fn the_nearest_surface_wins_each_pixel() {
        for order in [[0, 1], [1, 0]] {
            let mut z = ZBuffer::new(camera()).unwrap();
            let triangles = [(facing(0.08), 7u32, 3u32), (facing(0.05), 2, 9)];
            for k in order {
                let (q, item, face) = triangles[k];
                z.draw(&q, item, face);
            }
            let hit = z.hit(32, 24).unwrap();
            assert_eq!((hit.item, hit.face), (2, 9), "order {order:?}");
            assert!((hit.z - 0.05).abs() < 1e-15, "{}", hit.z);
            assert!((hit.cos_view - hit.point.coords.normalize().z).abs() < 1e-12);
        }
        let mut z = ZBuffer::new(camera()).unwrap();
        let behind = facing(-0.05);
        z.draw(&behind, 0, 0);
        assert!(z.hits().iter().all(Option::is_none));
        z.draw(&facing(0.05), 0, 0);
        assert!(z.hit(0, 0).is_none() && z.hit(64, 0).is_none());
        let drawn = z.hits().iter().filter(|h| h.is_some()).count();
        // Base and height of z at range z: 40 pixels each at fx = fy = 40, so 800 pixels.
        assert!((760..840).contains(&drawn), "{drawn} pixels");
    }
}
