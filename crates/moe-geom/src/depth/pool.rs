//! Depth pixels on a surface pooled into observations of patches of it.
//!
//! A pixel that sees a surface measures a point `p` of it. Against a mesh at vertices `x` it
//! gives the point-to-plane residual `n · (p − q(x))`, where `q(x)` is the point of the
//! predicted face the pixel's ray met (fixed barycentric weights on the face's vertices) and `n`
//! that face's outward normal: only the normal component is seen, a pixel says nothing about
//! sliding along the surface. The residual is linear in the vertices, so the pixels of a patch
//! of surface pool exactly into one observation, their mean: `value = mean(n·p)` measured,
//! `Σ_v a_v · x_v` predicted with `a_v = mean(w_v n)`. Its variance is that of a mean of pixels
//! under the camera's noise ([`DepthNoise`]: the white part averages, the correlated part does
//! not).
//!
//! Both the physics estimator and the SR-ARAP registration read the depth image through these
//! patches.

use serde::{Deserialize, Serialize};

use crate::depth::{AssociationOptions, DepthImage, DepthPoint};
use crate::error::GeomError;
use crate::math::{Iso3, Point3, Real, Vector3};

/// A depth camera's noise at the ranges a wrist camera sees a finger: white noise per pixel
/// growing with the square of the range (stereo), a part shared by neighbouring pixels that
/// does not average away, and quantisation to the image's depth unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DepthNoise {
    /// White depth noise at zero range, metres. Default 0.0005 (the virtual camera's).
    pub sigma_base_m: Real,
    /// Growth of the white noise with squared range, 1/metre. Default 0.0025 (the virtual
    /// camera's).
    pub sigma_per_m2: Real,
    /// Error shared by the pixels of a neighbourhood, metres. Default 1e-4 (an assumption).
    pub correlated_sigma_m: Real,
    /// Depth unit the image is quantised to, metres (0: none). Default 0.
    pub quantum_m: Real,
}

impl Default for DepthNoise {
    fn default() -> Self {
        Self {
            sigma_base_m: 0.0005,
            sigma_per_m2: 0.0025,
            correlated_sigma_m: 1e-4,
            quantum_m: 0.0,
        }
    }
}

impl DepthNoise {
    /// The variance of one pixel's depth at range `z`: white noise and quantisation.
    pub fn pixel_variance(&self, z: Real) -> Real {
        let sigma = self.sigma_base_m + self.sigma_per_m2 * z * z;
        sigma * sigma + self.quantum_m * self.quantum_m / 12.0
    }

    /// The same camera with twice the white and correlated noise, quantised to whole
    /// millimetres (as a ROS 2 `16UC1` depth topic is).
    #[must_use]
    pub fn harsher(&self) -> Self {
        Self {
            sigma_base_m: 2.0 * self.sigma_base_m,
            sigma_per_m2: 2.0 * self.sigma_per_m2,
            correlated_sigma_m: 2.0 * self.correlated_sigma_m,
            quantum_m: 0.001,
        }
    }

    /// The variance of the mean of pixels whose white variances sum to `white_sum` over `n`
    /// pixels: the white part averaged, the correlated part whole.
    pub fn mean_variance(&self, white_sum: Real, n: usize) -> Real {
        let n = n.max(1) as Real;
        white_sum / (n * n) + self.correlated_sigma_m * self.correlated_sigma_m
    }

    /// Checks every figure.
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] naming the first bad one.
    pub fn validate(&self) -> Result<(), GeomError> {
        for (name, v) in [
            ("noise.sigma_base_m", self.sigma_base_m),
            ("noise.sigma_per_m2", self.sigma_per_m2),
            ("noise.correlated_sigma_m", self.correlated_sigma_m),
            ("noise.quantum_m", self.quantum_m),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(GeomError::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be finite and non-negative",
                });
            }
        }
        Ok(())
    }
}

