//! Scoring marker detections against the ground truth of a recorded or simulated episode, and
//! the marker study over the paper's scenes
//! ([`run_marker_study`](crate::markers::run_marker_study)).

use moe_arap::{MultiShapeEstimator, ShapeConfig};
use moe_geom::{HandKeypoints, HandModel, Point3, Real, Transform, bcd};
use moe_record::{EpisodeFrame, EpisodeInfo};
use moe_tendon_sim::camera::{RenderItem, RgbdCamera};
use serde::Serialize;

use crate::LabError;
use moe_touch::perception::{MarkerDetection, MarkerDetector};

mod study;

pub use study::{
    MARKER_SCENES, MarkerSceneView, MarkerStudyOptions, MarkerStudyReport, PooledPlateMarkers,
    marker_scene, pool_plates, run_marker_study,
};

/// A reported marker within this distance of its own true position is a correct detection;
/// within it of another marker's true position, an identity swap; otherwise a false detection.
pub const MATCH_RADIUS_M: Real = 0.003;

/// Surfaces closer than this to a marker vertex along its line of sight do not hide it.
pub const VISIBILITY_TOLERANCE_M: Real = 3e-4;

/// Running tallies of detections against the truth.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MarkerScore {
    frames: usize,
    visible: usize,
    detected: usize,
    detected_hidden: usize,
    errors_m: Vec<Real>,
    false_detections: usize,
    swaps: usize,
}

/// A detection report: what [`MarkerScore::report`] returns.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerReport {
    /// Frames scored.
    pub frames: usize,
    /// Markers visible in the ground truth (summed over frames).
    pub visible: usize,
    /// Visible markers correctly detected.
    pub detected: usize,
    /// `detected / visible` (1 when nothing is visible).
    pub detection_rate: Real,
    /// Markers correctly detected although their vertex is hidden (part of the patch is seen).
    pub detected_hidden: usize,
    /// Position error of the correct detections, millimetres: mean, 95th percentile, max.
    pub mean_error_mm: Real,
    /// 95th percentile of the position error, millimetres.
    pub p95_error_mm: Real,
    /// Largest position error, millimetres.
    pub max_error_mm: Real,
    /// Reported markers near no true marker.
    pub false_detections: usize,
    /// Reported markers at another marker's true position.
    pub identity_swaps: usize,
}

impl MarkerScore {
    /// Scores one frame: `detected` against the true marker centres `truth` (hand frame, per
    /// finger) of which `visible` are seen by the camera.
    ///
    /// # Errors
    /// [`LabError::InvalidEvaluation`] when the three do not have the same layout.
    pub fn add(
        &mut self,
        detected: &HandKeypoints,
        truth: &[Vec<Point3>],
        visible: &[Vec<bool>],
    ) -> Result<(), LabError> {
        let same_layout = detected.fingers.len() == truth.len()
            && truth.len() == visible.len()
            && detected
                .fingers
                .iter()
                .zip(truth)
                .zip(visible)
                .all(|((d, t), v)| d.len() == t.len() && t.len() == v.len());
        if !same_layout {
            return Err(LabError::InvalidEvaluation {
                reason: "detected keypoints, true markers and visibility differ in layout".into(),
            });
        }
        self.frames += 1;
        for (f, (d, t)) in detected.fingers.iter().zip(truth).enumerate() {
            for (m, p) in d.iter().enumerate() {
                let seen = visible[f][m];
                self.visible += usize::from(seen);
                let Some(p) = p else { continue };
                let own = (p - t[m]).norm();
                if own <= MATCH_RADIUS_M {
                    self.errors_m.push(own);
                    if seen {
                        self.detected += 1;
                    } else {
                        self.detected_hidden += 1;
                    }
                    continue;
                }
                let near_other = truth.iter().enumerate().any(|(g, tg)| {
                    tg.iter()
                        .enumerate()
                        .any(|(n, q)| (g, n) != (f, m) && (p - q).norm() <= MATCH_RADIUS_M)
                });
                if near_other {
                    self.swaps += 1;
                } else {
                    self.false_detections += 1;
                }
            }
        }
        Ok(())
    }

    /// Adds another score's tallies.
    pub fn merge(&mut self, other: &MarkerScore) {
        self.frames += other.frames;
        self.visible += other.visible;
        self.detected += other.detected;
        self.detected_hidden += other.detected_hidden;
        self.errors_m.extend_from_slice(&other.errors_m);
        self.false_detections += other.false_detections;
        self.swaps += other.swaps;
    }

