//! The contact network on a bare point cloud, without a hand: the check of a model file against
//! a reference implementation's logits (`moe-touch contact --points`). A hand's shape goes
//! through the runtime's estimator instead (`moe_touch::pipeline::load_contact_model` and
//! `DgcnnEstimator::estimate_inputs`); a point cloud has no fingers, so it needs the raw network,
//! in either float type and with or without a card.

use std::path::Path;

use moe_contact::candle_core::{DType, Device, Tensor};
use moe_contact::{
    Aggregation, DeviceKind, Dgcnn, ForwardTimings, Mode, ModelCard, contact_probability,
    open_device,
};

use crate::error::LabError;

/// The float type the network computes in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NetworkPrecision {
    /// 32-bit (as trained).
    #[default]
    F32,
    /// 64-bit (for validation against a reference).
    F64,
}

/// How the network of [`PointCloudModel::load`] runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PointCloudOptions {
    /// Its float type.
    pub precision: NetworkPrecision,
    /// Its device.
    pub device: DeviceKind,
    /// Edge aggregation overriding the card's (the weights do not depend on it).
    pub aggregation: Option<Aggregation>,
}

/// A model file's network with its card (the defaults, widened to the weights, when the file
/// has none).
#[derive(Debug)]
pub struct PointCloudModel {
    net: Dgcnn,
    card: ModelCard,
    has_card: bool,
}

/// The network's output on a point cloud, point by point in input order.
#[derive(Debug, Clone, PartialEq)]
pub struct PointCloudContact {
    /// The two logits of each point.
    pub logits: Vec<[f64; 2]>,
    /// The contact probability of each point.
    pub probability: Vec<f64>,
    /// The network's stage timings.
    pub timings: ForwardTimings,
}

impl PointCloudModel {
    /// Reads and checks `NAME.safetensors` and its card `NAME.json` when there is one.
    ///
    /// # Errors
    /// Unreadable or malformed weights or card, a card that contradicts the weights, or a device
    /// this build does not have.
    pub fn load(path: &Path, options: &PointCloudOptions) -> Result<Self, LabError> {
        let device = open_device(options.device)?;
        let files = moe_io::read_model_files(path)?;
        let card = files
            .card
            .as_deref()
            .map(ModelCard::from_json)
            .transpose()?;
        let dtype = match options.precision {
            NetworkPrecision::F32 => DType::F32,
            NetworkPrecision::F64 => DType::F64,
        };
        let mut net = Dgcnn::from_safetensors(&files.weights, card.as_ref(), dtype, &device)?;
        if let Some(a) = options.aggregation {
            net.set_aggregation(a);
        }
        let has_card = card.is_some();
        let mut card = card.unwrap_or_else(|| ModelCard::new(net.config().clone()));
        card.architecture.aggregation = net.config().aggregation;
        Ok(Self {
            net,
            card,
            has_card,
        })
    }

    /// The card (the defaults without one), with the aggregation the network runs.
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// Whether the model file had a card.
    pub fn has_card(&self) -> bool {
        self.has_card
    }

    /// The edge aggregation the network runs.
    pub fn aggregation(&self) -> Aggregation {
        self.net.config().aggregation
    }

    /// The network on `points` (metres, normalised as the card says).
    ///
    /// # Errors
    /// Fewer points than the network's `k`, non-finite points, a card whose input features
    /// are not the points' coordinates alone, or a failing tensor operation.
    pub fn estimate(&self, points: &[[f64; 3]]) -> Result<PointCloudContact, LabError> {
        let spec = &self.card.architecture.input;
        if spec.features != [moe_contact::InputFeature::Xyz] {
            return Err(LabError::InvalidEvaluation {
                reason: format!(
                    "the model's input features ({}) cannot be made from a point cloud",
                    spec.describe()
                ),
            });
        }
        let n = points.len();
        let mut values: Vec<f64> = points.iter().flatten().copied().collect();
        spec.normalise(&mut values);
        let x = Tensor::from_vec(values, (1, n, 3), &Device::Cpu)
            .map_err(moe_contact::ContactError::from)?;
        let out = self.net.forward_with(&x, Mode::Eval)?;
        let to_vec = |t: &Tensor| -> Result<Vec<f64>, moe_contact::ContactError> {
            Ok(t.to_dtype(DType::F64)?.flatten_all()?.to_vec1::<f64>()?)
        };
        let logits = to_vec(&out.logits)?;
        let probability = to_vec(&contact_probability(&out.logits)?)?;
        Ok(PointCloudContact {
            logits: logits.chunks_exact(2).map(|l| [l[0], l[1]]).collect(),
            probability,
            timings: out.timings,
        })
    }
}
