//! A finger bent into a constant-curvature arc (60° at the tip), reconstructed from its markers
//! (paper App. C's robustness check).
//!
//! Measured with the paper's settings (α = 0.01, 50 iterations from rest): BCD 1.02 mm with all
//! 7 markers and 1.15 mm with markers 0, 2, 4, 6 (max vertex error ≈ 11 mm at the tip's far side:
//! 50 iterations of SR-ARAP are not converged — 1000 give BCD 0.54 mm / 0.57 mm).

use moe_arap::{MultiShapeEstimator, ShapeConfig};
use moe_geom::{FingerParams, bcd};

use crate::{bend, bent_keypoints, two_finger_hand};

/// BCD in millimetres between the estimated shape and the analytic bend, worst finger.
fn arc_error_mm(missing: &[usize]) -> f64 {
    let hand = two_finger_hand();
    let tip = 60f64.to_radians();
    let kappa = tip / FingerParams::default().length_m;
    let mut estimator = MultiShapeEstimator::new(hand.clone(), ShapeConfig::default()).unwrap();
    // Attach every marker to its nearest rest vertex before the bent frame.
    estimator.assign_handles(&hand.rest_keypoints()).unwrap();
    let est = estimator
        .estimate(&bent_keypoints(&hand, tip, missing))
        .unwrap();
    let mut worst: f64 = 0.0;
    for (i, f) in hand.fingers().iter().enumerate() {
        let analytic: Vec<_> = f
            .model
            .mesh()
            .vertices()
            .iter()
            .map(|p| f.hand_from_finger.transform_point(&bend(p, kappa)))
            .collect();
        let d = bcd(&est.shape.fingers[i], &analytic).unwrap() * 1e3;
        let report = &est.reports[i];
        assert_eq!(report.iterations, 50);
        assert_eq!(report.markers_used.len(), 7 - missing.len());
        worst = worst.max(d);
    }
    worst
}

#[test]
fn seven_markers_reconstruct_the_arc_and_four_at_most_double_the_error() {
    let full = arc_error_mm(&[]);
    eprintln!("60° arc, 7 markers: BCD {full:.3} mm");
    assert!(full < 1.5, "BCD with 7 markers {full} mm");
    // The tip marker and every other one along the finger remain: markers 0, 2, 4, 6.
    let four = arc_error_mm(&[1, 3, 5]);
    eprintln!("60° arc, 4 of 7 markers: BCD {four:.3} mm");
    assert!(
        four <= 2.0 * full,
        "4 markers {four} mm vs 7 markers {full} mm"
    );
}
