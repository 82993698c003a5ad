//! A plane fitted to 3-D points by RANSAC with a least-squares refit on the inliers, as
//! `moe-touch plane` reports it.

use moe_geom::{Point3, RansacConfig, Real, fit_plane_ransac};
use serde::Serialize;

use crate::error::LabError;

/// The `moe-touch plane --json` report. Its fields are in alphabetical order, the order the
/// report has always had.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlaneReport {
    /// Indices of the points within the threshold of the plane, ascending.
    pub inliers: Vec<usize>,
    /// Samples drawn before the fit stopped.
    pub iterations: usize,
    /// The unit normal `n`.
    pub normal: [Real; 3],
    /// Number of inliers.
    pub num_inliers: usize,
    /// The offset `d`, metres (`n·x + d = 0` on the plane).
    pub offset_m: Real,
    /// Number of points.
    pub points: usize,
    /// RMS distance of the inliers to the plane, metres.
    pub rms_m: Real,
    /// Seed of the sampling.
    pub seed: u64,
    /// Inlier distance, metres.
    pub threshold_m: Real,
}

/// Fits a plane to `points`.
///
/// # Errors
/// [`moe_geom::GeomError`] for fewer than 3 points, non-finite or collinear points, or a
/// configuration out of range.
pub fn fit_plane(points: &[Point3], config: &RansacConfig) -> Result<PlaneReport, LabError> {
    let fit = fit_plane_ransac(points, config)?;
    Ok(PlaneReport {
        num_inliers: fit.inliers.len(),
        inliers: fit.inliers,
        iterations: fit.iterations,
        normal: fit.normal.into(),
        offset_m: fit.offset,
        points: points.len(),
        rms_m: fit.rms_m,
        seed: config.seed,
        threshold_m: config.distance_threshold_m,
    })
}

impl PlaneReport {
    /// The one line `moe-touch plane` prints.
    pub fn line(&self) -> String {
        let [x, y, z] = self.normal;
        format!(
            "plane: n = ({x:.6}, {y:.6}, {z:.6}), d = {:.6} m (n·x + d = 0); {} of {} points \
             within {} m, RMS {:.3} mm; {} samples",
            self.offset_m,
            self.num_inliers,
            self.points,
            self.threshold_m,
            1e3 * self.rms_m,
            self.iterations
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_a_plane_are_all_inliers_and_the_line_names_the_plane() {
        let points: Vec<Point3> = (0..20)
            .map(|k| Point3::new(f64::from(k % 5) * 0.01, f64::from(k / 5) * 0.01, 0.1))
            .collect();
        let report = fit_plane(&points, &RansacConfig::default()).unwrap();
        assert_eq!(report.num_inliers, 20);
        assert!((report.normal[2].abs() - 1.0).abs() < 1e-12, "{report:?}");
        assert!(
            report.line().starts_with("plane: n = ("),
            "{}",
            report.line()
        );
        assert!(fit_plane(&points[..2], &RansacConfig::default()).is_err());
    }
}