/// Checks the settings every reader of the depth image shares: the camera's noise, the
/// association's sampling and gates, the patches' spacing and their fewest pixels (named as in
/// a `[depth]` settings table).
///
/// # Errors
/// [`GeomError::InvalidParameter`] naming the first bad one.
pub fn check_depth_settings(
    noise: &DepthNoise,
    association: &AssociationOptions,
    patch_spacing_m: Real,
    min_pixels: usize,
) -> Result<(), GeomError> {
    noise.validate()?;
    association.validate()?;
    if !(patch_spacing_m.is_finite() && patch_spacing_m > 0.0) {
        return Err(GeomError::InvalidParameter {
            name: "depth.patch_spacing_m",
            value: patch_spacing_m,
            reason: "must be finite and positive",
        });
    }
    if min_pixels == 0 {
        return Err(GeomError::InvalidParameter {
            name: "depth.min_pixels",
            value: 0.0,
            reason: "must be at least 1",
        });
    }
    Ok(())
}

/// One depth pixel seen on a surface, in the surface's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePixel {
    /// The face of the predicted surface the pixel's ray meets.
    pub face: u32,
    /// Where the ray meets the predicted surface.
    pub predicted: Point3,
    /// The face's outward unit normal.
    pub normal: Vector3,
    /// The measured point.
    pub measured: Point3,
    /// Variance of the measured point along the normal (the depth noise projected), m².
    pub variance: Real,
}

/// Associated depth pixels ([`DepthPoint`], hand frame) in the frame `frame_from_hand` maps
/// to, each with the variance of its point-to-plane distance: the pixel's depth variance
/// projected on the normal along the ray (`σ_z · |n · ray| / cos α`, α the ray's angle from
/// the optical axis). Pixels that are holes in `depth` are left out.
pub fn surface_pixels(
    found: &[DepthPoint],
    depth: &DepthImage<'_>,
    noise: &DepthNoise,
    frame_from_hand: &Iso3,
) -> Vec<SurfacePixel> {
    let hand_from_camera: Iso3 = *depth.hand_from_camera().iso();
    let eye = Point3::from(hand_from_camera.translation.vector);
    let axis = hand_from_camera.rotation * Vector3::z();
    found
        .iter()
        .filter_map(|p| {
            let z = depth.depth(p.pixel[0], p.pixel[1])?;
            let ray = (p.measured_in_hand - eye).try_normalize(0.0)?;
            let cos_axis = ray.dot(&axis).max(1e-6);
            let along = p.normal_in_hand.dot(&ray) / cos_axis;
            Some(SurfacePixel {
                face: p.face,
                predicted: frame_from_hand * p.predicted_in_hand,
                normal: frame_from_hand * p.normal_in_hand,
                measured: frame_from_hand * p.measured_in_hand,
                variance: noise.pixel_variance(z) * along * along,
            })
        })
        .collect()
}

/// The patches pixels are pooled over: per face of a surface, its patch.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfacePatches {
    of_face: Vec<u32>,
    count: usize,
}

impl SurfacePatches {
    /// Patches about `spacing_m` across on the rest surface (`vertices`, `faces`): centres
    /// chosen greedily at least the spacing apart, every face given to the centre nearest its
    /// centroid.
    pub fn new(vertices: &[Point3], faces: &[[u32; 3]], spacing_m: Real) -> Self {
        let mut centres: Vec<Point3> = Vec::new();
        for p in vertices {
            if centres.iter().all(|c| (c - p).norm() >= spacing_m) {
                centres.push(*p);
            }
        }
        let of_face = faces
            .iter()
            .map(|f| {
                let centroid = Point3::from(
                    f.iter()
                        .filter_map(|&i| vertices.get(i as usize))
                        .map(|v| v.coords)
                        .sum::<Vector3>()
                        / 3.0,
                );
                centres
                    .iter()
                    .enumerate()
                    .min_by(|a, b| {
                        (a.1 - centroid)
                            .norm_squared()
                            .total_cmp(&(b.1 - centroid).norm_squared())
                    })
                    .map_or(0, |(k, _)| k as u32)
            })
            .collect();
        Self {
            of_face,
            count: centres.len(),
        }
    }

