//! Contact from physics evaluated as tactile sensors are specified: per finger, how often a
//! press is detected, how far the estimated place is from the true one and how far the force,
//! by the finger's true force; beside the paper's per-vertex contact metrics, for the physics
//! estimator, the DGCNN on the physics estimator's (dented) shapes and the paper's chain
//! (SR-ARAP shape from the same markers, DGCNN) on the same frames.
//!
//! Frames are evaluated as streams: one trajectory after the other, in order, with the
//! estimator reset between trajectories (the physics estimator simulates the free finger from
//! one frame to the next). The markers are the simulated ones, the same with Gaussian noise,
//! or ones a caller supplies (detected by the perception stage in rendered frames).

use std::time::Instant;

use moe_arap::{MultiShapeEstimator, ShapeConfig, ShapeDepth};
use moe_contact::{ContactMetrics, ContactReport, DgcnnEstimator};
use moe_geom::HandEstimator as _;
use moe_geom::{
    ContactInput, HandKeypoints, HandModel, HandShape, LabelledFrame, OwnedDepthImage, Point3,
    Real, SeededRng, Vector3, WorldFromHand, bcd,
};
use moe_physics::{PhysicsEstimate, PhysicsEstimator};
use moe_tendon_sim::{Scene, SceneConfig, SimFrame, run_saving};
use serde::Serialize;

use crate::error::LabError;

/// One frame of a stream with what the force evaluation needs besides the labels.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamFrame {
    /// The labelled frame (true surface, labels, markers, pose, pulls).
    pub frame: LabelledFrame,
    /// Time in its trajectory, seconds.
    pub time_secs: Real,
    /// `vertex_force_n[f][v]`: normal magnitude of the contact force on vertex `v` of finger
    /// `f`, newtons.
    pub vertex_force_n: Vec<Vec<Real>>,
    /// The net contact force on each finger, hand frame, newtons (`None` for data sets made
    /// before it was recorded: the force table then uses the summed magnitudes).
    pub finger_force_n: Option<Vec<Vector3>>,
}

impl StreamFrame {
    /// A simulated frame of `hand` as a stream frame (markers are the marker vertices of the
    /// surface, pulls the commanded ones).
    ///
    /// # Errors
    /// A force-driven tendon (its command is a tension, not a pull).
    pub fn from_sim(
        hand: &HandModel,
        frame: &SimFrame,
        trajectory_id: u64,
        frame_index: u32,
    ) -> Result<Self, LabError> {
        let fingers: Vec<Vec<Point3>> = frame
            .fingers
            .iter()
            .map(|g| g.vertices_in_hand.clone())
            .collect();
        let markers = hand.keypoints_on(&fingers);
        Ok(Self {
            frame: LabelledFrame {
                trajectory_id,
                frame_index,
                shape: HandShape { fingers },
                contact: frame.fingers.iter().map(|g| g.labels.clone()).collect(),
                markers,
                world_from_hand: WorldFromHand::new(frame.world_from_hand),
                tendon_pull_m: frame.tendon_pulls_m()?,
            },
            time_secs: frame.time_secs,
            vertex_force_n: frame
                .fingers
                .iter()
                .map(|g| g.contact_force_n.clone())
                .collect(),
            finger_force_n: Some(frame.fingers.iter().map(|g| g.force_in_hand_n).collect()),
        })
    }

    /// A data set frame as a stream frame, `frame_secs` apart from the previous one of its
    /// trajectory (the generator's time step times its frames' spacing).
    ///
    /// # Errors
    /// A frame that does not fit `layout`.
    pub fn from_dataset(
        frame: &moe_io::DatasetFrame,
        layout: &moe_io::DatasetLayout,
        frame_secs: Real,
    ) -> Result<Self, LabError> {
        Ok(Self {
            time_secs: f64::from(frame.frame_index) * frame_secs,
            vertex_force_n: layout.per_finger(&frame.contact_force_n, |&v| f64::from(v)),
            finger_force_n: frame.finger_force_n.as_ref().map(|v| {
                v.iter()
                    .map(|c| Vector3::new(c[0].into(), c[1].into(), c[2].into()))
                    .collect()
            }),
            frame: frame.to_labelled(layout)?,
        })
    }

