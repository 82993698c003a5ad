//! The cards as typed objects: a contact model's card (`moe_contact::ModelCard` and its
//! sections) and a data set's card (`moe_io::DatasetCard`), each with `to_dict()` for the raw
//! JSON form.

use std::collections::BTreeMap;

use pyo3::prelude::*;
use serde::Serialize;

use crate::convert::invalid;

/// `value` in its JSON form as Python objects (dicts, lists, numbers, strings, None).
fn json_object<T: Serialize + ?Sized>(py: Python<'_>, value: &T) -> PyResult<Py<PyAny>> {
    let json = serde_json::to_string(value).map_err(|e| invalid(e.to_string()))?;
    Ok(py.import("json")?.call_method1("loads", (json,))?.unbind())
}

/// A contact model's card (`NAME.json` beside `NAME.safetensors`; Rust's
/// `moe_contact::ModelCard`): what the weights are and how they were made.
#[pyclass(module = "moe_touch", frozen)]
pub(crate) struct ModelCard {
    /// Card format version.
    #[pyo3(get)]
    format_version: u32,
    /// Probability at or above which a vertex is in contact.
    #[pyo3(get)]
    threshold: f64,
    /// The input feature groups in channel order (`architecture["input"]["features"]`).
    #[pyo3(get)]
    features: Vec<String>,
    /// The network (`DgcnnConfig`: `k`, layer widths, aggregation, dropout, input), raw.
    #[pyo3(get)]
    architecture: Py<PyAny>,
    /// The hand the model was trained for, if recorded.
    #[pyo3(get)]
    hand: Option<Py<CardHand>>,
    /// How the weights were trained, if recorded.
    #[pyo3(get)]
    training: Option<Py<CardTraining>>,
    /// The data the model was trained on, if recorded.
    #[pyo3(get)]
    dataset: Option<Py<CardDataset>>,
    /// The learning curve, if recorded.
    #[pyo3(get)]
    metrics: Option<Py<CardMetrics>>,
    /// The whole card, JSON.
    json: String,
}

impl ModelCard {
    /// The typed form of `card`.
    pub(crate) fn new(py: Python<'_>, card: &moe_contact::ModelCard) -> PyResult<Self> {
        let features = card
            .architecture
            .input
            .features
            .iter()
            .map(|f| match serde_json::to_value(f) {
                Ok(serde_json::Value::String(s)) => Ok(s),
                Ok(other) => Ok(other.to_string()),
                Err(e) => Err(invalid(e.to_string())),
            })
            .collect::<PyResult<_>>()?;
        Ok(Self {
            format_version: card.format_version,
            threshold: card.threshold,
            features,
            architecture: json_object(py, &card.architecture)?,
            hand: card
                .hand
                .as_ref()
                .map(|h| {
                    Py::new(
                        py,
                        CardHand {
                            name: h.name.clone(),
                            finger_num_vertices: h.finger_num_vertices.clone(),
                            finger_digests: h.finger_digests.clone(),
                        },
                    )
                })
                .transpose()?,
            training: card
                .training
                .as_ref()
                .map(|t| Py::new(py, CardTraining::new(py, t)?))
                .transpose()?,
            dataset: card
                .dataset
                .as_ref()
                .map(|d| Py::new(py, CardDataset::new(py, d)?))
                .transpose()?,
            metrics: card
                .metrics
                .as_ref()
                .map(|m| Py::new(py, CardMetrics::new(py, m)?))
                .transpose()?,
            json: serde_json::to_string(card).map_err(|e| invalid(e.to_string()))?,
        })
    }
}

#[pymethods]
impl ModelCard {
    /// The card as the dict its JSON file holds.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        py.import("json")?.call_method1("loads", (&self.json,))
    }

    fn __repr__(&self) -> String {
        let hand = self
            .hand
            .as_ref()
            .map_or_else(|| "None".to_owned(), |h| format!("{:?}", h.get().name));
        format!(
            "ModelCard(threshold={}, features={:?}, hand={hand})",
            self.threshold, self.features
        )
    }
}

/// The hand a model was trained for (Rust's `moe_contact::CardHand`).
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct CardHand {
    /// A preset name or the hand config's file name.
    name: String,
    /// Surface vertices of each finger.
    finger_num_vertices: Vec<usize>,
    /// Digest of each finger's rest mesh (empty in cards written before digests were kept).
    finger_digests: Vec<String>,
}

/// How the weights were trained (Rust's `moe_contact::CardTraining`).
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct CardTraining {
    /// The command line that trained the model.
    command: String,
    /// Optimiser, schedule, loss weighting, seed (`TrainConfig`), raw.
    config: Py<PyAny>,
    /// The contact class weight of the loss.
    contact_weight: f64,
    /// The model the weights started from (fine-tuning), if any.
    init: Option<String>,
    /// The shapes the network learned from: sr-arap, simulated, both or physics.
    input_shape: String,
    /// Gaussian noise added to the training frames' markers, metres.
    marker_noise_m: f64,
    /// Probability that a training frame's marker was dropped.
    marker_dropout: f64,
    /// Probability that a training finger's most distal markers were hidden together.
    marker_tip_occlusion: f64,
    /// Longest run of distal markers hidden together.
    marker_tip_run: usize,
    /// Point sets trained per second.
    sets_per_second: f64,
    /// Seconds spent in training steps.
    train_seconds: f64,
    /// Training point sets.
    train_sets: usize,
    /// Validation point sets.
    validation_sets: usize,
    /// Wall time of the run, seconds.
    wall_time_s: f64,
}

