//! The multi-finger estimator: occlusion, warm start, reports and bad input.

use moe_arap::{ArapError, MultiShapeEstimator, ShapeConfig};
use moe_geom::{GeomError, Point3, Real};

use crate::{bent_keypoints, two_finger_hand};

#[test]
fn rest_keypoints_give_the_rest_hand_and_handles_are_the_marker_vertices() {
    let hand = two_finger_hand();
    let mut est = MultiShapeEstimator::new(hand.clone(), ShapeConfig::default()).unwrap();
    let out = est.estimate(&hand.rest_keypoints()).unwrap();
    for (i, f) in hand.fingers().iter().enumerate() {
        let rest = hand.rest_vertices_in_hand(i);
        let err = out.shape.fingers[i]
            .iter()
            .zip(&rest)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        assert!(err < 1e-12, "finger {i}: {err:e}");
        let expected: Vec<Option<u32>> =
            f.model.marker_vertices().iter().map(|&v| Some(v)).collect();
        assert_eq!(est.handle_vertices(i), expected.as_slice());
        assert!(!out.reports[i].all_markers_missing);
    }
}

#[test]
fn occluded_markers_are_dropped_per_frame_without_error() {
    let hand = two_finger_hand();
    let tip = 40f64.to_radians();
    let options = ShapeConfig {
        iterations: 20,
        ..ShapeConfig::default()
    };
    let mut est = MultiShapeEstimator::new(hand.clone(), options).unwrap();
    let first = est.estimate(&bent_keypoints(&hand, tip, &[])).unwrap();
    let handles: Vec<_> = (0..2).map(|i| est.handle_vertices(i).to_vec()).collect();
    for missing in [vec![], vec![3], vec![0, 6], vec![1, 2, 5]] {
        let out = est.estimate(&bent_keypoints(&hand, tip, &missing)).unwrap();
        for (i, finger_handles) in handles.iter().enumerate() {
            let r = &out.reports[i];
            assert_eq!(r.iterations, 20);
            assert_eq!(r.markers_used.len(), 7 - missing.len());
            assert!(missing.iter().all(|m| !r.markers_used.contains(m)));
            // Handle vertices were attached when the estimator was built and kept.
            assert_eq!(est.handle_vertices(i), finger_handles.as_slice());
            // Visible markers sit exactly on their keypoints.
            let kp = bent_keypoints(&hand, tip, &missing);
            for &m in &r.markers_used {
                let v = finger_handles[m].unwrap() as usize;
                let err = (out.shape.fingers[i][v] - kp.fingers[i][m].unwrap()).norm();
                assert!(err < 1e-12);
            }
        }
        if missing.is_empty() {
            assert_eq!(out.shape, first.shape);
        }
    }
}

#[test]
fn a_finger_with_every_marker_missing_stays_at_its_start_shape() {
    let hand = two_finger_hand();
    let tip = 30f64.to_radians();
    let mut kp = bent_keypoints(&hand, tip, &[]);
    // From rest: finger 1 fully occluded stays at rest, finger 0 is solved.
    let mut est = MultiShapeEstimator::unattached(hand.clone(), ShapeConfig::default()).unwrap();
    kp.fingers[1] = vec![None; 7];
    let out = est.estimate(&kp).unwrap();
    assert!(out.reports[1].all_markers_missing && !out.reports[0].all_markers_missing);
    assert_eq!(out.reports[1].iterations, 0);
    assert_eq!(out.shape.fingers[1], hand.rest_vertices_in_hand(1));
    assert_eq!(est.handle_vertices(1), &[None; 7]);

    // Warm start: a fully occluded frame keeps the previous frame's shape.
    let warm = ShapeConfig {
        warm_start: true,
        iterations: 30,
        ..ShapeConfig::default()
    };
    let mut est = MultiShapeEstimator::new(hand.clone(), warm).unwrap();
    let seen = est.estimate(&bent_keypoints(&hand, tip, &[])).unwrap();
    assert!(!seen.reports[0].warm_started);
    let hidden = est
        .estimate(&bent_keypoints(&hand, tip, &[0, 1, 2, 3, 4, 5, 6]))
        .unwrap();
    for i in 0..2 {
        assert!(hidden.reports[i].all_markers_missing && hidden.reports[i].warm_started);
        assert_eq!(hidden.shape.fingers[i], seen.shape.fingers[i]);
    }
    // The next visible frame continues from there.
    let again = est.estimate(&bent_keypoints(&hand, tip, &[])).unwrap();
    assert!(again.reports[0].warm_started);
    let last = again.reports[0].energy.last().copied().unwrap();
    assert!(last <= seen.reports[0].energy.last().copied().unwrap() * 1.01);
}

#[test]
fn bad_keypoints_give_typed_errors() {
    let hand = two_finger_hand();
    let mut est = MultiShapeEstimator::new(hand.clone(), ShapeConfig::default()).unwrap();
    let mut kp = hand.rest_keypoints();
    kp.fingers[1][4] = Some(Point3::new(0.0, Real::NAN, 0.0));
    assert_eq!(
        est.estimate(&kp).unwrap_err(),
        ArapError::NonFiniteKeypoint {
            finger: 1,
            marker: 4
        }
    );
    kp.fingers[1][4] = Some(Point3::new(Real::INFINITY, 0.0, 0.0));
    assert!(matches!(
        est.estimate(&kp),
        Err(ArapError::NonFiniteKeypoint {
            finger: 1,
            marker: 4
        })
    ));
    let mut short = hand.rest_keypoints();
    short.fingers[0].pop();
    assert!(matches!(
        est.estimate(&short),
        Err(ArapError::Geom(GeomError::LengthMismatch { .. }))
    ));
    let bad = ShapeConfig {
        alpha: Real::NAN,
        ..ShapeConfig::default()
    };
    assert!(matches!(
        MultiShapeEstimator::new(hand.clone(), bad),
        Err(ArapError::InvalidConfig { name: "alpha", .. })
    ));
    // A non-manifold mesh is refused when the mesh is built: three faces on one edge.
    let v = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
        Point3::new(0.0, -1.0, 0.0),
        Point3::new(0.0, 0.0, 1.0),
    ];
    let err = moe_geom::TriMesh::new(v, vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]]).unwrap_err();
    let err: ArapError = err.into();
    assert!(
        matches!(err, ArapError::Geom(GeomError::NonManifoldEdge { .. })),
        "{err}"
    );
}
