//! The model card, `NAME.json` beside `NAME.safetensors`: what the weights are (architecture,
//! input features and their normalisation, threshold), which finger they were trained for, and
//! how they were made (typed sections: training, data set, learning curve).

use moe_geom::HandModel;
#[cfg(doc)]
use moe_geom::TriMesh;
use serde::{Deserialize, Serialize};

use crate::config::DgcnnConfig;
use crate::error::ContactError;
use crate::train::TrainConfig;

/// Format version of the model card written by this crate.
pub const CARD_FORMAT_VERSION: u32 = 1;

/// The hand a model was trained for, so that a model is not run on another hand by mistake.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CardHand {
    /// A name for the hand (a preset name or the config's file name).
    pub name: String,
    /// Surface vertices of each finger.
    pub finger_num_vertices: Vec<usize>,
    /// [`TriMesh::digest`] of each finger's rest mesh (finger frame): a model runs only on a
    /// finger whose rest mesh has one of these digests. Empty in cards written before digests
    /// were recorded (then the vertex counts are checked).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub finger_digests: Vec<String>,
}

impl CardHand {
    /// The record of `hand` under `name`: its fingers' vertex counts and rest-mesh digests.
    pub fn of(name: &str, hand: &HandModel) -> Self {
        Self {
            name: name.to_owned(),
            finger_num_vertices: hand
                .fingers()
                .iter()
                .map(|f| f.model.mesh().num_vertices())
                .collect(),
            finger_digests: hand
                .fingers()
                .iter()
                .map(|f| f.model.mesh().digest())
                .collect(),
        }
    }
}

/// How the weights were trained: the card's `training` section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CardTraining {
    /// The command line that trained the model.
    pub command: String,
    /// Optimiser, schedule, loss weighting, seed.
    pub config: TrainConfig,
    /// The contact class weight of the loss that was used.
    pub contact_weight: f64,
    /// The model the weights started from (fine-tuning), if any.
    pub init: Option<String>,
    /// The shapes the network learned from: `sr-arap` (estimated from the markers),
    /// `simulated`, `both`, or `physics` (the physics estimator's dented shape).
    pub input_shape: String,
    /// Gaussian noise added to the training frames' markers, m.
    #[serde(default)]
    pub marker_noise_m: f64,
    /// Probability that a training frame's marker was dropped.
    #[serde(default)]
    pub marker_dropout: f64,
    /// Probability that a training finger's most distal markers were hidden together.
    #[serde(default)]
    pub marker_tip_occlusion: f64,
    /// Longest run of distal markers hidden together.
    #[serde(default)]
    pub marker_tip_run: usize,
    /// Point sets trained per second.
    pub sets_per_second: f64,
    /// Seconds spent in training steps.
    pub train_seconds: f64,
    /// Training point sets.
    pub train_sets: usize,
    /// Validation point sets.
    pub validation_sets: usize,
    /// Wall time of the run, seconds.
    pub wall_time_s: f64,
}

/// One data set a model was trained on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CardDataSource {
    /// Its directory when the model was trained.
    pub dir: String,
    /// Its seed.
    pub seed: u64,
    /// Its frames.
    pub frames: u64,
    /// Its trajectories.
    pub trajectories: u64,
    /// The rule that labelled its contacts.
    pub label_rule: String,
    /// The command that regenerates it.
    pub regenerate: String,
    /// The generator's parameters as its data set card records them.
    pub generator: serde_json::Value,
}

/// The data the model was trained on: the card's `dataset` section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CardDataset {
    /// The data sets, their splits pooled.
    pub sets: Vec<CardDataSource>,
    /// Training frames used.
    pub train_frames: usize,
    /// Validation frames used.
    pub validation_frames: usize,
}

/// One epoch of training, measured on the validation frames.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EpochRecord {
    /// The epoch, from 1.
    pub epoch: usize,
    /// Its learning rate.
    #[serde(deserialize_with = "nan_if_null")]
    pub learning_rate: f64,
    /// Mean training loss.
    #[serde(deserialize_with = "nan_if_null")]
    pub train_loss: f64,
    /// Validation loss.
    #[serde(deserialize_with = "nan_if_null")]
    pub validation_loss: f64,
    /// The threshold of best validation F1.
    #[serde(deserialize_with = "nan_if_null")]
    pub validation_threshold: f64,
    /// Validation F1 at that threshold.
    #[serde(deserialize_with = "nan_if_null")]
    pub validation_f1: f64,
    /// Validation precision at that threshold.
    #[serde(deserialize_with = "nan_if_null")]
    pub validation_precision: f64,
    /// Validation recall at that threshold.
    #[serde(deserialize_with = "nan_if_null")]
    pub validation_recall: f64,
    /// Validation intersection over union at that threshold.
    #[serde(deserialize_with = "nan_if_null")]
    pub validation_iou: f64,
    /// Validation F1 at 0.5.
    #[serde(deserialize_with = "nan_if_null")]
    pub validation_f1_at_half: f64,
    /// Contact BCD on the validation frames at the chosen threshold, mm.
    #[serde(default = "nan", deserialize_with = "nan_if_null")]
    pub validation_contact_bcd_mm: f64,
    /// Validation contact frames with no predicted contact.
    #[serde(default = "nan", deserialize_with = "nan_if_null")]
    pub validation_miss_rate: f64,
    /// Validation frames without contact but with a prediction.
    #[serde(default = "nan", deserialize_with = "nan_if_null")]
    pub validation_false_alarm_rate: f64,
    /// Seconds the epoch took.
    #[serde(deserialize_with = "nan_if_null")]
    pub seconds: f64,
}