impl CardTraining {
    fn new(py: Python<'_>, t: &moe_contact::CardTraining) -> PyResult<Self> {
        Ok(Self {
            command: t.command.clone(),
            config: json_object(py, &t.config)?,
            contact_weight: t.contact_weight,
            init: t.init.clone(),
            input_shape: t.input_shape.clone(),
            marker_noise_m: t.marker_noise_m,
            marker_dropout: t.marker_dropout,
            marker_tip_occlusion: t.marker_tip_occlusion,
            marker_tip_run: t.marker_tip_run,
            sets_per_second: t.sets_per_second,
            train_seconds: t.train_seconds,
            train_sets: t.train_sets,
            validation_sets: t.validation_sets,
            wall_time_s: t.wall_time_s,
        })
    }
}

/// The data a model was trained on (Rust's `moe_contact::CardDataset`).
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct CardDataset {
    /// The data sets, their splits pooled.
    sets: Vec<Py<CardDataSource>>,
    /// Training frames used.
    train_frames: usize,
    /// Validation frames used.
    validation_frames: usize,
}

impl CardDataset {
    fn new(py: Python<'_>, d: &moe_contact::CardDataset) -> PyResult<Self> {
        Ok(Self {
            sets: d
                .sets
                .iter()
                .map(|s| {
                    Py::new(
                        py,
                        CardDataSource {
                            dir: s.dir.clone(),
                            seed: s.seed,
                            frames: s.frames,
                            trajectories: s.trajectories,
                            label_rule: s.label_rule.clone(),
                            regenerate: s.regenerate.clone(),
                            generator: json_object(py, &s.generator)?,
                        },
                    )
                })
                .collect::<PyResult<_>>()?,
            train_frames: d.train_frames,
            validation_frames: d.validation_frames,
        })
    }
}

/// One data set a model was trained on (Rust's `moe_contact::CardDataSource`).
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct CardDataSource {
    /// Its directory when the model was trained.
    dir: String,
    /// Its seed.
    seed: u64,
    /// Its frames.
    frames: u64,
    /// Its trajectories.
    trajectories: u64,
    /// The rule that labelled its contacts.
    label_rule: String,
    /// The command that regenerates it.
    regenerate: String,
    /// The generator's parameters as its data set card records them, raw.
    generator: Py<PyAny>,
}

/// The learning curve (Rust's `moe_contact::CardMetrics`).
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct CardMetrics {
    /// Every epoch trained, in order.
    epochs: Vec<Py<EpochRecord>>,
}

impl CardMetrics {
    fn new(py: Python<'_>, m: &moe_contact::CardMetrics) -> PyResult<Self> {
        Ok(Self {
            epochs: m
                .epochs
                .iter()
                .map(|e| Py::new(py, EpochRecord::from(e)))
                .collect::<PyResult<_>>()?,
        })
    }
}

/// One epoch of training measured on the validation frames (Rust's
/// `moe_contact::EpochRecord`); NaN where a metric was not defined.
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct EpochRecord {
    /// The epoch, from 1.
    epoch: usize,
    /// Its learning rate.
    learning_rate: f64,
    /// Mean training loss.
    train_loss: f64,
    /// Validation loss.
    validation_loss: f64,
    /// The threshold of best validation F1.
    validation_threshold: f64,
    /// Validation F1 at that threshold.
    validation_f1: f64,
    /// Validation precision at that threshold.
    validation_precision: f64,
    /// Validation recall at that threshold.
    validation_recall: f64,
    /// Validation intersection over union at that threshold.
    validation_iou: f64,
    /// Validation F1 at 0.5.
    validation_f1_at_half: f64,
    /// Contact BCD on the validation frames at the chosen threshold, mm.
    validation_contact_bcd_mm: f64,
    /// Validation contact frames with no predicted contact.
    validation_miss_rate: f64,
    /// Validation frames without contact but with a prediction.
    validation_false_alarm_rate: f64,
    /// Seconds the epoch took.
    seconds: f64,
}

impl From<&moe_contact::EpochRecord> for EpochRecord {
    fn from(e: &moe_contact::EpochRecord) -> Self {
        Self {
            epoch: e.epoch,
            learning_rate: e.learning_rate,
            train_loss: e.train_loss,
            validation_loss: e.validation_loss,
            validation_threshold: e.validation_threshold,
            validation_f1: e.validation_f1,
            validation_precision: e.validation_precision,
            validation_recall: e.validation_recall,
            validation_iou: e.validation_iou,
            validation_f1_at_half: e.validation_f1_at_half,
            validation_contact_bcd_mm: e.validation_contact_bcd_mm,
            validation_miss_rate: e.validation_miss_rate,
            validation_false_alarm_rate: e.validation_false_alarm_rate,
            seconds: e.seconds,
        }
    }
}