    /// The true net force on finger `f`: the recorded vector's magnitude, or the summed
    /// magnitudes without it.
    pub fn true_force_n(&self, f: usize) -> Real {
        match &self.finger_force_n {
            Some(v) => v[f].norm(),
            None => self.vertex_force_n[f].iter().sum(),
        }
    }
}

/// The stream of a simulated scene (trajectory `trajectory_id`).
///
/// # Errors
/// Divergence of the simulation, a scene whose hand is not `hand`'s layout, or a force-driven
/// tendon.
pub fn simulate_stream(
    config: &SceneConfig,
    hand: &HandModel,
    trajectory_id: u64,
) -> Result<Vec<StreamFrame>, LabError> {
    let mut scene = Scene::with_hand(config.clone(), hand.clone())?;
    let steps = scene.num_steps();
    let frames = run_saving(&mut scene, steps)?;
    frames
        .iter()
        .enumerate()
        .map(|(k, f)| StreamFrame::from_sim(hand, f, trajectory_id, k as u32))
        .collect()
}

/// Where the markers the estimators see come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MarkerSource<'a> {
    /// The simulated markers.
    Exact,
    /// The simulated markers moved by Gaussian noise of `sigma_m` per coordinate, seeded per
    /// trajectory and frame.
    Noisy {
        /// Standard deviation per coordinate, metres.
        sigma_m: Real,
        /// Seed.
        seed: u64,
    },
    /// Markers detected in rendered frames (`None` where unseen), with the frames' depth
    /// images.
    Given(&'a [PerceivedFrame]),
}

/// What the wrist camera gave of one rendered frame: the markers the perception stage
/// detected in it and its depth image.
#[derive(Debug, Clone, PartialEq)]
pub struct PerceivedFrame {
    /// The markers detected (`None` where unseen), hand frame.
    pub keypoints: HandKeypoints,
    /// The frame's depth image with its camera.
    pub depth: OwnedDepthImage,
}

impl MarkerSource<'_> {
    /// The markers of frame `k`.
    fn markers(&self, k: usize, frame: &LabelledFrame) -> Result<HandKeypoints, LabError> {
        match *self {
            Self::Exact => Ok(frame.markers.clone()),
            Self::Noisy { sigma_m, seed } => {
                let mut rng = SeededRng::new(seed)
                    .split(frame.trajectory_id)
                    .split(u64::from(frame.frame_index));
                Ok(frame.markers.with_noise(sigma_m, &mut rng))
            }
            Self::Given(all) => {
                all.get(k)
                    .map(|p| p.keypoints.clone())
                    .ok_or_else(|| LabError::InvalidEvaluation {
                        reason: format!("{} marker sets for frame {k}", all.len()),
                    })
            }
        }
    }

    /// The depth image of frame `k`, where the source has one.
    fn depth(&self, k: usize) -> Option<moe_geom::DepthImage<'_>> {
        match *self {
            Self::Given(all) => all.get(k).map(|p| p.depth.view()),
            _ => None,
        }
    }

    /// A short name for reports.
    pub fn name(&self) -> String {
        match self {
            Self::Exact => "exact".into(),
            Self::Noisy { sigma_m, .. } => format!("noise {:.2} mm", sigma_m * 1e3),
            Self::Given(_) => "perceived".into(),
        }
    }
}

/// The force bins of the table, newtons: `[0, 0.05)`, `[0.05, 0.2)`, `[0.2, 0.5)`, `[0.5, ∞)`.
pub const FORCE_BINS_N: [Real; 5] = [0.0, 0.05, 0.2, 0.5, Real::INFINITY];

/// One force bin of the table: fingers whose true net force is in `[lo_n, hi_n)` and that are
/// labelled in contact.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForceBin {
    /// Lower edge, newtons.
    pub lo_n: Real,
    /// Upper edge, newtons (∞ for the last).
    pub hi_n: Real,
    /// Pressed finger-frames.
    pub fingers: u64,
    /// Of those, with a load found on the finger.
    pub detected: u64,
    /// `detected / fingers`.
    pub detection_rate: Real,
    /// Median distance between the estimated and the true place (force-weighted centroids on
    /// the rest surface), mm; NaN when nothing was detected.
    pub location_median_mm: Real,
    /// Its along-the-finger part, mm.
    pub along_median_mm: Real,
    /// Median `|estimated − true|` net force, newtons.
    pub force_error_median_n: Real,
    /// Median of that error over the true force, percent.
    pub force_error_median_pct: Real,
}

