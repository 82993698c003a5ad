//! Training: the loss is PyTorch's weighted cross-entropy, training learns, and a run is a pure
//! function of its seed that resumes from a checkpoint to the same weights.

use moe_contact::candle_core::{Device, Tensor};
use moe_contact::{
    Aggregation, ContactError, ModelWeights, OptimizerConfig, TrainConfig, Trainer, TrainingSets,
    weighted_cross_entropy,
};
use moe_geom::SeededRng;

use crate::common::small_config;

/// Sets of random points in the normalised cube [−1, 1]³ (as training normalises its inputs)
/// whose contact label is a half-space with a random offset per set: learnable from xyz, with
/// about a third of the points in contact.
fn half_space_sets(sets: usize, n: usize, seed: u64) -> TrainingSets {
    let mut rng = SeededRng::new(seed);
    let mut out = TrainingSets::new(n, 3);
    for _ in 0..sets {
        let offset = rng.uniform_range(0.2, 0.5);
        let mut x = Vec::with_capacity(n * 3);
        let mut y = Vec::with_capacity(n);
        for _ in 0..n {
            let p = [
                rng.uniform_range(-1.0, 1.0),
                rng.uniform_range(-1.0, 1.0),
                rng.uniform_range(-1.0, 1.0),
            ];
            y.push(p[0] > offset);
            x.extend(p);
        }
        out.push(&x, &y).unwrap();
    }
    out
}

fn config(optimizer: OptimizerConfig, epochs: usize) -> TrainConfig {
    TrainConfig {
        epochs,
        batch_size: 4,
        optimizer,
        seed: 5,
        ..TrainConfig::default()
    }
}

fn adamw() -> OptimizerConfig {
    TrainConfig::default().optimizer
}

fn weights_of(t: &Trainer) -> ModelWeights {
    ModelWeights::of(t.network()).unwrap()
}

#[test]
fn the_weighted_loss_is_the_weighted_mean_of_the_negative_log_likelihoods() {
    let logits: [[f64; 2]; 3] = [[0.3, -1.2], [2.0, 0.5], [-0.7, 0.1]];
    let labels = [1u32, 0, 1];
    let w = 4.0;
    let t = Tensor::new(&logits, &Device::Cpu).unwrap();
    let y = Tensor::new(&labels, &Device::Cpu).unwrap();
    let got = weighted_cross_entropy(&t, &y, w)
        .unwrap()
        .to_scalar::<f64>()
        .unwrap();
    let (mut num, mut den) = (0.0, 0.0);
    for (l, &c) in logits.iter().zip(&labels) {
        let lse = (l[0].exp() + l[1].exp()).ln();
        let weight = if c == 1 { w } else { 1.0 };
        num += weight * (lse - l[c as usize]);
        den += weight;
    }
    assert!((got - num / den).abs() < 1e-12, "{got} vs {}", num / den);
}

#[test]
fn training_lowers_the_validation_loss() {
    let train = half_space_sets(24, 64, 1);
    let validation = half_space_sets(8, 64, 2);
    let mut arch = small_config(Aggregation::Max);
    arch.dropout = 0.1;
    let mut c = config(
        OptimizerConfig::AdamW {
            learning_rate: 3e-3,
            weight_decay: 1e-4,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        },
        6,
    );
    c.batch_size = 2;
    let mut trainer = Trainer::new(arch, c, &train).unwrap();
    let before = trainer.evaluate(&validation).unwrap();
    let mut losses = vec![before.loss];
    for _ in 0..6 {
        let mut steps = 0;
        trainer
            .run_epoch(&train, &mut |_, _, _| steps += 1)
            .unwrap();
        assert_eq!(steps, 12);
        losses.push(trainer.evaluate(&validation).unwrap().loss);
    }
    // Lower after every one of the first epochs, and well below chance at the end.
    assert!(
        losses[..4].windows(2).all(|w| w[1] < w[0]) && losses[6] < 0.7 * losses[0],
        "validation loss per epoch: {losses:?}"
    );
    let (_, best) = trainer.evaluate(&validation).unwrap().best();
    assert!(best.f1() > 0.6, "F1 {}", best.f1());
}

