//! The physical limit of locating a press from what the camera gives: the Cramér–Rao bound of
//! the place along and around the finger, from the model's Jacobian of the observations with
//! respect to the press's place and force vector and their noise. The observations are the
//! markers' coordinates, the depth image's view of the finger's surface ([`DepthBoundModel`]),
//! or both.

use moe_geom::camera::ray_triangle;
use moe_geom::{CameraIntrinsics, Iso3, Point3, Real, Vector3};
use serde::{Deserialize, Serialize};

use crate::config::DepthNoise;
use crate::error::PhysicsError;
use crate::estimator::PhysicsEstimator;
use crate::finger::FingerObservation;

/// What the bound assumes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BoundOptions {
    /// Force of the press, along the inward normal, newtons. Default 0.2.
    pub force_n: Real,
    /// Noise of a marker coordinate, metres. Default 1.6e-4: the perception stage's markers
    /// are 0.25 mm from the truth on average, the mean norm of an isotropic 3-D Gaussian of
    /// 0.16 mm per coordinate.
    pub marker_sigma_m: Real,
    /// Independent frames of a held press (the bound shrinks as one over their square root).
    /// Default 1.
    pub frames: usize,
    /// Whether the markers are observed. Default true.
    pub markers: bool,
    /// The depth image as an observation, when given. Default none.
    pub depth: Option<DepthBoundModel>,
}

impl Default for BoundOptions {
    fn default() -> Self {
        Self {
            force_n: 0.2,
            marker_sigma_m: 1.6e-4,
            frames: 1,
            markers: true,
            depth: None,
        }
    }
}

impl BoundOptions {
    /// What the options observe, in words: `markers`, `depth` or `markers and depth`.
    pub fn observed(&self) -> &'static str {
        match (self.markers, self.depth.is_some()) {
            (true, true) => "markers and depth",
            (false, _) => "depth",
            (true, false) => "markers",
        }
    }

    /// Checks the options.
    ///
    /// # Errors
    /// [`PhysicsError::InvalidParameter`] naming the bad one.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        for (name, v) in [
            ("force_n", self.force_n),
            ("marker_sigma_m", self.marker_sigma_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(PhysicsError::InvalidParameter {
                    name,
                    value: v,
                    reason: "must be finite and positive",
                });
            }
        }
        if self.frames == 0 {
            return Err(PhysicsError::InvalidParameter {
                name: "frames",
                value: 0.0,
                reason: "must be at least 1",
            });
        }
        match &self.depth {
            Some(depth) => depth.validate(),
            None if !self.markers => Err(PhysicsError::InvalidParameter {
                name: "markers",
                value: 0.0,
                reason: "the bound needs an observation: markers, depth or both",
            }),
            None => Ok(()),
        }
    }
}

/// The wrist camera's depth image as an observation for the bound.
///
/// Every surface vertex the camera sees (in front of it, inside the image, within range, facing
/// it at less than the grazing angle, not hidden by the finger's own surface) is observed along
/// its normal: a depth pixel constrains only the distance to the surface, not where on it the
/// pixel lies. Its pixels are those that fall on its share of the surface (a third of its faces'
/// areas, foreshortened and at its range). Each pixel's depth error is the camera's
/// [`DepthNoise`], the estimator's own model: a white part `σ(z) = sigma_base_m + sigma_per_m2 ·
/// z²` (stereo error grows with the square of the range), with quantisation to `quantum_m`
/// adding `quantum_m² / 12` to its variance; averaging a vertex's `n` pixels divides the white
/// variance by `n`, but a correlated part (`correlated_sigma_m`, shared by neighbouring pixels)
/// does not average away. The defaults are
/// the virtual camera's: mounted 2 cm behind the palm looking along the fingers, 640 × 480 at a
/// 380-pixel focal length, σ = 0.5 mm + 0.0025 m⁻¹ · z², range 1 cm – 3 m, no depth beyond 85°
/// from the normal; the correlated part (0.1 mm) and no quantisation are assumptions of the
/// model, not measured figures: [`DepthBoundModel::harsher`] doubles both noise parts and
/// quantises to whole millimetres, as a ROS 2 `16UC1` depth topic does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DepthBoundModel {
    /// The camera's intrinsics.
    pub intrinsics: CameraIntrinsics,
    /// Where the camera is on the hand (camera frame to hand frame).
    pub hand_from_camera: Iso3,
    /// The depth noise.
    pub noise: DepthNoise,
    /// Nearest valid depth, metres.
    pub min_range_m: Real,
    /// Farthest valid depth, metres.
    pub max_range_m: Real,
    /// Surfaces seen more obliquely than this (angle between the ray and the normal) give no
    /// depth, degrees.
    pub grazing_deg: Real,
}