/// The force table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForceTable {
    /// Per bin.
    pub bins: Vec<ForceBin>,
    /// Finger-frames not labelled in contact.
    pub unpressed_fingers: u64,
    /// Of those, with a load found (false alarms).
    pub false_alarm_fingers: u64,
    /// Smallest force `F` such that at least 90 % of the pressed fingers carrying `F` or more
    /// are detected, newtons (NaN when no such force).
    pub force_detected_90pct_n: Real,
    /// Whether the true forces are net vectors (else summed magnitudes, an old data set).
    pub net_force_truth: bool,
}

/// Figures of the physics estimator over the frames.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsEvaluation {
    /// Where the markers came from.
    pub markers: String,
    /// Frames evaluated.
    pub frames: u64,
    /// Trajectories they come from.
    pub trajectories: u64,
    /// Contact by the physics estimator's per-vertex map (probability ≥ 0.5).
    pub physics: ContactReport,
    /// The DGCNN on the physics estimator's shapes.
    pub dgcnn_on_physics: Option<ContactReport>,
    /// The paper's chain on the same markers: the DGCNN on SR-ARAP shapes.
    pub dgcnn_on_sr_arap: Option<ContactReport>,
    /// The DGCNN on SR-ARAP shapes registered to the markers and the depth image (when any
    /// frame carries one; a frame without one is solved from its markers).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dgcnn_on_sr_arap_depth: Option<ContactReport>,
    /// The DGCNN on the true shapes: what the network does when the shape is right.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dgcnn_on_true_shape: Option<ContactReport>,
    /// The two together: contact on the fingers the physics estimator finds pressed, where the
    /// DGCNN on its shape puts it (the physics estimator's region on a finger where the
    /// network finds none).
    pub physics_placed_by_dgcnn: Option<ContactReport>,
    /// Shape BCD of the physics estimator's surface against the true one, mm.
    pub physics_shape_bcd_mm: Real,
    /// Shape BCD of SR-ARAP from the same markers, mm (when the chain is evaluated).
    pub sr_arap_shape_bcd_mm: Real,
    /// Shape BCD of SR-ARAP registered to the markers and the depth image, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sr_arap_depth_shape_bcd_mm: Option<Real>,
    /// The force table.
    pub forces: ForceTable,
    /// Onset, hold (flicker) and release of the presses through the streams.
    pub stream: StreamTable,
    /// Median time of the physics estimator per frame, ms.
    pub physics_ms_median: Real,
    /// 90th percentile of that time, ms.
    pub physics_ms_p90: Real,
    /// Finger-frames whose estimate failed (too few markers, a static solve that did not
    /// converge); they count as no contact.
    pub failed_fingers: u64,
    /// Linear solves per finger-frame (Newton iterations, dynamic steps, tangents): what the
    /// estimator's time grows with, and what `frame_solve_budget` bounds.
    pub solves: SolveCounts,
    /// Finger-frames whose load search stopped at the frame's budget of solves.
    pub degraded_fingers: u64,
}

/// Median, 99th percentile and largest number of linear solves per finger-frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SolveCounts {
    /// Median.
    pub median: usize,
    /// 99th percentile (nearest rank, rounded up).
    pub p99: usize,
    /// Largest.
    pub max: usize,
}

impl SolveCounts {
    fn of(mut counts: Vec<usize>) -> Self {
        counts.sort_unstable();
        let at = |q: Real| crate::nearest_rank(&counts, q).unwrap_or(0);
        Self {
            median: at(0.5),
            p99: at(0.99),
            max: counts.last().copied().unwrap_or(0),
        }
    }
}

/// One pressed or unpressed finger-frame's outcome.
#[derive(Debug, Clone, Copy)]
struct FingerOutcome {
    /// The trajectory of the frame.
    trajectory: u64,
    pressed: bool,
    truth_n: Real,
    detected: bool,
    location_m: Real,
    along_m: Real,
    force_error_n: Real,
}