    /// The figures so far.
    pub fn report(&self) -> MarkerReport {
        let mut e = self.errors_m.clone();
        e.sort_by(Real::total_cmp);
        let mean = if e.is_empty() {
            0.0
        } else {
            e.iter().sum::<Real>() / e.len() as Real
        };
        let p95 = if e.is_empty() {
            0.0
        } else {
            e[((0.95 * e.len() as Real).ceil() as usize).clamp(1, e.len()) - 1]
        };
        MarkerReport {
            frames: self.frames,
            visible: self.visible,
            detected: self.detected,
            detection_rate: if self.visible == 0 {
                1.0
            } else {
                self.detected as Real / self.visible as Real
            },
            detected_hidden: self.detected_hidden,
            mean_error_mm: 1e3 * mean,
            p95_error_mm: 1e3 * p95,
            max_error_mm: 1e3 * e.last().copied().unwrap_or(0.0),
            false_detections: self.false_detections,
            identity_swaps: self.swaps,
        }
    }
}

/// The camera of an episode (its intrinsics and mounting; the noise plays no part here).
pub fn episode_camera(info: &EpisodeInfo) -> RgbdCamera {
    RgbdCamera {
        intrinsics: info.camera.into(),
        hand_from_camera: Transform::new(info.hand_from_camera),
        ..RgbdCamera::default()
    }
}

/// Whether the episode has ground truth to score against (true markers and finger meshes).
pub fn has_ground_truth(info: &EpisodeInfo, frame: &EpisodeFrame) -> bool {
    !frame.markers_in_hand.is_empty()
        && frame.markers_in_hand.len() == info.finger_faces.len()
        && frame.finger_vertices_in_hand.len() == info.finger_faces.len()
}

/// Which true markers of an episode frame the camera sees: each marker's line of sight is
/// cast against the frame's true finger meshes and obstacles.
///
/// # Errors
/// A frame without ground truth, or meshes whose faces index past their vertices.
pub fn visible_markers(
    info: &EpisodeInfo,
    frame: &EpisodeFrame,
) -> Result<Vec<Vec<bool>>, LabError> {
    if !has_ground_truth(info, frame) {
        return Err(LabError::InvalidEvaluation {
            reason: "the frame has no ground-truth markers and finger meshes".into(),
        });
    }
    let camera = episode_camera(info);
    let obstacles = crate::episode::obstacles_in_hand(&frame.world_from_hand, &frame.obstacles);
    let mut items: Vec<RenderItem<'_>> = frame
        .finger_vertices_in_hand
        .iter()
        .zip(&info.finger_faces)
        .map(|(v, f)| surface_item(v, f))
        .collect();
    items.extend(
        obstacles
            .iter()
            .zip(&frame.obstacles)
            .map(|(v, o)| surface_item(v, &o.faces)),
    );
    let flat: Vec<Point3> = frame.markers_in_hand.iter().flatten().copied().collect();
    let seen = camera.visible(&items, &flat, VISIBILITY_TOLERANCE_M)?;
    let mut out = Vec::with_capacity(frame.markers_in_hand.len());
    let mut k = 0;
    for m in &frame.markers_in_hand {
        out.push(seen[k..k + m.len()].to_vec());
        k += m.len();
    }
    Ok(out)
}

fn surface_item<'a>(vertices: &'a [Point3], faces: &'a [[u32; 3]]) -> RenderItem<'a> {
    RenderItem {
        vertices_in_hand: vertices,
        faces,
        albedo: [0; 3],
        markers_in_hand: &[],
        marker_radius_m: 0.0,
    }
}

/// Detection and its effect on shape estimation over one episode with ground truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EpisodeMarkerReport {
    /// Scene name from the episode.
    pub scene: String,
    /// Detection against the true markers.
    pub markers: MarkerReport,
    /// SR-ARAP shape BCD from the detected keypoints, mm (mean over frames).
    pub shape_bcd_detected_mm: Real,
    /// SR-ARAP shape BCD from every true marker, mm (mean over frames).
    pub shape_bcd_truth_mm: Real,
    /// SR-ARAP shape BCD from the true markers the camera sees (occluded ones left out), mm:
    /// what a perfect detector would give.
    pub shape_bcd_truth_visible_mm: Real,
    /// Largest per-frame excess of the detected-keypoint BCD over the true-keypoint BCD, mm.
    pub shape_bcd_worst_excess_mm: Real,
    /// Mean detection time per frame, milliseconds (this machine, this build).
    pub detect_ms: Real,
    /// The tallies behind `markers`, to pool several episodes with [`MarkerScore::merge`].
    #[serde(skip)]
    pub score: MarkerScore,
}

