//! The DGCNN contact network on candle: three EdgeConv layers and the per-point head.

use std::sync::Arc;
use std::time::Instant;

use candle_core::{D, DType, Device, Module, Tensor};
use candle_nn::{Init, VarBuilder};
use moe_geom::SeededRng;

use crate::config::{Aggregation, DgcnnConfig};
use crate::error::ContactError;
use crate::ops::{Dropout, EdgeGraph, EdgeReduce, KnnSelect, MaxOverPoints};

/// Names of the tensors of a model file, in the order of the network.
pub fn tensor_names() -> Vec<String> {
    tensor_shapes(&DgcnnConfig::default(), 3)
        .into_iter()
        .map(|(name, _)| name)
        .collect()
}

/// The shape of every tensor of a network with `config` and `in_channels` input channels, in
/// [`tensor_names`] order.
pub fn tensor_shapes(config: &DgcnnConfig, in_channels: usize) -> Vec<(String, Vec<usize>)> {
    let mut shapes = Vec::with_capacity(15);
    let mut width_in = in_channels;
    for (l, &w) in config.edge_widths.iter().enumerate() {
        shapes.push((format!("edge{}.theta", l + 1), vec![w, width_in]));
        shapes.push((format!("edge{}.phi.weight", l + 1), vec![w, width_in]));
        shapes.push((format!("edge{}.phi.bias", l + 1), vec![w]));
        width_in = w;
    }
    let [h0, h1] = config.head_widths;
    for (h, (out, inp)) in [(h0, 2 * config.local_width()), (h1, h0), (2, h1)]
        .into_iter()
        .enumerate()
    {
        shapes.push((format!("head.{h}.weight"), vec![out, inp]));
        shapes.push((format!("head.{h}.bias"), vec![out]));
    }
    shapes
}

/// Wall time of each stage of one forward pass, seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ForwardTimings {
    /// The three kNN searches.
    pub knn_s: f64,
    /// The three EdgeConv products and reductions.
    pub edgeconv_s: f64,
    /// Global pooling and the per-point head.
    pub head_s: f64,
}

impl ForwardTimings {
    /// Sum of the stages.
    pub fn total_s(&self) -> f64 {
        self.knn_s + self.edgeconv_s + self.head_s
    }
}

/// Everything one forward pass produces.
#[derive(Debug, Clone)]
pub struct ForwardOutput {
    /// `(B, N, 2)` logits: no contact, contact.
    pub logits: Tensor,
    /// Per layer, the `(B, N, k)` neighbour table (point indices within each set, nearest first),
    /// flattened row-major.
    pub neighbours: [Vec<u32>; 3],
    /// Wall time per stage.
    pub timings: ForwardTimings,
}

/// Whether a forward pass trains (dropout on, drawn from a seeded generator) or evaluates.
#[derive(Debug)]
pub enum Mode<'a> {
    /// Inference: no dropout.
    Eval,
    /// Training: dropout masks drawn from `rng`, so a run is reproducible.
    Train(&'a mut SeededRng),
}

/// One EdgeConv layer: `h'_i = AGG_j ReLU(Θ(h_i − h_j) + Φh_i + b)`.
#[derive(Debug, Clone)]
struct EdgeConv {
    theta: Tensor,
    phi_weight: Tensor,
    phi_bias: Tensor,
    width: usize,
}

/// PyTorch `nn.Linear`'s initialisation, uniform in ±1/√fan_in (training reseeds every tensor
/// from its own generator; candle's cannot be seeded).
fn linear_init(width_in: usize) -> Init {
    let bound = 1.0 / (width_in as f64).sqrt();
    Init::Uniform {
        lo: -bound,
        up: bound,
    }
}

fn edge_conv(width_in: usize, width: usize, vb: VarBuilder<'_>) -> candle_core::Result<EdgeConv> {
    let uniform = linear_init(width_in);
    Ok(EdgeConv {
        theta: vb.get_with_hints((width, width_in), "theta", uniform)?,
        phi_weight: vb.get_with_hints((width, width_in), "phi.weight", uniform)?,
        phi_bias: vb.get_with_hints(width, "phi.bias", uniform)?,
        width,
    })
}

#[derive(Debug, Clone)]
struct Linear {
    weight: Tensor,
    bias: Tensor,
}

fn linear(width_in: usize, width: usize, vb: VarBuilder<'_>) -> candle_core::Result<Linear> {
    let uniform = linear_init(width_in);
    Ok(Linear {
        weight: vb.get_with_hints((width, width_in), "weight", uniform)?,
        bias: vb.get_with_hints(width, "bias", uniform)?,
    })
}

