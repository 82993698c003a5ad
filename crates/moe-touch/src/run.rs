//! Running the pipeline over a recorded episode: the result frames (for the Foxglove file) and
//! the figures against the ground truth where the episode has it.

use moe_contact::{ContactMetrics, ContactReport};
use moe_geom::{ContactEstimator, HandShape, Real, ShapeEstimator, bcd};
use moe_io::{EpisodeFrame, EpisodeInfo, RunFrame, RunTruth};
use serde::Serialize;

use crate::perception::score::{MarkerReport, MarkerScore, has_ground_truth, visible_markers};
use crate::{Pipeline, StageTimings, TouchError};

/// One frame of a run report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameReport {
    /// Frame time, nanoseconds.
    pub time_ns: u64,
    /// Markers found.
    pub markers_found: usize,
    /// Fingers none of whose markers were found.
    pub fingers_without_markers: Vec<usize>,
    /// Estimated contact points.
    pub contact_points: usize,
    /// Shape BCD against the true surface, mm (frames with ground truth).
    pub shape_bcd_mm: Option<Real>,
    /// True contact vertices (frames with ground truth).
    pub true_contact_vertices: Option<usize>,
    /// Stage timings, milliseconds.
    pub timings: StageTimings,
}

/// Mean, median and largest time of one stage over a run, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TimingSummary {
    /// Mean.
    pub mean_ms: Real,
    /// Median.
    pub median_ms: Real,
    /// Largest.
    pub max_ms: Real,
}

impl TimingSummary {
    fn of(mut values: Vec<Real>) -> Self {
        if values.is_empty() {
            return Self {
                mean_ms: 0.0,
                median_ms: 0.0,
                max_ms: 0.0,
            };
        }
        values.sort_by(Real::total_cmp);
        Self {
            mean_ms: values.iter().sum::<Real>() / values.len() as Real,
            median_ms: values[values.len() / 2],
            max_ms: values[values.len() - 1],
        }
    }
}

/// The figures of a whole run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunReport {
    /// Frames processed.
    pub frames: usize,
    /// Why the episode ended early, if it was cut short (the frames before the cut ran).
    pub truncated: Option<String>,
    /// Marker detection against the visible true markers (episodes with ground truth).
    pub markers: Option<MarkerReport>,
    /// Mean shape BCD against the true surfaces, mm.
    pub shape_bcd_mm: Option<Real>,
    /// Contact estimation against the true contacts (BCD/UCD, misses, false alarms, F1).
    pub contact: Option<ContactReport>,
    /// Per stage over the frames.
    pub markers_ms: TimingSummary,
    /// Shape estimation.
    pub shape_ms: TimingSummary,
    /// Contact estimation.
    pub contact_ms: TimingSummary,
    /// The whole frame.
    pub total_ms: TimingSummary,
    /// Frames per second from the mean frame time.
    pub frames_per_second: Real,
    /// Every frame.
    pub per_frame: Vec<FrameReport>,
}

/// Runs `pipeline` over `frames` of an episode (`info`) in order, from a fresh stream, and
/// returns the result frames and the report (`truncated`: why the episode's frames stop early,
/// if they do).
///
/// # Errors
/// A stage's failure on a frame, or ground truth that does not fit the hand.
pub fn run_episode<S, C>(
    pipeline: &mut Pipeline<S, C>,
    info: &EpisodeInfo,
    frames: &[EpisodeFrame],
    truncated: Option<String>,
) -> Result<(Vec<RunFrame>, RunReport), TouchError>
where
    S: ShapeEstimator,
    C: ContactEstimator,
{
    crate::perception::score::check_hand(pipeline.hand(), info)?;
    pipeline.reset();
    let truth = frames.iter().all(|f| has_ground_truth(info, f)) && !frames.is_empty();
    let mut score = MarkerScore::default();
    let mut contact = ContactMetrics::default();
    let mut bcd_sum = 0.0;
    let mut out = Vec::with_capacity(frames.len());
    let mut per_frame = Vec::with_capacity(frames.len());
    for frame in frames {
        let est = pipeline.process_episode_frame(frame)?;
        let mut shape_bcd_mm = None;
        let mut true_contact_vertices = None;
        let run_truth = if truth {
            let visible = visible_markers(info, frame)?;
            score.add(&est.keypoints, &frame.markers_in_hand, &visible)?;
            let true_shape = HandShape {
                fingers: frame.finger_vertices_in_hand.clone(),
            };
            let a: Vec<_> = est.shape.fingers.iter().flatten().copied().collect();
            let b: Vec<_> = true_shape.fingers.iter().flatten().copied().collect();
            let d = bcd(&a, &b)?;
            bcd_sum += d;
            shape_bcd_mm = Some(1e3 * d);
            let labels = |ids: &[Vec<u32>]| -> Vec<Vec<bool>> {
                ids.iter()
                    .zip(&info.finger_num_vertices)
                    .map(|(ids, &n)| {
                        let mut l = vec![false; n];
                        for &i in ids {
                            if let Some(x) = l.get_mut(i as usize) {
                                *x = true;
                            }
                        }
                        l
                    })
                    .collect()
            };
            let true_labels = labels(&frame.contact_vertices);
            let predicted = est.contact.vertices_above(pipeline.threshold());
            contact.add(&true_shape, &true_labels, &labels(&predicted))?;
            true_contact_vertices = Some(frame.contact_vertices.iter().map(Vec::len).sum());
            Some(RunTruth {
                vertices_in_hand: frame.finger_vertices_in_hand.clone(),
                contact_vertices: frame.contact_vertices.clone(),
                obstacles: frame.obstacles.clone(),
            })
        } else {
            None
        };
        per_frame.push(FrameReport {
            time_ns: frame.time_ns,
            markers_found: est.markers.found,
            fingers_without_markers: est.fingers_without_markers.clone(),
            contact_points: est.contacts_in_world.len(),
            shape_bcd_mm,
            true_contact_vertices,
            timings: est.timings,
        });
        out.push(RunFrame {
            time_ns: frame.time_ns,
            color_rgb8: frame.color_rgb8.clone(),
            world_from_hand: frame.world_from_hand,
            markers_in_hand: est.keypoints.fingers,
            vertices_in_hand: est.shape.fingers,
            contact_probability: est.contact.fingers,
            contacts_in_world: est.contacts_in_world.iter().map(|c| c.point).collect(),
            truth: run_truth,
        });
    }
    let stage = |f: fn(&StageTimings) -> Real| {
        TimingSummary::of(per_frame.iter().map(|r| f(&r.timings)).collect())
    };
    let total_ms = stage(|t| t.total_ms);
    let report = RunReport {
        frames: frames.len(),
        truncated,
        markers: truth.then(|| score.report()),
        shape_bcd_mm: truth.then(|| 1e3 * bcd_sum / frames.len() as Real),
        contact: truth.then(|| contact.report()),
        markers_ms: stage(|t| t.markers_ms),
        shape_ms: stage(|t| t.shape_ms),
        contact_ms: stage(|t| t.contact_ms),
        frames_per_second: if total_ms.mean_ms > 0.0 {
            1e3 / total_ms.mean_ms
        } else {
            0.0
        },
        total_ms,
        per_frame,
    };
    Ok((out, report))
}

/// The run file's fixed information for an episode and a model.
pub fn run_info(info: &EpisodeInfo, model: &str, threshold: Real) -> moe_io::RunInfo {
    moe_io::RunInfo {
        model: model.to_owned(),
        threshold,
        episode: info.clone(),
    }
}
