//! Running the pipeline over a recorded episode: the result frames (for the Foxglove file) and
//! the figures against the ground truth where the episode has it.

use moe_contact::{ContactMetrics, ContactReport};
use moe_geom::{HandEstimator, HandShape, Point3, Real, Vector3, bcd};
use moe_physics::{ContactLoad, PhysicsDetails};
use moe_record::{EpisodeFrame, EpisodeInfo, RunForces, RunFrame, RunLoad, RunTruth};
use serde::Serialize;

use crate::LabError;
use crate::markers::{MarkerReport, MarkerScore, has_ground_truth, visible_markers};
use moe_touch::{FrameFailure, FrameStage, Pipeline, StageTimings, StreamEvent};

mod summary;

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
    /// Where the frame stands in the stream (a gap beyond the memory horizon restarts it;
    /// `null` for a frame refused before it entered the stream).
    pub stream: Option<StreamEvent>,
    /// Why the frame has no estimate, for a frame the pipeline could not estimate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<FailureRecord>,
    /// Per finger, the estimated force on it (contact estimators that estimate force).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub finger_forces: Option<Vec<FingerForceRecord>>,
    /// The loads the physics estimator found.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loads: Option<Vec<LoadRecord>>,
}

/// Why a frame of a run has no estimate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FailureRecord {
    /// The stage that failed.
    pub stage: FrameStage,
    /// Its error.
    pub error: String,
}

/// The estimated force on one finger in one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FingerForceRecord {
    /// The net force the world exerts on the finger, hand frame, newtons.
    pub force_n: Vector3,
    /// Its magnitude, newtons.
    pub magnitude_n: Real,
    /// Probability that the finger is pressed (the physics estimator).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pressed_probability: Option<Real>,
    /// Loads found on the finger (the physics estimator).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loads: Option<usize>,
    /// Linear solves the physics estimator made for the finger in this frame (Newton
    /// iterations, dynamic steps, tangents): what its time grows with.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solves: Option<usize>,
    /// Whether the physics estimator's load search stopped at the frame's budget of solves
    /// (`frame_solve_budget`): the loads are the best it found within it.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub degraded: bool,
    /// Why the physics estimator has no estimate for the finger in this frame (too few
    /// markers, a static solve that did not converge): its force is then zero.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// One load the physics estimator found, hand frame, SI units (as `moe-touch contact --method
/// physics` writes it to `loads.json` and `moe-touch run` to its report).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoadRecord {
    /// Finger index.
    pub finger: usize,
    /// The vertex at the centre of the loaded patch.
    pub vertex: u32,
    /// The patch's centre on the rest surface, hand frame, metres.
    pub location_rest_m: Point3,
    /// The same point on the estimated (dented) surface, hand frame, metres.
    pub location_m: Point3,
    /// The force the world exerts on the finger, hand frame, newtons.
    pub force_n: Vector3,
    /// Its magnitude, newtons.
    pub magnitude_n: Real,
    /// Standard deviation of the magnitude, newtons.
    pub magnitude_sd_n: Real,
    /// Posterior standard deviation of the place along the finger's axis, metres (`null` where
    /// the estimator gives none, as for a finger's second load).
    pub location_sd_along_m: Option<Real>,
    /// The same around the finger's axis, metres.
    pub location_sd_around_m: Option<Real>,
}

impl From<&ContactLoad> for LoadRecord {
    fn from(l: &ContactLoad) -> Self {
        let finite = |x: Real| x.is_finite().then_some(x);
        Self {
            finger: l.finger,
            vertex: l.vertex,
            location_rest_m: l.location_rest,
            location_m: l.location,
            force_n: l.force_n,
            magnitude_n: l.magnitude_n,
            magnitude_sd_n: l.magnitude_sd_n,
            location_sd_along_m: finite(l.location_sd_m[0]),
            location_sd_around_m: finite(l.location_sd_m[1]),
        }
    }
}

/// Per finger, the estimated forces of a physics estimate: net force, pressed probability,
/// loads and failure.
pub fn finger_force_records(e: &PhysicsDetails) -> Vec<FingerForceRecord> {
    e.finger_forces_n()
        .into_iter()
        .zip(&e.fingers)
        .enumerate()
        .map(|(f, (force_n, r))| FingerForceRecord {
            force_n,
            magnitude_n: force_n.norm(),
            pressed_probability: Some(r.pressed_probability),
            loads: Some(e.loads.iter().filter(|l| l.finger == f).count()),
            solves: Some(r.solves),
            degraded: r.degraded,
            error: r.error.clone(),
        })
        .collect()
}

