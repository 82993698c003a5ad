//! The trained contact network (DGCNN) on its own: a hand's surface in, contact probability per
//! vertex out.

use std::path::PathBuf;
use std::sync::Mutex;

use moe_contact::DgcnnEstimator;
use moe_geom::{ContactEstimator, ContactInput, HandShape, Observation};
use numpy::{PyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::card::ModelCard;
use crate::convert::{self, OrRaise, invalid};
use crate::hand::Hand;

/// A trained contact model (`NAME.safetensors` with its card `NAME.json`) for a hand, in f32 on
/// the CPU.
#[pyclass(module = "moe_touch")]
pub struct ContactModel {
    pub(crate) model: Mutex<DgcnnEstimator>,
    threshold: f64,
    num_fingers: usize,
    /// The card (read once, so that asking for it never waits on an estimate).
    card: Py<ModelCard>,
}

impl ContactModel {
    /// The model of `path` for `hand`, as the pipeline loads it.
    pub(crate) fn estimator(path: &std::path::Path, hand: &Hand) -> PyResult<DgcnnEstimator> {
        moe_touch::pipeline::load_contact_model(path, &hand.model).py()
    }
}

#[pymethods]
impl ContactModel {
    /// Loads the model at `path` (its card beside it) for `hand`; a model trained for another
    /// hand or finger is refused with the reason.
    #[new]
    fn new(py: Python<'_>, path: PathBuf, hand: &Hand) -> PyResult<Self> {
        let model = py.detach(|| Self::estimator(&path, hand))?;
        let card = Py::new(py, ModelCard::new(py, model.card())?)?;
        Ok(Self {
            card,
            threshold: model.threshold(),
            model: Mutex::new(model),
            num_fingers: hand.model.num_fingers(),
        })
    }

    /// The contact threshold of the model's card: vertices at or above it are in contact.
    #[getter]
    fn threshold(&self) -> f64 {
        self.threshold
    }

    /// The model card (threshold, features, architecture, hand, training, data set, metrics;
    /// `to_dict()` for the raw form).
    #[getter]
    fn card(&self, py: Python<'_>) -> Py<ModelCard> {
        self.card.clone_ref(py)
    }

    /// Contact probability of every vertex of `vertices`, one `(n, 3)` array per finger (hand
    /// frame, the hand's vertex order), with `pulls` `(fingers, tendons)` metres for a model
    /// that takes them. Returns one `(n,)` array per finger.
    #[pyo3(signature = (vertices, pulls=None))]
    fn estimate<'py>(
        &self,
        py: Python<'py>,
        vertices: Vec<PyReadonlyArray2<'py, f64>>,
        pulls: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Vec<Bound<'py, PyArray1<f64>>>> {
        if vertices.len() != self.num_fingers {
            return Err(invalid(format!(
                "vertices: {} arrays for a hand of {} fingers",
                vertices.len(),
                self.num_fingers
            )));
        }
        let shape = HandShape {
            fingers: vertices
                .iter()
                .enumerate()
                .map(|(f, v)| convert::to_points(v, &format!("vertices[{f}]")))
                .collect::<PyResult<_>>()?,
        };
        let pulls = pulls.as_ref().map(convert::to_pulls).transpose()?;
        let estimate = py.detach(|| {
            let mut model = convert::lock(&self.model, "contact model")?;
            let mut observation = Observation::new();
            observation.tendon_pull_m = pulls.as_deref();
            model.estimate(&ContactInput::new(&shape, observation)).py()
        })?;
        Ok(estimate
            .map
            .fingers
            .into_iter()
            .map(|p| convert::array1(py, p))
            .collect())
    }
}
