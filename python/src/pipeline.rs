//! The per-frame pipeline: colour, depth and the hand's pose in; markers, shape, contact and
//! force out.

use std::path::PathBuf;
use std::sync::Mutex;

use moe_geom::{Observation, WorldFromHand};
use moe_physics::{HandMaterial, PhysicsConfig, PhysicsDetails};
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::{FrameFailure, PaperPipeline, PhysicsPipeline, RgbdFrame, StreamEvent};
use numpy::{PyArray1, PyArray2, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::contact::ContactModel;
use crate::convert::{self, OrRaise, invalid};
use crate::hand::{Camera, Hand};
use crate::physics::ContactLoad;
use crate::settings::settings;
use crate::shape::shape_config;

/// The two pipelines the tool runs.
enum Inner {
    /// The physics estimator (the tool's default).
    Physics(Box<PhysicsPipeline>),
    /// SR-ARAP and a trained network (the paper's pipeline).
    Paper(Box<PaperPipeline>),
}

/// What one frame gives: the runtime's `FrameEstimate` and, with the physics estimator, its
/// details.
struct Processed {
    estimate: moe_touch::FrameEstimate,
    physics: Option<PhysicsDetails>,
}

/// The marker detector for `camera` and `hand`, with parameters from `detector` (a TOML or JSON
/// `DetectorConfig` file, or a dict of its fields) or the defaults.
fn detector(
    camera: &Camera,
    hand: &Hand,
    config: Option<&Bound<'_, PyAny>>,
) -> PyResult<MarkerDetector> {
    let config: DetectorConfig = settings(config, "detector")?;
    MarkerDetector::new(
        camera.intrinsics,
        camera.hand_from_camera,
        &hand.model,
        config,
    )
    .py()
}

/// The whole pipeline on wrist RGB-D frames: marker perception, the hand's shape, contact per
/// vertex, contact points in the hand and the world, and with the physics estimator the force
/// on every vertex and finger. Frames given with their time carry memory across the stream.
#[pyclass(module = "moe_touch")]
pub struct Pipeline {
    inner: Mutex<Inner>,
    size: (usize, usize),
    num_fingers: usize,
    /// Tendons of every finger (`None` for a hand whose fingers differ: no pulls from Python).
    tendons: Option<usize>,
    /// `"physics"` or `"dgcnn"` (the tool's `--contact`).
    method: &'static str,
    threshold: f64,
}

impl Pipeline {
    fn wrap(inner: Inner, camera: &Camera, hand: &Hand) -> Self {
        // Read once here, so that asking for them never waits on a frame being processed.
        let (method, threshold) = match &inner {
            Inner::Physics(p) => ("physics", p.threshold()),
            Inner::Paper(p) => ("dgcnn", p.threshold()),
        };
        Self {
            inner: Mutex::new(inner),
            size: (
                camera.intrinsics.height as usize,
                camera.intrinsics.width as usize,
            ),
            num_fingers: hand.model.num_fingers(),
            tendons: hand.model.tendons_per_finger().ok(),
            method,
            threshold,
        }
    }

    fn lock(&self) -> PyResult<std::sync::MutexGuard<'_, Inner>> {
        convert::lock(&self.inner, "pipeline")
    }
}

#[pymethods]
impl Pipeline {
    /// The physics estimator's pipeline (the `moe-touch` tool's default): the finger's FEM model
    /// read backwards from the markers, the tendon pulls and the hand's pose. `material`
    /// (`HandMaterial`; `moe-touch calibrate` writes it), `config` (`PhysicsConfig`) and
    /// `detector` (the marker detector's `DetectorConfig`) are each a TOML or JSON file or a
    /// dict of the settings (unknown keys are refused); the defaults without.
    #[staticmethod]
    #[pyo3(signature = (hand, camera, *, material=None, config=None, detector=None))]
    fn physics(
        py: Python<'_>,
        hand: &Hand,
        camera: &Camera,
        material: Option<&Bound<'_, PyAny>>,
        config: Option<&Bound<'_, PyAny>>,
        detector: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let marker_detector = self::detector(camera, hand, detector)?;
        // The estimator validates both.
        let material: HandMaterial = settings(material, "material")?;
        let config: PhysicsConfig = settings(config, "config")?;
        let pipeline = py.detach(|| {
            PhysicsPipeline::physics(hand.model.clone(), marker_detector, &material, &config).py()
        })?;
        Ok(Self::wrap(Inner::Physics(Box::new(pipeline)), camera, hand))
    }