/// The estimated forces of a run, per finger over its frames.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForceSummary {
    /// Per finger.
    pub fingers: Vec<FingerForceSummary>,
}

/// The estimated force on one finger over a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FingerForceSummary {
    /// Frames with a non-zero estimated force on the finger.
    pub frames_with_force: usize,
    /// The largest estimated magnitude, newtons.
    pub max_magnitude_n: Real,
    /// The frame of the largest magnitude (its time, nanoseconds).
    pub max_time_ns: Option<u64>,
    /// Frames in which the estimator had no estimate for the finger.
    #[serde(skip_serializing_if = "is_zero")]
    pub failed_frames: usize,
    /// Frames in which the load search on the finger stopped at the frame's budget.
    #[serde(skip_serializing_if = "is_zero")]
    pub degraded_frames: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl ForceSummary {
    fn of(per_frame: &[FrameReport]) -> Option<Self> {
        let mut fingers: Vec<FingerForceSummary> = Vec::new();
        for frame in per_frame {
            let forces = frame.finger_forces.as_ref()?;
            if fingers.is_empty() {
                fingers = vec![
                    FingerForceSummary {
                        frames_with_force: 0,
                        max_magnitude_n: 0.0,
                        max_time_ns: None,
                        failed_frames: 0,
                        degraded_frames: 0,
                    };
                    forces.len()
                ];
            }
            for (s, f) in fingers.iter_mut().zip(forces) {
                if f.magnitude_n > 0.0 {
                    s.frames_with_force += 1;
                }
                if f.magnitude_n > s.max_magnitude_n {
                    s.max_magnitude_n = f.magnitude_n;
                    s.max_time_ns = Some(frame.time_ns);
                }
                s.failed_frames += usize::from(f.error.is_some());
                s.degraded_frames += usize::from(f.degraded);
            }
        }
        (!fingers.is_empty()).then_some(Self { fingers })
    }
}

/// Mean, median, 99th percentile and largest time of one stage over a run, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TimingSummary {
    /// Frames summarised.
    pub frames: usize,
    /// Mean.
    pub mean_ms: Real,
    /// Median.
    pub median_ms: Real,
    /// 99th percentile (nearest rank: the largest of fewer than 51 frames).
    pub p99_ms: Real,
    /// Largest.
    pub max_ms: Real,
}

impl TimingSummary {
    /// The summary of `values` (all zero for none).
    pub fn of(mut values: Vec<Real>) -> Self {
        if values.is_empty() {
            return Self {
                frames: 0,
                mean_ms: 0.0,
                median_ms: 0.0,
                p99_ms: 0.0,
                max_ms: 0.0,
            };
        }
        values.sort_by(Real::total_cmp);
        let n = values.len();
        // Nearest rank, rounded up: the 99th percentile of a short run is its largest frame.
        let at = |q: Real| crate::nearest_rank(&values, q).unwrap_or(0.0);
        Self {
            frames: n,
            mean_ms: values.iter().sum::<Real>() / n as Real,
            median_ms: at(0.5),
            p99_ms: at(0.99),
            max_ms: at(1.0),
        }
    }
}

/// Whole-frame times of a stream as a robot lives with them: the first frame (from rest), the
/// frames after it, and those split by whether the finger is pressed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StreamTimings {
    /// The first frame, milliseconds (the estimator starts from rest).
    pub first_ms: Real,
    /// Every frame after the first.
    pub after_first: TimingSummary,
    /// The frames after the first with a press.
    pub pressed: TimingSummary,
    /// The frames after the first without one.
    pub free: TimingSummary,
    /// What says a frame is pressed: `"ground truth"` (a true contact vertex, for episodes
    /// with ground truth) or `"estimate"` (a contact point estimated).
    pub press_from: &'static str,
}

impl StreamTimings {
    /// The timings of `per_frame` (`truth`: whether the frames have ground truth).
    fn of(per_frame: &[FrameReport], truth: bool) -> Self {
        let pressed = |f: &FrameReport| match (truth, f.true_contact_vertices) {
            (true, Some(n)) => n > 0,
            _ => f.contact_points > 0,
        };
        let after = per_frame.get(1..).unwrap_or(&[]);
        let total = |keep: &dyn Fn(&FrameReport) -> bool| {
            TimingSummary::of(
                after
                    .iter()
                    .filter(|f| keep(f))
                    .map(|f| f.timings.total_ms)
                    .collect(),
            )
        };
        Self {
            first_ms: per_frame.first().map_or(0.0, |f| f.timings.total_ms),
            after_first: total(&|_| true),
            pressed: total(&|f| pressed(f)),
            free: total(&|f| !pressed(f)),
            press_from: if truth { "ground truth" } else { "estimate" },
        }
    }
}

