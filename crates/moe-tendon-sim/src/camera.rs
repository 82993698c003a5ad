//! A virtual wrist RGB-D camera: renders colour and depth of the hand, its red markers and the
//! obstacles by z-buffer rasterisation, then applies a documented sensor noise model.
//!
//! Geometry: the camera's optical frame is OpenCV's (x right, y down, z forward); a point
//! `(x, y, z)` projects to the pixel `(u, v) = (fx·x/z + cx, fy·y/z + cy)`, pixel `(i, j)` having its
//! centre at `(u, v) = (i, j)`. Depth is the z coordinate in the camera frame (as RealSense and
//! OpenCV report it), not the ray length. Occlusion — of markers by objects or by other fingers —
//! comes from the z-buffer alone: nothing is hidden or shown by rule.
//!
//! Markers are painted, not modelled: a surface point within `marker_radius_m` of one of its
//! item's marker centres is red. The red region is therefore the patch of the real surface around
//! the marker vertex, and it deforms and hides exactly as the surface does.
//!
//! Noise model ([`NoiseModel`](crate::camera::NoiseModel), defaults chosen to resemble a short-range stereo RGB-D camera such
//! as the RealSense D405):
//! - depth: `z + N(0, σ(z)²)` with `σ(z) = depth_std_base_m + depth_std_per_m2 · z²` (structured-light
//!   and stereo depth error grows with the square of the distance);
//! - missing depth (reported as 0): outside `[min_depth_m, max_depth_m]`, and where the surface is
//!   seen at more than `grazing_dropout_deg` from its normal (stereo matching fails at grazing
//!   angles);
//! - colour: every channel `+ N(0, color_std²)` in 8-bit levels, clamped to `[0, 255]`.
//!
//! The noise is drawn from a [`SeededRng`](moe_geom::SeededRng) in pixel order, so a seed fixes the image bit for bit.

use moe_geom::rng::SeededRng;
use moe_geom::transform::{Transform, frame};
use moe_geom::{GeomError, Iso3, Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

pub use moe_geom::CameraIntrinsics;

/// Sensor noise; see the module documentation for the model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NoiseModel {
    /// Depth noise standard deviation at zero range, metres. Default 0.0005.
    pub depth_std_base_m: Real,
    /// Growth of the depth standard deviation with squared range, 1/metre. Default 0.0025
    /// (σ = 1.1 mm at 0.5 m).
    pub depth_std_per_m2: Real,
    /// Surfaces seen more obliquely than this (angle between the ray and the normal) have no
    /// depth. Default 85°.
    pub grazing_dropout_deg: Real,
    /// Nearest valid depth, metres. Default 0.01.
    pub min_depth_m: Real,
    /// Farthest valid depth, metres. Default 3.0.
    pub max_depth_m: Real,
    /// Colour noise standard deviation, 8-bit levels. Default 2.0.
    pub color_std: Real,
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self {
            depth_std_base_m: 0.0005,
            depth_std_per_m2: 0.0025,
            grazing_dropout_deg: 85.0,
            min_depth_m: 0.01,
            max_depth_m: 3.0,
            color_std: 2.0,
        }
    }
}

impl NoiseModel {
    /// An ideal sensor: exact depth everywhere in range, no dropout, exact colour.
    pub fn ideal() -> Self {
        Self {
            depth_std_base_m: 0.0,
            depth_std_per_m2: 0.0,
            grazing_dropout_deg: 90.0,
            min_depth_m: 0.0,
            max_depth_m: Real::INFINITY,
            color_std: 0.0,
        }
    }

    /// Depth standard deviation at range `z`.
    pub fn depth_std(&self, z: Real) -> Real {
        self.depth_std_base_m + self.depth_std_per_m2 * z * z
    }

    fn validate(&self) -> Result<(), GeomError> {
        let checks = [
            (
                "depth_std_base_m",
                self.depth_std_base_m,
                self.depth_std_base_m >= 0.0,
            ),
            (
                "depth_std_per_m2",
                self.depth_std_per_m2,
                self.depth_std_per_m2 >= 0.0,
            ),
            ("color_std", self.color_std, self.color_std >= 0.0),
            (
                "grazing_dropout_deg",
                self.grazing_dropout_deg,
                (0.0..=90.0).contains(&self.grazing_dropout_deg),
            ),
            ("min_depth_m", self.min_depth_m, self.min_depth_m >= 0.0),
            (
                "max_depth_m",
                self.max_depth_m,
                self.max_depth_m > self.min_depth_m,
            ),
        ];
        for (name, value, ok) in checks {
            if !ok || value.is_nan() {
                return Err(GeomError::InvalidParameter {
                    name,
                    value,
                    reason: "out of range",
                });
            }
        }
        Ok(())
    }
}

