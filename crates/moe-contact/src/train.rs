//! Training the DGCNN on labelled point sets held in memory: weighted cross-entropy, AdamW or
//! SGD with momentum (PyTorch's semantics), step decay of the learning rate, seeded everything,
//! checkpoints that resume to the same weights.

use std::collections::HashMap;

use candle_core::backprop::GradStore;
use candle_core::{D, DType, Device, Tensor, Var};
use candle_nn::{VarBuilder, VarMap};
use moe_geom::{LabelledFrame, SeededRng};
use safetensors::tensor::Dtype;
use serde::{Deserialize, Serialize};

use crate::config::DgcnnConfig;
use crate::error::ContactError;
use crate::estimator::FeatureBuilder;
use crate::network::{Dgcnn, Mode};
use crate::tensor_file::{self, Entry};
use crate::weights::ModelWeights;

/// The optimiser and its hyper-parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum OptimizerConfig {
    /// Adam with decoupled weight decay (PyTorch's `AdamW`).
    AdamW {
        /// Learning rate at epoch 0.
        learning_rate: f64,
        /// Decoupled weight decay.
        weight_decay: f64,
        /// First-moment decay.
        beta1: f64,
        /// Second-moment decay.
        beta2: f64,
        /// Denominator offset.
        eps: f64,
    },
    /// SGD with momentum and L2 weight decay (PyTorch's `SGD`; the paper's optimiser).
    Sgd {
        /// Learning rate at epoch 0.
        learning_rate: f64,
        /// Momentum.
        momentum: f64,
        /// L2 weight decay added to the gradient.
        weight_decay: f64,
    },
}

impl OptimizerConfig {
    /// The paper's recipe (App. D): learning rate 1e-3, momentum 0.3, weight decay 1e-4.
    pub fn paper() -> Self {
        Self::Sgd {
            learning_rate: 1e-3,
            momentum: 0.3,
            weight_decay: 1e-4,
        }
    }

    fn learning_rate(&self) -> f64 {
        match self {
            Self::AdamW { learning_rate, .. } | Self::Sgd { learning_rate, .. } => *learning_rate,
        }
    }
}

/// How to train.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    /// Passes over the training sets.
    pub epochs: usize,
    /// Point sets per optimiser step.
    pub batch_size: usize,
    /// The optimiser.
    pub optimizer: OptimizerConfig,
    /// The learning rate is multiplied by `lr_gamma` every `lr_step_epochs` epochs.
    pub lr_step_epochs: usize,
    /// See `lr_step_epochs`.
    pub lr_gamma: f64,
    /// Loss weight of the contact class relative to 1 for no contact; `None` takes the ratio of
    /// non-contact to contact points in the training sets (each class then weighs the same).
    pub contact_weight: Option<f64>,
    /// Seed of the initial weights, the shuffling and the dropout masks.
    pub seed: u64,
    /// Fraction of the sets without any contact point that an epoch trains on (a fresh seeded
    /// draw every epoch; sets with contact are always used). 1 uses every set.
    #[serde(default = "one")]
    pub negative_fraction: f64,
}

fn one() -> f64 {
    1.0
}

impl Default for TrainConfig {
    /// The paper's recipe: batch 32, step decay 0.5 every 20 epochs, dropout from the
    /// architecture, AdamW at 1e-3 with weight decay 1e-4.
    fn default() -> Self {
        Self {
            epochs: 10,
            batch_size: 32,
            optimizer: OptimizerConfig::AdamW {
                learning_rate: 1e-3,
                weight_decay: 1e-4,
                beta1: 0.9,
                beta2: 0.999,
                eps: 1e-8,
            },
            lr_step_epochs: 20,
            lr_gamma: 0.5,
            contact_weight: None,
            seed: 0,
            negative_fraction: 1.0,
        }
    }
}

/// Most epochs of one training run.
pub const MAX_EPOCHS: usize = 10_000;