/// JSON has no NaN: a metric that was not defined (no contact frame to place, say) is written
/// as `null` and read back as NaN.
fn nan_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

fn nan() -> f64 {
    f64::NAN
}

/// The learning curve: the card's `metrics` section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CardMetrics {
    /// Every epoch trained, in order.
    pub epochs: Vec<EpochRecord>,
}

/// `NAME.json` beside `NAME.safetensors`: what the weights are and how they were made.
///
/// Only `architecture` is needed to run the network; a weights file without a card runs with
/// [`DgcnnConfig::default`] widened to the weights' layer widths.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelCard {
    /// Card format version ([`CARD_FORMAT_VERSION`]).
    pub format_version: u32,
    /// The network.
    pub architecture: DgcnnConfig,
    /// Probability at or above which a vertex is reported as in contact (chosen on validation
    /// data by training; 0.5 when not given).
    #[serde(default = "default_threshold")]
    pub threshold: f64,
    /// The hand the model was trained for, if recorded.
    #[serde(default)]
    pub hand: Option<CardHand>,
    /// How the weights were trained (optimiser, schedule, loss, seed, wall time, the command that
    /// reproduces them).
    #[serde(default, deserialize_with = "provenance")]
    pub training: Option<CardTraining>,
    /// The data the model was trained on.
    #[serde(default, deserialize_with = "dataset_section")]
    pub dataset: Option<CardDataset>,
    /// The learning curve.
    #[serde(default, deserialize_with = "provenance")]
    pub metrics: Option<CardMetrics>,
}

/// A provenance section (training, learning curve) as its typed record. One written by an
/// earlier version in another form is dropped on reading, not refused: the weights, the
/// architecture, the threshold and the hand are what a model needs to run.
fn provenance<'de, D, T>(d: D) -> Result<Option<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: serde::de::DeserializeOwned,
{
    let value = Option::<serde_json::Value>::deserialize(d)?;
    Ok(value.and_then(|v| serde_json::from_value(v).ok()))
}

/// The data set section; the one-record form earlier versions wrote for a single data set
/// (`{"dir": …, "seed": …, …, "train_frames": …}`) is read as a list of one.
fn dataset_section<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<Option<CardDataset>, D::Error> {
    let Some(mut value) = Option::<serde_json::Value>::deserialize(d)? else {
        return Ok(None);
    };
    if let Some(map) = value.as_object_mut()
        && !map.contains_key("sets")
        && map.contains_key("dir")
    {
        let counts: Vec<(String, serde_json::Value)> = ["train_frames", "validation_frames"]
            .iter()
            .filter_map(|k| map.remove(*k).map(|v| ((*k).to_owned(), v)))
            .collect();
        let source = serde_json::Value::Object(std::mem::take(map));
        map.insert("sets".into(), serde_json::Value::Array(vec![source]));
        map.extend(counts);
    }
    Ok(serde_json::from_value(value).ok())
}

fn default_threshold() -> f64 {
    0.5
}

impl ModelCard {
    /// A card for `architecture` with nothing else recorded.
    pub fn new(architecture: DgcnnConfig) -> Self {
        Self {
            format_version: CARD_FORMAT_VERSION,
            architecture,
            threshold: default_threshold(),
            hand: None,
            training: None,
            dataset: None,
            metrics: None,
        }
    }

    /// Parses a card from JSON and validates it.
    ///
    /// # Errors
    /// [`ContactError::MalformedCard`] for JSON that is not a card, [`ContactError::InvalidConfig`]
    /// for out-of-range values.
    pub fn from_json(text: &str) -> Result<Self, ContactError> {
        let card: Self = serde_json::from_str(text).map_err(|e| ContactError::MalformedCard {
            message: e.to_string(),
        })?;
        card.validate()?;
        Ok(card)
    }

    /// The card as pretty-printed JSON.
    ///
    /// # Errors
    /// Never in practice (every field serialises); kept fallible for the JSON writer.
    pub fn to_json(&self) -> Result<String, ContactError> {
        serde_json::to_string_pretty(self).map_err(|e| ContactError::MalformedCard {
            message: e.to_string(),
        })
    }