/// The figures of a whole run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunReport {
    /// Frames processed.
    pub frames: usize,
    /// Frames the pipeline could not estimate (each marked in `per_frame`): the stream went
    /// on after them, and the figures against the ground truth are over the others.
    #[serde(skip_serializing_if = "is_zero")]
    pub failed_frames: usize,
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
    /// The estimator (shape and contact).
    pub estimate_ms: TimingSummary,
    /// Contact points (smoothing, threshold, world frame).
    pub points_ms: TimingSummary,
    /// The whole frame.
    pub total_ms: TimingSummary,
    /// The whole frame as a stream sees it: the first frame, then the frames after it, with
    /// and without a press.
    pub stream_ms: StreamTimings,
    /// Frames per second from the mean frame time.
    pub frames_per_second: Real,
    /// The estimated forces per finger over the run (contact estimators that estimate force).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub forces: Option<ForceSummary>,
    /// Every frame.
    pub per_frame: Vec<FrameReport>,
}

/// Runs `pipeline` over `frames` of an episode (`info`) in order, from a fresh stream, and
/// returns the result frames and the report (`truncated`: why the episode's frames stop early,
/// if they do).
///
/// A frame the pipeline cannot estimate does not end the run: its report names the failing
/// stage and the error ([`FrameReport::failure`]), its result frame has the markers found and
/// no estimate, and the stream goes on with the next frame. The figures against the ground
/// truth are over the estimated frames; [`RunReport::failed_frames`] counts the others.
///
/// # Errors
/// Ground truth that does not fit the hand.
///
/// Every frame carries the force on each finger where the estimator estimates per-vertex force
/// (the sum over its vertices), and the estimator's details add what they know
/// ([`RunDetails`]: the physics estimator's loads, pressed probabilities and failures), in the
/// report and in the result frames.
pub fn run_episode<E>(
    pipeline: &mut Pipeline<E>,
    info: &EpisodeInfo,
    frames: &[EpisodeFrame],
    truncated: Option<String>,
) -> Result<(Vec<RunFrame>, RunReport), LabError>
where
    E: HandEstimator,
    E::Details: RunDetails,
{
    crate::markers::check_hand(pipeline.hand(), info)?;
    pipeline.reset();
    let truth = frames.iter().all(|f| has_ground_truth(info, f)) && !frames.is_empty();
    let mut score = MarkerScore::default();
    let mut contact = ContactMetrics::default();
    let mut bcd_sum = 0.0;
    let mut estimated = 0usize;
    let mut out = Vec::with_capacity(frames.len());
    let mut per_frame = Vec::with_capacity(frames.len());
    for frame in frames {
        let run_truth = truth.then(|| RunTruth {
            vertices_in_hand: frame.finger_vertices_in_hand.clone(),
            contact_vertices: frame.contact_vertices.clone(),
            obstacles: frame.obstacles.clone(),
        });
        let true_contact_vertices =
            truth.then(|| frame.contact_vertices.iter().map(Vec::len).sum());
        let est = match pipeline.process(frame.rgbd(), &frame.observation()) {
            Ok(est) => est,
            Err(failure) => {
                if let (true, Some(keypoints)) = (truth, &failure.keypoints) {
                    let visible = visible_markers(info, frame)?;
                    score.add(keypoints, &frame.markers_in_hand, &visible)?;
                }
                let (report, result) = failed_frame::<E::Details>(pipeline.hand(), frame, *failure);
                per_frame.push(FrameReport {
                    true_contact_vertices,
                    ..report
                });
                out.push(RunFrame {
                    truth: run_truth,
                    ..result
                });
                continue;
            }
        };
        estimated += 1;
        let mut shape_bcd_mm = None;
        if truth {
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
        }
        let (finger_forces, loads) = frame_forces(&est);
        let forces = finger_forces.as_ref().map(|fingers| RunForces {
            finger_force_n: fingers.iter().map(|f| f.force_n).collect(),
            pressed_probability: fingers
                .iter()
                .map(|f| f.pressed_probability)
                .collect::<Option<Vec<_>>>(),
            loads: loads
                .iter()
                .flatten()
                .map(|l| RunLoad {
                    finger: l.finger,
                    location_in_hand: l.location_m,
                    force_n: l.force_n,
                })
                .collect(),
        });
        per_frame.push(FrameReport {
            time_ns: frame.time_ns,
            markers_found: est.markers.found,
            fingers_without_markers: est.fingers_without_markers.clone(),
            contact_points: est.contacts_in_world.len(),
            shape_bcd_mm,
            true_contact_vertices,
            timings: est.timings,
            stream: Some(est.stream),
            failure: None,
            finger_forces,
            loads,
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
            forces,
        });
    }
    let stage = |f: fn(&StageTimings) -> Real| {
        TimingSummary::of(per_frame.iter().map(|r| f(&r.timings)).collect())
    };
    let total_ms = stage(|t| t.total_ms);
    let scored = truth && estimated > 0;
    let report = RunReport {
        frames: frames.len(),
        failed_frames: frames.len() - estimated,
        truncated,
        markers: truth.then(|| score.report()),
        shape_bcd_mm: scored.then(|| 1e3 * bcd_sum / estimated as Real),
        contact: scored.then(|| contact.report()),
        markers_ms: stage(|t| t.markers_ms),
        estimate_ms: stage(|t| t.estimate_ms),
        points_ms: stage(|t| t.points_ms),
        frames_per_second: if total_ms.mean_ms > 0.0 {
            1e3 / total_ms.mean_ms
        } else {
            0.0
        },
        total_ms,
        stream_ms: StreamTimings::of(&per_frame, truth),
        forces: ForceSummary::of(&per_frame),
        per_frame,
    };
    Ok((out, report))
}