/// The physics estimator's outcome for finger `f` of `frame`.
fn finger_outcome(
    hand: &HandModel,
    frame: &StreamFrame,
    estimate: &PhysicsEstimate,
    f: usize,
) -> FingerOutcome {
    let truth_n = frame.true_force_n(f);
    let pressed = frame.frame.contact[f].iter().any(|&c| c);
    let hf = &hand.fingers()[f];
    let rest = hf.model.mesh().vertices();
    let weights = &frame.vertex_force_n[f];
    let total: Real = weights.iter().sum();
    let loads: Vec<_> = estimate
        .details
        .loads
        .iter()
        .filter(|l| l.finger == f)
        .collect();
    let detected = !loads.is_empty();
    let (mut location_m, mut along_m, mut force_error_n) = (Real::NAN, Real::NAN, Real::NAN);
    if detected && total > 0.0 {
        // Force-weighted centroids on the rest surface, finger frame.
        let truth: Vector3 = weights
            .iter()
            .zip(rest)
            .map(|(w, p)| p.coords * (*w / total))
            .sum();
        let finger_from_hand = hf.hand_from_finger.iso().inverse();
        let mass: Real = loads.iter().map(|l| l.magnitude_n).sum();
        let est: Vector3 = loads
            .iter()
            .map(|l| {
                (finger_from_hand * l.location_rest).coords * (l.magnitude_n / mass.max(1e-12))
            })
            .sum();
        location_m = (est - truth).norm();
        along_m = (est.z - truth.z).abs();
        let net: Vector3 = loads.iter().map(|l| l.force_n).sum();
        force_error_n = (net.norm() - truth_n).abs();
    }
    FingerOutcome {
        trajectory: frame.frame.trajectory_id,
        pressed,
        truth_n,
        detected,
        location_m,
        along_m,
        force_error_n,
    }
}

fn median(mut v: Vec<Real>) -> Real {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return Real::NAN;
    }
    v.sort_by(Real::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// How the physics estimator follows presses through a stream: per finger, a press is a run of
/// consecutive frames of one trajectory labelled in contact.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StreamTable {
    /// Presses (runs of contact frames of one finger).
    pub presses: u64,
    /// Presses detected in their first frame.
    pub onset_detected: u64,
    /// Frames of a press after its first detection.
    pub held_frames: u64,
    /// Of those, frames where the press was not reported (a flicker: reported, then lost while
    /// still pressed).
    pub held_frames_dropped: u64,
    /// Presses whose detection flickered at least once.
    pub presses_with_flicker: u64,
    /// Presses followed by a contact-free frame of the same trajectory (a release).
    pub releases: u64,
    /// Of those, releases whose first free frame still reported a press.
    pub release_false_alarms: u64,
    /// Mean frames from a press's first frame to its first detection, over detected presses.
    pub onset_delay_frames_mean: Real,
}

/// The stream table of the outcomes (per finger, frames in trajectory order).
fn stream_table(outcomes: &[FingerOutcome], fingers: usize) -> StreamTable {
    let mut t = StreamTable::default();
    let mut delays = Vec::new();
    for f in 0..fingers {
        let seq: Vec<&FingerOutcome> = outcomes.iter().skip(f).step_by(fingers).collect();
        let mut k = 0;
        while k < seq.len() {
            if !seq[k].pressed {
                k += 1;
                continue;
            }
            let start = k;
            while k < seq.len() && seq[k].pressed && seq[k].trajectory == seq[start].trajectory {
                k += 1;
            }
            let run = &seq[start..k];
            t.presses += 1;
            t.onset_detected += u64::from(run[0].detected);
            if let Some(first) = run.iter().position(|o| o.detected) {
                delays.push(first as Real);
                let after = &run[first + 1..];
                let dropped = after.iter().filter(|o| !o.detected).count() as u64;
                t.held_frames += after.len() as u64;
                t.held_frames_dropped += dropped;
                t.presses_with_flicker += u64::from(dropped > 0);
            }
            if k < seq.len() && seq[k].trajectory == seq[start].trajectory && !seq[k].pressed {
                t.releases += 1;
                t.release_false_alarms += u64::from(seq[k].detected);
            }
        }
    }
    t.onset_delay_frames_mean = if delays.is_empty() {
        Real::NAN
    } else {
        delays.iter().sum::<Real>() / delays.len() as Real
    };
    t
}