/// A data set's card (`card.json`; Rust's `moe_io::DatasetCard`): layout, seed, generator,
/// shards and frame counts.
#[pyclass(module = "moe_touch", frozen)]
pub(crate) struct DatasetCard {
    /// Format version of the shards.
    #[pyo3(get)]
    format_version: u32,
    /// The frame layout.
    #[pyo3(get)]
    layout: Py<DatasetLayout>,
    /// Seed of the generator that produced the data.
    #[pyo3(get)]
    seed: u64,
    /// How the data were generated, raw.
    #[pyo3(get)]
    generator: Py<PyAny>,
    /// Every shard, in order.
    #[pyo3(get)]
    shards: Vec<Py<ShardEntry>>,
    /// Totals over all shards.
    #[pyo3(get)]
    totals: Py<FrameStats>,
    /// Totals per object family.
    #[pyo3(get)]
    families: BTreeMap<String, Py<FrameStats>>,
    /// The whole card, JSON.
    json: String,
}

impl DatasetCard {
    /// The typed form of `card`.
    pub(crate) fn new(py: Python<'_>, card: &moe_io::DatasetCard) -> PyResult<Self> {
        let l = &card.layout;
        Ok(Self {
            format_version: card.format_version,
            layout: Py::new(
                py,
                DatasetLayout {
                    finger_num_vertices: l.finger_num_vertices.clone(),
                    markers_per_finger: l.markers_per_finger.clone(),
                    tendons_per_finger: l.tendons_per_finger,
                    object_param_len: l.object_param_len,
                    object_families: l.object_families.clone(),
                },
            )?,
            seed: card.seed,
            generator: json_object(py, &card.generator)?,
            shards: card
                .shards
                .iter()
                .map(|s| {
                    Py::new(
                        py,
                        ShardEntry {
                            file: s.file.clone(),
                            stats: Py::new(py, FrameStats::from(&s.stats))?,
                        },
                    )
                })
                .collect::<PyResult<_>>()?,
            totals: Py::new(py, FrameStats::from(&card.totals))?,
            families: card
                .families
                .iter()
                .map(|(k, v)| Ok((k.clone(), Py::new(py, FrameStats::from(v))?)))
                .collect::<PyResult<_>>()?,
            json: serde_json::to_string(card).map_err(|e| invalid(e.to_string()))?,
        })
    }
}

#[pymethods]
impl DatasetCard {
    /// The card as the dict its `card.json` holds.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        py.import("json")?.call_method1("loads", (&self.json,))
    }

    fn __repr__(&self) -> String {
        format!(
            "DatasetCard({} shards, seed {})",
            self.shards.len(),
            self.seed
        )
    }
}

/// The frame layout of a data set (Rust's `moe_io::DatasetLayout`).
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct DatasetLayout {
    /// Surface vertices of each finger.
    finger_num_vertices: Vec<usize>,
    /// Markers of each finger.
    markers_per_finger: Vec<usize>,
    /// Tendons per finger.
    tendons_per_finger: usize,
    /// Length of every frame's `object_params`.
    object_param_len: usize,
    /// Names of the object families; `object_family` indexes this list.
    object_families: Vec<String>,
}

/// One shard as the card lists it (Rust's `moe_io::dataset::ShardEntry`).
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct ShardEntry {
    /// File name within the data set directory.
    file: String,
    /// Its counts.
    stats: Py<FrameStats>,
}

/// Counts over a set of frames (Rust's `moe_io::dataset::FrameStats`).
#[pyclass(module = "moe_touch", frozen, get_all)]
pub(crate) struct FrameStats {
    /// Frames.
    frames: u64,
    /// Distinct trajectories.
    trajectories: u64,
    /// Frames with at least one contact vertex.
    contact_frames: u64,
    /// Vertices labelled in contact, over all frames.
    contact_vertices: u64,
    /// Vertices, over all frames.
    vertices: u64,
    /// Frames that carry the fingers' net contact forces.
    force_frames: u64,
}

impl From<&moe_io::dataset::FrameStats> for FrameStats {
    fn from(s: &moe_io::dataset::FrameStats) -> Self {
        Self {
            frames: s.frames,
            trajectories: s.trajectories,
            contact_frames: s.contact_frames,
            contact_vertices: s.contact_vertices,
            vertices: s.vertices,
            force_frames: s.force_frames,
        }
    }
}

#[pymethods]
impl FrameStats {
    /// Fraction of all vertices that are labelled in contact.
    #[getter]
    fn contact_ratio(&self) -> f64 {
        if self.vertices == 0 {
            0.0
        } else {
            self.contact_vertices as f64 / self.vertices as f64
        }
    }
}