#[test]
fn a_resumed_run_ends_with_the_weights_of_an_uninterrupted_one() {
    let train = half_space_sets(10, 40, 3);
    let arch = small_config(Aggregation::Max);
    for optimizer in [adamw(), OptimizerConfig::paper()] {
        let mut whole = Trainer::new(arch.clone(), config(optimizer.clone(), 3), &train).unwrap();
        for _ in 0..3 {
            whole.run_epoch(&train, &mut |_, _, _| {}).unwrap();
        }
        let mut first = Trainer::new(arch.clone(), config(optimizer.clone(), 3), &train).unwrap();
        first.run_epoch(&train, &mut |_, _, _| {}).unwrap();
        let checkpoint = first.checkpoint().unwrap();
        drop(first);
        // A checkpoint of one optimiser does not resume a run of the other.
        let other_kind = match optimizer {
            OptimizerConfig::AdamW { .. } => OptimizerConfig::paper(),
            OptimizerConfig::Sgd { .. } => adamw(),
        };
        assert!(matches!(
            Trainer::resume(arch.clone(), config(other_kind, 3), &train, &checkpoint),
            Err(moe_contact::ContactError::InvalidConfig {
                field: "optimizer",
                ..
            })
        ));
        let mut resumed = Trainer::resume(
            arch.clone(),
            config(optimizer.clone(), 3),
            &train,
            &checkpoint,
        )
        .unwrap();
        assert_eq!(resumed.epochs_done(), 1);
        for _ in 0..2 {
            resumed.run_epoch(&train, &mut |_, _, _| {}).unwrap();
        }
        assert_eq!(weights_of(&resumed), weights_of(&whole), "{optimizer:?}");
        // And the seed decides: another seed gives other weights.
        let mut other_config = config(optimizer.clone(), 3);
        other_config.seed = 6;
        let mut other = Trainer::new(arch.clone(), other_config, &train).unwrap();
        other.run_epoch(&train, &mut |_, _, _| {}).unwrap();
        assert_ne!(weights_of(&other), weights_of(&whole));
    }
}

#[test]
fn bad_training_input_is_refused() {
    let arch = small_config(Aggregation::Max);
    moe_geom::assert_err!(
        Trainer::new(arch.clone(), config(adamw(), 1), &TrainingSets::new(40, 3)),
        ContactError::InvalidBatch { message } if message == "no training sets"
    );
    let mut no_contact = TrainingSets::new(20, 3);
    no_contact.push(&[0.01; 60], &[false; 20]).unwrap();
    moe_geom::assert_err!(
        Trainer::new(arch.clone(), config(adamw(), 1), &no_contact),
        ContactError::InvalidBatch { message } if message.contains("no contact point")
    );
    let mut sets = TrainingSets::new(20, 3);
    moe_geom::assert_err!(
        sets.push(&[0.0; 59], &[false; 20]),
        ContactError::InvalidBatch { message }
            if message.contains("59 features and 20 labels")
    );
    let mut nan = vec![0.0; 60];
    nan[31] = f64::NAN;
    moe_geom::assert_err!(
        sets.push(&nan, &[false; 20]),
        ContactError::NonFinitePoint { set: 0, index: 10 }
    );
    let mut c = config(adamw(), 1);
    c.batch_size = 0;
    moe_geom::assert_err!(
        c.validate(),
        ContactError::InvalidConfig {
            field: "batch_size",
            ..
        }
    );
}