impl TrainConfig {
    /// Checks the fields.
    ///
    /// # Errors
    /// [`ContactError::InvalidConfig`] naming the field.
    pub fn validate(&self) -> Result<(), ContactError> {
        let bad = |field: &'static str, message: String| {
            Err(ContactError::InvalidConfig { field, message })
        };
        if !(1..=MAX_EPOCHS).contains(&self.epochs) {
            return bad(
                "epochs",
                format!("{} is not in 1..={MAX_EPOCHS}", self.epochs),
            );
        }
        if self.batch_size == 0 || self.batch_size > 4096 {
            return bad(
                "batch_size",
                format!("{} is not in 1..=4096", self.batch_size),
            );
        }
        if self.lr_step_epochs == 0 {
            return bad("lr_step_epochs", "must be at least 1".into());
        }
        if !(self.lr_gamma > 0.0 && self.lr_gamma <= 1.0) {
            return bad("lr_gamma", format!("{} is not in (0, 1]", self.lr_gamma));
        }
        if let Some(w) = self.contact_weight
            && !(w.is_finite() && w > 0.0)
        {
            return bad("contact_weight", format!("{w} must be finite and positive"));
        }
        if !(self.negative_fraction > 0.0 && self.negative_fraction <= 1.0) {
            return bad(
                "negative_fraction",
                format!("{} is not in (0, 1]", self.negative_fraction),
            );
        }
        let lr = self.optimizer.learning_rate();
        if !(lr.is_finite() && lr > 0.0) {
            return bad(
                "optimizer.learning_rate",
                format!("{lr} must be finite and positive"),
            );
        }
        Ok(())
    }

    /// The learning rate of `epoch` (0-based).
    pub fn learning_rate_at(&self, epoch: usize) -> f64 {
        let steps = (epoch / self.lr_step_epochs) as i32;
        self.optimizer.learning_rate() * self.lr_gamma.powi(steps)
    }
}

/// Labelled point sets of one size, in memory: the network's input features and a 0/1 label per
/// point.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrainingSets {
    points: usize,
    channels: usize,
    features: Vec<f32>,
    labels: Vec<u32>,
}

impl TrainingSets {
    /// An empty collection of sets of `points` points with `channels` channels.
    pub fn new(points: usize, channels: usize) -> Self {
        Self {
            points,
            channels,
            features: Vec::new(),
            labels: Vec::new(),
        }
    }

    /// The point sets of labelled frames, as `features` makes them (every set of a frame, frame
    /// after frame).
    ///
    /// # Errors
    /// A frame that does not fit the hand (naming the finger and vertex), or point sets of
    /// different sizes (fingers with different vertex counts in per-finger sets).
    pub fn from_frames(
        features: &FeatureBuilder,
        frames: &[LabelledFrame],
    ) -> Result<Self, ContactError> {
        let sets = features.point_sets();
        let points = sets.first().map_or(0, |s| s.1);
        if let Some((_, n)) = sets.iter().find(|s| s.1 != points) {
            return Err(ContactError::InvalidBatch {
                message: format!(
                    "point sets of {points} and {n} points: training needs sets of one size                      (whole-hand sets, or fingers with equal vertex counts)"
                ),
            });
        }
        let mut out = Self::new(points, features.channels());
        for frame in frames {
            let inputs = features.input_sets_with(&frame.shape, Some(&frame.tendon_pull_m))?;
            let labels = features.arrange(&frame.contact);
            for (x, y) in inputs.iter().zip(&labels) {
                out.push(x, y)?;
            }
        }
        Ok(out)
    }

    /// Adds one set: row-major features `(points, channels)` and its labels.
    ///
    /// # Errors
    /// [`ContactError::InvalidBatch`] for sizes that do not fit, non-finite features or labels
    /// other than 0 and 1.
    pub fn push(&mut self, features: &[f64], labels: &[bool]) -> Result<(), ContactError> {
        if features.len() != self.points * self.channels || labels.len() != self.points {
            return Err(ContactError::InvalidBatch {
                message: format!(
                    "a training set has {} features and {} labels; sets here are {} points × {} \
                     channels",
                    features.len(),
                    labels.len(),
                    self.points,
                    self.channels
                ),
            });
        }
        if let Some(i) = features.iter().position(|v| !v.is_finite()) {
            return Err(ContactError::NonFinitePoint {
                set: self.len(),
                index: i / self.channels,
            });
        }
        self.features.extend(features.iter().map(|&v| v as f32));
        self.labels.extend(labels.iter().map(|&l| u32::from(l)));
        Ok(())
    }

    /// Number of sets.
    pub fn len(&self) -> usize {
        self.labels.len().checked_div(self.points).unwrap_or(0)
    }