/// The report and the result frame of a frame the pipeline could not estimate (without the
/// ground truth, which the caller adds): the markers found, when perception ran, and no
/// estimate (no vertices; zero forces on every finger in a run whose estimator estimates force).
fn failed_frame<D: RunDetails>(
    hand: &moe_geom::HandModel,
    frame: &EpisodeFrame,
    failure: FrameFailure,
) -> (FrameReport, RunFrame) {
    let fingers = hand.num_fingers();
    let error = FailureRecord {
        stage: failure.stage,
        error: failure.to_string(),
    };
    let markers_in_hand = match failure.keypoints {
        Some(k) => k.fingers,
        None => hand
            .fingers()
            .iter()
            .map(|f| vec![None; f.model.marker_vertices().len()])
            .collect(),
    };
    let finger_forces = D::ESTIMATES_FORCE.then(|| {
        (0..fingers)
            .map(|_| FingerForceRecord {
                force_n: Vector3::zeros(),
                magnitude_n: 0.0,
                pressed_probability: None,
                loads: None,
                solves: None,
                degraded: false,
                error: Some(error.error.clone()),
            })
            .collect::<Vec<_>>()
    });
    let forces = D::ESTIMATES_FORCE.then(|| RunForces {
        finger_force_n: vec![Vector3::zeros(); fingers],
        pressed_probability: None,
        loads: Vec::new(),
    });
    (
        FrameReport {
            time_ns: frame.time_ns,
            markers_found: failure.markers.as_ref().map_or(0, |m| m.found),
            fingers_without_markers: failure.fingers_without_markers,
            contact_points: 0,
            shape_bcd_mm: None,
            true_contact_vertices: None,
            timings: failure.timings,
            stream: failure.stream,
            failure: Some(error),
            finger_forces,
            loads: D::ESTIMATES_FORCE.then(Vec::new),
        },
        RunFrame {
            time_ns: frame.time_ns,
            color_rgb8: frame.color_rgb8.clone(),
            world_from_hand: frame.world_from_hand,
            markers_in_hand,
            vertices_in_hand: vec![Vec::new(); fingers],
            contact_probability: vec![Vec::new(); fingers],
            contacts_in_world: Vec::new(),
            truth: None,
            forces,
        },
    )
}

/// What an estimator's details add to a run's report and result frames.
pub trait RunDetails {
    /// Whether the estimator's details give forces (a run with forces: a frame it could not
    /// estimate carries zero forces).
    const ESTIMATES_FORCE: bool;

    /// Per finger, the estimated force with what the estimator knows of it, and the loads it
    /// found; `None` for an estimator whose details say nothing of forces.
    fn forces(&self) -> Option<(Vec<FingerForceRecord>, Vec<LoadRecord>)>;
}

/// The paper's chain says nothing beyond shape and contact.
impl RunDetails for () {
    const ESTIMATES_FORCE: bool = false;

    fn forces(&self) -> Option<(Vec<FingerForceRecord>, Vec<LoadRecord>)> {
        None
    }
}