#[test]
fn negative_sampling_keeps_every_contact_set_and_a_seeded_share_of_the_others() {
    // 40 sets, of which the odd ones have no contact point at all.
    let mut rng = SeededRng::new(9);
    let mut train = TrainingSets::new(16, 3);
    for s in 0..40 {
        let x: Vec<f64> = (0..48).map(|_| rng.uniform_range(-1.0, 1.0)).collect();
        let y: Vec<bool> = (0..16).map(|i| s % 2 == 0 && i < 4).collect();
        train.push(&x, &y).unwrap();
    }
    assert_eq!((0..40).filter(|&s| train.has_contact(s)).count(), 20);
    let arch = small_config(Aggregation::Max);
    let mut c = config(adamw(), 2);
    c.batch_size = 1;
    c.negative_fraction = 0.25;
    let steps_of = |c: &TrainConfig| {
        let mut t = Trainer::new(arch.clone(), c.clone(), &train).unwrap();
        let mut per_epoch = Vec::new();
        for _ in 0..2 {
            let mut n = 0;
            t.run_epoch(&train, &mut |_, _, _| n += 1).unwrap();
            per_epoch.push(n);
        }
        (per_epoch, weights_of(&t))
    };
    let (steps, weights) = steps_of(&c);
    // Every contact set plus about a quarter of the 20 others, drawn afresh each epoch.
    for &n in &steps {
        assert!((20 + 1..=20 + 12).contains(&n), "steps per epoch {steps:?}");
    }
    assert_eq!(steps_of(&c), (steps.clone(), weights), "seeded");
    c.negative_fraction = 1.0;
    assert_eq!(steps_of(&c).0, vec![40, 40]);
    c.negative_fraction = 0.0;
    assert!(matches!(
        Trainer::new(arch.clone(), c, &train),
        Err(moe_contact::ContactError::InvalidConfig {
            field: "negative_fraction",
            ..
        })
    ));
}

#[test]
fn the_evaluation_of_probabilities_matches_the_network_s_loss() {
    let sets = half_space_sets(6, 32, 4);
    let arch = small_config(Aggregation::Max);
    let trainer = Trainer::new(arch, config(adamw(), 1), &sets).unwrap();
    let direct = trainer.evaluate(&sets).unwrap();
    let p = moe_contact::predict(trainer.network(), &sets, 4).unwrap();
    assert_eq!(p.len(), 6 * 32);
    assert!(p.iter().all(|v| (0.0..=1.0).contains(v)));
    // The loss recomputed from the probabilities and the labels by hand.
    let w = trainer.contact_weight();
    let (mut num, mut den) = (0.0, 0.0);
    for (s, chunk) in p.chunks(32).enumerate() {
        for (&q, l) in chunk.iter().zip(sets.labels_of(s)) {
            let (weight, py) = if l { (w, q) } else { (1.0, 1.0 - q) };
            num -= weight * py.ln();
            den += weight;
        }
    }
    assert!(
        (direct.loss - num / den).abs() < 1e-9,
        "{} vs {}",
        direct.loss,
        num / den
    );
    let via = moe_contact::evaluation_of(&p, (0..sets.len()).flat_map(|s| sets.labels_of(s)), w);
    assert_eq!(via, direct);
}

#[test]
fn training_configs_are_bounded() {
    let field_of = |c: TrainConfig| match c.validate() {
        Err(moe_contact::ContactError::InvalidConfig { field, .. }) => field,
        other => panic!("{other:?}"),
    };
    assert_eq!(field_of(config(adamw(), 0)), "epochs");
    assert_eq!(
        field_of(config(adamw(), moe_contact::train::MAX_EPOCHS + 1)),
        "epochs"
    );
    assert!(
        config(adamw(), moe_contact::train::MAX_EPOCHS)
            .validate()
            .is_ok()
    );
    let mut c = config(adamw(), 1);
    c.batch_size = 0;
    assert_eq!(field_of(c), "batch_size");
    let mut c = config(adamw(), 1);
    c.batch_size = 4097;
    assert_eq!(field_of(c), "batch_size");
}