/// Something to render, with its geometry already in the hand frame.
#[derive(Debug, Clone, Copy)]
pub struct RenderItem<'a> {
    /// Vertex positions in the hand frame.
    pub vertices_in_hand: &'a [Point3],
    /// Triangles.
    pub faces: &'a [[u32; 3]],
    /// Surface colour (RGB).
    pub albedo: [u8; 3],
    /// Centres of painted red markers on this surface, hand frame (empty for obstacles).
    pub markers_in_hand: &'a [Point3],
    /// Radius of the painted markers, metres.
    pub marker_radius_m: Real,
}

impl RenderItem<'_> {
    /// The item's triangles in the camera frame.
    ///
    /// # Errors
    /// [`GeomError::FaceIndexOutOfRange`] for a face that indexes past the vertices.
    fn triangles_in(
        &self,
        camera_from_hand: &Transform<frame::Camera, frame::Hand>,
    ) -> Result<Vec<[Point3; 3]>, GeomError> {
        let verts: Vec<Point3> = camera_from_hand.transform_points(self.vertices_in_hand);
        self.faces
            .iter()
            .enumerate()
            .map(|(face, tri)| {
                let mut q = [Point3::origin(); 3];
                for (k, &v) in tri.iter().enumerate() {
                    q[k] = *verts
                        .get(v as usize)
                        .ok_or(GeomError::FaceIndexOutOfRange {
                            face,
                            index: v,
                            len: verts.len(),
                        })?;
                }
                Ok(q)
            })
            .collect()
    }
}

/// Colour of painted markers.
pub const MARKER_RED: [u8; 3] = [220, 25, 25];
/// Colour of the silicone fingers in recorded episodes.
pub const FINGER_ALBEDO: [u8; 3] = [215, 210, 200];
/// Colour of obstacles in recorded episodes.
pub const OBSTACLE_ALBEDO: [u8; 3] = [90, 120, 170];
/// Colour where nothing is hit.
pub const BACKGROUND: [u8; 3] = [30, 30, 30];

/// A rendered frame: row-major, `width × height` pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGB8, three bytes per pixel.
    pub color: Vec<u8>,
    /// Depth in metres along the optical axis; 0 where there is none.
    pub depth_m: Vec<f32>,
}

impl RgbdImage {
    /// Colour of pixel `(i, j)` (column, row).
    pub fn rgb(&self, i: u32, j: u32) -> [u8; 3] {
        let k = 3 * (j as usize * self.width as usize + i as usize);
        [self.color[k], self.color[k + 1], self.color[k + 2]]
    }

    /// Depth of pixel `(i, j)` (column, row), 0 when missing.
    pub fn depth(&self, i: u32, j: u32) -> f32 {
        self.depth_m[j as usize * self.width as usize + i as usize]
    }
}

/// The wrist camera: intrinsics, where it is mounted on the hand, and its noise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RgbdCamera {
    /// Pinhole intrinsics.
    pub intrinsics: CameraIntrinsics,
    /// Mounting pose: camera frame to hand frame.
    pub hand_from_camera: Transform<frame::Hand, frame::Camera>,
    /// Sensor noise.
    pub noise: NoiseModel,
}

impl Default for RgbdCamera {
    /// Mounted on the wrist 2 cm behind the palm centre, looking along the fingers (camera z =
    /// hand z, camera x = hand x, camera y = hand y), with the default intrinsics and noise.
    fn default() -> Self {
        Self {
            intrinsics: CameraIntrinsics::default(),
            hand_from_camera: Transform::new(Iso3::translation(0.0, 0.0, -0.02)),
            noise: NoiseModel::default(),
        }
    }
}

/// Per-pixel result of the visibility pass.
#[derive(Clone, Copy)]
struct Hit {
    z: Real,
    item: u32,
    /// Cosine between the viewing ray and the face normal (absolute value).
    cos_view: Real,
    /// The surface point in the camera frame.
    point: Point3,
}