    /// Number of patches.
    pub fn count(&self) -> usize {
        self.count
    }

    /// The patch of face `face`, `None` for a face the surface does not have.
    pub fn of_face(&self, face: u32) -> Option<u32> {
        self.of_face.get(face as usize).copied()
    }
}

/// Barycentric weights of `p` in triangle `t` (projected onto its plane), clamped to the
/// triangle; equal thirds for a degenerate one.
pub fn barycentric(t: [Point3; 3], p: &Point3) -> [Real; 3] {
    let (e0, e1, d) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (a, b, c) = (e0.dot(&e0), e0.dot(&e1), e1.dot(&e1));
    let (u, v) = (d.dot(&e0), d.dot(&e1));
    let det = a * c - b * b;
    if det.abs() <= 1e-12 * (a * c).max(Real::MIN_POSITIVE) {
        return [1.0 / 3.0; 3];
    }
    let w1 = ((c * u - b * v) / det).clamp(0.0, 1.0);
    let w2 = ((a * v - b * u) / det).clamp(0.0, 1.0 - w1);
    [1.0 - w1 - w2, w1, w2]
}

/// The pixels of one patch pooled into one observation: the mesh predicts `Σ a_v · x_v` over
/// `terms`, the pixels measured `value` (a mean point-to-plane position along the normals,
/// metres).
#[derive(Debug, Clone, PartialEq)]
pub struct PooledPatch {
    /// `(vertex, a_v)`.
    pub terms: Vec<(u32, Vector3)>,
    /// The measured value, metres.
    pub value: Real,
    /// Pixels pooled.
    pub pixels: usize,
    /// The patch.
    pub patch: u32,
    /// Variance of `value` under the camera's noise, m².
    pub variance: Real,
}

impl PooledPatch {
    /// What the patch predicts for vertices `x` (`position(v)` gives vertex `v`).
    pub fn predicted(&self, position: impl Fn(u32) -> Point3) -> Real {
        self.terms
            .iter()
            .map(|&(v, a)| a.dot(&position(v).coords))
            .sum()
    }
}

