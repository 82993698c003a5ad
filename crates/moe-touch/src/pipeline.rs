//! The pipeline a robot runs on every wrist-camera frame (paper Fig. 1): markers → keypoints →
//! hand shape → contact map → contact points in the hand and the world.

use std::time::Instant;

#[cfg(feature = "dgcnn")]
use moe_arap::{MultiShapeEstimator, ShapeConfig};
#[cfg(feature = "dgcnn")]
use moe_contact::DgcnnEstimator;
#[cfg(feature = "dgcnn")]
use moe_geom::Staged;
use moe_geom::{
    ContactMap, ContactPoint, DepthImage, HandEstimate, HandEstimator, HandKeypoints, HandModel,
    HandShape, Observation, Real, RgbdFrame, Vector3, WorldFromHand,
};
use serde::Serialize;

use crate::TouchError;
use crate::filter::{ContactSmoother, KeypointFilter};
use crate::perception::{MarkerDetection, MarkerDetector, MarkerDiagnostics};

/// Wall time of each stage of one frame, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct StageTimings {
    /// Marker perception.
    pub markers_ms: Real,
    /// The estimator: shape and contact (and, for the physics estimator, the loads).
    pub estimate_ms: Real,
    /// Contact points: smoothing, the threshold, the world frame.
    pub points_ms: Real,
    /// The whole frame.
    pub total_ms: Real,
}

/// Everything the pipeline estimates about one frame, with the estimator's own details `D`
/// (the physics estimator's loads and finger reports; nothing for the paper's chain).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameEstimate<D = ()> {
    /// Every marker in the hand frame, `None` where it was not seen (filtered, when the
    /// pipeline filters keypoints).
    pub keypoints: HandKeypoints,
    /// The estimated surface of every finger, hand frame.
    pub shape: HandShape,
    /// Contact probability of every vertex.
    pub contact: ContactMap,
    /// `vertex_force_n[f][v]`: the force on vertex `v` of finger `f`, hand frame, newtons, from
    /// an estimator that estimates force (the physics estimator); `None` otherwise.
    pub vertex_force_n: Option<Vec<Vec<Vector3>>>,
    /// Vertices at or above the contact threshold, positions in the hand frame.
    pub contacts_in_hand: Vec<ContactPoint>,
    /// The same contact points in the world frame.
    pub contacts_in_world: Vec<ContactPoint>,
    /// Where the hand was.
    pub world_from_hand: WorldFromHand,
    /// Fingers none of whose markers were seen (their shape is the estimator's fallback).
    pub fingers_without_markers: Vec<usize>,
    /// What marker perception saw and decided.
    pub markers: MarkerDiagnostics,
    /// Per-stage wall time.
    pub timings: StageTimings,
    /// Where the frame stands in the stream (whether the memory of earlier frames was kept).
    pub stream: StreamEvent,
    /// What the estimator says beyond shape and contact.
    pub details: D,
}

impl<D> FrameEstimate<D> {
    /// The estimate without the estimator's details, and the details.
    pub fn into_parts(self) -> (FrameEstimate, D) {
        let Self {
            keypoints,
            shape,
            contact,
            vertex_force_n,
            contacts_in_hand,
            contacts_in_world,
            world_from_hand,
            fingers_without_markers,
            markers,
            timings,
            stream,
            details,
        } = self;
        (
            FrameEstimate {
                keypoints,
                shape,
                contact,
                vertex_force_n,
                contacts_in_hand,
                contacts_in_world,
                world_from_hand,
                fingers_without_markers,
                markers,
                timings,
                stream,
                details: (),
            },
            details,
        )
    }
}

/// How far apart two frames of one stream may be by default, seconds: further apart, the
/// pipeline forgets what its stages carried (as [`Pipeline::reset`]) and says so.
pub const DEFAULT_MEMORY_HORIZON_SECS: Real = 1.0;