impl Default for DepthBoundModel {
    fn default() -> Self {
        Self {
            intrinsics: CameraIntrinsics::default(),
            hand_from_camera: Iso3::translation(0.0, 0.0, -0.02),
            noise: DepthNoise::default(),
            min_range_m: 0.01,
            max_range_m: 3.0,
            grazing_deg: 85.0,
        }
    }
}

/// What the camera sees of a finger ([`PhysicsEstimator::depth_coverage`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DepthCoverage {
    /// Surface vertices seen.
    pub vertices: usize,
    /// Surface vertices of the finger.
    pub surface_vertices: usize,
    /// Depth pixels that fall on the vertices seen (their shares of the surface).
    pub pixels: Real,
    /// Their range (median, 90th percentile), metres.
    pub depth_m: Spread,
}

/// A surface vertex the camera sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SeenVertex {
    /// The vertex.
    pub(crate) vertex: u32,
    /// Its depth (z in the camera frame), metres.
    pub(crate) depth_m: Real,
    /// Pixels per square metre of its surface there (foreshortening and range).
    pub(crate) pixels_per_m2: Real,
}

impl DepthBoundModel {
    /// The same camera with twice the white and correlated noise, quantised to whole
    /// millimetres.
    #[must_use]
    pub fn harsher(&self) -> Self {
        Self {
            noise: self.noise.harsher(),
            ..self.clone()
        }
    }

    /// Checks the model.
    ///
    /// # Errors
    /// [`PhysicsError::InvalidParameter`] naming the bad figure, or the intrinsics' error.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        self.intrinsics.validate()?;
        self.noise
            .validate()
            .map_err(PhysicsError::from_parameter)?;
        let checks = [
            ("min_range_m", self.min_range_m, self.min_range_m >= 0.0),
            (
                "max_range_m",
                self.max_range_m,
                self.max_range_m > self.min_range_m,
            ),
            (
                "grazing_deg",
                self.grazing_deg,
                self.grazing_deg > 0.0 && self.grazing_deg <= 90.0,
            ),
        ];
        for (name, value, ok) in checks {
            if !ok || value.is_nan() {
                return Err(PhysicsError::InvalidParameter {
                    name,
                    value,
                    reason: "out of range",
                });
            }
        }
        let n = &self.noise;
        if !(n.sigma_base_m + n.correlated_sigma_m + n.quantum_m > 0.0 || n.sigma_per_m2 > 0.0) {
            return Err(PhysicsError::InvalidParameter {
                name: "noise.sigma_base_m",
                value: n.sigma_base_m,
                reason: "a depth model without noise bounds nothing",
            });
        }
        Ok(())
    }

    /// The vertices of `surface` (with unit `normals` and `faces`, in some frame) that the
    /// camera at `camera_from_surface` sees.
    pub(crate) fn visible_vertices(
        &self,
        camera_from_surface: &Iso3,
        surface: &[Point3],
        normals: &[Vector3],
        faces: &[[u32; 3]],
    ) -> Vec<SeenVertex> {
        let k = &self.intrinsics;
        let (w, h) = (Real::from(k.width), Real::from(k.height));
        let cos_grazing = self.grazing_deg.to_radians().cos();
        let points: Vec<Point3> = surface.iter().map(|p| camera_from_surface * p).collect();
        let triangles: Vec<[Point3; 3]> = faces
            .iter()
            .map(|f| f.map(|i| points[i as usize]))
            .collect();
        let mut seen = Vec::new();
        for (v, (p, n)) in points.iter().zip(normals).enumerate() {
            let z = p.z;
            if !(self.min_range_m..=self.max_range_m).contains(&z) {
                continue;
            }
            let Some((u, r)) = k.project(p) else { continue };
            if !((-0.5..w - 0.5).contains(&u) && (-0.5..h - 0.5).contains(&r)) {
                continue;
            }
            let len = p.coords.norm();
            let ray = p.coords / len;
            // Facing the camera: the outward normal points back along the ray.
            let cos_view = -(camera_from_surface.rotation * n).dot(&ray);
            if cos_view < cos_grazing {
                continue;
            }
            let hidden = faces.iter().zip(&triangles).any(|(f, q)| {
                !f.contains(&(v as u32))
                    && ray_triangle(&ray, q).is_some_and(|t| t < len * (1.0 - 1e-6))
            });
            if hidden {
                continue;
            }
            seen.push(SeenVertex {
                vertex: v as u32,
                depth_m: z,
                // A surface element dA at distance ℓ seen at cos θ spans the solid angle
                // dA·cos θ / ℓ²; a pixel whose ray is at α from the optical axis spans
                // cos³α / (fx·fy), with cos α = z / ℓ: fx·fy·cos θ·ℓ / z³ pixels per unit area.
                pixels_per_m2: k.fx * k.fy * cos_view * len / (z * z * z),
            });
        }
        seen
    }
}