    /// Whether there are no sets.
    pub fn is_empty(&self) -> bool {
        self.labels.is_empty()
    }

    /// Points per set.
    pub fn points(&self) -> usize {
        self.points
    }

    /// Channels per point.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Number of contact points over all sets.
    pub fn contact_points(&self) -> usize {
        self.labels.iter().filter(|&&l| l == 1).count()
    }

    /// Whether set `s` has at least one contact point.
    pub fn has_contact(&self, s: usize) -> bool {
        self.labels[s * self.points..(s + 1) * self.points].contains(&1)
    }

    /// The labels of set `s`.
    pub fn labels_of(&self, s: usize) -> impl Iterator<Item = bool> + '_ {
        self.labels[s * self.points..(s + 1) * self.points]
            .iter()
            .map(|&l| l == 1)
    }

    fn batch(&self, sets: &[usize]) -> candle_core::Result<(Tensor, Tensor)> {
        let (n, c) = (self.points, self.channels);
        let mut x = Vec::with_capacity(sets.len() * n * c);
        let mut y = Vec::with_capacity(sets.len() * n);
        for &s in sets {
            x.extend_from_slice(&self.features[s * n * c..(s + 1) * n * c]);
            y.extend_from_slice(&self.labels[s * n..(s + 1) * n]);
        }
        Ok((
            Tensor::from_vec(x, (sets.len(), n, c), &Device::Cpu)?,
            Tensor::from_vec(y, sets.len() * n, &Device::Cpu)?,
        ))
    }
}

/// Weighted cross-entropy, PyTorch's `CrossEntropyLoss(weight=[1, w])` with mean reduction:
/// `Σ w_y · (−log p_y) / Σ w_y`. `logits` `(M, 2)`, `labels` `(M)` u32.
///
/// # Errors
/// Tensors of the wrong shapes.
pub fn weighted_cross_entropy(
    logits: &Tensor,
    labels: &Tensor,
    contact_weight: f64,
) -> Result<Tensor, ContactError> {
    let logp = candle_nn::ops::log_softmax(logits, D::Minus1)?;
    let picked = logp.gather(&labels.unsqueeze(1)?, 1)?.squeeze(1)?;
    let w = labels
        .to_dtype(logits.dtype())?
        .affine(contact_weight - 1.0, 1.0)?;
    Ok(((picked * &w)?.sum_all()?.neg()? / w.sum_all()?)?)
}

/// Per-point counts at one threshold.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Confusion {
    /// Contact predicted and true.
    pub true_positives: u64,
    /// Contact predicted, not true.
    pub false_positives: u64,
    /// Contact true, not predicted.
    pub false_negatives: u64,
}

impl Confusion {
    /// Precision (1 when nothing is predicted).
    pub fn precision(&self) -> f64 {
        let p = self.true_positives + self.false_positives;
        if p == 0 {
            1.0
        } else {
            self.true_positives as f64 / p as f64
        }
    }

    /// Recall (1 when nothing is true).
    pub fn recall(&self) -> f64 {
        let t = self.true_positives + self.false_negatives;
        if t == 0 {
            1.0
        } else {
            self.true_positives as f64 / t as f64
        }
    }

    /// F1 score (0 when there are no true positives).
    pub fn f1(&self) -> f64 {
        let d = 2 * self.true_positives + self.false_positives + self.false_negatives;
        if d == 0 {
            1.0
        } else {
            2.0 * self.true_positives as f64 / d as f64
        }
    }

    /// Intersection over union of the predicted and true contact sets.
    pub fn iou(&self) -> f64 {
        let u = self.true_positives + self.false_positives + self.false_negatives;
        if u == 0 {
            1.0
        } else {
            self.true_positives as f64 / u as f64
        }
    }
}

/// Thresholds on the contact probability at which validation counts are kept.
pub const THRESHOLDS: [f64; 19] = [
    0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85,
    0.9, 0.95,
];

/// Loss and per-point counts of the network on a collection of sets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// Weighted cross-entropy with the trainer's contact weight.
    pub loss: f64,
    /// Counts at each of [`THRESHOLDS`].
    pub confusion: Vec<Confusion>,
}

