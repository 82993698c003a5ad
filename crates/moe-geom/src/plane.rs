//! Plane fitting by RANSAC with a least-squares refit on the inliers (the behaviour of Open3D's
//! `segment_plane`): the surface a hand has touched, from its contact points.
//!
//! Each iteration draws three distinct points with a seeded generator, takes the plane through
//! them, and counts the points within the distance threshold; the plane with the most inliers
//! wins (ties: the lower RMS distance of its inliers). The iterations stop early once the chance
//! that a better sample was missed is below `1 − probability`, given the best inlier fraction so
//! far (the standard bound `k = log(1 − p) / log(1 − w³)`). The winner is refitted by least
//! squares on its inliers (the normal is the direction of least variance), and the inliers and
//! their RMS distance are recomputed for the refitted plane.

use nalgebra::SymmetricEigen;
use serde::{Deserialize, Serialize};

use crate::error::GeomError;
use crate::math::{Matrix3, Point3, Real, Vector3, is_finite_point};
use crate::rng::SeededRng;

/// The most iterations a fit may ask for.
pub const MAX_RANSAC_ITERATIONS: usize = 10_000_000;

/// Parameters of [`fit_plane_ransac`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RansacConfig {
    /// A point is an inlier when its distance to the plane is at most this, metres. Default
    /// 2 mm (a few times the contact estimates' noise).
    pub distance_threshold_m: Real,
    /// Most samples drawn. Default 1000.
    pub iterations: usize,
    /// Confidence at which the sampling stops early, in (0, 1]; 1 never stops early. Default
    /// 0.999999.
    pub probability: Real,
    /// Seed of the sampling.
    pub seed: u64,
}

impl Default for RansacConfig {
    fn default() -> Self {
        Self {
            distance_threshold_m: 0.002,
            iterations: 1000,
            probability: 0.999_999,
            seed: 0,
        }
    }
}

impl RansacConfig {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`GeomError::InvalidParameter`] naming the parameter.
    pub fn validate(&self) -> Result<(), GeomError> {
        let t = self.distance_threshold_m;
        if !(t.is_finite() && t > 0.0) {
            return Err(GeomError::InvalidParameter {
                name: "distance_threshold_m",
                value: t,
                reason: "must be finite and positive",
            });
        }
        if self.iterations == 0 || self.iterations > MAX_RANSAC_ITERATIONS {
            return Err(GeomError::InvalidParameter {
                name: "iterations",
                value: self.iterations as Real,
                reason: "must be between 1 and 10,000,000",
            });
        }
        let p = self.probability;
        if !(p > 0.0 && p <= 1.0) {
            return Err(GeomError::InvalidParameter {
                name: "probability",
                value: p,
                reason: "must be in (0, 1]",
            });
        }
        Ok(())
    }
}

/// A fitted plane `n·x + d = 0`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaneFit {
    /// Unit normal `n`. Its sign is chosen so that its largest component (in magnitude) is
    /// positive; see [`PlaneFit::oriented_toward`] for a side.
    pub normal: Vector3,
    /// Offset `d`, metres: `n·x + d` is the signed distance of `x`.
    pub offset: Real,
    /// Indices of the points within the threshold of the plane, ascending.
    pub inliers: Vec<usize>,
    /// RMS distance of the inliers to the plane, metres.
    pub rms_m: Real,
    /// Samples drawn before the fit stopped.
    pub iterations: usize,
}

impl PlaneFit {
    /// Signed distance of `p` to the plane (positive on the normal's side), metres.
    pub fn signed_distance(&self, p: &Point3) -> Real {
        self.normal.dot(&p.coords) + self.offset
    }

    /// The same plane with its normal pointing to the side of `p` (unchanged when `p` lies on
    /// the plane).
    pub fn oriented_toward(mut self, p: &Point3) -> Self {
        if self.signed_distance(p) < 0.0 {
            self.normal = -self.normal;
            self.offset = -self.offset;
        }
        self
    }
}

/// Centroid and the eigen-decomposition of the scatter of `points[idx]`, eigenvalues ascending.
fn principal_axes(
    points: &[Point3],
    idx: impl Iterator<Item = usize> + Clone,
) -> (Point3, [Real; 3], Matrix3) {
    let n = idx.clone().count().max(1) as Real;
    let centroid = idx.clone().map(|i| points[i].coords).sum::<Vector3>() / n;
    let mut scatter = Matrix3::zeros();
    for i in idx {
        let d = points[i].coords - centroid;
        scatter += d * d.transpose();
    }
    let eig = SymmetricEigen::new(scatter / n);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let values = order.map(|k| eig.eigenvalues[k]);
    let vectors = Matrix3::from_columns(&order.map(|k| eig.eigenvectors.column(k).into_owned()));
    (Point3::from(centroid), values, vectors)
}

/// The sign convention of [`PlaneFit::normal`].
fn canonical(n: Vector3) -> Vector3 {
    let k = n.iamax();
    if n[k] < 0.0 { -n } else { n }
}

