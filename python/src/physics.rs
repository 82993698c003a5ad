//! The physics estimator on its own: markers, tendon pulls and the hand's pose in; the dented
//! shape, contact, loads and forces out (the pipeline's physics stages without the camera).

use std::sync::Mutex;

use moe_geom::{HandEstimator as _, Observation, WorldFromHand};
use moe_physics::{HandMaterial, PhysicsConfig};
use numpy::{PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::convert::{self, OrRaise, invalid};
use crate::hand::Hand;
use crate::pipeline::{finger_forces, loads, pressed_probabilities};
use crate::settings::settings;
use crate::shape::to_keypoints;

/// The finger's FEM model read backwards from its markers: where and how hard each finger is
/// pressed, and its dented shape. Calls given a `time` carry memory across a stream.
#[pyclass(module = "moe_touch")]
pub(crate) struct PhysicsEstimator {
    estimator: Mutex<moe_physics::PhysicsEstimator>,
    num_fingers: usize,
    tendons: Option<usize>,
}

#[pymethods]
impl PhysicsEstimator {
    /// The estimator of `hand` with `material` (`HandMaterial`) and `config`
    /// (`PhysicsConfig`), each a TOML or JSON file or a dict of the settings (unknown keys are
    /// refused); defaults: the nominal silicone and the default settings.
    #[new]
    #[pyo3(signature = (hand, *, material=None, config=None))]
    fn new(
        py: Python<'_>,
        hand: &Hand,
        material: Option<&Bound<'_, PyAny>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let material: HandMaterial = settings(material, "material")?;
        let config: PhysicsConfig = settings(config, "config")?;
        let estimator =
            py.detach(|| moe_physics::PhysicsEstimator::new(&hand.model, &material, &config).py())?;
        Ok(Self {
            estimator: Mutex::new(estimator),
            num_fingers: hand.model.num_fingers(),
            tendons: hand.model.tendons_per_finger().ok(),
        })
    }

    /// Estimates every finger from `keypoints` (one `(markers, 3)` array per finger, hand
    /// frame, NaN rows not seen), `pulls` `(fingers, tendons)` metres, the hand's pose
    /// `world_from_hand` 4 × 4 (for gravity; default identity) and `time` seconds.
    #[pyo3(signature = (keypoints, pulls, world_from_hand=None, time=None))]
    fn estimate<'py>(
        &self,
        py: Python<'py>,
        keypoints: Vec<PyReadonlyArray2<'py, f64>>,
        pulls: PyReadonlyArray2<'py, f64>,
        world_from_hand: Option<PyReadonlyArray2<'py, f64>>,
        time: Option<f64>,
    ) -> PyResult<PhysicsEstimate> {
        if keypoints.len() != self.num_fingers {
            return Err(invalid(format!(
                "keypoints: {} arrays for a hand of {} fingers",
                keypoints.len(),
                self.num_fingers
            )));
        }
        let keypoints = to_keypoints(&keypoints, "keypoints")?;
        let pulls = convert::to_hand_pulls(&pulls, self.num_fingers, self.tendons)?;
        let world_from_hand = WorldFromHand::new(match &world_from_hand {
            Some(t) => convert::to_iso(t, "world_from_hand")?,
            None => moe_geom::Iso3::identity(),
        });
        let estimate = py.detach(|| {
            let mut estimator = convert::lock(&self.estimator, "physics estimator")?;
            let mut observation = Observation::from_keypoints(&keypoints)
                .with_tendon_pulls(&pulls)
                .with_world_from_hand(world_from_hand);
            observation.time_secs = time;
            estimator.estimate(&observation).py()
        })?;
        Ok(PhysicsEstimate {
            shape: estimate
                .shape
                .fingers
                .iter()
                .map(|v| convert::points(py, v).unbind())
                .collect(),
            contact: estimate
                .contact
                .fingers
                .iter()
                .map(|p| convert::array1(py, p.clone()).unbind())
                .collect(),
            vertex_force_n: estimate
                .vertex_force_n
                .iter()
                .flatten()
                .map(|f| convert::vectors(py, f).unbind())
                .collect(),
            finger_force_n: finger_forces(py, &estimate.details),
            pressed_probability: pressed_probabilities(py, &estimate.details),
            loads: loads(py, &estimate.details.loads)?,
            finger_errors: estimate
                .details
                .fingers
                .iter()
                .map(|f| f.error.clone())
                .collect(),
            solves: estimate.details.fingers.iter().map(|f| f.solves).collect(),
            degraded: estimate
                .details
                .fingers
                .iter()
                .map(|f| f.degraded)
                .collect(),
        })
    }

    /// Forgets the stream (warm starts and the previous observation).
    fn reset(&self, py: Python<'_>) -> PyResult<()> {
        py.detach(|| {
            convert::lock(&self.estimator, "physics estimator")?.reset();
            Ok(())
        })
    }

    /// The contact threshold of the physics estimator's probabilities.
    #[getter]
    fn threshold(&self) -> f64 {
        moe_physics::CONTACT_THRESHOLD
    }
}

