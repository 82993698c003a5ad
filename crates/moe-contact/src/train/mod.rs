//! Training the DGCNN on labelled point sets held in memory: weighted cross-entropy, AdamW or
//! SGD with momentum (PyTorch's semantics), step decay of the learning rate, seeded everything,
//! checkpoints that resume to the same weights.

mod checkpoint;
mod config;
mod evaluation;
mod sets;

pub use checkpoint::Checkpoint;
pub use config::{MAX_EPOCHS, OptimizerConfig, TrainConfig};
pub use evaluation::{
    Confusion, Evaluation, THRESHOLDS, evaluate, evaluation_of, predict, weighted_cross_entropy,
};
pub use sets::TrainingSets;

use candle_core::backprop::GradStore;
use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{VarBuilder, VarMap};
use moe_geom::SeededRng;

use crate::config::DgcnnConfig;
use crate::error::ContactError;
use crate::network::{Dgcnn, Mode};
use crate::weights::ModelWeights;

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
