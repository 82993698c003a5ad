//! Tendon routes through the finger body.

use serde::{Deserialize, Serialize};

use super::params::FingerParams;
use crate::math::{Point3, Real};

/// A tendon's path through the finger body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TendonRoute {
    /// Polyline from the base (first point) to the anchor (last point), in the finger frame.
    pub points_in_finger: Vec<Point3>,
    /// Index (within the same finger) of the antagonistic tendon.
    pub antagonist: usize,
}

impl TendonRoute {
    /// Length of the polyline.
    pub fn length(&self) -> Real {
        self.points_in_finger
            .windows(2)
            .map(|w| (w[1] - w[0]).norm())
            .sum()
    }
}

/// Four straight tendon routes at `tendon_offset_ratio` of the local radius, from the base plane
/// to the start of the tip cap, in the ±x and ±y directions.
pub(super) fn tendon_routes(params: &FingerParams) -> Vec<TendonRoute> {
    let dirs = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)];
    let antagonist = [1, 0, 3, 2];
    let segments = 16;
    let z_end = params.cap_start_z();
    dirs.iter()
        .zip(antagonist)
        .map(|(&(dx, dy), antagonist)| {
            let points_in_finger = (0..=segments)
                .map(|s| {
                    let z = z_end * s as Real / segments as Real;
                    let rho = params.tendon_offset_ratio * params.radius_at(z);
                    Point3::new(dx * rho, dy * rho, z)
                })
                .collect();
            TendonRoute {
                points_in_finger,
                antagonist,
            }
        })
        .collect()
}