impl Linear {
    /// `(M, in)` → `(M, out)`.
    fn forward_2d(&self, x: &Tensor) -> candle_core::Result<Tensor> {
        x.matmul(&self.weight.t()?)?.broadcast_add(&self.bias)
    }
}

/// The DGCNN of the paper (§4.3.2, App. D) with the architecture of a [`DgcnnConfig`].
///
/// Input `(B, N, C)`: `B` point sets of `N` points with `C` channels; output `(B, N, 2)` logits.
/// The same module runs forward and backward: build it from a [`candle_nn::VarMap`] to train.
#[derive(Debug, Clone)]
pub struct Dgcnn {
    config: DgcnnConfig,
    in_channels: usize,
    layers: [EdgeConv; 3],
    head: [Linear; 3],
    dtype: DType,
    device: Device,
}

impl Dgcnn {
    /// Builds the network from `vb` under the model file's names (`edge1.theta`, ...,
    /// `head.2.bias`); with a `VarMap`-backed builder the tensors are created as trainable
    /// variables.
    ///
    /// # Errors
    /// An invalid config, or a tensor of `vb` of the wrong shape.
    pub fn new(
        config: DgcnnConfig,
        in_channels: usize,
        vb: VarBuilder<'_>,
    ) -> Result<Self, ContactError> {
        config.validate()?;
        if in_channels == 0 {
            return Err(ContactError::InvalidConfig {
                field: "input channels",
                message: "the network needs at least one input channel".into(),
            });
        }
        let [w1, w2, w3] = config.edge_widths;
        let layers = [
            edge_conv(in_channels, w1, vb.pp("edge1"))?,
            edge_conv(w1, w2, vb.pp("edge2"))?,
            edge_conv(w2, w3, vb.pp("edge3"))?,
        ];
        let [h0, h1] = config.head_widths;
        let head = [
            linear(2 * config.local_width(), h0, vb.pp("head").pp("0"))?,
            linear(h0, h1, vb.pp("head").pp("1"))?,
            linear(h1, 2, vb.pp("head").pp("2"))?,
        ];
        Ok(Self {
            config,
            in_channels,
            layers,
            head,
            dtype: vb.dtype(),
            device: vb.device().clone(),
        })
    }

    /// The architecture.
    pub fn config(&self) -> &DgcnnConfig {
        &self.config
    }

    /// Input channels per point.
    pub fn in_channels(&self) -> usize {
        self.in_channels
    }

    /// The float type the network computes in.
    pub fn dtype(&self) -> DType {
        self.dtype
    }

    /// The device the network runs on.
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// Sets the edge aggregation (the weights do not depend on it).
    pub fn set_aggregation(&mut self, aggregation: Aggregation) {
        self.config.aggregation = aggregation;
    }

    /// Every tensor by its model-file name, in [`tensor_names`] order.
    pub fn named_tensors(&self) -> Vec<(String, Tensor)> {
        let tensors = self
            .layers
            .iter()
            .flat_map(|e| [&e.theta, &e.phi_weight, &e.phi_bias])
            .chain(self.head.iter().flat_map(|l| [&l.weight, &l.bias]));
        tensor_names().into_iter().zip(tensors.cloned()).collect()
    }

    /// Checks an input batch: `(B, N, C)` with `C` the network's input width, `N ≥ k`, every
    /// value finite.
    ///
    /// # Errors
    /// [`ContactError::InputWidth`], [`ContactError::TooFewPoints`],
    /// [`ContactError::NonFinitePoint`], [`ContactError::InvalidBatch`].
    pub fn check_input(&self, x: &Tensor) -> Result<(), ContactError> {
        let (b, n, c) = x.dims3().map_err(|_| ContactError::InvalidBatch {
            message: format!("input must be (sets, points, channels), got {:?}", x.dims()),
        })?;
        if b == 0 {
            return Err(ContactError::InvalidBatch {
                message: "the batch has no point sets".into(),
            });
        }
        if c != self.in_channels {
            return Err(ContactError::InputWidth {
                expected: self.in_channels,
                got: c,
            });
        }
        if n < self.config.k {
            return Err(ContactError::TooFewPoints {
                set: 0,
                points: n,
                k: self.config.k,
            });
        }
        let values = x.to_dtype(DType::F64)?.flatten_all()?.to_vec1::<f64>()?;
        if let Some(flat) = values.iter().position(|v| !v.is_finite()) {
            let point = flat / c;
            return Err(ContactError::NonFinitePoint {
                set: point / n,
                index: point % n,
            });
        }
        Ok(())
    }