    /// Checks the version, the architecture and the threshold.
    ///
    /// # Errors
    /// [`ContactError::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<(), ContactError> {
        if self.format_version != CARD_FORMAT_VERSION {
            return Err(ContactError::InvalidConfig {
                field: "format_version",
                message: format!(
                    "{} is not supported (this version reads {CARD_FORMAT_VERSION})",
                    self.format_version
                ),
            });
        }
        if !(self.threshold > 0.0 && self.threshold < 1.0) {
            return Err(ContactError::InvalidConfig {
                field: "threshold",
                message: format!("{} is not in (0, 1)", self.threshold),
            });
        }
        self.architecture.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{InputFeature, Normalisation, PointSet};

    #[test]
    fn a_card_round_trips_through_json() {
        let mut card = ModelCard::new(DgcnnConfig::default());
        card.architecture.input.features.push(InputFeature::RestXyz);
        card.architecture.input.point_set = PointSet::PerFinger;
        card.threshold = 0.3;
        let back = ModelCard::from_json(&card.to_json().unwrap()).unwrap();
        assert_eq!(back, card);
    }

    /// A metric JSON cannot hold (NaN: no contact frame to place) is written as null and read
    /// back as NaN, so that a card with it still loads.
    #[test]
    fn undefined_metrics_survive_json() {
        let record = EpochRecord {
            epoch: 1,
            learning_rate: 1e-3,
            train_loss: 0.5,
            validation_loss: 0.6,
            validation_threshold: 0.4,
            validation_f1: 0.0,
            validation_precision: 0.0,
            validation_recall: 0.0,
            validation_iou: 0.0,
            validation_f1_at_half: 0.0,
            validation_contact_bcd_mm: f64::NAN,
            validation_miss_rate: 1.0,
            validation_false_alarm_rate: 0.0,
            seconds: 2.0,
        };
        let mut card = ModelCard::new(DgcnnConfig::default());
        card.metrics = Some(CardMetrics {
            epochs: vec![record],
        });
        let json = card.to_json().unwrap();
        assert!(
            json.contains("\"validation_contact_bcd_mm\": null"),
            "{json}"
        );
        let back = ModelCard::from_json(&json).unwrap();
        let epochs = back.metrics.unwrap().epochs;
        assert!(epochs[0].validation_contact_bcd_mm.is_nan());
        assert_eq!(epochs[0].validation_miss_rate, 1.0);
    }

    /// Cards written before the sections were typed still load: the one-record data set form is
    /// read as a list of one, and a provenance section of another form is dropped, not refused.
    #[test]
    fn earlier_cards_still_load() {
        let mut v = serde_json::to_value(ModelCard::new(DgcnnConfig::default())).unwrap();
        v["dataset"] = serde_json::json!({
            "dir": "data/press800", "seed": 2026, "frames": 100, "trajectories": 8,
            "label_rule": "press", "regenerate": "moe-touch gen-data", "generator": {},
            "train_frames": 70, "validation_frames": 10
        });
        v["training"] = serde_json::json!({ "epochs": 3, "something": "else" });
        v["metrics"] = serde_json::json!([1, 2, 3]);
        let card = ModelCard::from_json(&v.to_string()).unwrap();
        let data = card.dataset.unwrap();
        assert_eq!((data.sets.len(), data.train_frames), (1, 70));
        assert_eq!(data.sets[0].dir, "data/press800");
        assert!(card.training.is_none() && card.metrics.is_none());
    }

    #[test]
    fn out_of_range_fields_are_named() {
        let check = |edit: fn(&mut ModelCard), field: &str| {
            let mut card = ModelCard::new(DgcnnConfig::default());
            edit(&mut card);
            match card.validate() {
                Err(ContactError::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        };
        check(|c| c.architecture.k = 0, "k");
        check(|c| c.architecture.edge_widths[1] = 0, "edge_widths");
        check(|c| c.architecture.dropout = 1.0, "dropout");
        check(|c| c.threshold = 1.5, "threshold");
        check(|c| c.architecture.input.features.clear(), "input.features");
        check(
            |c| {
                c.architecture.input.normalisation = Some(Normalisation {
                    mean: vec![0.0; 3],
                    std: vec![1.0, 0.0, 1.0],
                })
            },
            "input.normalisation.std",
        );
        check(|c| c.format_version = 7, "format_version");
    }

    #[test]
    fn unknown_card_fields_are_refused() {
        let mut v = serde_json::to_value(ModelCard::new(DgcnnConfig::default())).unwrap();
        v["architecture"]["kk"] = serde_json::json!(3);
        assert!(matches!(
            ModelCard::from_json(&v.to_string()),
            Err(ContactError::MalformedCard { .. })
        ));
    }
}