impl Evaluation {
    /// The threshold with the highest F1, and its counts (the lower threshold on ties).
    pub fn best(&self) -> (f64, Confusion) {
        let mut best = 0;
        for (i, c) in self.confusion.iter().enumerate() {
            if c.f1() > self.confusion[best].f1() {
                best = i;
            }
        }
        (THRESHOLDS[best], self.confusion[best])
    }

    /// Counts at `threshold` if it is one of [`THRESHOLDS`].
    pub fn at(&self, threshold: f64) -> Option<Confusion> {
        THRESHOLDS
            .iter()
            .position(|&t| (t - threshold).abs() < 1e-12)
            .map(|i| self.confusion[i])
    }
}

/// The optimiser's state: one entry per variable, sorted by name.
#[derive(Debug)]
enum OptimizerState {
    AdamW {
        m: Vec<Tensor>,
        v: Vec<Tensor>,
        t: u64,
    },
    Sgd {
        momentum: Vec<Option<Tensor>>,
    },
}

impl OptimizerState {
    fn kind(&self) -> &'static str {
        match self {
            Self::AdamW { .. } => "adamw",
            Self::Sgd { .. } => "sgd",
        }
    }
}

/// Everything needed to continue a run: the epochs done, the weights and the optimiser state.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    /// Safetensors bytes: the weights under their model-file names, the optimiser state under
    /// `opt.<kind>.<name>`, and the counters in the metadata.
    pub bytes: Vec<u8>,
}

/// Trains one network.
#[derive(Debug)]
pub struct Trainer {
    config: TrainConfig,
    vars: Vec<(String, Var)>,
    net: Dgcnn,
    state: OptimizerState,
    contact_weight: f64,
    epochs_done: usize,
}

impl Trainer {
    /// A trainer with weights drawn from `config.seed` ([`ModelWeights::seeded`]); the contact
    /// weight comes from `train` when the config leaves it open.
    ///
    /// # Errors
    /// Invalid configs, empty training sets or training sets without contact points when the
    /// contact weight must come from them.
    pub fn new(
        arch: DgcnnConfig,
        config: TrainConfig,
        train: &TrainingSets,
    ) -> Result<Self, ContactError> {
        Self::build(arch, config, train, None)
    }

    /// A trainer that starts from `weights` (fine-tuning a trained model) with fresh optimiser
    /// state; otherwise as [`Trainer::new`].
    ///
    /// # Errors
    /// As [`Trainer::new`], and weights that do not fit the architecture.
    pub fn from_weights(
        arch: DgcnnConfig,
        config: TrainConfig,
        train: &TrainingSets,
        weights: &ModelWeights,
    ) -> Result<Self, ContactError> {
        Self::build(arch, config, train, Some(weights))
    }