/// Where a frame stands in the stream of frames the pipeline sees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StreamEvent {
    /// A frame without a time: the stages carry their state over as for the next frame.
    Untimed,
    /// The first timed frame since the pipeline was made or reset.
    Started,
    /// A frame within the memory horizon of the previous one.
    Continued {
        /// Time since the previous frame, seconds.
        gap_secs: Real,
    },
    /// A frame further than the memory horizon from the previous one: what the stages carried
    /// was forgotten (as by [`Pipeline::reset`]) before it.
    Restarted {
        /// Time since the previous frame, seconds.
        gap_secs: Real,
    },
    /// The first frame after one whose estimator failed ([`FrameFailure`] at
    /// [`FrameStage::Estimate`]): the estimator starts again from rest, the marker tracks are
    /// kept.
    Recovered {
        /// Time since the previous frame, seconds (`None` for an untimed frame).
        gap_secs: Option<Real>,
    },
}

/// The stage of a frame that failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameStage {
    /// The frame was refused before any stage saw it (no wrist pose, a time not after the
    /// previous frame's, an observation that already carries markers): nothing changed.
    Input,
    /// Marker perception (images that do not fit the camera): the stream's memory is kept.
    Markers,
    /// The estimator (an observation that does not fit the hand, a failing solve): it is
    /// reset, and the next frame starts it from rest ([`StreamEvent::Recovered`]).
    Estimate,
    /// Contact points from the estimate: the stream's memory is kept.
    Points,
}

impl std::fmt::Display for FrameStage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Input => "input",
            Self::Markers => "markers",
            Self::Estimate => "estimate",
            Self::Points => "contact points",
        })
    }
}

/// A frame the pipeline could not estimate whole: what it found before the stage that failed,
/// and why that stage failed. The pipeline goes on with the next frame (see [`FrameStage`] for
/// what each failure does to the stream's memory).
#[derive(Debug)]
pub struct FrameFailure {
    /// Why.
    pub error: TouchError,
    /// The stage that failed.
    pub stage: FrameStage,
    /// The markers found, hand frame, when perception ran (filtered, when the pipeline filters
    /// keypoints).
    pub keypoints: Option<HandKeypoints>,
    /// What marker perception saw and decided, when it ran.
    pub markers: Option<MarkerDiagnostics>,
    /// Fingers none of whose markers were found, when perception ran.
    pub fingers_without_markers: Vec<usize>,
    /// Where the frame stood in the stream; `None` for a frame refused at
    /// [`FrameStage::Input`].
    pub stream: Option<StreamEvent>,
    /// Per-stage wall time up to the failure (zero for the stages that did not run).
    pub timings: StageTimings,
}

impl std::fmt::Display for FrameFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} stage: {}", self.stage, self.error)
    }
}

impl std::error::Error for FrameFailure {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.error.source()
    }
}

impl From<Box<FrameFailure>> for TouchError {
    fn from(f: Box<FrameFailure>) -> Self {
        f.error
    }
}

/// Checks a contact threshold as [`Pipeline::new`] does, for callers that take one long before
/// they build a pipeline.
///
/// # Errors
/// [`TouchError::InvalidParameter`] for a threshold outside `[0, 1]` (or NaN).
pub fn check_contact_threshold(threshold: Real) -> Result<(), TouchError> {
    if (0.0..=1.0).contains(&threshold) {
        Ok(())
    } else {
        Err(TouchError::InvalidParameter {
            name: "contact threshold",
            value: threshold,
            reason: "must be in [0, 1]",
        })
    }
}

/// The paper's estimator: SR-ARAP from the markers, then the DGCNN on that shape.
#[cfg(feature = "dgcnn")]
pub type PaperEstimator = Staged<MultiShapeEstimator, DgcnnEstimator>;

/// The paper's pipeline (`Pipeline::paper`).
#[cfg(feature = "dgcnn")]
pub type PaperPipeline = Pipeline<PaperEstimator>;

