//! Benchmarks of the contact network on the paper's workload: the default two-finger hand
//! (2 × 1024 vertices), k = 30, batch 1, f32; and the five-finger hand; per finger also with a
//! compact network (k = 16, widths 32/64/64 and 128/64).
//!
//! Besides criterion's figures, each case prints the median split of one frame into the kNN
//! searches, the EdgeConv layers and the head (from the network's own stage timings).
//! `train_step` measures one optimiser step on a batch of four frames; `knn` a KNN[All] query.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use moe_contact::candle_core::{DType, Device};
use moe_contact::{
    DgcnnConfig, DgcnnEstimator, FeatureFrame, ForwardTimings, InputFeature, KnnIndex, ModelCard,
    ModelWeights, PointSet, TrainConfig, Trainer, TrainingSets,
};
use moe_geom::{
    ContactInput, FingerParams, HandModel, HandPreset, HandShape, LabelledFrame, Vector3,
};

/// Every finger bent toward its +x side (deterministic).
fn bent(hand: &HandModel) -> HandShape {
    let mut shape = HandShape::rest(hand);
    for (f, finger) in hand.fingers().iter().enumerate() {
        for (v, p) in finger.model.mesh().vertices().iter().enumerate() {
            let s = p.z / 0.08;
            let moved = p + Vector3::new(0.01 * s * s, 0.0, -0.003 * s * s * s);
            shape.fingers[f][v] = finger.hand_from_finger.transform_point(&moved);
        }
    }
    shape
}

/// A network a quarter of the paper's cost: k = 16, EdgeConv widths 32/64/64, head 128/64.
fn compact() -> DgcnnConfig {
    DgcnnConfig {
        k: 16,
        edge_widths: [32, 64, 64],
        head_widths: [128, 64],
        ..DgcnnConfig::default()
    }
}

fn estimator(hand: &HandModel, point_set: PointSet) -> DgcnnEstimator {
    estimator_with(DgcnnConfig::default(), hand, point_set)
}

fn estimator_with(
    mut config: DgcnnConfig,
    hand: &HandModel,
    point_set: PointSet,
) -> DgcnnEstimator {
    config.input.point_set = point_set;
    if point_set == PointSet::PerFinger {
        config.input.frame = FeatureFrame::Finger;
        config.input.features.push(InputFeature::RestXyz);
    }
    let card = ModelCard::new(config.clone());
    let net = ModelWeights::seeded(&config, config.input.channels(), 1)
        .expect("weights")
        .build(Some(&card), DType::F32, &Device::Cpu)
        .expect("network");
    DgcnnEstimator::new(net, card, hand).expect("estimator")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn print_split(name: &str, est: &DgcnnEstimator, shape: &HandShape) {
    let runs: Vec<ForwardTimings> = (0..30)
        .map(|_| est.estimate_shapes(&[shape]).expect("estimate").1)
        .collect();
    let ms = |f: fn(&ForwardTimings) -> f64| median(runs.iter().map(f).collect()) * 1e3;
    eprintln!(
        "{name}: median split kNN {:.2} ms, EdgeConv {:.2} ms, head {:.2} ms, total {:.2} ms",
        ms(|t| t.knn_s),
        ms(|t| t.edgeconv_s),
        ms(|t| t.head_s),
        ms(ForwardTimings::total_s)
    );
}

fn contact(c: &mut Criterion) {
    for preset in [HandPreset::TwoFinger, HandPreset::FiveFinger] {
        let hand = HandModel::preset(preset, &FingerParams::default()).expect("preset");
        let shape = bent(&hand);
        for (set, label) in [
            (PointSet::WholeHand, "whole-hand"),
            (PointSet::PerFinger, "per-finger"),
        ] {
            let est = estimator(&hand, set);
            let name = format!("contact/{preset}/{label}");
            print_split(&name, &est, &shape);
            c.bench_function(&name, |b| {
                b.iter(|| {
                    black_box(
                        est.estimate_map(&ContactInput::shape(black_box(&shape)))
                            .expect("estimate"),
                    )
                })
            });
        }
        let est = estimator_with(compact(), &hand, PointSet::PerFinger);
        let name = format!("contact/{preset}/per-finger/compact");
        print_split(&name, &est, &shape);
        c.bench_function(&name, |b| {
            b.iter(|| {
                black_box(
                    est.estimate_map(&ContactInput::shape(black_box(&shape)))
                        .expect("estimate"),
                )
            })
        });
    }
}

/// One training step (forward with dropout, weighted cross-entropy, backward, AdamW) on a
/// batch of 4 frames of the two-finger hand: 8 per-finger sets of 1024 points (xyz + rest xyz),
/// or 4 whole-hand sets of 2048 points (xyz), as PyTorch's figure is measured; and the compact
/// network on the 8 per-finger sets.
fn train_step(c: &mut Criterion) {
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).expect("preset");
    let shape = bent(&hand);
    for (config, set, label) in [
        (DgcnnConfig::default(), PointSet::PerFinger, "per-finger"),
        (DgcnnConfig::default(), PointSet::WholeHand, "whole-hand"),
        (compact(), PointSet::PerFinger, "compact-per-finger"),
    ] {
        let est = estimator_with(config, &hand, set);
        let features = est.features();
        let mut sets = TrainingSets::new(features.point_sets()[0].1, features.channels());
        for _ in 0..4 {
            let labels: Vec<Vec<bool>> = shape
                .fingers
                .iter()
                .map(|f| (0..f.len()).map(|v| v % 97 == 0).collect())
                .collect();
            for (x, y) in features
                .input_sets(&shape)
                .expect("features")
                .iter()
                .zip(features.arrange(&labels))
            {
                sets.push(x, &y).expect("set");
            }
        }
        let config = TrainConfig {
            batch_size: sets.len(),
            ..TrainConfig::default()
        };
        let mut trainer =
            Trainer::new(est.card().architecture.clone(), config, &sets).expect("trainer");
        c.bench_function(&format!("train_step/two-finger/{label}/4-frames"), |b| {
            b.iter(|| black_box(trainer.run_epoch(&sets, &mut |_, _, _| {}).expect("step")))
        });
    }
}