/// Inliers of the plane `(n, d)` and the sum of their squared distances.
fn inliers_of(points: &[Point3], n: &Vector3, d: Real, threshold: Real) -> (Vec<usize>, Real) {
    let mut inliers = Vec::new();
    let mut sq = 0.0;
    for (i, p) in points.iter().enumerate() {
        let dist = n.dot(&p.coords) + d;
        if dist.abs() <= threshold {
            inliers.push(i);
            sq += dist * dist;
        }
    }
    (inliers, sq)
}

/// Fits a plane to `points` by RANSAC and a least-squares refit (see the module documentation).
///
/// # Errors
/// [`GeomError::TooFewPoints`] below 3 points, [`GeomError::NonFinitePoint`] (the first such
/// point), [`GeomError::DegeneratePoints`] when all points are collinear or coincide,
/// [`GeomError::InvalidParameter`] for a bad config.
pub fn fit_plane_ransac(points: &[Point3], config: &RansacConfig) -> Result<PlaneFit, GeomError> {
    config.validate()?;
    if points.len() < 3 {
        return Err(GeomError::TooFewPoints {
            what: "plane points",
            needed: 3,
            got: points.len(),
        });
    }
    if let Some(index) = points.iter().position(|p| !is_finite_point(p)) {
        return Err(GeomError::NonFinitePoint {
            what: "plane points",
            index,
        });
    }
    let (_, spread, _) = principal_axes(points, 0..points.len());
    if spread[1].is_nan() || spread[1] <= 1e-12 * spread[2] {
        return Err(GeomError::DegeneratePoints {
            what: "plane points",
            reason: "all points are collinear or coincide",
        });
    }
    let scale = spread[2].sqrt();
    let threshold = config.distance_threshold_m;
    let n_points = points.len();
    let mut rng = SeededRng::new(config.seed);
    let mut best: Option<(Vector3, Real, usize, Real)> = None;
    let mut needed = config.iterations;
    let mut drawn = 0;
    while drawn < needed {
        drawn += 1;
        let i = rng.below(n_points as u64) as usize;
        let mut j = rng.below(n_points as u64 - 1) as usize;
        if j >= i {
            j += 1;
        }
        let mut k = rng.below(n_points as u64 - 2) as usize;
        let (lo, hi) = (i.min(j), i.max(j));
        if k >= lo {
            k += 1;
        }
        if k >= hi {
            k += 1;
        }
        let normal = (points[j] - points[i]).cross(&(points[k] - points[i]));
        let len = normal.norm();
        if len.is_nan() || len <= 1e-9 * scale * scale {
            continue;
        }
        let n = normal / len;
        let d = -n.dot(&points[i].coords);
        let (inliers, sq) = inliers_of(points, &n, d, threshold);
        let count = inliers.len();
        let better = match best {
            None => true,
            Some((_, _, c, s)) => count > c || (count == c && sq < s),
        };
        if better {
            best = Some((n, d, count, sq));
            let w = count as Real / n_points as Real;
            if config.probability < 1.0 {
                let miss = 1.0 - w * w * w;
                if miss <= 0.0 {
                    needed = drawn;
                } else {
                    let k = (1.0 - config.probability).ln() / miss.ln();
                    if k.is_finite() {
                        needed = needed.min((k.ceil() as usize).max(drawn));
                    }
                }
            }
        }
    }
    let Some((n, d, _, _)) = best else {
        return Err(GeomError::DegeneratePoints {
            what: "plane points",
            reason: "no sample of three points spanned a plane",
        });
    };
    // Least-squares refit on the RANSAC inliers (at least the three sampled points).
    let (first, _) = inliers_of(points, &n, d, threshold);
    let (centroid, _, axes) = principal_axes(points, first.iter().copied());
    let normal = canonical(axes.column(0).into_owned().normalize());
    let offset = -normal.dot(&centroid.coords);
    let (inliers, sq) = inliers_of(points, &normal, offset, threshold);
    let rms_m = if inliers.is_empty() {
        0.0
    } else {
        (sq / inliers.len() as Real).sqrt()
    };
    Ok(PlaneFit {
        normal,
        offset,
        inliers,
        rms_m,
        iterations: drawn,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `inliers` noisy points on the plane through `origin` with normal `n` (within ±20 cm),
    /// then `outliers` points uniform in a 40 cm cube around it; and which points are inliers.
    fn noisy_plane(
        n: &Vector3,
        origin: &Point3,
        inliers: usize,
        outliers: usize,
        noise_m: Real,
        seed: u64,
    ) -> (Vec<Point3>, Vec<bool>) {
        let mut rng = SeededRng::new(seed);
        let n = n.normalize();
        let u = n.cross(&Vector3::new(0.3, 0.5, 0.8)).normalize();
        let v = n.cross(&u);
        let mut points = Vec::new();
        for _ in 0..inliers {
            points.push(
                origin
                    + u * rng.uniform_range(-0.2, 0.2)
                    + v * rng.uniform_range(-0.2, 0.2)
                    + n * (noise_m * rng.normal()),
            );
        }
        for _ in 0..outliers {
            let mut c = || rng.uniform_range(-0.2, 0.2);
            points.push(origin + Vector3::new(c(), c(), c()));
        }
        let truth = (0..inliers + outliers).map(|k| k < inliers).collect();
        (points, truth)
    }

    fn angle_deg(a: &Vector3, b: &Vector3) -> Real {
        a.normalize()
            .dot(&b.normalize())
            .abs()
            .min(1.0)
            .acos()
            .to_degrees()
    }

    #[test]
    fn recovers_a_known_plane_among_half_outliers() {
        let n_true = Vector3::new(0.0, -0.5, 0.866);
        let origin = Point3::new(0.01, -0.02, 0.03);
        let (points, truth) = noisy_plane(&n_true, &origin, 300, 300, 0.0005, 7);
        assert_eq!(truth.iter().filter(|t| **t).count(), 300);
        let config = RansacConfig {
            distance_threshold_m: 0.002,
            ..RansacConfig::default()
        };
        let fit = fit_plane_ransac(&points, &config).unwrap();
        assert!(
            angle_deg(&fit.normal, &n_true) < 0.5,
            "{}",
            angle_deg(&fit.normal, &n_true)
        );
        assert!((fit.normal.norm() - 1.0).abs() < 1e-12);
        assert!(fit.signed_distance(&origin).abs() < 5e-4);
        // Every true inlier found; outliers within the 2 mm slab are few (a 4 mm slab of a
        // 40 cm cube holds about 1 % of them).
        let found_true = fit.inliers.iter().filter(|&&i| truth[i]).count();
        let found_false = fit.inliers.len() - found_true;
        assert!(found_true >= 299, "{found_true} of 300 inliers");
        assert!(found_false <= 10, "{found_false} outliers taken");
        assert!(fit.rms_m < 0.001 && fit.rms_m > 0.0002, "{}", fit.rms_m);
        assert!(fit.iterations < config.iterations, "stopped early");
        // The same seed gives the same plane; another seed the same plane to within noise.
        assert_eq!(fit_plane_ransac(&points, &config).unwrap(), fit);
        let other = fit_plane_ransac(&points, &RansacConfig { seed: 9, ..config }).unwrap();
        assert!(angle_deg(&other.normal, &fit.normal) < 0.1);
    }

    #[test]
    fn an_exact_plane_is_exact_and_orientation_is_chosen() {
        let points: Vec<Point3> = (0..20)
            .map(|k| Point3::new(0.01 * (k % 5) as Real, 0.013 * (k / 5) as Real, 0.5))
            .collect();
        let fit = fit_plane_ransac(&points, &RansacConfig::default()).unwrap();
        assert!((fit.normal - Vector3::z()).norm() < 1e-12);
        assert!((fit.offset + 0.5).abs() < 1e-12);
        assert_eq!(fit.inliers, (0..20).collect::<Vec<_>>());
        let down = fit.clone().oriented_toward(&Point3::new(0.0, 0.0, 0.0));
        assert!((down.normal + Vector3::z()).norm() < 1e-12 && (down.offset - 0.5).abs() < 1e-12);
        assert!(down.signed_distance(&Point3::origin()) > 0.0);
        let up = fit.clone().oriented_toward(&Point3::new(0.0, 0.0, 1.0));
        assert_eq!(up, fit);
    }

    #[test]
    fn bad_input_is_a_typed_error() {
        let c = RansacConfig::default();
        let two = [Point3::origin(), Point3::new(1.0, 0.0, 0.0)];
        assert!(matches!(
            fit_plane_ransac(&two, &c),
            Err(GeomError::TooFewPoints {
                needed: 3,
                got: 2,
                ..
            })
        ));
        let line: Vec<Point3> = (0..10)
            .map(|k| Point3::new(k as Real, 2.0 * k as Real, 0.0))
            .collect();
        assert!(matches!(
            fit_plane_ransac(&line, &c),
            Err(GeomError::DegeneratePoints { .. })
        ));
        let same = vec![Point3::new(1.0, 1.0, 1.0); 5];
        assert!(matches!(
            fit_plane_ransac(&same, &c),
            Err(GeomError::DegeneratePoints { .. })
        ));
        let mut nan = line.clone();
        nan[1].y = 5.0;
        nan[4].z = Real::NAN;
        assert!(matches!(
            fit_plane_ransac(&nan, &c),
            Err(GeomError::NonFinitePoint { index: 4, .. })
        ));
        let plane: Vec<Point3> = (0..9)
            .map(|k| Point3::new((k % 3) as Real, (k / 3) as Real, 0.0))
            .collect();
        for bad in [
            RansacConfig {
                distance_threshold_m: 0.0,
                ..c
            },
            RansacConfig {
                distance_threshold_m: Real::NAN,
                ..c
            },
            RansacConfig { iterations: 0, ..c },
            RansacConfig {
                iterations: MAX_RANSAC_ITERATIONS + 1,
                ..c
            },
            RansacConfig {
                probability: 0.0,
                ..c
            },
        ] {
            assert!(matches!(
                fit_plane_ransac(&plane, &bad),
                Err(GeomError::InvalidParameter { .. })
            ));
        }
    }
}