    /// The paper's pipeline: SR-ARAP shape (`iterations` per frame, default 50;
    /// `warm_start` starts each frame from the previous shape), then the trained network at
    /// `model` (`NAME.safetensors` with its card), contact where it reaches the card's
    /// threshold (the tool's `--contact dgcnn`). `shape` (`ShapeConfig`, the tool's
    /// `--shape-config`; its `depth` part registers the shape to the depth image as well) and
    /// `detector` as the settings of `physics`.
    #[staticmethod]
    #[pyo3(signature = (hand, camera, model, *, iterations=None, warm_start=false, shape=None, detector=None))]
    #[allow(clippy::too_many_arguments)]
    fn paper(
        py: Python<'_>,
        hand: &Hand,
        camera: &Camera,
        model: PathBuf,
        iterations: Option<usize>,
        warm_start: bool,
        shape: Option<&Bound<'_, PyAny>>,
        detector: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let marker_detector = self::detector(camera, hand, detector)?;
        let options = shape_config(settings(shape, "shape")?, iterations, warm_start);
        let pipeline = py.detach(|| {
            let network = ContactModel::estimator(&model, hand)?;
            moe_touch::Pipeline::paper(hand.model.clone(), marker_detector, network, options).py()
        })?;
        Ok(Self::wrap(Inner::Paper(Box::new(pipeline)), camera, hand))
    }

    /// Runs every stage on one frame. `color` is `(height, width, 3)` uint8 RGB, `depth`
    /// `(height, width)` float32 metres (0 or NaN: no depth), `world_from_hand` 4 × 4, `pulls`
    /// `(fingers, tendons)` metres (the physics estimator needs them), `time`
    /// seconds on a clock that only moves forward (frames further apart than the memory
    /// horizon, or untimed, start afresh). The arrays are read in place when C-contiguous; do
    /// not change them from another thread during the call. The GIL is released while the
    /// pipeline runs.
    #[pyo3(signature = (color, depth, world_from_hand, pulls=None, time=None))]
    fn process<'py>(
        &self,
        py: Python<'py>,
        color: PyReadonlyArray3<'py, u8>,
        depth: PyReadonlyArray2<'py, f32>,
        world_from_hand: PyReadonlyArray2<'py, f64>,
        pulls: Option<PyReadonlyArray2<'py, f64>>,
        time: Option<f64>,
    ) -> PyResult<FrameEstimate> {
        // Refused before the pipeline sees the frame: the input stage, nothing changed.
        let checked = || -> PyResult<_> {
            let (h, w) = self.size;
            if color.shape() != [h, w, 3] {
                return Err(invalid(format!(
                    "color: expected a ({h}, {w}, 3) uint8 array for the camera, got shape {:?}",
                    color.shape()
                )));
            }
            if depth.shape() != [h, w] {
                return Err(invalid(format!(
                    "depth: expected a ({h}, {w}) float32 array for the camera, got shape {:?}",
                    depth.shape()
                )));
            }
            let world_from_hand =
                WorldFromHand::new(convert::to_iso(&world_from_hand, "world_from_hand")?);
            let pulls = pulls
                .as_ref()
                .map(|p| convert::to_hand_pulls(p, self.num_fingers, self.tendons))
                .transpose()?;
            Ok((world_from_hand, pulls))
        };
        let (world_from_hand, pulls) =
            checked().map_err(|e| with_status(py, e, "input", None, None, None))?;
        // C-contiguous arrays are read in place; others (Fortran order, strided views) are copied
        // once into row-major order (`as_slice` also accepts Fortran order, hence the check).
        let color_copy;
        let color_rgb8 = match color.as_slice() {
            Ok(s) if color.is_c_contiguous() => s,
            _ => {
                color_copy = color.as_array().iter().copied().collect::<Vec<u8>>();
                &color_copy
            }
        };
        let depth_copy;
        let depth_m = match depth.as_slice() {
            Ok(s) if depth.is_c_contiguous() => s,
            _ => {
                depth_copy = depth.as_array().iter().copied().collect::<Vec<f32>>();
                &depth_copy
            }
        };
        let processed = py.detach(|| {
            let mut inner = self.lock()?;
            let frame = RgbdFrame {
                color_rgb8,
                depth_m,
            };
            Ok::<_, PyErr>(run(
                &mut inner,
                frame,
                world_from_hand,
                pulls.as_deref(),
                time,
            ))
        })?;
        match processed {
            Ok(p) => FrameEstimate::new(py, p),
            Err(failure) => Err(frame_failure(py, *failure)),
        }
    }

    /// Forgets the stream (marker tracks, warm starts, the physics estimator's memory).
    fn reset(&self, py: Python<'_>) -> PyResult<()> {
        // Waits for a frame another thread is processing without holding the GIL.
        py.detach(|| {
            match &mut *self.lock()? {
                Inner::Physics(p) => p.reset(),
                Inner::Paper(p) => p.reset(),
            }
            Ok(())
        })
    }

    /// The contact threshold: vertices at or above it are contact points.
    #[getter]
    fn threshold(&self) -> f64 {
        self.threshold
    }

    /// `"physics"` or `"dgcnn"` (the tool's `--contact` for this pipeline).
    #[getter]
    fn method(&self) -> &'static str {
        self.method
    }
}

