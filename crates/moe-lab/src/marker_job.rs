//! Marker detection and tracking over a recorded episode, as `moe-touch markers` runs it: every
//! frame's keypoints as JSON Lines and a typed report (per-frame counts, tracking losses and,
//! for an episode with ground truth, the detection's score and its effect on shape
//! estimation).

use std::path::Path;

use moe_arap::ShapeConfig;
use moe_geom::HandModel;
use moe_io::IoError;
use moe_record::Episode;
use moe_touch::perception::{DetectorConfig, MarkerDetection, MarkerDetector};
use serde::Serialize;

use crate::draw::png_bytes;
use crate::error::LabError;
use crate::keypoints_file::KeypointsFile;
use crate::markers::{EpisodeMarkerReport, evaluate_episode};
use crate::output_files::OutputFiles;
use crate::overlay::draw_detection;

/// The `moe-touch markers --json` report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkersRecord {
    /// The episode's file.
    pub episode: String,
    /// The keypoints file.
    pub out: String,
    /// Frames of the episode.
    pub frames: usize,
    /// Markers of the hand.
    pub markers_per_frame: usize,
    /// Markers found in each frame.
    pub found_per_frame: Vec<usize>,
    /// Frames where tracking was lost (and the detector started again from the rest pose).
    pub tracking_lost_frames: Vec<usize>,
    /// The detector's parameters.
    pub config: DetectorConfig,
    /// Against the ground truth, when the episode has it.
    pub ground_truth: Option<EpisodeMarkerReport>,
}

/// An episode's markers, tracked: every frame's detection, the keypoints file's text and the
/// report.
#[derive(Debug, Clone)]
pub struct MarkerTracking {
    /// Every frame's detection, in order.
    pub detections: Vec<MarkerDetection>,
    /// One keypoints file per line and frame (`moe-touch shape --keypoints` reads a line).
    pub keypoints_lines: String,
    /// The report.
    pub record: MarkersRecord,
}

/// Runs `detector` over `episode`'s frames in order (see [`evaluate_episode`], with the default
/// SR-ARAP settings); `episode_file` and `out` name the episode and the keypoints file in the
/// report.
///
/// # Errors
/// Those of [`evaluate_episode`].
pub fn track_markers(
    hand: &HandModel,
    episode: &Episode,
    detector: &mut MarkerDetector,
    episode_file: &Path,
    out: &Path,
) -> Result<MarkerTracking, LabError> {
    let (detections, ground_truth) = evaluate_episode(
        hand,
        &episode.info,
        &episode.frames,
        detector,
        &ShapeConfig::default(),
    )?;
    let keypoints_lines = KeypointsFile::lines(
        episode
            .frames
            .iter()
            .zip(&detections)
            .map(|(frame, det)| (frame.time_ns, &det.keypoints)),
    )?;
    let record = MarkersRecord {
        episode: episode_file.display().to_string(),
        out: out.display().to_string(),
        frames: detections.len(),
        markers_per_frame: hand
            .fingers()
            .iter()
            .map(|f| f.model.marker_vertices().len())
            .sum(),
        found_per_frame: detections.iter().map(|d| d.diagnostics.found).collect(),
        tracking_lost_frames: detections
            .iter()
            .enumerate()
            .filter(|(_, d)| d.diagnostics.tracking_lost)
            .map(|(k, _)| k)
            .collect(),
        config: *detector.config(),
        ground_truth,
    };
    Ok(MarkerTracking {
        detections,
        keypoints_lines,
        record,
    })
}

impl MarkerTracking {
    /// Every frame's colour image with the detected markers ringed and labelled
    /// `finger.marker` and the rejected clusters crossed, as `frame_<k>.png`.
    ///
    /// # Errors
    /// Frames whose images do not have the detector's size, an image that cannot be encoded.
    pub fn overlays(
        &self,
        detector: &MarkerDetector,
        episode: &Episode,
    ) -> Result<OutputFiles, LabError> {
        let mut files = OutputFiles::new();
        for (k, (frame, det)) in episode.frames.iter().zip(&self.detections).enumerate() {
            let name = format!("frame_{k:04}.png");
            let img = draw_detection(detector, &frame.color_rgb8, det)?;
            let png = png_bytes(&img).map_err(|e| IoError::Serialize {
                path: name.clone().into(),
                message: e.to_string(),
            })?;
            files.add_bytes(name, png);
        }
        Ok(files)
    }
}

impl MarkersRecord {
    /// The lines `moe-touch markers` prints: the counts and, with ground truth, the score.
    pub fn summary(&self) -> String {
        let found: usize = self.found_per_frame.iter().sum();
        let mut text = format!(
            "{} frames, {} of {} markers found per frame on average, wrote {}",
            self.frames,
            found as f64 / self.frames.max(1) as f64,
            self.markers_per_frame,
            self.out
        );
        if let Some(r) = &self.ground_truth {
            let m = &r.markers;
            text.push_str(&format!(
                "\nagainst the ground truth: {:.1} % of {} visible markers detected, error mean \
                 {:.2} / p95 {:.2} / max {:.2} mm, {} false detections, {} identity swaps",
                100.0 * m.detection_rate,
                m.visible,
                m.mean_error_mm,
                m.p95_error_mm,
                m.max_error_mm,
                m.false_detections,
                m.identity_swaps
            ));
            text.push_str(&format!(
                "\nSR-ARAP shape BCD {:.3} mm from the detected keypoints, {:.3} mm from every \
                 true marker; detection {:.2} ms per frame",
                r.shape_bcd_detected_mm, r.shape_bcd_truth_mm, r.detect_ms
            ));
        }
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::{FingerParams, HandPreset};

    #[test]
    fn an_episode_with_ground_truth_gives_a_line_per_frame_and_a_scored_report() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/episodes/plate_tip_front_small.mcap");
        let episode = moe_record::read_episode(&path).unwrap();
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let mut detector =
            MarkerDetector::for_episode(&episode.info, &hand, DetectorConfig::default()).unwrap();
        let tracking =
            track_markers(&hand, &episode, &mut detector, &path, Path::new("kp.jsonl")).unwrap();
        assert_eq!(
            tracking.keypoints_lines.lines().count(),
            episode.frames.len()
        );
        assert_eq!(tracking.record.markers_per_frame, 14);
        assert!(tracking.record.ground_truth.is_some());
        assert_eq!(tracking.record.summary().lines().count(), 3);
        let overlays = tracking.overlays(&detector, &episode).unwrap();
        assert_eq!(overlays.names().count(), episode.frames.len());
    }
}