    /// Runs the network on `x` `(B, N, C)` after checking it; see [`Dgcnn::check_input`].
    ///
    /// # Errors
    /// Bad input (see [`Dgcnn::check_input`]) or a failing tensor operation.
    pub fn forward_with(&self, x: &Tensor, mode: Mode<'_>) -> Result<ForwardOutput, ContactError> {
        self.check_input(x)?;
        Ok(self.forward_unchecked(x, None, mode)?)
    }

    /// Runs the network with given neighbour tables instead of its own kNN searches: per layer
    /// a `(B, N, k)` table of indices within each set, flattened (as
    /// [`ForwardOutput::neighbours`] returns them). For fixed graphs (a mesh's own neighbourhoods)
    /// and for comparing two implementations on identical graphs.
    ///
    /// # Errors
    /// Bad input (see [`Dgcnn::check_input`]), a table of the wrong length or with an index
    /// outside its set.
    pub fn forward_with_graphs(
        &self,
        x: &Tensor,
        graphs: &[Vec<u32>; 3],
        mode: Mode<'_>,
    ) -> Result<ForwardOutput, ContactError> {
        self.check_input(x)?;
        let (b, n, _) = x.dims3()?;
        for (l, g) in graphs.iter().enumerate() {
            if g.len() != b * n * self.config.k {
                return Err(ContactError::InvalidBatch {
                    message: format!(
                        "neighbour table of layer {} has {} entries, expected {b} × {n} × {}",
                        l + 1,
                        g.len(),
                        self.config.k
                    ),
                });
            }
            if let Some(e) = g.iter().position(|&j| j as usize >= n) {
                return Err(ContactError::InvalidBatch {
                    message: format!(
                        "neighbour table of layer {}: entry {e} is {} but sets have {n} points",
                        l + 1,
                        g[e]
                    ),
                });
            }
        }
        Ok(self.forward_unchecked(x, Some(graphs), mode)?)
    }

    fn forward_unchecked(
        &self,
        x: &Tensor,
        graphs: Option<&[Vec<u32>; 3]>,
        mut mode: Mode<'_>,
    ) -> candle_core::Result<ForwardOutput> {
        let x = x
            .to_dtype(self.dtype)?
            .to_device(&self.device)?
            .contiguous()?;
        let n = x.dim(1)?;
        let k = self.config.k;
        let mut timings = ForwardTimings::default();
        let mut features = Vec::with_capacity(3);
        let mut neighbours: [Vec<u32>; 3] = Default::default();
        let mut h = x;
        // A training pass's backward follows: the max reductions keep their minimising
        // neighbours for it.
        let training = matches!(mode, Mode::Train(_));
        for (l, layer) in self.layers.iter().enumerate() {
            let t0 = Instant::now();
            let local = match graphs {
                Some(g) => g[l].clone(),
                None => knn(&h, k)?,
            };
            timings.knn_s += t0.elapsed().as_secs_f64();
            let t0 = Instant::now();
            h = self.edge_conv(layer, &h, &local, n, training)?;
            timings.edgeconv_s += t0.elapsed().as_secs_f64();
            features.push(h.clone());
            neighbours[l] = local;
        }
        let t0 = Instant::now();
        let logits = self.head_forward(&features, &mut mode)?;
        timings.head_s = t0.elapsed().as_secs_f64();
        Ok(ForwardOutput {
            logits,
            neighbours,
            timings,
        })
    }

    fn edge_conv(
        &self,
        layer: &EdgeConv,
        h: &Tensor,
        local: &[u32],
        n: usize,
        keep_argmin: bool,
    ) -> candle_core::Result<Tensor> {
        let (b, _, c_in) = h.dims3()?;
        let k = self.config.k;
        // Two per-point products side by side: [h(Θ+Φ)ᵀ | hΘᵀ].
        let w = Tensor::cat(&[&(&layer.theta + &layer.phi_weight)?, &layer.theta], 0)?;
        let ab = h.reshape((b * n, c_in))?.matmul(&w.t()?)?;
        let global: Vec<u32> = local
            .iter()
            .enumerate()
            .map(|(e, &j)| j + ((e / (n * k)) * n) as u32)
            .collect();
        let out = if self.device.is_cpu() {
            let graph = EdgeGraph {
                idx: Arc::new(global),
                k,
                set_len: n,
            };
            ab.apply_op2(
                &layer.phi_bias,
                // Only a pass whose products a backward can reach keeps the slots.
                EdgeReduce::new(graph, self.config.aggregation, keep_argmin && ab.track_op()),
            )?
        } else {
            edge_reduce_gathered(&ab, &layer.phi_bias, &global, k, self.config.aggregation)?
        };
        out.reshape((b, n, layer.width))
    }