/// `pixels` (on the surface `faces` as predicted at `predicted` vertices) pooled per patch of
/// `patches`: one observation per patch with at least `min_pixels`. A pixel of a face the
/// surface does not have is left out.
pub fn pool_pixels(
    pixels: &[SurfacePixel],
    faces: &[[u32; 3]],
    predicted: &[Point3],
    patches: &SurfacePatches,
    min_pixels: usize,
    noise: &DepthNoise,
) -> Vec<PooledPatch> {
    #[derive(Clone, Default)]
    struct Pool {
        terms: Vec<(u32, Vector3)>,
        value: Real,
        white: Real,
        pixels: usize,
    }
    let mut pools = vec![Pool::default(); patches.count];
    for px in pixels {
        let (Some(patch), Some(face)) = (patches.of_face(px.face), faces.get(px.face as usize))
        else {
            continue;
        };
        let Some(corners) = face
            .iter()
            .map(|&i| predicted.get(i as usize).copied())
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        let w = barycentric([corners[0], corners[1], corners[2]], &px.predicted);
        let pool = &mut pools[patch as usize];
        for (&v, w) in face.iter().zip(w) {
            match pool.terms.iter_mut().find(|t| t.0 == v) {
                Some(t) => t.1 += px.normal * w,
                None => pool.terms.push((v, px.normal * w)),
            }
        }
        pool.value += px.normal.dot(&px.measured.coords);
        pool.white += px.variance;
        pool.pixels += 1;
    }
    pools
        .into_iter()
        .zip(0u32..)
        .filter(|(p, _)| p.pixels >= min_pixels.max(1))
        .map(|(p, patch)| {
            let n = p.pixels as Real;
            PooledPatch {
                terms: p.terms.into_iter().map(|(v, a)| (v, a / n)).collect(),
                value: p.value / n,
                pixels: p.pixels,
                patch,
                variance: noise.mean_variance(p.white, p.pixels),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentric_weights_rebuild_the_point() {
        let t = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 2.0, 0.0),
        ];
        let p = Point3::new(0.25, 0.5, 0.3);
        let w = barycentric(t, &p);
        let q: Vector3 = t.iter().zip(w).map(|(v, w)| v.coords * w).sum();
        assert!((q - Vector3::new(0.25, 0.5, 0.0)).norm() < 1e-12, "{q}");
        assert!((w.iter().sum::<Real>() - 1.0).abs() < 1e-12);
        // Outside the triangle: clamped onto it.
        let w = barycentric(t, &Point3::new(2.0, 0.0, 0.0));
        assert_eq!(w, [0.0, 1.0, 0.0]);
    }

    fn grid() -> (Vec<Point3>, Vec<[u32; 3]>) {
        let vertices: Vec<Point3> = (0..10)
            .flat_map(|i| {
                (0..10).map(move |j| Point3::new(i as Real * 1e-3, j as Real * 1e-3, 0.0))
            })
            .collect();
        let mut faces = Vec::new();
        for i in 0..9u32 {
            for j in 0..9u32 {
                let v = i * 10 + j;
                faces.push([v, v + 10, v + 1]);
                faces.push([v + 1, v + 10, v + 11]);
            }
        }
        (vertices, faces)
    }

    #[test]
    fn every_face_has_a_patch_and_patches_are_spaced() {
        let (vertices, faces) = grid();
        let patches = SurfacePatches::new(&vertices, &faces, 0.003);
        // A 9 mm square with 3 mm spacing: centres on a 3 mm grid, 4 × 4.
        assert_eq!(patches.count(), 16);
        assert!(
            (0..faces.len() as u32).all(|f| patches.of_face(f).is_some_and(|p| (p as usize) < 16))
        );
        assert_eq!(patches.of_face(faces.len() as u32), None);
    }

    /// Pixels of a plane moved by `d` along its normal pool into patches whose prediction at
    /// the moved vertices is their value, and whose variance is the white noise averaged plus
    /// the correlated part.
    #[test]
    fn pooled_patches_predict_what_their_pixels_measure() {
        let (vertices, faces) = grid();
        let patches = SurfacePatches::new(&vertices, &faces, 0.003);
        let noise = DepthNoise::default();
        let normal = Vector3::z();
        let d = 0.0004;
        let pixels: Vec<SurfacePixel> = faces
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let c = Point3::from(
                    f.iter()
                        .map(|&i| vertices[i as usize].coords)
                        .sum::<Vector3>()
                        / 3.0,
                );
                SurfacePixel {
                    face: k as u32,
                    predicted: c,
                    normal,
                    measured: c + normal * d,
                    variance: 2.5e-7,
                }
            })
            .collect();
        let pooled = pool_pixels(&pixels, &faces, &vertices, &patches, 3, &noise);
        assert!(!pooled.is_empty());
        let moved: Vec<Point3> = vertices.iter().map(|p| p + normal * d).collect();
        for p in &pooled {
            assert!(p.pixels >= 3);
            let at_rest = p.predicted(|v| vertices[v as usize]);
            let at_moved = p.predicted(|v| moved[v as usize]);
            assert!((p.value - at_moved).abs() < 1e-15, "{p:?}");
            assert!((p.value - at_rest - d).abs() < 1e-15);
            let n = p.pixels as Real;
            let expected = 2.5e-7 / n + 1e-8;
            assert!((p.variance - expected).abs() < 1e-20, "{p:?}");
        }
        // Too few pixels: no patch.
        assert!(pool_pixels(&pixels[..2], &faces, &vertices, &patches, 3, &noise).is_empty());
    }

    #[test]
    fn noise_figures_are_checked_by_name() {
        DepthNoise::default().validate().unwrap();
        let bad = DepthNoise {
            correlated_sigma_m: Real::NAN,
            ..DepthNoise::default()
        };
        crate::assert_err!(
            bad.validate(),
            GeomError::InvalidParameter {
                name: "noise.correlated_sigma_m",
                ..
            }
        );
    }
}