/// KNN[All] queries: the nearest of 10,000 training frames of the default two-finger hand by its
/// 14 markers (42 coordinates), the query with every marker observed and with 4 of 7 per finger.
fn knn(c: &mut Criterion) {
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).expect("preset");
    let mut rng = moe_geom::SeededRng::new(3);
    let rest = hand.rest_keypoints();
    let jitter = |rng: &mut moe_geom::SeededRng| {
        let mut kp = rest.clone();
        for p in kp.fingers.iter_mut().flatten().flatten() {
            *p += Vector3::new(rng.normal(), rng.normal(), rng.normal()) * 0.003;
        }
        kp
    };
    let shape = HandShape::rest(&hand);
    let frames: Vec<LabelledFrame> = (0..10_000)
        .map(|t| LabelledFrame {
            trajectory_id: t,
            frame_index: 0,
            shape: shape.clone(),
            contact: shape.fingers.iter().map(|f| vec![false; f.len()]).collect(),
            markers: jitter(&mut rng),
            world_from_hand: moe_geom::WorldFromHand::new(moe_geom::Iso3::identity()),
            tendon_pull_m: vec![vec![0.0; 4]; shape.fingers.len()],
        })
        .collect();
    let index = KnnIndex::new(&frames, false).expect("index");
    let query = jitter(&mut rng);
    let mut partial = query.clone();
    for f in &mut partial.fingers {
        for m in [1, 3, 5] {
            f[m] = None;
        }
    }
    c.bench_function("knn/two-finger/10000-frames/all-markers", |b| {
        b.iter(|| black_box(index.nearest(black_box(&query)).expect("query")))
    });
    c.bench_function("knn/two-finger/10000-frames/4-of-7", |b| {
        b.iter(|| black_box(index.nearest(black_box(&partial)).expect("query")))
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30);
    targets = contact, knn
}
criterion_group! {
    name = training;
    config = Criterion::default().sample_size(10);
    targets = train_step
}
criterion_main!(benches, training);