    fn head_forward(
        &self,
        features: &[Tensor],
        mode: &mut Mode<'_>,
    ) -> candle_core::Result<Tensor> {
        let (b, n, _) = features[0].dims3()?;
        let width = self.config.local_width();
        let [l0, l1, l2] = &self.head;
        let h0 = l0.weight.dim(0)?;
        // The max over the points of each set, per layer: (B, 448).
        let mut pooled = Vec::with_capacity(features.len());
        for f in features {
            pooled.push(if self.device.is_cpu() {
                f.apply_op1(MaxOverPoints)?
            } else {
                f.max(1)?
            });
        }
        let glob = Tensor::cat(&pooled, 1)?;
        // head.0 on [loc | glob]: the global half is one row per set, G = glob W_globᵀ + b. It
        // reaches every point of its set through a one-hot column per set appended to loc, so
        // one matrix product [loc | onehot] [W_loc | Gᵀ]ᵀ does both halves (no broadcast over
        // the points).
        let w_loc = l0.weight.narrow(1, 0, width)?;
        let w_glob = l0.weight.narrow(1, width, width)?.contiguous()?;
        let g = glob.matmul(&w_glob.t()?)?.broadcast_add(&l0.bias)?; // (B, H0)
        let onehot: Vec<f64> = (0..b * n * b)
            .map(|e| if (e / b) / n == e % b { 1.0 } else { 0.0 })
            .collect();
        let onehot = Tensor::from_vec(onehot, (b, n, b), &self.device)?.to_dtype(self.dtype)?;
        let mut loc = features.to_vec();
        loc.push(onehot);
        let loc = Tensor::cat(&loc, 2)?.reshape((b * n, width + b))?;
        let w = Tensor::cat(&[&w_loc, &g.t()?], 1)?; // (H0, 448 + B)
        let z = loc.matmul(&w.t()?)?.relu()?;
        debug_assert_eq!(z.dims(), &[b * n, h0]);
        let z = self.dropout(&z, mode)?;
        let z = l1.forward_2d(&z)?.relu()?;
        let z = self.dropout(&z, mode)?;
        l2.forward_2d(&z)?.reshape((b, n, 2))
    }

    fn dropout(&self, x: &Tensor, mode: &mut Mode<'_>) -> candle_core::Result<Tensor> {
        let Mode::Train(rng) = mode else {
            return Ok(x.clone());
        };
        let p = self.config.dropout;
        if p == 0.0 {
            return Ok(x.clone());
        }
        // Element e takes the generator's e-th draw, as one sequential pass would.
        let op = Dropout {
            start: rng.clone(),
            p,
            scale: (1.0 / (1.0 - p)) as f32,
        };
        rng.skip(x.elem_count() as u64);
        if self.device.is_cpu() {
            return x.contiguous()?.apply_op1(op);
        }
        // Elsewhere the mask is drawn on the CPU (the op applied to ones, in f32 as its values
        // are) and multiplied in.
        let mask = Tensor::ones(x.shape(), DType::F32, &Device::Cpu)?
            .apply_op1_no_bwd(&op)?
            .to_dtype(self.dtype)?
            .to_device(&self.device)?;
        x * mask
    }
}

impl Module for Dgcnn {
    /// Inference on `(B, N, C)` without the input checks of [`Dgcnn::forward_with`]: logits
    /// `(B, N, 2)`.
    fn forward(&self, x: &Tensor) -> candle_core::Result<Tensor> {
        Ok(self.forward_unchecked(x, None, Mode::Eval)?.logits)
    }
}

/// Softmax probability of the contact class, `(B, N, 2)` logits → `(B, N)`.
///
/// # Errors
/// A tensor of the wrong shape.
pub fn contact_probability(logits: &Tensor) -> Result<Tensor, ContactError> {
    Ok(candle_nn::ops::softmax_last_dim(logits)?
        .narrow(D::Minus1, 1, 1)?
        .squeeze(D::Minus1)?)
}