    fn build(
        arch: DgcnnConfig,
        config: TrainConfig,
        train: &TrainingSets,
        init: Option<&ModelWeights>,
    ) -> Result<Self, ContactError> {
        config.validate()?;
        if train.is_empty() {
            return Err(ContactError::InvalidBatch {
                message: "no training sets".into(),
            });
        }
        let contact_weight = match config.contact_weight {
            Some(w) => w,
            None => {
                let pos = train.contact_points();
                if pos == 0 {
                    return Err(ContactError::InvalidBatch {
                        message: "the training sets have no contact point; give a contact weight"
                            .into(),
                    });
                }
                (train.labels.len() - pos) as f64 / pos as f64
            }
        };
        let varmap = VarMap::new();
        let net = Dgcnn::new(
            arch.clone(),
            train.channels(),
            VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu),
        )?;
        match init {
            Some(w) => w.assign_to(&varmap)?,
            None => {
                ModelWeights::seeded(&arch, train.channels(), config.seed)?.assign_to(&varmap)?
            }
        }
        let vars = sorted_vars(&varmap)?;
        let state = match config.optimizer {
            OptimizerConfig::AdamW { .. } => OptimizerState::AdamW {
                m: zeros_like(&vars)?,
                v: zeros_like(&vars)?,
                t: 0,
            },
            OptimizerConfig::Sgd { .. } => OptimizerState::Sgd {
                momentum: vec![None; vars.len()],
            },
        };
        Ok(Self {
            config,
            vars,
            net,
            state,
            contact_weight,
            epochs_done: 0,
        })
    }

    /// The network being trained.
    pub fn network(&self) -> &Dgcnn {
        &self.net
    }

    /// The contact weight of the loss.
    pub fn contact_weight(&self) -> f64 {
        self.contact_weight
    }

    /// Epochs completed.
    pub fn epochs_done(&self) -> usize {
        self.epochs_done
    }

    /// One pass over `train` in a seeded order (`seed`, epoch): returns the mean training loss
    /// over the steps. `on_step(step, steps, loss)` is called after every optimiser step.
    ///
    /// # Errors
    /// Sets of another size than the trainer's, or a failing tensor operation.
    pub fn run_epoch(
        &mut self,
        train: &TrainingSets,
        on_step: &mut dyn FnMut(usize, usize, f64),
    ) -> Result<f64, ContactError> {
        if train.channels() != self.net.in_channels() || train.is_empty() {
            return Err(ContactError::InvalidBatch {
                message: format!(
                    "training sets of {} channels ({} sets) for a network of {}",
                    train.channels(),
                    train.len(),
                    self.net.in_channels()
                ),
            });
        }
        let epoch = self.epochs_done;
        let stream = SeededRng::new(self.config.seed).split(1 + epoch as u64);
        let mut order_rng = stream.split(0);
        let mut keep_rng = stream.split(u64::MAX);
        let fraction = self.config.negative_fraction;
        let mut order: Vec<usize> = (0..train.len())
            .filter(|&s| fraction >= 1.0 || train.has_contact(s) || keep_rng.uniform() < fraction)
            .collect();
        for i in (1..order.len()).rev() {
            order.swap(i, order_rng.below(i as u64 + 1) as usize);
        }
        let lr = self.config.learning_rate_at(epoch);
        let steps = order.len().div_ceil(self.config.batch_size);
        let mut total = 0.0;
        for (step, sets) in order.chunks(self.config.batch_size).enumerate() {
            let (x, y) = train.batch(sets)?;
            let mut dropout = stream.split(1 + step as u64);
            let logits = self.net.forward_with(&x, Mode::Train(&mut dropout))?.logits;
            let loss =
                weighted_cross_entropy(&logits.reshape((y.dim(0)?, 2))?, &y, self.contact_weight)?;
            let value = f64::from(loss.to_scalar::<f32>()?);
            let grads = loss.backward()?;
            self.step(&grads, lr)?;
            total += value;
            on_step(step + 1, steps, value);
        }
        self.epochs_done += 1;
        Ok(total / steps as f64)
    }

    fn step(&mut self, grads: &GradStore, lr: f64) -> Result<(), ContactError> {
        match (&mut self.state, &self.config.optimizer) {
            (
                OptimizerState::AdamW { m, v, t },
                OptimizerConfig::AdamW {
                    weight_decay,
                    beta1,
                    beta2,
                    eps,
                    ..
                },
            ) => {
                *t += 1;
                let c1 = 1.0 - beta1.powi(*t as i32);
                let c2 = 1.0 - beta2.powi(*t as i32);
                for (i, (_, var)) in self.vars.iter().enumerate() {
                    let Some(g) = grads.get(var.as_tensor()) else {
                        continue;
                    };
                    let w = var.as_tensor();
                    let mi = ((&m[i] * *beta1)? + (g * (1.0 - beta1))?)?;
                    let vi = ((&v[i] * *beta2)? + (g.sqr()? * (1.0 - beta2))?)?;
                    let update = ((&mi / c1)? / ((&vi / c2)?.sqrt()? + *eps)?)?;
                    let decayed = (w * (1.0 - lr * weight_decay))?;
                    var.set(&(decayed - (update * lr)?)?)?;
                    m[i] = mi;
                    v[i] = vi;
                }
            }
            (
                OptimizerState::Sgd { momentum },
                OptimizerConfig::Sgd {
                    momentum: mu,
                    weight_decay,
                    ..
                },
            ) => {
                for (i, (_, var)) in self.vars.iter().enumerate() {
                    let Some(g) = grads.get(var.as_tensor()) else {
                        continue;
                    };
                    let w = var.as_tensor();
                    let g = (g + (w * *weight_decay)?)?;
                    let b = match momentum[i].take() {
                        Some(b) => ((b * *mu)? + &g)?,
                        None => g,
                    };
                    var.set(&(w - (&b * lr)?)?)?;
                    momentum[i] = Some(b);
                }
            }
            _ => {
                return Err(ContactError::InvalidConfig {
                    field: "optimizer",
                    message: "the optimiser state does not match its config".into(),
                });
            }
        }
        Ok(())
    }

    /// Loss and counts of the network (no dropout) on `sets`, `batch_size` sets at a time.
    ///
    /// # Errors
    /// A failing tensor operation, or sets of another width.
    pub fn evaluate(&self, sets: &TrainingSets) -> Result<Evaluation, ContactError> {
        evaluate(&self.net, sets, self.contact_weight, self.config.batch_size)
    }

    /// The state after the epochs done so far.
    ///
    /// # Errors
    /// A failing tensor copy.
    pub fn checkpoint(&self) -> Result<Checkpoint, ContactError> {
        let mut tensors: Vec<(String, Tensor)> = self
            .vars
            .iter()
            .map(|(n, v)| (n.clone(), v.as_tensor().clone()))
            .collect();
        let mut meta = HashMap::new();
        meta.insert("epochs_done".to_string(), self.epochs_done.to_string());
        meta.insert("optimizer".to_string(), self.state.kind().to_string());
        meta.insert(
            "contact_weight".to_string(),
            format!("{:?}", self.contact_weight),
        );
        match &self.state {
            OptimizerState::AdamW { m, v, t } => {
                meta.insert("adam_t".to_string(), t.to_string());
                for (i, (n, _)) in self.vars.iter().enumerate() {
                    tensors.push((format!("opt.m.{n}"), m[i].clone()));
                    tensors.push((format!("opt.v.{n}"), v[i].clone()));
                }
            }
            OptimizerState::Sgd { momentum } => {
                for (i, (n, _)) in self.vars.iter().enumerate() {
                    if let Some(b) = &momentum[i] {
                        tensors.push((format!("opt.momentum.{n}"), b.clone()));
                    }
                }
            }
        }
        let entries = tensors
            .iter()
            .map(|(n, t)| -> Result<Entry, ContactError> {
                let v = t.flatten_all()?.to_vec1::<f32>()?;
                Ok(Entry::f32(n.clone(), t.dims().to_vec(), &v))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Checkpoint {
            bytes: tensor_file::serialize(&entries, Some(meta))?,
        })
    }

    /// A trainer that continues from `checkpoint`: the same weights, optimiser state and epoch
    /// count, so that the remaining epochs give what an uninterrupted run gives.
    ///
    /// # Errors
    /// A checkpoint that does not fit the architecture or the optimiser.
    pub fn resume(
        arch: DgcnnConfig,
        config: TrainConfig,
        train: &TrainingSets,
        checkpoint: &Checkpoint,
    ) -> Result<Self, ContactError> {
        let mut trainer = Self::new(arch, config, train)?;
        let (st, meta) = tensor_file::parse(&checkpoint.bytes, "checkpoint")?;
        let number = |key: &str| -> Result<String, ContactError> {
            meta.get(key)
                .cloned()
                .ok_or_else(|| ContactError::MalformedWeights {
                    message: format!("checkpoint: no '{key}' in its metadata"),
                })
        };
        let parse_err = |key: &str| ContactError::MalformedWeights {
            message: format!("checkpoint: '{key}' is not a number"),
        };
        let kind = number("optimizer")?;
        if kind != trainer.state.kind() {
            return Err(ContactError::InvalidConfig {
                field: "optimizer",
                message: format!(
                    "the checkpoint was written by {kind}, the run is configured for {}",
                    trainer.state.kind()
                ),
            });
        }
        trainer.epochs_done = number("epochs_done")?
            .parse()
            .map_err(|_| parse_err("epochs_done"))?;
        trainer.contact_weight = number("contact_weight")?
            .parse()
            .map_err(|_| parse_err("contact_weight"))?;
        let load = |name: &str, like: &Tensor| -> Result<Tensor, ContactError> {
            let view = st.tensor(name).map_err(|_| ContactError::MissingTensor {
                name: name.to_string(),
            })?;
            if view.shape() != like.dims() || view.dtype() != Dtype::F32 {
                return Err(ContactError::TensorShape {
                    name: name.to_string(),
                    expected: like.dims().to_vec(),
                    got: view.shape().to_vec(),
                });
            }
            Ok(Tensor::from_vec(
                tensor_file::f32s(view.data()),
                like.dims(),
                &Device::Cpu,
            )?)
        };
        for (n, var) in &trainer.vars {
            var.set(&load(n, var.as_tensor())?)?;
        }
        let vars = &trainer.vars;
        match &mut trainer.state {
            OptimizerState::AdamW { m, v, t } => {
                *t = number("adam_t")?.parse().map_err(|_| parse_err("adam_t"))?;
                for (i, (n, var)) in vars.iter().enumerate() {
                    m[i] = load(&format!("opt.m.{n}"), var.as_tensor())?;
                    v[i] = load(&format!("opt.v.{n}"), var.as_tensor())?;
                }
            }
            OptimizerState::Sgd { momentum } => {
                for (i, (n, var)) in vars.iter().enumerate() {
                    let name = format!("opt.momentum.{n}");
                    momentum[i] = if st.names().iter().any(|k| *k == name) {
                        Some(load(&name, var.as_tensor())?)
                    } else {
                        None
                    };
                }
            }
        }
        Ok(trainer)
    }
}