/// The bound at one place of a finger.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlaceBound {
    /// The surface vertex at the centre of the pressed patch.
    pub vertex: u32,
    /// Its rest position, finger frame, metres.
    pub rest_in_finger: Point3,
    /// Standard deviation bound of the place along the finger's axis, metres.
    pub along_m: Real,
    /// Standard deviation bound of the place around the axis (arc length), metres.
    pub around_m: Real,
    /// Standard deviation bound of the force's magnitude, newtons.
    pub force_sd_n: Real,
}

impl PlaceBound {
    /// The bound over `frames` independent frames of the same held press: their Fisher
    /// information adds up, so every standard deviation shrinks by √frames (what
    /// [`BoundOptions::frames`] gives, without solving again).
    #[must_use]
    pub fn over_frames(&self, frames: usize) -> Self {
        let k = (frames.max(1) as Real).sqrt();
        Self {
            along_m: self.along_m / k,
            around_m: self.around_m / k,
            force_sd_n: self.force_sd_n / k,
            ..self.clone()
        }
    }
}

impl PhysicsEstimator {
    /// Runs `f` on finger `finger`'s model and its observation at rest as a bound sees it: no
    /// marker seen, `pulls`, gravity, the hand taken as the world, no time. `f` is also given
    /// the finger of the hand.
    fn with_bound_observation<T>(
        &mut self,
        finger: usize,
        pulls: &[Real],
        gravity_in_hand: Vector3,
        f: impl FnOnce(
            &mut crate::finger::FingerInverse,
            &FingerObservation<'_>,
            &moe_geom::HandFinger,
        ) -> Result<T, PhysicsError>,
    ) -> Result<T, PhysicsError> {
        let n = self.hand().num_fingers();
        if finger >= n {
            return Err(PhysicsError::LengthMismatch {
                what: "finger index (fingers of the hand)",
                expected: n,
                got: finger,
            });
        }
        let hf = self.hand().fingers()[finger].clone();
        let expected = hf.model.tendon_routes().len();
        if pulls.len() != expected {
            return Err(PhysicsError::FingerLengthMismatch {
                what: "tendon pulls",
                finger,
                expected,
                got: pulls.len(),
            });
        }
        let markers = vec![None; hf.model.marker_vertices().len()];
        let obs = FingerObservation {
            markers: &markers,
            gravity: hf.hand_from_finger.iso().inverse() * gravity_in_hand,
            world_from_finger: *hf.hand_from_finger.iso(),
            pulls,
            time_secs: None,
            depth: &[],
            covered: &[],
            seen_through: &[],
            image: None,
        };
        f(self.finger_mut(finger), &obs, &hf)
    }

    /// What the camera of `depth` sees of finger `finger` at its static shape under `pulls` and
    /// gravity (the hand taken as the world): how many surface vertices, how many depth pixels
    /// fall on them, and their range.
    ///
    /// # Errors
    /// As [`PhysicsEstimator::location_bounds`].
    pub fn depth_coverage(
        &mut self,
        finger: usize,
        pulls: &[Real],
        gravity_in_hand: Vector3,
        depth: &DepthBoundModel,
    ) -> Result<DepthCoverage, PhysicsError> {
        depth.validate()?;
        self.with_bound_observation(finger, pulls, gravity_in_hand, |inverse, obs, hf| {
            let seen = inverse.depth_view(obs, depth)?;
            let depths: Vec<Real> = seen.iter().map(|s| s.0).collect();
            Ok(DepthCoverage {
                vertices: seen.len(),
                surface_vertices: hf.model.mesh().num_vertices(),
                pixels: seen.iter().map(|s| s.1).sum(),
                depth_m: Spread::of(&depths),
            })
        })
    }