/// The pipeline on the physics estimator (`Pipeline::physics`, the default of `moe-touch run`
/// and `demo`). Needs the `physics` feature (the estimator simulates the finger with the FEM
/// model of `moe-tendon-sim`).
#[cfg(feature = "physics")]
pub type PhysicsPipeline = Pipeline<moe_physics::PhysicsEstimator>;

#[cfg(feature = "physics")]
impl Pipeline<moe_physics::PhysicsEstimator> {
    /// The physics estimator of `hand` with `material` and `config` behind `detector`, contact
    /// points where its probability reaches [`moe_physics::CONTACT_THRESHOLD`]. Its memory
    /// across frames (the free finger simulated through the stream, warm starts, and whatever
    /// memory the settings turn on) lasts while frames are timed and no further apart than the
    /// estimator's stream reaches ([`moe_physics::PhysicsConfig::stream_reach_secs`], the
    /// pipeline's memory horizon, so that a frame's [`StreamEvent`] says when it was
    /// forgotten); [`Pipeline::reset`] forgets it. Each frame's details are the loads with
    /// their force, place and uncertainty, and the finger reports
    /// ([`moe_physics::PhysicsDetails`]).
    ///
    /// # Errors
    /// [`TouchError::Physics`] for an invalid material or settings, a material fitted to
    /// another hand, or a finger the FEM cannot mesh.
    pub fn physics(
        hand: HandModel,
        detector: MarkerDetector,
        material: &moe_physics::HandMaterial,
        config: &moe_physics::PhysicsConfig,
    ) -> Result<Self, TouchError> {
        let estimator = moe_physics::PhysicsEstimator::new(&hand, material, config)?;
        Self::new(hand, detector, estimator, moe_physics::CONTACT_THRESHOLD)?
            .with_memory_horizon(config.stream_reach_secs())
    }

    /// [`Pipeline::physics`] with the nominal material and the default settings.
    ///
    /// # Errors
    /// As [`Pipeline::physics`].
    pub fn physics_default(hand: HandModel, detector: MarkerDetector) -> Result<Self, TouchError> {
        Self::physics(
            hand,
            detector,
            &moe_physics::HandMaterial::default(),
            &moe_physics::PhysicsConfig::default(),
        )
    }
}

#[cfg(feature = "dgcnn")]
impl Pipeline<PaperEstimator> {
    /// The paper's pipeline: SR-ARAP with `shape` settings from the markers `detector` finds,
    /// then `model` on that shape, contact points where its probability reaches the model
    /// card's threshold.
    ///
    /// # Errors
    /// SR-ARAP settings out of range or a hand it cannot solve ([`TouchError::Shape`]).
    pub fn paper(
        hand: HandModel,
        detector: MarkerDetector,
        model: DgcnnEstimator,
        shape: ShapeConfig,
    ) -> Result<Self, TouchError> {
        let threshold = model.threshold();
        let estimator = Staged::new(MultiShapeEstimator::new(hand.clone(), shape)?, model);
        Self::new(hand, detector, estimator, threshold)
    }
}

/// The detector, the estimator, and the state a stream of frames needs (marker tracks, the
/// estimator's warm start and memory, the filters); see the module documentation.
#[derive(Debug)]
pub struct Pipeline<E> {
    hand: HandModel,
    detector: MarkerDetector,
    estimator: E,
    threshold: Real,
    keypoint_filter: Option<KeypointFilter>,
    contact_smoother: Option<ContactSmoother>,
    memory_horizon_secs: Real,
    /// The last timed frame's time, seconds.
    last_time_secs: Option<Real>,
    /// Whether the previous frame's estimator failed (the next frame is
    /// [`StreamEvent::Recovered`]).
    recovering: bool,
}