/// Contact probability of every point of every set (`sets.len() × sets.points()`, set after
/// set), the network run without dropout, `batch_size` sets at a time.
///
/// # Errors
/// A failing tensor operation, or sets of another width.
pub fn predict(
    net: &Dgcnn,
    sets: &TrainingSets,
    batch_size: usize,
) -> Result<Vec<f64>, ContactError> {
    let mut out = Vec::with_capacity(sets.labels.len());
    let all: Vec<usize> = (0..sets.len()).collect();
    for chunk in all.chunks(batch_size.max(1)) {
        let (x, y) = sets.batch(chunk)?;
        let logits = net.forward_with(&x, Mode::Eval)?.logits;
        let logits = logits.reshape((y.dim(0)?, 2))?.to_dtype(DType::F64)?;
        let logp = candle_nn::ops::log_softmax(&logits, D::Minus1)?.to_vec2::<f64>()?;
        out.extend(logp.iter().map(|lp| lp[1].exp()));
    }
    Ok(out)
}

/// Loss and counts of `net` (no dropout) on `sets`.
///
/// # Errors
/// A failing tensor operation, or sets of another width.
pub fn evaluate(
    net: &Dgcnn,
    sets: &TrainingSets,
    contact_weight: f64,
    batch_size: usize,
) -> Result<Evaluation, ContactError> {
    Ok(evaluation_of(
        &predict(net, sets, batch_size)?,
        sets.labels.iter().map(|&l| l == 1),
        contact_weight,
    ))
}