/// What the physics estimator found (Rust's `moe_physics::PhysicsEstimate`): float64,
/// metres and newtons, hand frame.
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct PhysicsEstimate {
    /// The estimated (dented) surface, `(n, 3)` per finger.
    shape: Vec<Py<PyArray2<f64>>>,
    /// Contact probability of every vertex, `(n,)` per finger.
    contact: Vec<Py<PyArray1<f64>>>,
    /// Force on every vertex, newtons, `(n, 3)` per finger.
    vertex_force_n: Vec<Py<PyArray2<f64>>>,
    /// Net force the world exerts on every finger, newtons, `(fingers, 3)`.
    finger_force_n: Py<PyArray2<f64>>,
    /// Probability that each finger is pressed, `(fingers,)`.
    pressed_probability: Py<PyArray1<f64>>,
    /// The loads found.
    loads: Vec<Py<ContactLoad>>,
    /// Why a finger has no estimate (too few markers, a solve that did not converge), else None.
    finger_errors: Vec<Option<String>>,
    /// Linear solves each finger took this frame (Newton iterations, dynamic steps, tangents).
    solves: Vec<usize>,
    /// Whether each finger's load search stopped short of its converged answer: the frame's
    /// budget of solves spent, or a proposed load of which the model could carry no part (its
    /// loads are then the best found).
    degraded: Vec<bool>,
}

/// One load the physics estimator found on a finger (Rust's `moe_physics::ContactLoad`): hand
/// frame, metres and newtons.
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct ContactLoad {
    /// Finger index.
    finger: usize,
    /// The vertex at the centre of the loaded patch.
    vertex: u32,
    /// The load's place on the rest surface, `(3,)`.
    location_rest: Py<PyArray1<f64>>,
    /// The same point on the estimated (loaded) surface, `(3,)`.
    location: Py<PyArray1<f64>>,
    /// The force the world exerts on the finger, newtons, `(3,)`.
    force: Py<PyArray1<f64>>,
    /// Its magnitude, newtons.
    magnitude: f64,
    /// Standard deviation of the magnitude, newtons.
    magnitude_sd: f64,
    /// Standard deviation of the location along the finger's axis, metres (None where not
    /// estimated: a second load of a finger).
    location_sd_along: Option<f64>,
    /// Standard deviation of the location around the finger's axis, metres (None where not
    /// estimated).
    location_sd_around: Option<f64>,
    /// The patch: `(vertex, share of the force)` pairs.
    patch: Vec<(u32, f64)>,
}

impl ContactLoad {
    /// The load `l` with numpy vectors.
    pub(crate) fn new(py: Python<'_>, l: &moe_physics::ContactLoad) -> Self {
        let xyz = |v: &nalgebra::Vector3<f64>| convert::array1(py, vec![v.x, v.y, v.z]).unbind();
        let finite = |x: f64| x.is_finite().then_some(x);
        Self {
            finger: l.finger,
            vertex: l.vertex,
            location_rest: xyz(&l.location_rest.coords),
            location: xyz(&l.location.coords),
            force: xyz(&l.force_n),
            magnitude: l.magnitude_n,
            magnitude_sd: l.magnitude_sd_n,
            location_sd_along: finite(l.location_sd_m[0]),
            location_sd_around: finite(l.location_sd_m[1]),
            patch: l.patch.clone(),
        }
    }
}

#[pymethods]
impl ContactLoad {
    fn __repr__(&self) -> String {
        format!(
            "ContactLoad(finger={}, vertex={}, magnitude={:.4} N)",
            self.finger, self.vertex, self.magnitude
        )
    }
}