    /// The Cramér–Rao bound of a press at every place of finger `finger` that can move: the
    /// model linearised at the finger's static shape under `pulls` and gravity, with what
    /// `options` observes (every marker of the finger, the depth image's view of it, or both;
    /// the hand is taken as the world, so the camera sees the finger as mounted on the hand).
    ///
    /// # Errors
    /// A finger index out of range, pulls of the wrong length, invalid options, or a static
    /// solve that fails.
    pub fn location_bounds(
        &mut self,
        finger: usize,
        pulls: &[Real],
        gravity_in_hand: Vector3,
        options: &BoundOptions,
    ) -> Result<Vec<PlaceBound>, PhysicsError> {
        options.validate()?;
        self.with_bound_observation(finger, pulls, gravity_in_hand, |inverse, obs, hf| {
            let rest = hf.model.mesh().vertices();
            Ok(inverse
                .location_bounds(obs, options)?
                .into_iter()
                .map(|(vertex, [along_m, around_m, force_sd_n])| PlaceBound {
                    vertex,
                    rest_in_finger: rest[vertex as usize],
                    along_m,
                    around_m,
                    force_sd_n,
                })
                .collect())
        })
    }
}

/// Median and 90th percentile of a quantity over a set of places.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    /// The median.
    pub median: Real,
    /// The 90th percentile.
    pub p90: Real,
}

impl Spread {
    /// Nearest-rank quantiles of `values` (infinite values sort last; NaN for none).
    pub fn of(values: &[Real]) -> Self {
        Self {
            median: quantile(values, 0.5),
            p90: quantile(values, 0.9),
        }
    }
}

/// The `q` quantile of `values` by nearest rank (infinite values sort last; NaN for none).
pub fn quantile(values: &[Real], q: Real) -> Real {
    if values.is_empty() {
        return Real::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(Real::total_cmp);
    v[((q * (v.len() - 1) as Real).round() as usize).min(v.len() - 1)]
}

/// The regions a bound is summarised over: name and heights as fractions of the finger's
/// length (the tip includes the cap).
pub const BOUND_REGIONS: [(&str, Real, Real); 3] = [
    ("tip", 0.8, 1.0),
    ("middle", 0.4, 0.7),
    ("base", 0.12, 0.35),
];

/// The bound over one region of a finger.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegionBound {
    /// `tip`, `middle` or `base` ([`BOUND_REGIONS`]).
    pub region: &'static str,
    /// The region's lowest height, a fraction of the finger's length.
    pub z_from: Real,
    /// Its highest height.
    pub z_to: Real,
    /// Movable surface vertices in the region.
    pub vertices: usize,
    /// Of those, the ones whose bound is infinite (the markers do not determine a press there).
    pub unobservable: usize,
    /// Along-the-axis bound, mm.
    pub along_mm: Spread,
    /// Around-the-axis bound, mm.
    pub around_mm: Spread,
    /// Force-magnitude bound, newtons.
    pub force_sd_n: Spread,
}