impl<E: HandEstimator> Pipeline<E> {
    /// Puts the stages together: `detector` finds the markers of `hand`, `estimator` turns the
    /// observation into the hand's shape and contact, and vertices at or above `threshold`
    /// (the model card's, for a trained model) are contact points.
    ///
    /// # Errors
    /// [`TouchError::InvalidParameter`] for a threshold outside `[0, 1]`
    /// ([`check_contact_threshold`]).
    pub fn new(
        hand: HandModel,
        detector: MarkerDetector,
        estimator: E,
        threshold: Real,
    ) -> Result<Self, TouchError> {
        check_contact_threshold(threshold)?;
        Ok(Self {
            hand,
            detector,
            estimator,
            threshold,
            keypoint_filter: None,
            contact_smoother: None,
            memory_horizon_secs: DEFAULT_MEMORY_HORIZON_SECS,
            last_time_secs: None,
            recovering: false,
        })
    }
    /// Sets how far apart, in seconds, two timed frames may be and still be one stream
    /// (default [`DEFAULT_MEMORY_HORIZON_SECS`]); further apart, the stages forget the earlier
    /// frames and the frame's [`FrameEstimate::stream`] says so.
    ///
    /// # Errors
    /// [`TouchError::InvalidParameter`] for a horizon that is not finite and positive.
    pub fn with_memory_horizon(mut self, secs: Real) -> Result<Self, TouchError> {
        if !(secs.is_finite() && secs > 0.0) {
            return Err(TouchError::InvalidParameter {
                name: "memory horizon",
                value: secs,
                reason: "must be finite and positive (seconds)",
            });
        }
        self.memory_horizon_secs = secs;
        Ok(self)
    }

    /// Filters the detected keypoints over time before the shape stage (off by default: see
    /// docs/results.md).
    pub fn with_keypoint_filter(mut self, filter: KeypointFilter) -> Self {
        self.keypoint_filter = Some(filter);
        self
    }

    /// Smooths the contact map over time before thresholding (off by default).
    pub fn with_contact_smoothing(mut self, smoother: ContactSmoother) -> Self {
        self.contact_smoother = Some(smoother);
        self
    }

    /// The hand.
    pub fn hand(&self) -> &HandModel {
        &self.hand
    }

    /// The marker detector (its camera, its parameters).
    pub fn detector(&self) -> &MarkerDetector {
        &self.detector
    }

    /// The estimator.
    pub fn estimator(&self) -> &E {
        &self.estimator
    }

    /// The contact threshold.
    pub fn threshold(&self) -> Real {
        self.threshold
    }

    /// Forgets the stream: marker tracks and what the estimator carried from frame to frame.
    pub fn reset(&mut self) {
        self.detector.reset();
        self.estimator.reset();
        if let Some(f) = &mut self.keypoint_filter {
            f.reset();
        }
        if let Some(s) = &mut self.contact_smoother {
            s.reset();
        }
        self.last_time_secs = None;
        self.recovering = false;
    }

    /// Where a frame at `time_secs` stands in the stream: refuses a time that is not finite or
    /// not after the previous frame's (before any stage sees the frame), and forgets the stream
    /// after a gap beyond the horizon.
    fn enter_stream(&mut self, time_secs: Option<Real>) -> Result<StreamEvent, TouchError> {
        let Some(t) = time_secs else {
            let recovered = std::mem::take(&mut self.recovering);
            return Ok(if recovered {
                StreamEvent::Recovered { gap_secs: None }
            } else {
                StreamEvent::Untimed
            });
        };
        if !t.is_finite() {
            return Err(TouchError::InvalidParameter {
                name: "frame time",
                value: t,
                reason: "must be finite (seconds)",
            });
        }
        let event = match self.last_time_secs {
            None => StreamEvent::Started,
            Some(previous) if t <= previous => {
                return Err(TouchError::StreamOutOfOrder {
                    previous_secs: previous,
                    time_secs: t,
                });
            }
            Some(previous) if t - previous > self.memory_horizon_secs => {
                self.reset();
                StreamEvent::Restarted {
                    gap_secs: t - previous,
                }
            }
            Some(previous) if self.recovering => StreamEvent::Recovered {
                gap_secs: Some(t - previous),
            },
            Some(previous) => StreamEvent::Continued {
                gap_secs: t - previous,
            },
        };
        self.last_time_secs = Some(t);
        self.recovering = false;
        Ok(event)
    }