/// Runs `detector` over an episode's frames in order (tracks carry from frame to frame) and
/// returns every frame's detection and, when the episode has ground truth, the report:
/// detection against the visible true markers, and SR-ARAP (`shape`) from the detected
/// keypoints against SR-ARAP from every true marker, both scored by shape BCD against the
/// true meshes.
///
/// # Errors
/// Frames whose images do not fit the detector, a hand that is not the episode's, a failing
/// solve.
pub fn evaluate_episode(
    hand: &HandModel,
    info: &EpisodeInfo,
    frames: &[EpisodeFrame],
    detector: &mut MarkerDetector,
    shape: &ShapeConfig,
) -> Result<(Vec<MarkerDetection>, Option<EpisodeMarkerReport>), LabError> {
    check_hand(hand, info)?;
    let truth = frames
        .iter()
        .all(|f| has_ground_truth(info, f))
        .then(|| MultiShapeEstimator::new(hand.clone(), shape.clone()))
        .transpose()?;
    let mut detections = Vec::with_capacity(frames.len());
    let mut score = MarkerScore::default();
    let (mut detected_sum, mut truth_sum, mut worst) = (0.0, 0.0, Real::NEG_INFINITY);
    let mut visible_sum = 0.0;
    let mut seconds = 0.0;
    let mut arap = truth;
    for frame in frames {
        let t = std::time::Instant::now();
        let det = detector.detect(&frame.color_rgb8, &frame.depth_m)?;
        seconds += t.elapsed().as_secs_f64();
        if let Some(arap) = arap.as_mut() {
            let visible = visible_markers(info, frame)?;
            score.add(&det.keypoints, &frame.markers_in_hand, &visible)?;
            let true_vertices: Vec<Point3> = frame
                .finger_vertices_in_hand
                .iter()
                .flatten()
                .copied()
                .collect();
            let all = HandKeypoints {
                fingers: frame
                    .markers_in_hand
                    .iter()
                    .map(|m| m.iter().map(|p| Some(*p)).collect())
                    .collect(),
            };
            let mut shape_bcd = |kp: &HandKeypoints| -> Result<Real, LabError> {
                let est = arap.estimate(kp)?.shape;
                let v: Vec<Point3> = est.fingers.iter().flatten().copied().collect();
                Ok(bcd(&v, &true_vertices)?)
            };
            let seen = HandKeypoints {
                fingers: frame
                    .markers_in_hand
                    .iter()
                    .zip(&visible)
                    .map(|(m, v)| m.iter().zip(v).map(|(p, v)| v.then_some(*p)).collect())
                    .collect(),
            };
            let from_detected = shape_bcd(&det.keypoints)?;
            let from_truth = shape_bcd(&all)?;
            visible_sum += shape_bcd(&seen)?;
            detected_sum += from_detected;
            truth_sum += from_truth;
            worst = worst.max(from_detected - from_truth);
        }
        detections.push(det);
    }
    let n = frames.len().max(1) as Real;
    let report = arap.map(|_| EpisodeMarkerReport {
        scene: info.scene.clone(),
        markers: score.report(),
        shape_bcd_detected_mm: 1e3 * detected_sum / n,
        shape_bcd_truth_mm: 1e3 * truth_sum / n,
        shape_bcd_truth_visible_mm: 1e3 * visible_sum / n,
        shape_bcd_worst_excess_mm: if frames.is_empty() { 0.0 } else { 1e3 * worst },
        detect_ms: 1e3 * seconds / n,
        score,
    });
    Ok((detections, report))
}

/// Checks that `hand` is the episode's hand: as many fingers, as many vertices each.
///
/// # Errors
/// [`LabError::InvalidEvaluation`] naming the first difference.
pub fn check_hand(hand: &HandModel, info: &EpisodeInfo) -> Result<(), LabError> {
    match info.hand_mismatch(hand) {
        Some(reason) => Err(LabError::InvalidEvaluation { reason }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detections_are_correct_swapped_or_false() {
        let truth = vec![vec![
            Point3::new(0.0, 0.0, 0.01),
            Point3::new(0.0, 0.0, 0.02),
            Point3::new(0.0, 0.0, 0.03),
        ]];
        let visible = vec![vec![true, true, false]];
        let detected = HandKeypoints {
            fingers: vec![vec![
                Some(Point3::new(0.001, 0.0, 0.01)), // correct, 1 mm
                Some(Point3::new(0.0, 0.0, 0.0299)), // marker 2's place: a swap
                Some(Point3::new(0.02, 0.0, 0.03)),  // nowhere: false
            ]],
        };
        let mut s = MarkerScore::default();
        s.add(&detected, &truth, &visible).unwrap();
        let r = s.report();
        assert_eq!(
            (r.visible, r.detected, r.identity_swaps, r.false_detections),
            (2, 1, 1, 1)
        );
        assert!((r.detection_rate - 0.5).abs() < 1e-12);
        assert!((r.mean_error_mm - 1.0).abs() < 1e-9 && (r.max_error_mm - 1.0).abs() < 1e-9);
        let mut twice = s.clone();
        twice.merge(&s);
        assert_eq!(twice.report().visible, 4);
        moe_geom::assert_err!(
            s.add(&HandKeypoints { fingers: vec![] }, &truth, &visible),
            LabError::InvalidEvaluation { reason }
                if reason == "detected keypoints, true markers and visibility differ in layout"
        );
    }
}