/// The bounds of a finger of `length_m` summarised over [`BOUND_REGIONS`].
pub fn region_bounds(bounds: &[PlaceBound], length_m: Real) -> Vec<RegionBound> {
    BOUND_REGIONS
        .iter()
        .map(|&(region, lo, hi)| {
            let inside: Vec<&PlaceBound> = bounds
                .iter()
                .filter(|b| (lo..=hi).contains(&(b.rest_in_finger.z / length_m)))
                .collect();
            let spread = |f: fn(&PlaceBound) -> Real| {
                Spread::of(&inside.iter().map(|b| f(b)).collect::<Vec<_>>())
            };
            RegionBound {
                region,
                z_from: lo,
                z_to: hi,
                vertices: inside.len(),
                unobservable: inside
                    .iter()
                    .filter(|b| !(b.along_m.is_finite() && b.around_m.is_finite()))
                    .count(),
                along_mm: spread(|b| b.along_m * 1e3),
                around_mm: spread(|b| b.around_m * 1e3),
                force_sd_n: spread(|b| b.force_sd_n),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square of side `s` in the plane z = `z` (camera frame), facing the camera (normals
    /// toward −z), as two triangles; the vertices in the order of `faces`.
    fn square(s: Real, z: Real) -> (Vec<Point3>, Vec<Vector3>, Vec<[u32; 3]>) {
        let h = s / 2.0;
        let points = vec![
            Point3::new(-h, -h, z),
            Point3::new(h, -h, z),
            Point3::new(h, h, z),
            Point3::new(-h, h, z),
        ];
        (points, vec![-Vector3::z(); 4], vec![[0, 2, 1], [0, 3, 2]])
    }

    /// On the optical axis a surface element facing the camera at range z covers fx·fy / z²
    /// pixels per unit area; one that faces away, lies behind another, is out of range or too
    /// oblique is not seen.
    #[test]
    fn what_the_camera_sees_and_how_many_pixels() {
        let model = DepthBoundModel {
            hand_from_camera: Iso3::identity(),
            ..DepthBoundModel::default()
        };
        let (points, normals, faces) = square(0.002, 0.05);
        let seen = model.visible_vertices(&Iso3::identity(), &points, &normals, &faces);
        assert_eq!(seen.len(), 4);
        let k = &model.intrinsics;
        for s in &seen {
            let p = points[s.vertex as usize];
            let len = p.coords.norm();
            // cos θ = z / ℓ for a plane facing the axis: fx·fy·(z/ℓ)·ℓ / z³ = fx·fy / z².
            let expected = k.fx * k.fy / (p.z * p.z);
            assert!((s.pixels_per_m2 / expected - 1.0).abs() < 1e-12, "{s:?}");
            assert!((s.depth_m - 0.05).abs() < 1e-15 && len > p.z);
        }
        // Facing away.
        let away: Vec<Vector3> = normals.iter().map(|n| -n).collect();
        assert!(
            model
                .visible_vertices(&Iso3::identity(), &points, &away, &faces)
                .is_empty()
        );
        // Behind a larger square nearer the camera: hidden; in front of it: seen.
        let (near, near_n, near_f) = square(0.01, 0.04);
        let mut all = points.clone();
        all.extend(&near);
        let mut all_n = normals.clone();
        all_n.extend(&near_n);
        let mut all_f = faces.clone();
        all_f.extend(near_f.iter().map(|f| f.map(|i| i + 4)));
        let seen = model.visible_vertices(&Iso3::identity(), &all, &all_n, &all_f);
        assert_eq!(
            seen.iter().map(|s| s.vertex).collect::<Vec<_>>(),
            vec![4, 5, 6, 7]
        );
        // Nearer than the camera's minimum range.
        let (close, close_n, close_f) = square(0.002, 0.005);
        assert!(
            model
                .visible_vertices(&Iso3::identity(), &close, &close_n, &close_f)
                .is_empty()
        );
        // Seen at 89° from its normal, past the 85° grazing limit.
        let tilt = Iso3::rotation(Vector3::x() * 89f64.to_radians());
        let tilted: Vec<Point3> = points
            .iter()
            .map(|p| tilt * (p - Vector3::new(0.0, 0.0, 0.05)) + Vector3::new(0.0, 0.0, 0.05))
            .collect();
        let tilted_n: Vec<Vector3> = normals.iter().map(|n| tilt * n).collect();
        assert!(
            model
                .visible_vertices(&Iso3::identity(), &tilted, &tilted_n, &faces)
                .is_empty()
        );
    }

    /// A model that observes nothing, or a depth model with bad figures, is refused by name.
    #[test]
    fn bad_bound_options_are_refused() {
        let nothing = BoundOptions {
            markers: false,
            ..BoundOptions::default()
        };
        assert!(
            nothing
                .validate()
                .unwrap_err()
                .to_string()
                .contains("markers")
        );
        for (model, name) in [
            (
                DepthBoundModel {
                    noise: DepthNoise {
                        sigma_base_m: -1e-3,
                        ..DepthNoise::default()
                    },
                    ..DepthBoundModel::default()
                },
                "noise.sigma_base_m",
            ),
            (
                DepthBoundModel {
                    grazing_deg: Real::NAN,
                    ..DepthBoundModel::default()
                },
                "grazing_deg",
            ),
            (
                DepthBoundModel {
                    max_range_m: 0.005,
                    ..DepthBoundModel::default()
                },
                "max_range_m",
            ),
            (
                DepthBoundModel {
                    noise: DepthNoise {
                        sigma_base_m: 0.0,
                        sigma_per_m2: 0.0,
                        correlated_sigma_m: 0.0,
                        quantum_m: 0.0,
                    },
                    ..DepthBoundModel::default()
                },
                "bounds nothing",
            ),
        ] {
            let options = BoundOptions {
                depth: Some(model),
                ..BoundOptions::default()
            };
            let err = options.validate().unwrap_err().to_string();
            assert!(err.contains(name), "{err}");
        }
        // The harsher noise is harsher in every part.
        let d = DepthBoundModel::default();
        let h = d.harsher();
        assert_eq!((h.intrinsics, h.min_range_m), (d.intrinsics, d.min_range_m));
        assert!(h.noise.pixel_variance(0.05) > d.noise.pixel_variance(0.05));
        assert!(h.noise.correlated_sigma_m > d.noise.correlated_sigma_m);
        assert_eq!(h.noise.quantum_m, 0.001);
    }
}