/// One frame through `inner`, timed when `time` is given.
fn run(
    inner: &mut Inner,
    frame: RgbdFrame<'_>,
    world_from_hand: WorldFromHand,
    pulls: Option<&[Vec<f64>]>,
    time: Option<f64>,
) -> Result<Processed, Box<FrameFailure>> {
    let mut observation = Observation::new().with_world_from_hand(world_from_hand);
    observation.tendon_pull_m = pulls;
    observation.time_secs = time;
    Ok(match inner {
        Inner::Physics(p) => {
            let (estimate, physics) = p.process(frame, &observation)?.into_parts();
            Processed {
                estimate,
                physics: Some(physics),
            }
        }
        Inner::Paper(p) => Processed {
            estimate: p.process(frame, &observation)?,
            physics: None,
        },
    })
}

/// A frame the pipeline could not estimate, raised as the `MoeTouchError` of its error's kind
/// with the frame's status as attributes: `stage` (`"input"`, `"markers"`, `"estimate"` or
/// `"contact points"`), `keypoints` (per finger, the markers found, NaN where unseen; `None`
/// when perception did not run), `markers_found`, `stream` and `gap_secs` (`None` for a frame
/// refused before it entered the stream). The pipeline goes on with the next frame.
fn frame_failure(py: Python<'_>, failure: FrameFailure) -> PyErr {
    let keypoints = failure.keypoints.as_ref().map(|k| {
        k.fingers
            .iter()
            .map(|m| convert::optional_points(py, m).unbind())
            .collect::<Vec<_>>()
    });
    with_status(
        py,
        convert::raise(&failure.error),
        &failure.stage.to_string(),
        keypoints,
        failure.markers.as_ref().map(|m| m.found),
        failure.stream,
    )
}

/// `err` with a failed frame's status as attributes (see [`frame_failure`]).
fn with_status(
    py: Python<'_>,
    err: PyErr,
    stage: &str,
    keypoints: Option<Vec<Py<PyArray2<f64>>>>,
    markers_found: Option<usize>,
    stream: Option<StreamEvent>,
) -> PyErr {
    let value = err.value(py);
    let (stream, gap_secs) = stream.map_or((None, None), |e| {
        let (kind, gap) = stream_kind(e);
        (Some(kind), gap)
    });
    let set = || -> PyResult<()> {
        value.setattr("stage", stage)?;
        value.setattr("keypoints", keypoints)?;
        value.setattr("markers_found", markers_found)?;
        value.setattr("stream", stream)?;
        value.setattr("gap_secs", gap_secs)?;
        Ok(())
    };
    match set() {
        Ok(()) => err,
        Err(e) => e,
    }
}