/// The force table of the outcomes.
fn force_table(outcomes: &[FingerOutcome], net_force_truth: bool) -> ForceTable {
    let bins = FORCE_BINS_N
        .windows(2)
        .map(|w| {
            let sel: Vec<&FingerOutcome> = outcomes
                .iter()
                .filter(|o| o.pressed && o.truth_n >= w[0] && o.truth_n < w[1])
                .collect();
            let det: Vec<&&FingerOutcome> = sel.iter().filter(|o| o.detected).collect();
            ForceBin {
                lo_n: w[0],
                hi_n: w[1],
                fingers: sel.len() as u64,
                detected: det.len() as u64,
                detection_rate: det.len() as Real / sel.len().max(1) as Real,
                location_median_mm: median(det.iter().map(|o| o.location_m * 1e3).collect()),
                along_median_mm: median(det.iter().map(|o| o.along_m * 1e3).collect()),
                force_error_median_n: median(det.iter().map(|o| o.force_error_n).collect()),
                force_error_median_pct: median(
                    det.iter()
                        .filter(|o| o.truth_n > 0.0)
                        .map(|o| 100.0 * o.force_error_n / o.truth_n)
                        .collect(),
                ),
            }
        })
        .collect();
    let unpressed: Vec<&FingerOutcome> = outcomes.iter().filter(|o| !o.pressed).collect();
    // Smallest F with ≥ 90 % detection among the pressed fingers carrying F or more.
    let mut pressed: Vec<&FingerOutcome> = outcomes.iter().filter(|o| o.pressed).collect();
    pressed.sort_by(|a, b| a.truth_n.total_cmp(&b.truth_n));
    let mut force_detected_90pct_n = Real::NAN;
    let mut detected_above = pressed.iter().filter(|o| o.detected).count();
    for (k, o) in pressed.iter().enumerate() {
        let n = pressed.len() - k;
        if detected_above as Real >= 0.9 * n as Real {
            force_detected_90pct_n = o.truth_n;
            break;
        }
        detected_above -= usize::from(o.detected);
    }
    ForceTable {
        bins,
        unpressed_fingers: unpressed.len() as u64,
        false_alarm_fingers: unpressed.iter().filter(|o| o.detected).count() as u64,
        force_detected_90pct_n,
        net_force_truth,
    }
}

/// `frames` with their shapes replaced by the physics estimator's (the dented surface it
/// estimates from each frame's markers, perturbed by `augmentation` when given), each
/// trajectory run as a stream (frames in order, `frame_index × frame_secs` seconds apart; the
/// estimator reset at each new trajectory): the training input of a contact model that reads
/// the physics estimator's shapes. Trajectories run in parallel, one estimator per thread. A
/// finger the estimator cannot estimate keeps the estimator's free shape.
///
/// # Errors
/// Frames that do not fit the hand, an invalid augmentation, or a failing estimator.
pub fn with_physics_shapes(
    hand: &HandModel,
    frames: &[LabelledFrame],
    frame_secs: Real,
    material: &moe_physics::HandMaterial,
    config: &moe_physics::PhysicsConfig,
    augmentation: Option<&crate::contact_eval::MarkerAugmentation>,
) -> Result<Vec<LabelledFrame>, LabError> {
    use rayon::prelude::*;
    if let Some(a) = augmentation {
        a.validate()?;
    }
    if !(frame_secs.is_finite() && frame_secs > 0.0) {
        return Err(LabError::InvalidParameter {
            name: "frame_secs",
            value: frame_secs,
            reason: "must be finite and positive",
        });
    }
    let distal_order = crate::contact_eval::distal_marker_order(hand);
    // Runs of consecutive frames of one trajectory, with their first frame's index in `frames`.
    let mut runs: Vec<(usize, &[LabelledFrame])> = Vec::new();
    let mut start = 0;
    for k in 1..=frames.len() {
        if k == frames.len() || frames[k].trajectory_id != frames[start].trajectory_id {
            runs.push((start, &frames[start..k]));
            start = k;
        }
    }
    let out: Vec<Vec<LabelledFrame>> = runs
        .par_iter()
        .map_init(
            || PhysicsEstimator::new(hand, material, config),
            |estimator, &(first, run)| {
                let estimator = estimator.as_mut().map_err(|e| LabError::from(e.clone()))?;
                estimator.reset();
                run.iter()
                    .enumerate()
                    .map(|(j, frame)| {
                        frame.shape.check_against(hand)?;
                        let markers = match augmentation {
                            Some(a) => {
                                let mut rng = SeededRng::new(a.seed).split((first + j) as u64);
                                a.apply(&frame.markers, &distal_order, &mut rng)
                            }
                            None => frame.markers.clone(),
                        };
                        let est = estimator.estimate(
                            &frame
                                .observation()
                                .with_keypoints(&markers)
                                .with_time(f64::from(frame.frame_index) * frame_secs),
                        )?;
                        Ok(LabelledFrame {
                            shape: est.shape,
                            ..frame.clone()
                        })
                    })
                    .collect::<Result<Vec<_>, LabError>>()
            },
        )
        .collect::<Result<_, _>>()?;
    Ok(out.into_iter().flatten().collect())
}

