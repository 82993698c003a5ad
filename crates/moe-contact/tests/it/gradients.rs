//! The network trains: analytic gradients through the fused kernels agree with finite
//! differences, and an optimiser step lowers the loss.

use moe_contact::candle_core::{DType, Device, Tensor, Var};
use moe_contact::candle_nn::{Optimizer, SGD, VarBuilder, VarMap, loss};
use moe_contact::{Aggregation, Dgcnn, DgcnnConfig, Mode, ModelWeights};
use moe_geom::SeededRng;

use crate::common::{random_points, small_config, tensor};

fn trainable(config: &DgcnnConfig, c: usize, seed: u64) -> (VarMap, Dgcnn) {
    let vm = VarMap::new();
    let net = Dgcnn::new(
        config.clone(),
        c,
        VarBuilder::from_varmap(&vm, DType::F64, &Device::Cpu),
    )
    .unwrap();
    ModelWeights::seeded(config, c, seed)
        .unwrap()
        .assign_to(&vm)
        .unwrap();
    (vm, net)
}

/// A smooth scalar of the logits: a fixed random linear functional.
fn objective(net: &Dgcnn, x: &Tensor, probe: &Tensor) -> Tensor {
    objective_in(net, x, probe, Mode::Eval)
}

/// [`objective`] with the forward pass in `mode`.
fn objective_in(net: &Dgcnn, x: &Tensor, probe: &Tensor, mode: Mode<'_>) -> Tensor {
    let logits = net.forward_with(x, mode).unwrap().logits;
    (logits * probe).unwrap().sum_all().unwrap()
}

/// The functional's weights: uniform in [-1, 1) for each logit of `sets` sets of `n` points.
fn random_probe(rng: &mut SeededRng, sets: usize, n: usize) -> Tensor {
    let probe: Vec<f64> = (0..sets * n * 2)
        .map(|_| rng.uniform_range(-1.0, 1.0))
        .collect();
    Tensor::from_vec(probe, (sets, n, 2), &Device::Cpu).unwrap()
}

fn sorted_vars(vm: &VarMap) -> Vec<(String, Var)> {
    let data = vm.data().lock().unwrap();
    let mut v: Vec<(String, Var)> = data.iter().map(|(k, v)| (k.clone(), v.clone())).collect();
    v.sort_by(|a, b| a.0.cmp(&b.0));
    v
}

#[test]
fn gradients_agree_with_finite_differences() {
    let (sets, n, c) = (2, 60, 3);
    for aggregation in [Aggregation::Max, Aggregation::Sum] {
        let config = small_config(aggregation);
        let (vm, net) = trainable(&config, c, 17);
        let x = tensor(&random_points(sets, n, c, 2), sets, n, c);
        let mut rng = SeededRng::new(8);
        let probe = random_probe(&mut rng, sets, n);
        let grads = objective(&net, &x, &probe).backward().unwrap();
        let eps = 1e-6;
        let mut checked = 0;
        for (name, var) in sorted_vars(&vm) {
            let grad = grads
                .get(var.as_tensor())
                .unwrap_or_else(|| panic!("{aggregation}: no gradient for {name}"))
                .flatten_all()
                .unwrap()
                .to_vec1::<f64>()
                .unwrap();
            let base = var
                .as_tensor()
                .flatten_all()
                .unwrap()
                .to_vec1::<f64>()
                .unwrap();
            let dims = var.dims().to_vec();
            for _ in 0..4 {
                let e = rng.below(base.len() as u64) as usize;
                let at = |delta: f64| {
                    let mut v = base.clone();
                    v[e] += delta;
                    var.set(&Tensor::from_vec(v, dims.as_slice(), &Device::Cpu).unwrap())
                        .unwrap();
                    objective(&net, &x, &probe).to_scalar::<f64>().unwrap()
                };
                let numeric = (at(eps) - at(-eps)) / (2.0 * eps);
                var.set(&Tensor::from_vec(base.clone(), dims.as_slice(), &Device::Cpu).unwrap())
                    .unwrap();
                let analytic = grad[e];
                assert!(
                    (numeric - analytic).abs() <= 1e-5 * (1.0 + analytic.abs()),
                    "{aggregation}: {name}[{e}]: analytic {analytic}, numeric {numeric}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 15 * 4);
    }
}

#[test]
fn one_optimiser_step_lowers_the_loss_of_its_batch() {
    let (sets, n, c) = (4, 64, 3);
    for aggregation in [Aggregation::Max, Aggregation::Sum] {
        let config = small_config(aggregation);
        let (vm, net) = trainable(&config, c, 23);
        let x = tensor(&random_points(sets, n, c, 12), sets, n, c);
        let mut rng = SeededRng::new(1);
        let labels: Vec<u32> = (0..sets * n)
            .map(|_| u32::from(rng.uniform() < 0.2))
            .collect();
        let labels = Tensor::from_vec(labels, sets * n, &Device::Cpu).unwrap();
        let loss_of = |net: &Dgcnn, mode: Mode<'_>| {
            let logits = net.forward_with(&x, mode).unwrap().logits;
            loss::cross_entropy(&logits.reshape((sets * n, 2)).unwrap(), &labels).unwrap()
        };
        // Plain gradient descent: a small enough step along the gradient must descend.
        let mut opt = SGD::new(vm.all_vars(), 1e-3).unwrap();
        let before = loss_of(&net, Mode::Eval).to_scalar::<f64>().unwrap();
        opt.backward_step(&loss_of(&net, Mode::Eval)).unwrap();
        let after = loss_of(&net, Mode::Eval).to_scalar::<f64>().unwrap();
        assert!(after < before, "{aggregation}: {before} -> {after}");
    }
}

#[test]
fn dropout_is_drawn_from_the_seed() {
    let (n, c) = (50, 3);
    let config = small_config(Aggregation::Max);
    let (_vm, net) = trainable(&config, c, 2);
    let x = tensor(&random_points(1, n, c, 3), 1, n, c);
    let train = |seed: u64| {
        let mut rng = SeededRng::new(seed);
        crate::common::values(&net.forward_with(&x, Mode::Train(&mut rng)).unwrap().logits)
    };
    let eval = crate::common::values(&net.forward_with(&x, Mode::Eval).unwrap().logits);
    assert_eq!(train(5), train(5));
    assert_ne!(train(5), train(6));
    assert_ne!(train(5), eval);
}

#[test]
fn a_training_pass_has_the_gradients_of_an_evaluation_pass() {
    // Without dropout both passes compute the same function. A training pass's backward reads
    // the minimising neighbours that its forward kept; an evaluation pass's searches again.
    let (sets, n, c) = (2, 60, 3);
    let mut config = small_config(Aggregation::Max);
    config.dropout = 0.0;
    // Widths past and between the minimum's blocks of eight channels.
    config.edge_widths = [8, 12, 21];
    let (vm, net) = trainable(&config, c, 23);
    let x = tensor(&random_points(sets, n, c, 4), sets, n, c);
    let mut rng = SeededRng::new(9);
    let probe = random_probe(&mut rng, sets, n);
    let eval = objective(&net, &x, &probe).backward().unwrap();
    let train = objective_in(&net, &x, &probe, Mode::Train(&mut rng))
        .backward()
        .unwrap();
    for (name, var) in sorted_vars(&vm) {
        let get = |g: &moe_contact::candle_core::backprop::GradStore| {
            g.get(var.as_tensor())
                .unwrap_or_else(|| panic!("no gradient for {name}"))
                .flatten_all()
                .unwrap()
                .to_vec1::<f64>()
                .unwrap()
        };
        assert_eq!(get(&train), get(&eval), "{name}");
    }
}
