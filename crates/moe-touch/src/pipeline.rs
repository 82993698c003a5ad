//! The pipeline a robot runs on every wrist-camera frame (paper Fig. 1): markers → keypoints →
//! hand shape → contact map → contact points in the hand and the world.

use std::path::Path;
use std::time::Instant;

use moe_contact::DgcnnEstimator;
use moe_geom::{
    ContactEstimator, ContactInput, ContactMap, ContactPoint, HandKeypoints, HandModel, HandShape,
    Real, ShapeEstimator, ShapeInput, Vector3, WorldFromHand,
};
use serde::Serialize;

use crate::TouchError;
use crate::filter::{ContactSmoother, KeypointFilter};
use crate::perception::{MarkerDetector, MarkerDiagnostics};

/// One wrist-camera frame: colour (RGB8, row-major) and depth (metres along the optical axis,
/// row-major, 0 or NaN where missing), both of the detector's image size.
#[derive(Debug, Clone, Copy)]
pub struct RgbdFrame<'a> {
    /// RGB8, three bytes per pixel.
    pub color_rgb8: &'a [u8],
    /// Depth, metres.
    pub depth_m: &'a [f32],
}

/// Wall time of each stage of one frame, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct StageTimings {
    /// Marker perception.
    pub markers_ms: Real,
    /// Shape estimation.
    pub shape_ms: Real,
    /// Contact estimation and contact points.
    pub contact_ms: Real,
    /// The whole frame.
    pub total_ms: Real,
}

/// Everything the pipeline estimates about one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameEstimate {
    /// Every marker in the hand frame, `None` where it was not seen (filtered, when the
    /// pipeline filters keypoints).
    pub keypoints: HandKeypoints,
    /// The estimated surface of every finger, hand frame.
    pub shape: HandShape,
    /// Contact probability of every vertex.
    pub contact: ContactMap,
    /// `vertex_force_n[f][v]`: the force on vertex `v` of finger `f`, hand frame, newtons, from
    /// a contact estimator that estimates force (the physics estimator); `None` otherwise.
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

/// The pipeline on the physics estimator (the default of `moe-touch run` and `demo`): one
/// estimate per frame serves as its shape and contact stages. Needs the `physics` feature (the
/// estimator simulates the finger with the FEM model of `moe-tendon-sim`).
#[cfg(feature = "physics")]
pub type PhysicsPipeline =
    Pipeline<moe_physics::PhysicsShapeStage, moe_physics::PhysicsContactStage>;

#[cfg(feature = "physics")]
impl PhysicsPipeline {
    /// The physics estimator of `hand` with `material` and `config` behind `detector`, contact
    /// points where its probability reaches [`moe_physics::CONTACT_THRESHOLD`]. Its memory
    /// across frames (the free finger simulated through the stream, warm starts, and whatever
    /// memory the settings turn on) lasts while frames are timed and no further apart than the
    /// estimator's stream reaches ([`moe_physics::PhysicsConfig::stream_reach_secs`], the
    /// pipeline's memory horizon, so that a frame's [`StreamEvent`] says when it was
    /// forgotten); [`Pipeline::reset`] forgets it.
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
        let (shape, contact) = estimator.stages();
        Self::new(
            hand,
            detector,
            shape,
            contact,
            moe_physics::CONTACT_THRESHOLD,
        )?
        .with_memory_horizon(config.stream_reach_secs())
    }

    /// The physics estimator's full estimate of the last frame (loads with their places,
    /// forces and uncertainties, per-finger reports), when there is one.
    pub fn last_physics_estimate(&self) -> Option<moe_physics::PhysicsEstimate> {
        self.contact.last_estimate()
    }
}

/// The stages, and the state a stream of frames needs (marker tracks, the shape estimator's
/// warm start, whatever the contact estimator carries); see the module documentation.
#[derive(Debug)]
pub struct Pipeline<S, C> {
    hand: HandModel,
    detector: MarkerDetector,
    shape: S,
    contact: C,
    threshold: Real,
    keypoint_filter: Option<KeypointFilter>,
    contact_smoother: Option<ContactSmoother>,
    memory_horizon_secs: Real,
    /// The last timed frame's time, seconds.
    last_time_secs: Option<Real>,
}

