//! Integration tests of `moe-arap` on the parametric hand.

mod arc;
mod depth;
mod estimator;

use moe_geom::{FingerParams, HandKeypoints, HandModel, HandPreset, Point3, Real};

/// The default two-finger hand.
pub(crate) fn two_finger_hand() -> HandModel {
    HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).expect("preset")
}

/// Maps a point of the straight finger (finger frame) onto a constant-curvature bend in the
/// xz-plane toward +x: the neutral axis (x = y = 0) becomes an arc of curvature `kappa`, and the
/// cross-section at height `z` is rotated by `kappa · z` about the y axis.
pub(crate) fn bend(p: &Point3, kappa: Real) -> Point3 {
    let phi = kappa * p.z;
    let rho = 1.0 / kappa;
    let axis = Point3::new(rho * (1.0 - phi.cos()), 0.0, rho * phi.sin());
    axis + moe_geom::Vector3::new(phi.cos(), 0.0, -phi.sin()) * p.x + moe_geom::Vector3::y() * p.y
}

/// Keypoints of every finger bent by `bend` with the tip turned by `tip_angle` (radians); markers
/// listed in `missing` are reported as occluded.
pub(crate) fn bent_keypoints(
    hand: &HandModel,
    tip_angle: Real,
    missing: &[usize],
) -> HandKeypoints {
    let fingers = hand
        .fingers()
        .iter()
        .map(|f| {
            let kappa = tip_angle / FingerParams::default().length_m;
            f.model
                .marker_positions()
                .iter()
                .enumerate()
                .map(|(m, p)| {
                    (!missing.contains(&m))
                        .then(|| f.hand_from_finger.transform_point(&bend(p, kappa)))
                })
                .collect()
        })
        .collect();
    HandKeypoints { fingers }
}