/// What else is evaluated on the same frames besides the physics estimator.
#[derive(Debug, Clone, Copy)]
pub struct Comparison<'a> {
    /// The trained network: the DGCNN on the physics shapes, and on SR-ARAP shapes.
    pub dgcnn: Option<&'a DgcnnEstimator>,
    /// SR-ARAP options of the paper's chain (its depth settings are used, enabled, for the
    /// row registered to the depth image; the paper's row reads markers only).
    pub shape: &'a ShapeConfig,
    /// Every frame on its own: the physics estimator is reset before each frame (no stream:
    /// the free finger starts from rest, nothing is carried over), the ablation of memory
    /// across frames.
    pub forget_between_frames: bool,
}

/// Evaluates `estimator` on `frames` (whole trajectories, in order) with markers from `source`,
/// and the comparison on the same markers.
///
/// # Errors
/// Frames or markers that do not fit the hand, or a failing estimator (a finger whose physics
/// estimate fails is counted in [`PhysicsEvaluation::failed_fingers`] instead).
pub fn evaluate_physics(
    hand: &HandModel,
    frames: &[StreamFrame],
    source: MarkerSource<'_>,
    estimator: &mut PhysicsEstimator,
    comparison: Comparison<'_>,
) -> Result<PhysicsEvaluation, LabError> {
    if frames.is_empty() {
        return Err(LabError::InvalidEvaluation {
            reason: "no frames to evaluate".into(),
        });
    }
    let markers_only = ShapeConfig {
        depth: ShapeDepth {
            enabled: false,
            ..comparison.shape.depth.clone()
        },
        ..comparison.shape.clone()
    };
    let with_depth = ShapeConfig {
        depth: ShapeDepth {
            enabled: true,
            ..comparison.shape.depth.clone()
        },
        ..comparison.shape.clone()
    };
    let has_depth = (0..frames.len()).any(|k| source.depth(k).is_some());
    let mut arap = match comparison.dgcnn {
        Some(_) => Some(MultiShapeEstimator::new(hand.clone(), markers_only)?),
        None => None,
    };
    let mut arap_depth = match comparison.dgcnn {
        Some(_) if has_depth => Some(MultiShapeEstimator::new(hand.clone(), with_depth)?),
        _ => None,
    };
    let mut physics = ContactMetrics::default();
    let mut on_physics = ContactMetrics::default();
    let mut on_arap = ContactMetrics::default();
    let mut on_arap_depth = ContactMetrics::default();
    let mut on_truth = ContactMetrics::default();
    let mut placed = ContactMetrics::default();
    let (mut physics_bcd, mut arap_bcd, mut arap_depth_bcd) = (0.0, 0.0, 0.0);
    let mut outcomes = Vec::new();
    let mut times = Vec::with_capacity(frames.len());
    let mut failed = 0;
    let mut degraded = 0;
    let mut solves = Vec::with_capacity(frames.len() * hand.num_fingers());
    let mut trajectories = 0;
    let mut previous: Option<u64> = None;
    for (k, sf) in frames.iter().enumerate() {
        let frame = &sf.frame;
        frame.shape.check_against(hand)?;
        let new_trajectory = previous != Some(frame.trajectory_id);
        if new_trajectory || comparison.forget_between_frames {
            estimator.reset();
            // A warm-started SR-ARAP (the shape config's `warm_start`) forgets as well.
            for a in [arap.as_mut(), arap_depth.as_mut()].into_iter().flatten() {
                a.reset_tracking();
            }
        }
        if new_trajectory {
            trajectories += 1;
            previous = Some(frame.trajectory_id);
        }
        let markers = source.markers(k, frame)?;
        let start = Instant::now();
        let mut observation = frame.observation().with_keypoints(&markers);
        if let Some(depth) = source.depth(k) {
            observation = observation.with_depth(depth);
        }
        let est = estimator.estimate(&observation.with_time(sf.time_secs))?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
        failed += est
            .details
            .fingers
            .iter()
            .filter(|f| f.error.is_some())
            .count() as u64;
        degraded += est.details.fingers.iter().filter(|f| f.degraded).count() as u64;
        solves.extend(est.details.fingers.iter().map(|f| f.solves));
        let physics_labels = est.contact.labels_at(moe_physics::CONTACT_THRESHOLD);
        physics.add(&frame.shape, &frame.contact, &physics_labels)?;
        physics_bcd += bcd_of(&est.shape, &frame.shape)?;
        for f in 0..hand.num_fingers() {
            outcomes.push(finger_outcome(hand, sf, &est, f));
        }
        if let (Some(dgcnn), Some(arap)) = (comparison.dgcnn, arap.as_mut()) {
            // The network's contact labels on a shape of this frame.
            let labels_on = |shape: &HandShape| -> Result<Vec<Vec<bool>>, LabError> {
                let p = dgcnn.estimate_map(&ContactInput::new(shape, observation))?;
                Ok(p.labels_at(dgcnn.threshold()))
            };
            let network_labels = labels_on(&est.shape)?;
            on_physics.add(&frame.shape, &frame.contact, &network_labels)?;
            let together: Vec<Vec<bool>> = physics_labels
                .iter()
                .zip(&network_labels)
                .map(|(ph, nw)| {
                    if !ph.iter().any(|&c| c) {
                        vec![false; ph.len()]
                    } else if nw.iter().any(|&c| c) {
                        nw.clone()
                    } else {
                        ph.clone()
                    }
                })
                .collect();
            placed.add(&frame.shape, &frame.contact, &together)?;
            let shape = arap.estimate(&markers)?.shape;
            arap_bcd += bcd_of(&shape, &frame.shape)?;
            on_arap.add(&frame.shape, &frame.contact, &labels_on(&shape)?)?;
            if let Some(arap_depth) = arap_depth.as_mut() {
                let shape = arap_depth
                    .estimate_with(&markers, observation.depth.as_ref())?
                    .shape;
                arap_depth_bcd += bcd_of(&shape, &frame.shape)?;
                on_arap_depth.add(&frame.shape, &frame.contact, &labels_on(&shape)?)?;
            }
            on_truth.add(&frame.shape, &frame.contact, &labels_on(&frame.shape)?)?;
        }
    }
    let n = frames.len() as Real;
    let mut sorted = times.clone();
    sorted.sort_by(Real::total_cmp);
    let net = frames.iter().all(|f| f.finger_force_n.is_some());
    Ok(PhysicsEvaluation {
        markers: source.name(),
        frames: frames.len() as u64,
        trajectories,
        physics: physics.report(),
        dgcnn_on_physics: comparison.dgcnn.map(|_| on_physics.report()),
        dgcnn_on_sr_arap: comparison.dgcnn.map(|_| on_arap.report()),
        dgcnn_on_sr_arap_depth: arap_depth.as_ref().map(|_| on_arap_depth.report()),
        dgcnn_on_true_shape: comparison.dgcnn.map(|_| on_truth.report()),
        physics_placed_by_dgcnn: comparison.dgcnn.map(|_| placed.report()),
        physics_shape_bcd_mm: 1e3 * physics_bcd / n,
        sr_arap_shape_bcd_mm: if comparison.dgcnn.is_some() {
            1e3 * arap_bcd / n
        } else {
            Real::NAN
        },
        sr_arap_depth_shape_bcd_mm: arap_depth.as_ref().map(|_| 1e3 * arap_depth_bcd / n),
        forces: force_table(&outcomes, net),
        stream: stream_table(&outcomes, hand.num_fingers()),
        physics_ms_median: median(sorted.clone()),
        physics_ms_p90: sorted[(sorted.len() * 9 / 10).min(sorted.len() - 1)],
        failed_fingers: failed,
        solves: SolveCounts::of(solves),
        degraded_fingers: degraded,
    })
}

