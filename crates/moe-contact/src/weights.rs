//! Model files: the network's tensors as safetensors bytes, in PyTorch's `nn.Linear` layout.
//!
//! The bytes are read and written by the caller (`moe-io` or a binary); this module only
//! (de)serialises and validates them against the architecture and the model card.

use std::collections::BTreeMap;
use std::collections::HashMap;

use candle_core::{DType, Device, Tensor};
use candle_nn::VarBuilder;
use safetensors::tensor::Dtype;

use crate::card::ModelCard;
use crate::config::DgcnnConfig;
use crate::error::ContactError;
use crate::network::{Dgcnn, tensor_names, tensor_shapes};
use crate::tensor_file::{self, Entry};

/// The float32 tensors of a model file by name, validated for finiteness.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelWeights {
    tensors: BTreeMap<String, (Vec<usize>, Vec<f32>)>,
}

impl ModelWeights {
    /// Parses safetensors bytes. Every tensor must be float32 and finite; names are checked
    /// later, against the architecture.
    ///
    /// # Errors
    /// [`ContactError::MalformedWeights`], [`ContactError::TensorDtype`],
    /// [`ContactError::NonFiniteWeight`].
    pub fn parse(bytes: &[u8]) -> Result<Self, ContactError> {
        let (st, _) = tensor_file::parse(bytes, "model file")?;
        let mut tensors = BTreeMap::new();
        for (name, view) in st.tensors() {
            if view.dtype() != Dtype::F32 {
                return Err(ContactError::TensorDtype {
                    name,
                    got: format!("{:?}", view.dtype()).to_lowercase(),
                });
            }
            let values = tensor_file::f32s(view.data());
            if let Some(index) = values.iter().position(|v| !v.is_finite()) {
                return Err(ContactError::NonFiniteWeight { name, index });
            }
            tensors.insert(name, (view.shape().to_vec(), values));
        }
        Ok(Self { tensors })
    }

    /// Weights for `config` drawn from a seeded generator with PyTorch's `nn.Linear`
    /// initialisation (uniform in ±1/√fan_in for weights and biases alike), tensor by tensor in
    /// [`tensor_names`] order: the same seed gives the same weights.
    ///
    /// # Errors
    /// An invalid config.
    pub fn seeded(
        config: &DgcnnConfig,
        in_channels: usize,
        seed: u64,
    ) -> Result<Self, ContactError> {
        config.validate()?;
        let mut rng = moe_geom::SeededRng::new(seed);
        let shapes = tensor_shapes(config, in_channels);
        let mut tensors = BTreeMap::new();
        let mut fan_in = in_channels;
        for (name, shape) in shapes {
            if shape.len() == 2 {
                fan_in = shape[1];
            }
            let bound = 1.0 / (fan_in.max(1) as f64).sqrt();
            let count: usize = shape.iter().product();
            let values = (0..count)
                .map(|_| rng.uniform_range(-bound, bound) as f32)
                .collect();
            tensors.insert(name, (shape, values));
        }
        Ok(Self { tensors })
    }

    /// Copies these weights into the variables of `varmap` (a network built from it for
    /// training), by name, converted to each variable's dtype.
    ///
    /// # Errors
    /// [`ContactError::MissingTensor`] when a variable has no tensor here,
    /// [`ContactError::TensorShape`] when the shapes differ.
    pub fn assign_to(&self, varmap: &candle_nn::VarMap) -> Result<(), ContactError> {
        let data = varmap.data().lock().map_err(|_| ContactError::Tensor {
            message: "the variable map's lock is poisoned".into(),
        })?;
        let mut names: Vec<&String> = data.keys().collect();
        names.sort();
        for name in names {
            let var = &data[name];
            let (shape, values) = self
                .get(name)
                .ok_or_else(|| ContactError::MissingTensor { name: name.clone() })?;
            if shape != var.dims() {
                return Err(ContactError::TensorShape {
                    name: name.clone(),
                    expected: var.dims().to_vec(),
                    got: shape.to_vec(),
                });
            }
            let t = Tensor::from_slice(values, shape, &Device::Cpu)?
                .to_dtype(var.dtype())?
                .to_device(var.device())?;
            var.set(&t)?;
        }
        Ok(())
    }