/// Loss and counts of contact probabilities `p` against `labels`, point by point.
pub fn evaluation_of(
    p: &[f64],
    labels: impl IntoIterator<Item = bool>,
    contact_weight: f64,
) -> Evaluation {
    let mut confusion = vec![Confusion::default(); THRESHOLDS.len()];
    let (mut weighted_nll, mut weight) = (0.0, 0.0);
    for (&p, l) in p.iter().zip(labels) {
        let w = if l { contact_weight } else { 1.0 };
        let py = if l { p } else { 1.0 - p };
        weighted_nll -= w * py.max(f64::MIN_POSITIVE).ln();
        weight += w;
        for (c, &t) in confusion.iter_mut().zip(&THRESHOLDS) {
            match (p >= t, l) {
                (true, true) => c.true_positives += 1,
                (true, false) => c.false_positives += 1,
                (false, true) => c.false_negatives += 1,
                (false, false) => {}
            }
        }
    }
    Evaluation {
        loss: if weight > 0.0 {
            weighted_nll / weight
        } else {
            0.0
        },
        confusion,
    }
}

fn sorted_vars(varmap: &VarMap) -> Result<Vec<(String, Var)>, ContactError> {
    let data = varmap.data().lock().map_err(|_| ContactError::Tensor {
        message: "the variable map's lock is poisoned".into(),
    })?;
    let mut vars: Vec<(String, Var)> = data.iter().map(|(n, v)| (n.clone(), v.clone())).collect();
    vars.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(vars)
}

fn zeros_like(vars: &[(String, Var)]) -> Result<Vec<Tensor>, ContactError> {
    vars.iter()
        .map(|(_, v)| Ok(v.as_tensor().zeros_like()?))
        .collect()
}