/// The stream event as the Python API names it, and its gap in seconds.
fn stream_kind(e: StreamEvent) -> (&'static str, Option<f64>) {
    match e {
        StreamEvent::Untimed => ("untimed", None),
        StreamEvent::Started => ("started", None),
        StreamEvent::Continued { gap_secs } => ("continued", Some(gap_secs)),
        StreamEvent::Restarted { gap_secs } => ("restarted", Some(gap_secs)),
        StreamEvent::Recovered { gap_secs } => ("recovered", gap_secs),
    }
}

/// The physics estimator's loads as `ContactLoad` objects.
pub(crate) fn loads(
    py: Python<'_>,
    loads: &[moe_physics::ContactLoad],
) -> PyResult<Vec<Py<ContactLoad>>> {
    loads
        .iter()
        .map(|l| Py::new(py, ContactLoad::new(py, l)))
        .collect()
}

/// The net force the world exerts on every finger, `(fingers, 3)`.
pub(crate) fn finger_forces(py: Python<'_>, e: &PhysicsDetails) -> Py<PyArray2<f64>> {
    convert::vectors(py, &e.finger_forces_n()).unbind()
}

/// The probability that each finger is pressed, `(fingers,)`.
pub(crate) fn pressed_probabilities(py: Python<'_>, e: &PhysicsDetails) -> Py<PyArray1<f64>> {
    convert::array1(
        py,
        e.fingers.iter().map(|f| f.pressed_probability).collect(),
    )
    .unbind()
}

/// Wall time of each stage of one frame, milliseconds.
#[pyclass(module = "moe_touch", frozen, get_all)]
#[derive(Debug, Clone, Copy)]
pub struct StageTimings {
    /// Marker perception.
    markers_ms: f64,
    /// The estimator (shape and contact).
    estimate_ms: f64,
    /// Contact points (the threshold, the world frame).
    points_ms: f64,
    /// The whole frame.
    total_ms: f64,
}

#[pymethods]
impl StageTimings {
    fn __repr__(&self) -> String {
        format!(
            "StageTimings(markers_ms={:.3}, estimate_ms={:.3}, points_ms={:.3}, total_ms={:.3})",
            self.markers_ms, self.estimate_ms, self.points_ms, self.total_ms
        )
    }
}

/// Everything the pipeline estimated about one frame. Arrays are float64 in metres and
/// newtons; per-finger values are lists with one array per finger.
#[pyclass(module = "moe_touch", frozen, get_all)]
pub struct FrameEstimate {
    /// Every marker in the hand frame, `(markers, 3)` per finger, NaN where not seen.
    keypoints: Vec<Py<PyArray2<f64>>>,
    /// The estimated surface, hand frame, `(n, 3)` per finger.
    shape: Vec<Py<PyArray2<f64>>>,
    /// Contact probability of every vertex, `(n,)` per finger.
    contact: Vec<Py<PyArray1<f64>>>,
    /// Force on every vertex, hand frame, newtons, `(n, 3)` per finger (physics), else None.
    vertex_force_n: Option<Vec<Py<PyArray2<f64>>>>,
    /// Net force the world exerts on every finger, hand frame, newtons, `(fingers, 3)`
    /// (physics), else None.
    finger_force_n: Option<Py<PyArray2<f64>>>,
    /// Probability that each finger is pressed, `(fingers,)` (physics), else None.
    pressed_probability: Option<Py<PyArray1<f64>>>,
    /// The loads found (physics; empty otherwise).
    loads: Vec<Py<ContactLoad>>,
    /// Contact points (vertices at or above the threshold), hand frame, `(k, 3)`.
    contacts_in_hand: Py<PyArray2<f64>>,
    /// The same points in the world frame, `(k, 3)`.
    contacts_in_world: Py<PyArray2<f64>>,
    /// Finger of each contact point, `(k,)`.
    contact_finger: Py<PyArray1<u32>>,
    /// Vertex of each contact point on its finger, `(k,)`.
    contact_vertex: Py<PyArray1<u32>>,
    /// Probability of each contact point, `(k,)`.
    contact_point_probability: Py<PyArray1<f64>>,
    /// Markers found in the image.
    markers_found: usize,
    /// Fingers none of whose markers were seen.
    fingers_without_markers: Vec<usize>,
    /// Where the hand was, world-from-hand 4 × 4.
    world_from_hand: Py<PyArray2<f64>>,
    /// Per-stage wall time.
    timings: StageTimings,
    /// Where the frame stands in the stream: "untimed", "started", "continued", "restarted" or
    /// "recovered" (the first frame after one whose estimate failed: the estimator starts
    /// again from rest).
    stream: &'static str,
    /// Seconds since the previous frame ("continued", "restarted", a timed "recovered"), else
    /// None.
    gap_secs: Option<f64>,
}