    /// These weights for a network with `channels` input channels, the first ones being the
    /// channels they were trained on: the first layer's weights get zero columns for the new
    /// channels (and learn from them when trained further). The network then computes what it
    /// computed before when the new channels are constant over each point set (as
    /// `tendon-pull` is with per-finger sets); otherwise the first layer's neighbourhoods, found
    /// over all channels, change, and the start is only near it.
    ///
    /// # Errors
    /// [`ContactError::MissingTensor`] / [`ContactError::TensorShape`] for weights without a
    /// first layer of rank 2, [`ContactError::InvalidConfig`] when `channels` is fewer than the
    /// weights take.
    pub fn with_input_channels(&self, channels: usize) -> Result<Self, ContactError> {
        let old = self.shape_of("edge1.theta", 2)?[1];
        if old == 0 || channels < old {
            return Err(ContactError::InvalidConfig {
                field: "input channels",
                message: format!(
                    "the weights take {old} input channels; they cannot be widened to {channels}"
                ),
            });
        }
        let mut out = self.clone();
        for name in ["edge1.theta", "edge1.phi.weight"] {
            let rows = self.shape_of(name, 2)?[0];
            let (shape, values) = &self.tensors[name];
            if shape[1] != old {
                return Err(ContactError::TensorShape {
                    name: name.to_string(),
                    expected: vec![rows, old],
                    got: shape.clone(),
                });
            }
            let mut wide = Vec::with_capacity(rows * channels);
            for row in values.chunks_exact(old) {
                wide.extend_from_slice(row);
                wide.resize(wide.len() + channels - old, 0.0);
            }
            out.tensors
                .insert(name.to_string(), (vec![rows, channels], wide));
        }
        Ok(out)
    }

