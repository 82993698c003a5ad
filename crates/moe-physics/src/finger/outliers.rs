//! Outliers: a marker the best fit leaves far off is left out and the loads searched again.

use moe_geom::Point3;

use super::compliance::Linear;
use super::free::StaticStart;
use super::gauss_newton::Solved;
use super::{Baseline, FingerInverse, FingerObservation};
use crate::error::PhysicsError;

impl FingerInverse {
    /// The marker (slot) that nodes `x` leave furthest from its observation, when that is more
    /// than `outlier_sigma` standard deviations and a marker can be spared (`observed` above
    /// the fewest the estimator works with).
    pub(super) fn outlier(
        &self,
        x: &[Point3],
        markers: &[Option<Point3>],
        observed: usize,
    ) -> Option<usize> {
        let limit = self.config.outlier_sigma * self.config.marker_sigma_m;
        if limit.is_nan() || limit <= 0.0 || observed <= self.config.min_markers {
            return None;
        }
        markers
            .iter()
            .zip(&self.markers)
            .enumerate()
            .filter_map(|(slot, (m, &v))| {
                m.map(|p| (slot, (p - self.mech.surface_position(x, v)).norm()))
            })
            .filter(|&(_, d)| d > limit)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(slot, _)| slot)
    }

    /// Searches the loads again from the static free shape with marker slot `worst` left out;
    /// returns the baseline without it, the fit and its linear model.
    pub(super) fn search_without_marker(
        &mut self,
        obs: &FingerObservation<'_>,
        start: &StaticStart,
        worst: usize,
        base: &Baseline,
        solves: &mut usize,
    ) -> Result<(Baseline, Solved, Linear), PhysicsError> {
        let mut kept = start.markers.clone();
        kept[worst] = None;
        let kobs = FingerObservation {
            markers: &kept,
            depth: &start.depth,
            ..*obs
        };
        let chi0 = self.residual_sq(&start.x, &kobs);
        let fresh = Solved {
            x: start.x.clone(),
            loads: Vec::new(),
            chi: chi0,
        };
        let (state, lin) = self.search_loads(&kobs, fresh, solves)?;
        let base = Baseline {
            chi0,
            observed: base.observed - 1,
            n_obs: base.n_obs - 3.0,
            depth: base.depth,
        };
        Ok((base, state, lin))
    }
}
