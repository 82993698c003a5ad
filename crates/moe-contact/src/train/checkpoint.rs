//! Checkpoints: the state of a run written out, and a trainer that continues from it.

use std::collections::HashMap;

use candle_core::{Device, Tensor};
use safetensors::tensor::Dtype;

use super::config::TrainConfig;
use super::sets::TrainingSets;
use super::{OptimizerState, Trainer};
use crate::config::DgcnnConfig;
use crate::error::ContactError;
use crate::tensor_file::{self, Entry};

/// Everything needed to continue a run: the epochs done, the weights and the optimiser state.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    /// Safetensors bytes: the weights under their model-file names, the optimiser state under
    /// `opt.<kind>.<name>`, and the counters in the metadata.
    pub bytes: Vec<u8>,
}

impl Trainer {
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
