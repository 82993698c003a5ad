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
//! - colour: every channel `+ N(0, color_std²)` in 8-bit levels, clamped to `[0, 255]`;
//! - optionally (off by default), a depth error shared by neighbouring pixels, as stereo
//!   matching makes it: a field of `N(0, depth_correlated_std_m²)` values on a grid
//!   `depth_correlation_px` pixels apart, interpolated bilinearly (drawn from its own stream of
//!   the seed, so the white noise stays the same), and quantisation of the depth to
//!   `depth_quantum_m` (a ROS 2 `16UC1` depth topic is whole millimetres);
//! - optionally (off by default), a stereo camera's artefacts: no depth where its second imager,
//!   `stereo_baseline_m` along the camera's +x, does not see the surface (the occlusion shadow
//!   beside a nearer surface, the band along the image's left edge), and flying pixels, a share
//!   of the pixels at a depth step reporting a depth between the two surfaces.
//!
//! [`RgbdCamera::d405_wrist`](crate::camera::RgbdCamera::d405_wrist) is a camera one can buy,
//! mounted where its depth works, with each figure's source.
//!
//! The noise is drawn from a [`SeededRng`](moe_geom::SeededRng) in pixel order, so a seed fixes the image bit for bit.

use moe_geom::camera::ray_triangle;
use moe_geom::rng::SeededRng;
use moe_geom::transform::{Transform, frame};
use moe_geom::zbuffer::{ZBuffer, ZHit};
use moe_geom::{GeomError, Iso3, Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::is_zero;

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
    /// Standard deviation of the depth error shared by neighbouring pixels, metres. Default 0.
    /// (Left out of written settings while 0, as are the next two at their defaults, so that
    /// scene files written before these fields existed stay the same.)
    #[serde(skip_serializing_if = "is_zero")]
    pub depth_correlated_std_m: Real,
    /// Spacing of that error's independent values, pixels. Default 16.
    #[serde(skip_serializing_if = "is_default_spacing")]
    pub depth_correlation_px: u32,
    /// Depth unit the image is quantised to, metres (0: none). Default 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub depth_quantum_m: Real,
    /// Distance from the depth origin (the left imager) to the second imager of a stereo
    /// camera, along the camera's +x, metres (0: no second imager). A surface point the second
    /// imager cannot see — hidden behind something nearer, or outside its image — has no
    /// depth, as a stereo camera's left–right check leaves it: the holes beside a finger in
    /// front of an object, and the band along the image's left edge. Default 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub stereo_baseline_m: Real,
    /// Share of the pixels at a depth step (a 4-neighbour more than `flying_pixel_step_m`
    /// away) whose depth lands between the two surfaces, uniformly (flying pixels: the
    /// matching window straddles both). Drawn from its own stream of the seed. Default 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub flying_pixel_fraction: Real,
    /// Smallest depth step between neighbouring pixels that makes flying pixels, metres.
    /// Default 0.005.
    #[serde(skip_serializing_if = "is_default_flying_step")]
    pub flying_pixel_step_m: Real,
}

fn is_default_flying_step(x: &Real) -> bool {
    *x == DEFAULT_FLYING_STEP_M
}

const DEFAULT_FLYING_STEP_M: Real = 0.005;

fn is_default_spacing(px: &u32) -> bool {
    *px == 16
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
            depth_correlated_std_m: 0.0,
            depth_correlation_px: 16,
            depth_quantum_m: 0.0,
            stereo_baseline_m: 0.0,
            flying_pixel_fraction: 0.0,
            flying_pixel_step_m: DEFAULT_FLYING_STEP_M,
        }
    }
}

impl NoiseModel {
    /// An ideal sensor: exact depth everywhere in range, no dropout, exact colour (the
    /// correlated error, quantisation, second imager and flying pixels stay off, as by
    /// default).
    pub fn ideal() -> Self {
        Self {
            depth_std_base_m: 0.0,
            depth_std_per_m2: 0.0,
            grazing_dropout_deg: 90.0,
            min_depth_m: 0.0,
            max_depth_m: Real::INFINITY,
            color_std: 0.0,
            ..Self::default()
        }
    }