    /// Tensor names, sorted.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.tensors.keys().map(String::as_str)
    }

    /// A tensor's shape and values.
    pub fn get(&self, name: &str) -> Option<(&[usize], &[f32])> {
        self.tensors
            .get(name)
            .map(|(s, v)| (s.as_slice(), v.as_slice()))
    }

    fn shape_of(&self, name: &str, rank: usize) -> Result<&[usize], ContactError> {
        let (shape, _) = self.get(name).ok_or_else(|| ContactError::MissingTensor {
            name: name.to_string(),
        })?;
        if shape.len() != rank {
            return Err(ContactError::TensorShape {
                name: name.to_string(),
                expected: vec![0; rank],
                got: shape.to_vec(),
            });
        }
        Ok(shape)
    }

    /// The architecture these weights imply — layer widths and input channels from the tensor
    /// shapes, everything else from `card` or the defaults — checked against every tensor.
    ///
    /// # Errors
    /// [`ContactError::MissingTensor`], [`ContactError::UnexpectedTensor`],
    /// [`ContactError::TensorShape`], and [`ContactError::CardMismatch`] where the card
    /// contradicts the weights.
    pub fn architecture(
        &self,
        card: Option<&ModelCard>,
    ) -> Result<(DgcnnConfig, usize), ContactError> {
        for name in tensor_names() {
            if self.get(&name).is_none() {
                return Err(ContactError::MissingTensor { name });
            }
        }
        let known = tensor_names();
        if let Some(extra) = self.names().find(|n| !known.iter().any(|k| k == n)) {
            return Err(ContactError::UnexpectedTensor {
                name: extra.to_string(),
            });
        }
        let in_channels = self.shape_of("edge1.theta", 2)?[1];
        let mut edge_widths = [0; 3];
        for (l, w) in edge_widths.iter_mut().enumerate() {
            *w = self.shape_of(&format!("edge{}.theta", l + 1), 2)?[0];
        }
        let head_widths = [
            self.shape_of("head.0.weight", 2)?[0],
            self.shape_of("head.1.weight", 2)?[0],
        ];
        let config = match card {
            Some(card) => {
                let a = &card.architecture;
                if a.edge_widths != edge_widths {
                    return Err(ContactError::CardMismatch {
                        field: "architecture.edge_widths",
                        card: format!("{:?}", a.edge_widths),
                        weights: format!("{edge_widths:?}"),
                    });
                }
                if a.head_widths != head_widths {
                    return Err(ContactError::CardMismatch {
                        field: "architecture.head_widths",
                        card: format!("{:?}", a.head_widths),
                        weights: format!("{head_widths:?}"),
                    });
                }
                if a.input.channels() != in_channels {
                    return Err(ContactError::CardMismatch {
                        field: "architecture.input.features",
                        card: format!("{} ({} channels)", a.input.describe(), a.input.channels()),
                        weights: format!("{in_channels} input channels in edge1.theta"),
                    });
                }
                a.clone()
            }
            None => DgcnnConfig {
                edge_widths,
                head_widths,
                ..DgcnnConfig::default()
            },
        };
        config.validate()?;
        for (name, expected) in tensor_shapes(&config, in_channels) {
            let (got, _) = self
                .get(&name)
                .ok_or_else(|| ContactError::MissingTensor { name: name.clone() })?;
            if got != expected.as_slice() {
                return Err(ContactError::TensorShape {
                    name,
                    expected,
                    got: got.to_vec(),
                });
            }
        }
        Ok((config, in_channels))
    }

    /// The network these weights define, computing in `dtype` on `device`.
    ///
    /// # Errors
    /// See [`ModelWeights::architecture`].
    pub fn build(
        &self,
        card: Option<&ModelCard>,
        dtype: DType,
        device: &Device,
    ) -> Result<Dgcnn, ContactError> {
        let (config, in_channels) = self.architecture(card)?;
        let mut map = HashMap::new();
        for (name, (shape, values)) in &self.tensors {
            let t = Tensor::from_slice(values, shape.as_slice(), &Device::Cpu)?
                .to_dtype(dtype)?
                .to_device(device)?;
            map.insert(name.clone(), t);
        }
        Dgcnn::new(
            config,
            in_channels,
            VarBuilder::from_tensors(map, dtype, device),
        )
    }

    /// The weights of a network (converted to float32; exact for weights that were float32).
    ///
    /// # Errors
    /// A failing tensor copy.
    pub fn of(net: &Dgcnn) -> Result<Self, ContactError> {
        let mut tensors = BTreeMap::new();
        for (name, t) in net.named_tensors() {
            let shape = t.dims().to_vec();
            let values = t
                .to_device(&Device::Cpu)?
                .to_dtype(DType::F32)?
                .flatten_all()?
                .to_vec1::<f32>()?;
            tensors.insert(name, (shape, values));
        }
        Ok(Self { tensors })
    }

    /// Safetensors bytes (tensors sorted by name, no metadata): the same weights give the same
    /// bytes.
    ///
    /// # Errors
    /// [`ContactError::MalformedWeights`] if the serialiser refuses (it does not for valid
    /// shapes).
    pub fn to_bytes(&self) -> Result<Vec<u8>, ContactError> {
        let entries: Vec<Entry> = self
            .tensors
            .iter()
            .map(|(name, (shape, values))| Entry::f32(name.clone(), shape.clone(), values))
            .collect();
        tensor_file::serialize(&entries, None)
    }
}

impl Dgcnn {
    /// Loads a network from model-file bytes and an optional card.
    ///
    /// # Errors
    /// See [`ModelWeights::parse`] and [`ModelWeights::architecture`].
    pub fn from_safetensors(
        bytes: &[u8],
        card: Option<&ModelCard>,
        dtype: DType,
        device: &Device,
    ) -> Result<Self, ContactError> {
        ModelWeights::parse(bytes)?.build(card, dtype, device)
    }

    /// The network's weights as model-file bytes (float32).
    ///
    /// # Errors
    /// A failing tensor copy.
    pub fn to_safetensors(&self) -> Result<Vec<u8>, ContactError> {
        ModelWeights::of(self)?.to_bytes()
    }
}
