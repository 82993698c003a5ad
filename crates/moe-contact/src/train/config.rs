//! How to train: the optimiser and the run's hyper-parameters.

use serde::{Deserialize, Serialize};

use crate::error::ContactError;

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