/// The k nearest neighbours of every point of every set in `h` `(B, N, C)`, in the features'
/// own space: a `(B, N, k)` table of indices within each set, nearest first, flattened. Outside
/// the autograd graph.
pub(crate) fn knn(h: &Tensor, k: usize) -> candle_core::Result<Vec<u32>> {
    let h = h.detach();
    let (b, n, _) = h.dims3()?;
    let mut out = Vec::with_capacity(b * n * k);
    for s in 0..b {
        let hs = h.get(s)?.contiguous()?;
        let idx = if h.device().is_cpu() {
            hs.apply_op1_no_bwd(&KnnSelect { k })?
        } else {
            // Devices without the selection kernel: a full sort (ties in the device's order).
            let ns = hs.sqr()?.sum(D::Minus1)?;
            let inner = hs.matmul(&hs.t()?)?;
            let d = ns
                .unsqueeze(1)?
                .broadcast_add(&ns.unsqueeze(0)?)?
                .sub(&(inner * 2.0)?)?;
            d.arg_sort_last_dim(true)?.narrow(1, 0, k)?.contiguous()?
        };
        out.extend(idx.flatten_all()?.to_vec1::<u32>()?);
    }
    Ok(out)
}

/// The EdgeConv reduction by gathering the neighbours' `B` rows with standard tensor ops: the
/// form for devices without the fused CPU kernels (also differentiable).
pub(crate) fn edge_reduce_gathered(
    ab: &Tensor,
    bias: &Tensor,
    global: &[u32],
    k: usize,
    aggregation: Aggregation,
) -> candle_core::Result<Tensor> {
    let (rows, two_c) = ab.dims2()?;
    let c = two_c / 2;
    let a = ab.narrow(1, 0, c)?.broadcast_add(bias)?; // (rows, C)
    let bmat = ab.narrow(1, c, c)?.contiguous()?;
    let idx = Tensor::from_slice(global, rows * k, ab.device())?;
    let nb = bmat.index_select(&idx, 0)?.reshape((rows, k, c))?;
    match aggregation {
        Aggregation::Max => a.sub(&nb.min(1)?)?.relu(),
        Aggregation::Sum => a.unsqueeze(1)?.broadcast_sub(&nb)?.relu()?.sum(1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ModelWeights;

    #[test]
    fn dropout_masks_are_the_generators_sequential_stream() {
        let config = DgcnnConfig {
            k: 4,
            edge_widths: [4, 4, 4],
            head_widths: [4, 4],
            ..DgcnnConfig::default()
        };
        let net = ModelWeights::seeded(&config, config.input.channels(), 1)
            .unwrap()
            .build(None, DType::F32, &Device::Cpu)
            .unwrap();
        // Several parallel chunks and a partial one.
        let count = 3 * crate::ops::DROPOUT_CHUNK + 5;
        let x = Tensor::ones(count, DType::F32, &Device::Cpu).unwrap();
        let mut rng = SeededRng::new(11);
        let _ = rng.normal(); // a pending normal deviate, which dropout must leave alone
        let mut sequential = rng.clone();
        let got = net
            .dropout(&x, &mut Mode::Train(&mut rng))
            .unwrap()
            .to_vec1::<f32>()
            .unwrap();
        let p = config.dropout;
        let scale = (1.0 / (1.0 - p)) as f32;
        let want: Vec<f32> = (0..count)
            .map(|_| if sequential.uniform() < p { 0.0 } else { scale })
            .collect();
        assert_eq!(got, want);
        assert_eq!(
            rng, sequential,
            "the generator ends where the sequential draws end"
        );
        let dropped = got.iter().filter(|&&v| v == 0.0).count() as f64 / count as f64;
        assert!((dropped - p).abs() < 0.01, "dropped fraction {dropped}");
        // The backward pass applies the same mask to the gradient: d/dx Σ probe ⊙ drop(x).
        let mut again = SeededRng::new(11);
        let _ = again.normal();
        let xv = candle_core::Var::from_tensor(&(x * 3.0).unwrap()).unwrap();
        let probe: Vec<f32> = (0..count).map(|e| (e % 7) as f32 - 3.0).collect();
        let probe_t = Tensor::from_vec(probe.clone(), count, &Device::Cpu).unwrap();
        let out = net
            .dropout(xv.as_tensor(), &mut Mode::Train(&mut again))
            .unwrap();
        assert_eq!(
            out.to_vec1::<f32>().unwrap(),
            got.iter().map(|m| 3.0 * m).collect::<Vec<_>>()
        );
        let grads = (out * probe_t)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        let dx = grads.get(xv.as_tensor()).unwrap().to_vec1::<f32>().unwrap();
        let want: Vec<f32> = probe.iter().zip(&got).map(|(q, m)| q * m).collect();
        assert_eq!(dx, want);
    }
}