/// The physics estimator: per finger its force, pressed probability, loads and failure; every
/// load with its place, force and uncertainty.
impl RunDetails for PhysicsDetails {
    const ESTIMATES_FORCE: bool = true;

    fn forces(&self) -> Option<(Vec<FingerForceRecord>, Vec<LoadRecord>)> {
        Some((
            finger_force_records(self),
            self.loads.iter().map(LoadRecord::from).collect(),
        ))
    }
}

/// A frame's forces: from the estimator's details where they give them (per finger and its
/// loads), else from the per-vertex forces (per finger only), else none.
fn frame_forces<D: RunDetails>(
    est: &moe_touch::FrameEstimate<D>,
) -> (Option<Vec<FingerForceRecord>>, Option<Vec<LoadRecord>>) {
    if let Some((fingers, loads)) = est.details.forces() {
        return (Some(fingers), Some(loads));
    }
    (
        est.vertex_force_n.as_ref().map(|fingers| {
            fingers
                .iter()
                .map(|v| {
                    let force_n: Vector3 = v.iter().sum();
                    FingerForceRecord {
                        force_n,
                        magnitude_n: force_n.norm(),
                        pressed_probability: None,
                        loads: None,
                        solves: None,
                        degraded: false,
                        error: None,
                    }
                })
                .collect()
        }),
        None,
    )
}

/// The run file's fixed information for an episode and a model (a run without forces; set
/// [`moe_record::RunInfo::force_arrow_m_per_n`] for one with).
pub fn run_info(info: &EpisodeInfo, model: &str, threshold: Real) -> moe_record::RunInfo {
    moe_record::RunInfo {
        model: model.to_owned(),
        threshold,
        episode: info.clone(),
        force_arrow_m_per_n: None,
    }
}

/// The default length of a force arrow in a result file: 0.2 m per newton (a 50 mN press draws
/// a 10 mm arrow).
pub const DEFAULT_FORCE_ARROW_M_PER_N: Real = 0.2;

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(total_ms: Real, truth: Option<usize>, contact_points: usize) -> FrameReport {
        FrameReport {
            time_ns: 0,
            markers_found: 14,
            fingers_without_markers: Vec::new(),
            contact_points,
            shape_bcd_mm: None,
            true_contact_vertices: truth,
            timings: StageTimings {
                total_ms,
                ..StageTimings::default()
            },
            stream: Some(StreamEvent::Started),
            failure: None,
            finger_forces: None,
            loads: None,
        }
    }

    #[test]
    fn percentiles_are_nearest_ranks_and_a_short_run_has_its_largest_as_p99() {
        let t = TimingSummary::of((1..=200).rev().map(Real::from).collect());
        assert_eq!(
            (t.frames, t.median_ms, t.p99_ms, t.max_ms),
            (200, 100.0, 198.0, 200.0)
        );
        assert_eq!(t.mean_ms, 100.5);
        let short = TimingSummary::of(vec![3.0, 1.0, 2.0]);
        assert_eq!(
            (short.median_ms, short.p99_ms, short.max_ms),
            (2.0, 3.0, 3.0)
        );
        assert_eq!(TimingSummary::of(Vec::new()).frames, 0);
    }

    #[test]
    fn a_stream_splits_its_frames_after_the_first_by_the_truth_or_else_the_estimate() {
        // The first frame (from rest) is apart; of the others, two pressed and one free.
        let frames = [
            frame(50.0, Some(0), 0),
            frame(30.0, Some(4), 0),
            frame(20.0, Some(0), 9),
            frame(40.0, Some(7), 3),
        ];
        let by_truth = StreamTimings::of(&frames, true);
        assert_eq!(by_truth.first_ms, 50.0);
        assert_eq!(by_truth.after_first.frames, 3);
        assert_eq!(by_truth.after_first.max_ms, 40.0);
        assert_eq!(
            (by_truth.pressed.frames, by_truth.pressed.max_ms),
            (2, 40.0)
        );
        assert_eq!((by_truth.free.frames, by_truth.free.max_ms), (1, 20.0));
        assert_eq!(by_truth.press_from, "ground truth");
        // Without ground truth, a frame is pressed where contact points were estimated.
        let by_estimate = StreamTimings::of(&frames, false);
        assert_eq!(
            (by_estimate.pressed.frames, by_estimate.pressed.median_ms),
            (2, 20.0)
        );
        assert_eq!(by_estimate.free.max_ms, 30.0);
        assert_eq!(by_estimate.press_from, "estimate");
    }
}