/// The BCD between two shapes as whole-hand point sets (as Table 1's shape rows), metres.
fn bcd_of(a: &HandShape, b: &HandShape) -> Result<Real, LabError> {
    let a: Vec<Point3> = a.fingers.iter().flatten().copied().collect();
    let b: Vec<Point3> = b.fingers.iter().flatten().copied().collect();
    Ok(bcd(&a, &b)?)
}

/// A simulated stream with the markers the perception stage detects in its rendered wrist
/// camera frames: the scene is simulated, every saved frame rendered by the scene's camera
/// (noise seeded by `seed`) and its markers detected and tracked by a detector with parameters
/// `detector`. Returns the stream and, per frame, the detected keypoints and the depth
/// image.
///
/// # Errors
/// As [`simulate_stream`], and a camera or detector the scene does not allow.
pub fn simulate_perceived(
    config: &SceneConfig,
    hand: &HandModel,
    trajectory_id: u64,
    seed: u64,
    detector: moe_touch::perception::DetectorConfig,
) -> Result<(Vec<StreamFrame>, Vec<PerceivedFrame>), LabError> {
    let mut scene = Scene::with_hand(config.clone(), hand.clone())?;
    let recorder = crate::episode::EpisodeRecorder::new(&scene, "perceived", seed)?;
    let mut detector =
        moe_touch::perception::MarkerDetector::for_episode(recorder.info(), hand, detector)?;
    let steps = scene.num_steps();
    let mut stream = Vec::new();
    let mut seen = Vec::new();
    moe_tendon_sim::run_with(&mut scene, steps, |scene, state| {
        let saved = scene.frame(state);
        let index = stream.len() as u64;
        let rendered = recorder.frame(scene, &saved, index)?;
        let detection = detector.detect(&rendered.color_rgb8, &rendered.depth_m)?;
        seen.push(PerceivedFrame {
            keypoints: detection.keypoints,
            depth: OwnedDepthImage::new(
                rendered.depth_m,
                *detector.intrinsics(),
                detector.hand_from_camera(),
            )?,
        });
        stream.push(StreamFrame::from_sim(
            hand,
            &saved,
            trajectory_id,
            index as u32,
        )?);
        Ok::<(), LabError>(())
    })?;
    Ok((stream, seen))
}