impl<S, C> Pipeline<S, C>
where
    S: ShapeEstimator,
    C: ContactEstimator,
{
    /// Puts the stages together: `detector` finds the markers of `hand`, `shape` turns them into
    /// the hand's surface, `contact` scores every vertex, and vertices at or above `threshold`
    /// (the model card's, for a trained model) are contact points.
    ///
    /// # Errors
    /// [`TouchError::InvalidParameter`] for a threshold outside `[0, 1]`
    /// ([`check_contact_threshold`]).
    pub fn new(
        hand: HandModel,
        detector: MarkerDetector,
        shape: S,
        contact: C,
        threshold: Real,
    ) -> Result<Self, TouchError> {
        check_contact_threshold(threshold)?;
        Ok(Self {
            hand,
            detector,
            shape,
            contact,
            threshold,
            keypoint_filter: None,
            contact_smoother: None,
            memory_horizon_secs: DEFAULT_MEMORY_HORIZON_SECS,
            last_time_secs: None,
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

    /// The contact stage.
    pub fn contact_estimator(&self) -> &C {
        &self.contact
    }

    /// The contact threshold.
    pub fn threshold(&self) -> Real {
        self.threshold
    }

    /// Forgets the stream: marker tracks, the shape estimator's warm start and what the contact
    /// estimator carried from frame to frame.
    pub fn reset(&mut self) {
        self.detector.reset();
        self.shape.reset();
        self.contact.reset();
        if let Some(f) = &mut self.keypoint_filter {
            f.reset();
        }
        if let Some(s) = &mut self.contact_smoother {
            s.reset();
        }
        self.last_time_secs = None;
    }

    /// Where a frame at `time_secs` stands in the stream: refuses a time that is not finite or
    /// not after the previous frame's (before any stage sees the frame), and forgets the stream
    /// after a gap beyond the horizon.
    fn enter_stream(&mut self, time_secs: Option<Real>) -> Result<StreamEvent, TouchError> {
        let Some(t) = time_secs else {
            return Ok(StreamEvent::Untimed);
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
            Some(previous) => StreamEvent::Continued {
                gap_secs: t - previous,
            },
        };
        self.last_time_secs = Some(t);
        Ok(event)
    }

    /// Runs every stage on a recorded episode frame: its images, its wrist pose, its tendon
    /// pulls and its time.
    ///
    /// # Errors
    /// As [`Pipeline::process_with_pulls`].
    pub fn process_episode_frame(
        &mut self,
        frame: &moe_io::EpisodeFrame,
    ) -> Result<FrameEstimate, TouchError> {
        self.process_timed(
            RgbdFrame {
                color_rgb8: &frame.color_rgb8,
                depth_m: &frame.depth_m,
            },
            WorldFromHand::new(frame.world_from_hand),
            Some(&frame.tendon_pull_m),
            1e-9 * frame.time_ns as f64,
        )
    }

    /// Runs every stage on one frame of a hand at `world_from_hand`, without the tendon pulls
    /// (for contact models that do not take them).
    ///
    /// # Errors
    /// As [`Pipeline::process_with_pulls`].
    pub fn process(
        &mut self,
        frame: RgbdFrame<'_>,
        world_from_hand: WorldFromHand,
    ) -> Result<FrameEstimate, TouchError> {
        self.process_with_pulls(frame, world_from_hand, None)
    }

    /// Runs every stage on one frame of a hand at `world_from_hand` whose tendons the robot
    /// pulled by `tendon_pull_m[f][t]` metres (what a contact model with the `tendon-pull`
    /// feature needs; others ignore it).
    ///
    /// # Errors
    /// Images that do not fit the camera, pulls that do not fit the hand (or missing where the
    /// contact model needs them), or a failing stage.
    pub fn process_with_pulls(
        &mut self,
        frame: RgbdFrame<'_>,
        world_from_hand: WorldFromHand,
        tendon_pull_m: Option<&[Vec<f64>]>,
    ) -> Result<FrameEstimate, TouchError> {
        self.process_observation(frame, world_from_hand, tendon_pull_m, None)
    }

    /// Runs every stage on one frame taken at `time_secs` (seconds on any clock that only
    /// moves forward, such as the camera's timestamps): the stream's memory (marker tracks,
    /// the physics estimator's simulation of the free finger) carries over from the previous
    /// frame when it is at most the memory's horizon earlier, and is forgotten after a longer
    /// gap, as [`FrameEstimate::stream`] reports. This is the call for a live stream.
    ///
    /// # Errors
    /// [`TouchError::StreamOutOfOrder`] for a time not after the previous frame's (nothing
    /// changes), and as [`Pipeline::process_with_pulls`].
    pub fn process_timed(
        &mut self,
        frame: RgbdFrame<'_>,
        world_from_hand: WorldFromHand,
        tendon_pull_m: Option<&[Vec<f64>]>,
        time_secs: f64,
    ) -> Result<FrameEstimate, TouchError> {
        self.process_observation(frame, world_from_hand, tendon_pull_m, Some(time_secs))
    }

    /// [`Pipeline::process_with_pulls`], with the frame's time in seconds where the caller has
    /// one (for estimators that carry state between frames).
    fn process_observation(
        &mut self,
        frame: RgbdFrame<'_>,
        world_from_hand: WorldFromHand,
        tendon_pull_m: Option<&[Vec<f64>]>,
        time_secs: Option<f64>,
    ) -> Result<FrameEstimate, TouchError> {
        let stream = self.enter_stream(time_secs)?;
        let start = Instant::now();
        let mut detection = self.detector.detect(frame.color_rgb8, frame.depth_m)?;
        if let Some(f) = &mut self.keypoint_filter {
            detection.keypoints = f.filter(&detection.keypoints);
        }
        let t_markers = Instant::now();
        let shape = self
            .shape
            .estimate_shape_with(&ShapeInput {
                keypoints: &detection.keypoints,
                tendon_pull_m,
                world_from_hand: Some(&world_from_hand),
                time_secs,
            })
            .map_err(TouchError::from_shape_stage)?;
        let t_shape = Instant::now();
        let estimate = self
            .contact
            .estimate(&ContactInput {
                shape: &shape,
                keypoints: Some(&detection.keypoints),
                tendon_pull_m,
                world_from_hand: Some(&world_from_hand),
                time_secs,
            })
            .map_err(TouchError::from_contact_stage)?;
        let vertex_force_n = estimate.vertex_force_n;
        let mut contact = estimate.map;
        if let Some(s) = &mut self.contact_smoother {
            contact = s.smooth(&contact);
        }
        let contacts_in_hand = contact.contacts_above(self.threshold, &shape)?;
        let contacts_in_world = contacts_in_hand
            .iter()
            .map(|c| ContactPoint {
                point: world_from_hand.transform_point(&c.point),
                ..*c
            })
            .collect();
        let end = Instant::now();
        let ms = |a: Instant, b: Instant| 1e3 * (b - a).as_secs_f64();
        let fingers_without_markers = detection
            .keypoints
            .fingers
            .iter()
            .enumerate()
            .filter(|(_, m)| m.iter().all(Option::is_none))
            .map(|(f, _)| f)
            .collect();
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
                shape_ms: ms(t_markers, t_shape),
                contact_ms: ms(t_shape, end),
                total_ms: ms(start, end),
            },
            stream,
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
pub fn load_contact_model(path: &Path, hand: &HandModel) -> Result<DgcnnEstimator, TouchError> {
    let files = moe_io::read_model_files(path)?;
    let card = files.card.ok_or_else(|| TouchError::MissingModelCard {
        path: files.card_path.clone(),
    })?;
    Ok(DgcnnEstimator::from_bytes(&files.weights, &card, hand)?)
}