impl RgbdCamera {
    /// Renders the items and applies the noise model with `seed`.
    ///
    /// # Errors
    /// Invalid intrinsics or noise parameters, or a face index out of range in an item.
    pub fn render(&self, items: &[RenderItem<'_>], seed: u64) -> Result<RgbdImage, GeomError> {
        self.intrinsics.validate()?;
        self.noise.validate()?;
        let (w, h) = (
            self.intrinsics.width as usize,
            self.intrinsics.height as usize,
        );
        let mut hits: Vec<Option<Hit>> = vec![None; w * h];
        let camera_from_hand = self.hand_from_camera.inverse();
        let mut markers_in_camera: Vec<Vec<Point3>> = Vec::with_capacity(items.len());
        for (index, item) in items.iter().enumerate() {
            for q in item.triangles_in(&camera_from_hand)? {
                self.raster_triangle(&q, index as u32, &mut hits);
            }
            markers_in_camera.push(camera_from_hand.transform_points(item.markers_in_hand));
        }
        Ok(self.shade(items, &markers_in_camera, &hits, seed))
    }

    /// Which of `points_in_hand` the camera sees: a point is visible when it projects inside
    /// the image in front of the camera and no surface of `items` crosses the line of sight to
    /// it short of `tolerance_m` before the point (the point's own surface does not hide it).
    /// Exact ray casting against every triangle, independent of the pixel grid and the noise:
    /// this is the ground truth that marker detection is scored against.
    ///
    /// # Errors
    /// Invalid intrinsics, or a face index out of range in an item.
    pub fn visible(
        &self,
        items: &[RenderItem<'_>],
        points_in_hand: &[Point3],
        tolerance_m: Real,
    ) -> Result<Vec<bool>, GeomError> {
        self.intrinsics.validate()?;
        let camera_from_hand = self.hand_from_camera.inverse();
        let targets: Vec<Point3> = camera_from_hand.transform_points(points_in_hand);
        let k = &self.intrinsics;
        let (w, h) = (Real::from(k.width), Real::from(k.height));
        let mut visible: Vec<bool> = targets
            .iter()
            .map(|p| {
                k.project(p).is_some_and(|(u, v)| {
                    (-0.5..w - 0.5).contains(&u) && (-0.5..h - 0.5).contains(&v)
                })
            })
            .collect();
        for item in items {
            for q in item.triangles_in(&camera_from_hand)? {
                for (seen, p) in visible.iter_mut().zip(&targets) {
                    if *seen {
                        let len = p.coords.norm();
                        if let Some(t) = ray_triangle(&(p.coords / len), &q)
                            && t < len - tolerance_m
                        {
                            *seen = false;
                        }
                    }
                }
            }
        }
        Ok(visible)
    }

    /// Clips a camera-frame triangle at the near plane and rasterises what remains.
    fn raster_triangle(&self, q: &[Point3; 3], item: u32, hits: &mut [Option<Hit>]) {
        const NEAR: Real = 1e-3;
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
            self.raster_clipped(&[poly[0], poly[k], poly[k + 1]], &normal, item, hits);
        }
    }

    fn raster_clipped(
        &self,
        q: &[Point3; 3],
        normal: &Vector3,
        item: u32,
        hits: &mut [Option<Hit>],
    ) {
        let cam = &self.intrinsics;
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
                let slot = &mut hits[j * cam.width as usize + i];
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
                *slot = Some(Hit {
                    z,
                    item,
                    cos_view,
                    point,
                });
            }
        }
    }

    fn shade(
        &self,
        items: &[RenderItem<'_>],
        markers_in_camera: &[Vec<Point3>],
        hits: &[Option<Hit>],
        seed: u64,
    ) -> RgbdImage {
        let noise = &self.noise;
        let cos_grazing = noise.grazing_dropout_deg.to_radians().cos();
        let mut rng = SeededRng::new(seed);
        let mut color = Vec::with_capacity(hits.len() * 3);
        let mut depth_m = Vec::with_capacity(hits.len());
        for hit in hits {
            let (rgb, depth) = match hit {
                None => (BACKGROUND.map(Real::from), 0.0),
                Some(hit) => {
                    let item = &items[hit.item as usize];
                    let r2 = item.marker_radius_m * item.marker_radius_m;
                    let on_marker = markers_in_camera[hit.item as usize]
                        .iter()
                        .any(|m| (m - hit.point).norm_squared() <= r2);
                    let base = if on_marker { MARKER_RED } else { item.albedo };
                    let shade = 0.5 + 0.5 * hit.cos_view;
                    let rgb = base.map(|c| Real::from(c) * shade);
                    let in_range = (noise.min_depth_m..=noise.max_depth_m).contains(&hit.z);
                    let seen = hit.cos_view >= cos_grazing - 1e-12;
                    let depth = if in_range && seen {
                        (hit.z + noise.depth_std(hit.z) * rng.normal()).max(0.0)
                    } else {
                        0.0
                    };
                    (rgb, depth)
                }
            };
            for c in rgb {
                let noisy = if noise.color_std > 0.0 {
                    c + noise.color_std * rng.normal()
                } else {
                    c
                };
                color.push(noisy.round().clamp(0.0, 255.0) as u8);
            }
            depth_m.push(depth as f32);
        }
        RgbdImage {
            width: self.intrinsics.width,
            height: self.intrinsics.height,
            color,
            depth_m,
        }
    }
}

/// Distance along the unit ray `dir` from the origin to triangle `q`, `None` if it misses
/// (Möller–Trumbore, both faces).
fn ray_triangle(dir: &Vector3, q: &[Point3; 3]) -> Option<Real> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::{FingerParams, HandModel, HandPreset};

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
    fn red_centroid(
        img: &RgbdImage,
        u: Real,
        v: Real,
        radius_px: Real,
    ) -> Option<(Real, Real, usize)> {
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
}