impl FrameEstimate {
    fn new(py: Python<'_>, p: Processed) -> PyResult<Self> {
        let e = p.estimate;
        let points = |f: &[moe_geom::ContactPoint]| {
            convert::points(py, &f.iter().map(|c| c.point).collect::<Vec<_>>()).unbind()
        };
        let (stream, gap_secs) = stream_kind(e.stream);
        let physics = p.physics.as_ref();
        let loads = physics.map_or_else(|| Ok(Vec::new()), |e| loads(py, &e.loads))?;
        Ok(Self {
            keypoints: e
                .keypoints
                .fingers
                .iter()
                .map(|k| convert::optional_points(py, k).unbind())
                .collect(),
            shape: e
                .shape
                .fingers
                .iter()
                .map(|v| convert::points(py, v).unbind())
                .collect(),
            contact: e
                .contact
                .fingers
                .into_iter()
                .map(|p| convert::array1(py, p).unbind())
                .collect(),
            vertex_force_n: e.vertex_force_n.as_ref().map(|fingers| {
                fingers
                    .iter()
                    .map(|f| convert::vectors(py, f).unbind())
                    .collect()
            }),
            finger_force_n: physics.map(|e| finger_forces(py, e)),
            pressed_probability: physics.map(|e| pressed_probabilities(py, e)),
            loads,
            contacts_in_hand: points(&e.contacts_in_hand),
            contacts_in_world: points(&e.contacts_in_world),
            contact_finger: convert::array1(
                py,
                e.contacts_in_hand.iter().map(|c| c.finger as u32).collect(),
            )
            .unbind(),
            contact_vertex: convert::array1(
                py,
                e.contacts_in_hand.iter().map(|c| c.vertex).collect(),
            )
            .unbind(),
            contact_point_probability: convert::array1(
                py,
                e.contacts_in_hand.iter().map(|c| c.probability).collect(),
            )
            .unbind(),
            markers_found: e.markers.found,
            fingers_without_markers: e.fingers_without_markers,
            world_from_hand: convert::iso(py, e.world_from_hand.iso()).unbind(),
            timings: StageTimings {
                markers_ms: e.timings.markers_ms,
                estimate_ms: e.timings.estimate_ms,
                points_ms: e.timings.points_ms,
                total_ms: e.timings.total_ms,
            },
            stream,
            gap_secs,
        })
    }
}

#[pymethods]
impl FrameEstimate {
    /// Number of contact points.
    #[getter]
    fn num_contacts(&self, py: Python<'_>) -> usize {
        self.contacts_in_hand.bind(py).shape()[0]
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "FrameEstimate({} markers, {} contact points, {:.1} ms)",
            self.markers_found,
            self.num_contacts(py),
            self.timings.total_ms
        )
    }
}