    /// Runs every stage on one camera frame: finds the markers in `frame`, adds them to
    /// `observation` (what the robot knows: the wrist pose, which the pipeline needs for contact
    /// points in the world; the tendon pulls, which the physics estimator and models that take
    /// them need; the time, for a stream), and estimates.
    ///
    /// With a time (seconds on any clock that only moves forward, such as the camera's stamps)
    /// the stream's memory (marker tracks, the physics estimator's simulation of the free
    /// finger) carries over from the previous frame when it is at most the memory's horizon
    /// earlier, and is forgotten after a longer gap, as [`FrameEstimate::stream`] reports.
    /// Without one the frame is [`StreamEvent::Untimed`]. A recorded frame gives both halves:
    /// `pipeline.process(frame.rgbd(), &frame.observation())`.
    ///
    /// A frame that fails is one frame: the pipeline stays usable, and the next frame goes on
    /// from the stream's memory, or, after a failed estimate, from an estimator at rest
    /// ([`StreamEvent::Recovered`]).
    ///
    /// # Errors
    /// A [`FrameFailure`] with what the frame gave before its failing stage (the markers
    /// found, when perception ran) and the error: at [`FrameStage::Input`],
    /// [`TouchError::MissingObservation`] without the wrist pose,
    /// [`TouchError::InvalidObservation`] for an observation that already carries markers or a
    /// depth image (the pipeline finds the markers in the frame and passes its depth image on,
    /// with the camera's intrinsics and mount, to the estimator), [`TouchError::StreamOutOfOrder`]
    /// for a time not after the previous frame's, a time that is not finite; at
    /// [`FrameStage::Markers`], images that do not fit the camera; at [`FrameStage::Estimate`],
    /// an observation that does not fit the hand or a failing estimator.
    pub fn process(
        &mut self,
        frame: RgbdFrame<'_>,
        observation: &Observation<'_>,
    ) -> Result<FrameEstimate<E::Details>, Box<FrameFailure>> {
        let refused = |error: TouchError| {
            Box::new(FrameFailure {
                error,
                stage: FrameStage::Input,
                keypoints: None,
                markers: None,
                fingers_without_markers: Vec::new(),
                stream: None,
                timings: StageTimings::default(),
            })
        };
        if observation.keypoints.is_some() {
            return Err(refused(TouchError::InvalidObservation {
                reason: "it already carries markers; the pipeline finds them in the frame \
                         (give the keypoints to the estimator itself instead)",
            }));
        }
        if observation.depth.is_some() {
            return Err(refused(TouchError::InvalidObservation {
                reason: "it already carries a depth image; the pipeline takes the frame's",
            }));
        }
        let world_from_hand = observation.world_from_hand.ok_or_else(|| {
            refused(TouchError::MissingObservation {
                what: "the wrist pose (world_from_hand), for contact points in the world",
            })
        })?;
        let stream = self.enter_stream(observation.time_secs).map_err(refused)?;
        let start = Instant::now();
        let ms = |a: Instant, b: Instant| 1e3 * (b - a).as_secs_f64();
        let mut detection = match self.detector.detect(frame.color_rgb8, frame.depth_m) {
            Ok(d) => d,
            Err(error) => {
                let markers_ms = ms(start, Instant::now());
                return Err(Box::new(FrameFailure {
                    error,
                    stage: FrameStage::Markers,
                    keypoints: None,
                    markers: None,
                    fingers_without_markers: Vec::new(),
                    stream: Some(stream),
                    timings: StageTimings {
                        markers_ms,
                        total_ms: markers_ms,
                        ..StageTimings::default()
                    },
                }));
            }
        };
        if let Some(f) = &mut self.keypoint_filter {
            detection.keypoints = f.filter(&detection.keypoints);
        }
        let t_markers = Instant::now();
        let fingers_without_markers: Vec<usize> = detection
            .keypoints
            .fingers
            .iter()
            .enumerate()
            .filter(|(_, m)| m.iter().all(Option::is_none))
            .map(|(f, _)| f)
            .collect();
        // The frame's size was checked by the detector, whose camera took it.
        let estimated = DepthImage::new(
            frame.depth_m,
            *self.detector.intrinsics(),
            self.detector.hand_from_camera(),
        )
        .map_err(TouchError::from)
        .and_then(|depth| {
            self.estimator
                .estimate(
                    &observation
                        .with_keypoints(&detection.keypoints)
                        .with_depth(depth),
                )
                .map_err(TouchError::from_estimator)
        });
        let t_estimate = Instant::now();
        let failed = |error: TouchError, stage: FrameStage, detection: MarkerDetection| {
            let end = Instant::now();
            Box::new(FrameFailure {
                error,
                stage,
                keypoints: Some(detection.keypoints),
                markers: Some(detection.diagnostics),
                fingers_without_markers: fingers_without_markers.clone(),
                stream: Some(stream),
                timings: StageTimings {
                    markers_ms: ms(start, t_markers),
                    estimate_ms: ms(t_markers, t_estimate),
                    points_ms: ms(t_estimate, end),
                    total_ms: ms(start, end),
                },
            })
        };
        let HandEstimate {
            shape,
            contact,
            vertex_force_n,
            details,
        } = match estimated {
            Ok(e) => e,
            Err(error) => {
                // What the estimator carried may be half advanced: it starts again from rest,
                // and so does what was smoothed of its maps. The marker tracks are kept.
                self.estimator.reset();
                if let Some(s) = &mut self.contact_smoother {
                    s.reset();
                }
                self.recovering = true;
                return Err(failed(error, FrameStage::Estimate, detection));
            }
        };
        let contact = match &mut self.contact_smoother {
            Some(s) => s.smooth(&contact),
            None => contact,
        };
        let contacts_in_hand = match contact.contacts_above(self.threshold, &shape) {
            Ok(c) => c,
            Err(e) => return Err(failed(e.into(), FrameStage::Points, detection)),
        };
        let contacts_in_world = contacts_in_hand
            .iter()
            .map(|c| ContactPoint {
                point: world_from_hand.transform_point(&c.point),
                ..*c
            })
            .collect();
        let end = Instant::now();
        Ok(FrameEstimate {
            keypoints: detection.keypoints,
            shape,
            contact,
            vertex_force_n,
            contacts_in_hand,
            contacts_in_world,
            world_from_hand,
            fingers_without_markers,
            markers: detection.diagnostics,
            timings: StageTimings {
                markers_ms: ms(start, t_markers),
                estimate_ms: ms(t_markers, t_estimate),
                points_ms: ms(t_estimate, end),
                total_ms: ms(start, end),
            },
            stream,
            details,
        })
    }
}

/// Loads a trained contact model (`NAME.safetensors` and its card `NAME.json`) for `hand`, in
/// f32 on the CPU: what the pipeline runs.
///
/// # Errors
/// Unreadable or malformed files, a missing card ([`TouchError::MissingModelCard`]: the card
/// carries the input features, their normalisation and the threshold), or a model trained for
/// another hand.
#[cfg(feature = "dgcnn")]
pub fn load_contact_model(
    path: &std::path::Path,
    hand: &HandModel,
) -> Result<DgcnnEstimator, TouchError> {
    let files = moe_io::read_model_files(path)?;
    let card = files.card.ok_or_else(|| TouchError::MissingModelCard {
        path: files.card_path.clone(),
    })?;
    Ok(DgcnnEstimator::from_bytes(&files.weights, &card, hand)?)
}