/// One trial of a plate scene (Table 2) for the physics estimator.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsPlateTrial {
    /// Scene name.
    pub scene: String,
    /// Region pressed.
    pub region: String,
    /// Trial number (0: the scene as committed).
    pub trial: u64,
    /// Frames with true contact.
    pub contact_frames: u64,
    /// The physics estimator's map over those frames.
    pub physics: ContactReport,
    /// The DGCNN on the physics shapes over those frames.
    pub dgcnn_on_physics: Option<ContactReport>,
}

/// Table 2 for the physics estimator: every plate scene, `trials` trials each (trial 0 as
/// committed, the others perturbed as [`crate::contact_eval::perturbed_plate`] does), the whole
/// stream estimated in order and the frames with true contact scored.
///
/// # Errors
/// As [`simulate_stream`] and the estimators.
pub fn evaluate_plates_physics(
    hand: &HandModel,
    scenes: &[crate::contact_eval::PlateScene],
    trials: u64,
    seed: u64,
    estimator: &mut PhysicsEstimator,
    dgcnn: Option<&DgcnnEstimator>,
) -> Result<Vec<PhysicsPlateTrial>, LabError> {
    let mut out = Vec::new();
    for t in crate::contact_eval::plate_trials(scenes, trials, seed) {
        let (scene, trial) = (t.scene, t.trial);
        let frames = simulate_stream(&t.config, hand, trial)?;
        estimator.reset();
        let (mut physics, mut on_physics) = (ContactMetrics::default(), ContactMetrics::default());
        let mut contact_frames = 0;
        for sf in &frames {
            let frame = &sf.frame;
            let est = estimator.estimate(&frame.observation().with_time(sf.time_secs))?;
            if frame.contact_count() == 0 {
                continue;
            }
            contact_frames += 1;
            physics.add(
                &frame.shape,
                &frame.contact,
                &est.contact.labels_at(moe_physics::CONTACT_THRESHOLD),
            )?;
            if let Some(d) = dgcnn {
                let p = d.estimate_map(&ContactInput::of_frame(frame, &est.shape))?;
                on_physics.add(&frame.shape, &frame.contact, &p.labels_at(d.threshold()))?;
            }
        }
        out.push(PhysicsPlateTrial {
            scene: scene.name.clone(),
            region: scene.region.clone(),
            trial,
            contact_frames,
            physics: physics.report(),
            dgcnn_on_physics: dgcnn.map(|_| on_physics.report()),
        });
    }
    Ok(out)
}

mod table;
#[cfg(test)]
mod tests;
