//! Shared set-up: small seeded networks, random point sets, and a literal per-edge DGCNN.

use moe_contact::candle_core::{DType, Device, Tensor};
use moe_contact::{Aggregation, Dgcnn, DgcnnConfig, ModelWeights};
use moe_geom::SeededRng;

/// A small architecture for tests that compare against slow references.
pub(crate) fn small_config(aggregation: Aggregation) -> DgcnnConfig {
    DgcnnConfig {
        k: 8,
        edge_widths: [8, 16, 32],
        head_widths: [32, 16],
        aggregation,
        ..DgcnnConfig::default()
    }
}

/// A network with seeded weights.
pub(crate) fn seeded_net(
    config: &DgcnnConfig,
    in_channels: usize,
    seed: u64,
    dtype: DType,
) -> Dgcnn {
    ModelWeights::seeded(config, in_channels, seed)
        .unwrap()
        .build(
            Some(&moe_contact::ModelCard::new(DgcnnConfig {
                input: input_with_channels(in_channels),
                ..config.clone()
            })),
            dtype,
            &Device::Cpu,
        )
        .unwrap()
}

/// An input spec with `channels` channels (xyz, or xyz + rest xyz).
pub(crate) fn input_with_channels(channels: usize) -> moe_contact::InputSpec {
    let mut spec = moe_contact::InputSpec::default();
    if channels == 6 {
        spec.features.push(moe_contact::InputFeature::RestXyz);
    }
    assert_eq!(spec.channels(), channels, "tests use 3 or 6 channels");
    spec
}

/// `sets × n` random points in a 5 cm box with `channels` channels, row-major.
pub(crate) fn random_points(sets: usize, n: usize, channels: usize, seed: u64) -> Vec<f64> {
    let mut rng = SeededRng::new(seed);
    (0..sets * n * channels)
        .map(|_| rng.uniform_range(-0.025, 0.025))
        .collect()
}

/// The input tensor `(sets, n, channels)` in f64.
pub(crate) fn tensor(values: &[f64], sets: usize, n: usize, channels: usize) -> Tensor {
    Tensor::from_slice(values, (sets, n, channels), &Device::Cpu).unwrap()
}

/// A tensor's values as f64, flattened.
pub(crate) fn values(t: &Tensor) -> Vec<f64> {
    t.to_dtype(DType::F64)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1::<f64>()
        .unwrap()
}

/// Largest absolute difference.
pub(crate) fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The k nearest by exact squared distances (coordinate differences), self first, ties to the
/// lower index: the definition, for one set of `n` points with `c` channels.
pub(crate) fn knn_by_definition(h: &[f64], n: usize, c: usize, k: usize) -> Vec<Vec<usize>> {
    (0..n)
        .map(|i| {
            let mut d: Vec<(f64, usize)> = (0..n)
                .map(|j| {
                    let d = (0..c)
                        .map(|ch| (h[i * c + ch] - h[j * c + ch]).powi(2))
                        .sum::<f64>();
                    (d, j)
                })
                .collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            d[..k].iter().map(|x| x.1).collect()
        })
        .collect()
}

fn weight(w: &ModelWeights, name: &str) -> (Vec<usize>, Vec<f64>) {
    let (shape, v) = w.get(name).unwrap();
    (shape.to_vec(), v.iter().map(|&x| f64::from(x)).collect())
}

/// `y = x Wᵀ + b` for one row.
fn affine(x: &[f64], w: &(Vec<usize>, Vec<f64>), b: Option<&(Vec<usize>, Vec<f64>)>) -> Vec<f64> {
    let (out, inp) = (w.0[0], w.0[1]);
    (0..out)
        .map(|o| {
            let s: f64 = (0..inp).map(|i| w.1[o * inp + i] * x[i]).sum();
            s + b.map_or(0.0, |b| b.1[o])
        })
        .collect()
}

/// The network written out literally, in plain f64 loops, for one set: per edge
/// `ReLU(Θ(h_i − h_j) + Φh_i + b)` (one matrix product per edge), aggregated over the kNN of
/// each layer's input, then the head on `[loc | glob]`. Returns the logits `(n, 2)` row-major and
/// the kNN tables.
pub(crate) fn literal_forward(
    w: &ModelWeights,
    config: &DgcnnConfig,
    x: &[f64],
    n: usize,
    c_in: usize,
) -> (Vec<f64>, Vec<Vec<Vec<usize>>>) {
    let mut h = x.to_vec();
    let mut c = c_in;
    let mut locals: Vec<Vec<f64>> = vec![Vec::new(); n];
    let mut tables = Vec::new();
    for l in 1..=3 {
        let theta = weight(w, &format!("edge{l}.theta"));
        let phi = weight(w, &format!("edge{l}.phi.weight"));
        let bias = weight(w, &format!("edge{l}.phi.bias"));
        let width = theta.0[0];
        let table = knn_by_definition(&h, n, c, config.k);
        let mut next = vec![0.0_f64; n * width];
        for i in 0..n {
            let hi = &h[i * c..(i + 1) * c];
            let phi_i = affine(hi, &phi, Some(&bias));
            for &j in &table[i] {
                let diff: Vec<f64> = (0..c).map(|ch| hi[ch] - h[j * c + ch]).collect();
                let e = affine(&diff, &theta, None);
                for o in 0..width {
                    let v = (e[o] + phi_i[o]).max(0.0);
                    let slot = &mut next[i * width + o];
                    *slot = match config.aggregation {
                        Aggregation::Max => (*slot).max(v),
                        Aggregation::Sum => *slot + v,
                    };
                }
            }
        }
        for i in 0..n {
            locals[i].extend_from_slice(&next[i * width..(i + 1) * width]);
        }
        tables.push(table);
        h = next;
        c = width;
    }
    let lw = locals[0].len();
    let glob: Vec<f64> = (0..lw)
        .map(|ch| {
            locals
                .iter()
                .map(|r| r[ch])
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect();
    let heads: Vec<_> = (0..3)
        .map(|i| {
            (
                weight(w, &format!("head.{i}.weight")),
                weight(w, &format!("head.{i}.bias")),
            )
        })
        .collect();
    let mut logits = Vec::with_capacity(2 * n);
    for row in &locals {
        let z: Vec<f64> = row.iter().chain(&glob).copied().collect();
        let z: Vec<f64> = affine(&z, &heads[0].0, Some(&heads[0].1))
            .into_iter()
            .map(|v| v.max(0.0))
            .collect();
        let z: Vec<f64> = affine(&z, &heads[1].0, Some(&heads[1].1))
            .into_iter()
            .map(|v| v.max(0.0))
            .collect();
        logits.extend(affine(&z, &heads[2].0, Some(&heads[2].1)));
    }
    (logits, tables)
}