    /// The same camera with a harsher depth: twice the white noise, a correlated error of
    /// 0.2 mm over 16 pixels, and whole millimetres.
    #[must_use]
    pub fn harsher(&self) -> Self {
        Self {
            depth_std_base_m: 2.0 * self.depth_std_base_m,
            depth_std_per_m2: 2.0 * self.depth_std_per_m2,
            depth_correlated_std_m: 2e-4,
            depth_correlation_px: 16,
            depth_quantum_m: 1e-3,
            ..*self
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
                "depth_correlated_std_m",
                self.depth_correlated_std_m,
                self.depth_correlated_std_m >= 0.0 && self.depth_correlated_std_m.is_finite(),
            ),
            (
                "depth_correlation_px",
                Real::from(self.depth_correlation_px),
                self.depth_correlation_px >= 1,
            ),
            (
                "depth_quantum_m",
                self.depth_quantum_m,
                self.depth_quantum_m >= 0.0 && self.depth_quantum_m.is_finite(),
            ),
            (
                "grazing_dropout_deg",
                self.grazing_dropout_deg,
                (0.0..=90.0).contains(&self.grazing_dropout_deg),
            ),
            (
                "stereo_baseline_m",
                self.stereo_baseline_m,
                (0.0..=1.0).contains(&self.stereo_baseline_m),
            ),
            (
                "flying_pixel_fraction",
                self.flying_pixel_fraction,
                (0.0..=1.0).contains(&self.flying_pixel_fraction),
            ),
            (
                "flying_pixel_step_m",
                self.flying_pixel_step_m,
                self.flying_pixel_step_m > 0.0 && self.flying_pixel_step_m.is_finite(),
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

/// The D405's stereo baseline, metres (Intel RealSense D405 product specification).
pub const D405_BASELINE_M: Real = 0.018;

/// Disparity error of the stereo match, pixels, that [`RgbdCamera::d405_wrist`]'s depth noise
/// assumes: 0.2, the rule of thumb for stereo matching (FLIR/Point Grey knowledge base article
/// 10102), 2.5 × Intel's typical 0.08 for well-textured scenes, since the D405 has no
/// projector and silicone has little texture.
pub const D405_SUBPIXEL_PX: Real = 0.2;

impl RgbdCamera {
    /// A D405-class short-range stereo RGB-D camera on the wrist, mounted where its depth
    /// works: 4.5 cm behind the palm centre, looking along the fingers, at 424 × 240, the
    /// resolution with the shortest documented minimum depth (40 mm; 70 mm at 848 × 480).
    /// It is turned 90° about its optical axis, so that the stereo baseline (camera x) runs
    /// along the hand's y, across the plane the two fingers spread in: both imagers then see
    /// the fingers' inner faces alike (with the baseline along the hand's x, the second imager
    /// saw one finger's face edge-on and marker detection on three of the plate scenes fell
    /// from 73 to 47 %). Every figure and its source:
    /// - intrinsics from the 87° × 58° depth field of view (fx = 212 / tan 43.5°,
    ///   fy = 120 / tan 29°), principal point at the image centre;
    /// - depth range 40 mm – 0.5 m: the minimum Z at 424 × 240 and the top of the "ideal range
    ///   7–50 cm" (Intel D401/D405 data sheet, as quoted on DigiKey's technical forum,
    ///   <https://forum.digikey.com/t/the-intel-realsense-depth-camera-d405/50822>);
    /// - white depth noise σ(z) = z² · s / (fx · B), Intel's depth-RMS relation (white paper
    ///   "Subpixel linearity improvement for Intel RealSense depth cameras"; tuning guide "Tuning
    ///   depth cameras for best performance"), with B = [`D405_BASELINE_M`] and
    ///   s = [`D405_SUBPIXEL_PX`]: 0.12 mm at 5 cm, 0.5 mm at 10 cm;
    /// - depth in units of 0.1 mm, the D405's default depth unit (librealsense pull request
    ///   8946);
    /// - holes where the second imager does not see the surface (the left–right check of a
    ///   stereo camera), 18 mm along +x;
    /// - assumptions without a published figure: a correlated error of 0.1 mm over 16 pixels
    ///   (as the estimators' depth model assumes), half the pixels at a depth step of more than
    ///   5 mm flying, dropout beyond 85° from the normal and colour noise of 2 levels (as the
    ///   default camera).
    ///
    /// Not modelled: the bias of red paint and translucent silicone in stereo matching,
    /// exposure, motion blur and the depth–colour registration error.
    pub fn d405_wrist() -> Self {
        let intrinsics = CameraIntrinsics {
            width: 424,
            height: 240,
            fx: 223.4,
            fy: 216.5,
            cx: 211.5,
            cy: 119.5,
        };
        Self {
            intrinsics,
            hand_from_camera: Transform::new(Iso3::new(
                Vector3::new(0.0, 0.0, -0.045),
                Vector3::z() * std::f64::consts::FRAC_PI_2,
            )),
            noise: NoiseModel {
                depth_std_base_m: 0.0,
                depth_std_per_m2: D405_SUBPIXEL_PX / (intrinsics.fx * D405_BASELINE_M),
                grazing_dropout_deg: 85.0,
                min_depth_m: 0.04,
                max_depth_m: 0.5,
                color_std: 2.0,
                depth_correlated_std_m: 1e-4,
                depth_correlation_px: 16,
                depth_quantum_m: 1e-4,
                stereo_baseline_m: D405_BASELINE_M,
                flying_pixel_fraction: 0.5,
                flying_pixel_step_m: DEFAULT_FLYING_STEP_M,
            },
        }
    }

    /// Checks the intrinsics, the noise parameters and the mount (finite, its rotation a unit
    /// quaternion).
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] naming the first bad value.
    pub fn validate(&self) -> Result<(), GeomError> {
        self.intrinsics.validate()?;
        self.noise.validate()?;
        let mount = self.hand_from_camera.iso();
        let values = mount
            .translation
            .vector
            .iter()
            .chain(mount.rotation.coords.iter());
        for &value in values {
            if !value.is_finite() {
                return Err(GeomError::InvalidParameter {
                    name: "hand_from_camera",
                    value,
                    reason: "not finite",
                });
            }
        }
        let norm = mount.rotation.coords.norm();
        if (norm - 1.0).abs() > 1e-6 {
            return Err(GeomError::InvalidParameter {
                name: "hand_from_camera.rotation",
                value: norm,
                reason: "not a unit quaternion",
            });
        }
        Ok(())
    }

    /// Renders the items and applies the noise model with `seed`.
    ///
    /// # Errors
    /// Invalid intrinsics or noise parameters, or a face index out of range in an item.
    pub fn render(&self, items: &[RenderItem<'_>], seed: u64) -> Result<RgbdImage, GeomError> {
        self.noise.validate()?;
        let mut zbuffer = ZBuffer::new(self.intrinsics)?;
        let camera_from_hand = self.hand_from_camera.inverse();
        // The stereo camera's second imager, `stereo_baseline_m` along the camera's +x.
        let baseline = self.noise.stereo_baseline_m;
        let mut second = (baseline > 0.0)
            .then(|| ZBuffer::new(self.intrinsics))
            .transpose()?;
        let mut markers_in_camera: Vec<Vec<Point3>> = Vec::with_capacity(items.len());
        for (index, item) in items.iter().enumerate() {
            for (face, q) in item.triangles_in(&camera_from_hand)?.iter().enumerate() {
                zbuffer.draw(q, index as u32, face as u32);
                if let Some(second) = &mut second {
                    second.draw(
                        &q.map(|p| p - Vector3::x() * baseline),
                        index as u32,
                        face as u32,
                    );
                }
            }
            markers_in_camera.push(camera_from_hand.transform_points(item.markers_in_hand));
        }
        Ok(self.shade(
            items,
            &markers_in_camera,
            zbuffer.hits(),
            second.as_ref(),
            seed,
        ))
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

    /// Whether the stereo camera's second imager (`second`, `stereo_baseline_m` along +x) sees
    /// the surface point `point` (camera frame): it projects inside the second image and
    /// nothing there lies more than [`SECOND_VIEW_TOLERANCE_M`] in front of it.
    fn second_imager_sees(&self, second: &ZBuffer, point: &Point3) -> bool {
        let p = point - Vector3::x() * self.noise.stereo_baseline_m;
        let Some((u, v)) = self.intrinsics.project(&p) else {
            return false;
        };
        let (i, j) = (u.round(), v.round());
        let (w, h) = (
            Real::from(self.intrinsics.width),
            Real::from(self.intrinsics.height),
        );
        if !(0.0..w).contains(&i) || !(0.0..h).contains(&j) {
            return false;
        }
        second
            .hit(i as u32, j as u32)
            .is_none_or(|hit| hit.z >= p.z - SECOND_VIEW_TOLERANCE_M)
    }

    /// The depth each pixel reports before the noise: none outside the range, at grazing
    /// angles or where the second imager does not see the surface; between two surfaces at a
    /// depth step for the flying pixels.
    fn clean_depth(
        &self,
        hits: &[Option<ZHit>],
        second: Option<&ZBuffer>,
        seed: u64,
    ) -> Vec<Option<Real>> {
        let noise = &self.noise;
        let cos_grazing = noise.grazing_dropout_deg.to_radians().cos();
        let mut depth: Vec<Option<Real>> = hits
            .iter()
            .map(|hit| {
                hit.as_ref().and_then(|hit| {
                    let in_range = (noise.min_depth_m..=noise.max_depth_m).contains(&hit.z);
                    let seen = hit.cos_view >= cos_grazing - 1e-12;
                    let stereo = second.is_none_or(|s| self.second_imager_sees(s, &hit.point));
                    (in_range && seen && stereo).then_some(hit.z)
                })
            })
            .collect();
        if noise.flying_pixel_fraction > 0.0 {
            let (w, h) = (
                self.intrinsics.width as usize,
                self.intrinsics.height as usize,
            );
            let mut rng = SeededRng::new(seed).split(FLYING_STREAM);
            for (k, pixel) in depth.iter_mut().enumerate() {
                let Some(z) = *pixel else { continue };
                let (i, j) = (k % w, k / w);
                let neighbours = [
                    (i > 0).then(|| k - 1),
                    (i + 1 < w).then(|| k + 1),
                    (j > 0).then(|| k - w),
                    (j + 1 < h).then(|| k + w),
                ];
                // The true surface across the largest step.
                let across = neighbours
                    .into_iter()
                    .flatten()
                    .filter_map(|n| hits[n].as_ref().map(|hit| hit.z))
                    .max_by(|a, b| (a - z).abs().total_cmp(&(b - z).abs()));
                if let Some(other) = across
                    && (other - z).abs() > noise.flying_pixel_step_m
                    && rng.uniform() < noise.flying_pixel_fraction
                {
                    *pixel = Some(z + rng.uniform() * (other - z));
                }
            }
        }
        depth
    }

    fn shade(
        &self,
        items: &[RenderItem<'_>],
        markers_in_camera: &[Vec<Point3>],
        hits: &[Option<ZHit>],
        second: Option<&ZBuffer>,
        seed: u64,
    ) -> RgbdImage {
        let noise = &self.noise;
        let clean = self.clean_depth(hits, second, seed);
        let mut rng = SeededRng::new(seed);
        let mut color = Vec::with_capacity(hits.len() * 3);
        let mut depth_m = Vec::with_capacity(hits.len());
        let field = CorrelatedField::new(
            self.intrinsics.width,
            self.intrinsics.height,
            noise,
            &SeededRng::new(seed).split(CORRELATED_STREAM),
        );
        let width = self.intrinsics.width as usize;
        for (k, (hit, clean)) in hits.iter().zip(&clean).enumerate() {
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
                    let depth = match *clean {
                        Some(z) => {
                            let shared = field.at((k % width) as u32, (k / width) as u32);
                            let d = (z + noise.depth_std(z) * rng.normal() + shared).max(0.0);
                            if noise.depth_quantum_m > 0.0 {
                                (d / noise.depth_quantum_m).round() * noise.depth_quantum_m
                            } else {
                                d
                            }
                        }
                        None => 0.0,
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

/// How far in front of a surface point the second imager's nearest surface may lie and the
/// point still count as seen by it (the two imagers' rays meet the same surface at points a
/// fraction of a pixel apart).
const SECOND_VIEW_TOLERANCE_M: Real = 0.002;

/// The seed's stream of the flying pixels (apart from the white noise's).
const FLYING_STREAM: u64 = 0x666c_7969;

/// The seed's stream of the correlated depth error (apart from the white noise's).
const CORRELATED_STREAM: u64 = 0x636f_7272;

/// A depth error shared by neighbouring pixels: independent values on a coarse grid,
/// interpolated bilinearly (all zero when the model has none).
struct CorrelatedField {
    step: u32,
    columns: usize,
    values: Vec<Real>,
}

impl CorrelatedField {
    fn new(width: u32, height: u32, noise: &NoiseModel, rng: &SeededRng) -> Self {
        let step = noise.depth_correlation_px.max(1);
        if noise.depth_correlated_std_m <= 0.0 {
            return Self {
                step,
                columns: 0,
                values: Vec::new(),
            };
        }
        let columns = (width / step + 2) as usize;
        let rows = (height / step + 2) as usize;
        let mut rng = rng.clone();
        let values = (0..columns * rows)
            .map(|_| noise.depth_correlated_std_m * rng.normal())
            .collect();
        Self {
            step,
            columns,
            values,
        }
    }

    /// The error at pixel `(i, j)`, metres.
    fn at(&self, i: u32, j: u32) -> Real {
        if self.values.is_empty() {
            return 0.0;
        }
        let (gx, gy) = (i / self.step, j / self.step);
        let (fx, fy) = (
            Real::from(i % self.step) / Real::from(self.step),
            Real::from(j % self.step) / Real::from(self.step),
        );
        let v = |x: u32, y: u32| self.values[y as usize * self.columns + x as usize];
        let top = v(gx, gy) * (1.0 - fx) + v(gx + 1, gy) * fx;
        let bottom = v(gx, gy + 1) * (1.0 - fx) + v(gx + 1, gy + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

#[cfg(test)]
mod tests;
