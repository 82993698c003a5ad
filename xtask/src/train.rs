//! `cargo xtask train`: trains the contact network on a generated data set — a thin command over
//! `moe_contact::train`, with data loading, checkpoints, progress and the model card.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use moe_contact::{
    Aggregation, CardHand, Checkpoint, ContactMetrics, ContactReport, DgcnnConfig, FeatureBuilder,
    FeatureFrame, InputFeature, InputSpec, ModelCard, ModelWeights, Normalisation, OptimizerConfig,
    PointSet, TrainConfig, Trainer, TrainingSets, evaluation_of,
};
use moe_geom::{HandModel, LabelledFrame, Real};
use moe_io::{DatasetReader, Split, SplitFractions};
use moe_tendon_sim::randomize::RandomSceneParams;
use moe_touch::contact_eval::{MarkerAugmentation, with_estimated_shapes};
use serde::Serialize;

/// Arguments of `cargo xtask train`.
#[derive(Debug, Args)]
pub(crate) struct TrainArgs {
    /// Data set directory (as `cargo xtask gen-data` writes it); repeat to train on several data
    /// sets of the same hand. Each data set's trajectories are split into training, validation
    /// and test sets by its own seed; the splits are then pooled.
    #[arg(long, required = true)]
    data: Vec<PathBuf>,
    /// Output model path without extension: writes NAME.safetensors and the card NAME.json, and
    /// keeps NAME.checkpoint.safetensors while training.
    #[arg(long, value_name = "models/NAME")]
    out: PathBuf,
    /// Epochs in the whole run (a resumed run continues up to this many), 1–10,000.
    #[arg(long, default_value_t = 10, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=moe_contact::train::MAX_EPOCHS as u64))]
    epochs: usize,
    /// Seed of the weights, the order and the dropout.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Continue from NAME.checkpoint.safetensors.
    #[arg(long)]
    resume: bool,
    /// Point sets per step, 1–4096.
    #[arg(long, default_value_t = 32, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=4096))]
    batch_size: usize,
    /// Optimiser: adamw, or sgd (the paper's: momentum 0.3).
    #[arg(long, value_enum, default_value = "adamw")]
    optimizer: OptimizerArg,
    /// Learning rate at epoch 0 (halved every 20 epochs).
    #[arg(long, default_value_t = 1e-3)]
    lr: f64,
    /// Contact class weight of the loss (default: non-contact / contact points in training).
    #[arg(long)]
    contact_weight: Option<f64>,
    /// Point sets: per-finger (finger frame) or whole-hand (hand frame).
    #[arg(long, value_enum, default_value = "per-finger")]
    point_set: PointSetArg,
    /// Input features, comma-separated, in channel order: xyz (the deformed position),
    /// rest-xyz (the vertex's rest position), deformation (local curvature change, its one-ring
    /// mean and the areal strain).
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "xyz,rest-xyz"
    )]
    features: Vec<FeatureArg>,
    /// Edge aggregation: max or sum.
    #[arg(long, default_value = "max")]
    aggregation: Aggregation,
    /// Neighbourhood size of the EdgeConv layers, the point itself included (the paper's 30).
    #[arg(long, default_value_t = 30, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=moe_contact::config::MAX_K as u64))]
    k: usize,
    /// Output widths of the three EdgeConv layers (the paper's 64,128,256).
    #[arg(long, value_delimiter = ',', default_value = "64,128,256", value_parser = width_parser())]
    edge_widths: Vec<usize>,
    /// Widths of the head's two hidden layers (the paper's 512,256).
    #[arg(long, value_delimiter = ',', default_value = "512,256", value_parser = width_parser())]
    head_widths: Vec<usize>,
    /// The learning rate halves every this many epochs (the paper's 20).
    #[arg(long, default_value_t = 20, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    lr_step_epochs: usize,
    /// Use at most this many training frames (the first ones, in data set order).
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    max_frames: Option<usize>,
    /// Shapes the network learns from: the SR-ARAP estimate from each frame's markers (what it
    /// sees at run time), the simulated surface, both, or the physics estimator's dented shape.
    #[arg(long, value_enum, default_value = "both")]
    input_shape: InputShapeArg,
    /// Start from these weights (a trained model's NAME.safetensors) instead of seeded ones,
    /// with fresh optimiser state: fine-tuning. Ignored with --resume.
    #[arg(long, value_name = "M.safetensors")]
    init: Option<PathBuf>,
    /// Fraction of the point sets without contact that each epoch trains on (a fresh draw
    /// every epoch; sets with contact are always used).
    #[arg(long, default_value_t = 1.0)]
    negative_fraction: f64,
    /// Standard deviation (m, per coordinate) of the Gaussian noise added to the training
    /// frames' markers before their (SR-ARAP or physics) shapes are computed, as detection adds it at run
    /// time (one seeded draw per frame; validation frames keep their true markers).
    #[arg(long, value_name = "M", default_value_t = 0.0)]
    marker_noise: f64,
    /// Probability that a training frame's marker is dropped before its estimated shape is
    /// computed, as an occluded or missed marker is at run time.
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    marker_dropout: f64,
    /// Probability that a training frame's finger has its most distal markers hidden together
    /// (a run of 1 to `--marker-tip-run` markers) before its estimated shape is computed, as a
    /// pressing fingertip's are from the wrist camera.
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    marker_tip_occlusion: f64,
    /// Longest run of distal markers `--marker-tip-occlusion` hides (never more than all but
    /// one of a finger's markers; without `--marker-tip-occlusion` it has no effect).
    #[arg(long, value_name = "N", default_value_t = 3,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=64))]
    marker_tip_run: usize,
}

fn width_parser() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new()
        .range(1..=moe_contact::config::MAX_WIDTH as u64)
}

/// `N` widths from a comma-separated option, or an error naming the option.
fn widths<const N: usize>(option: &str, values: &[usize]) -> Result<[usize; N]> {
    values.try_into().map_err(|_| {
        anyhow::anyhow!(
            "--{option} takes {N} comma-separated widths, got {}",
            values.len()
        )
    })
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum FeatureArg {
    Xyz,
    RestXyz,
    Deformation,
    /// The finger's tendon pulls as bending and co-contraction (the same on all its vertices).
    TendonPull,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum OptimizerArg {
    Adamw,
    Sgd,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
enum InputShapeArg {
    /// SR-ARAP from the frame's markers (the paper's 50 iterations from rest).
    SrArap,
    /// The simulated surface.
    Simulated,
    /// Both: every training frame twice, as simulated and as SR-ARAP estimated; validation on
    /// the SR-ARAP shapes (what the model sees at run time).
    Both,
    /// The physics estimator's dented shape from the frame's markers (nominal material, default
    /// settings; each trajectory run as a stream), for training and validation.
    Physics,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum PointSetArg {
    PerFinger,
    WholeHand,
}

/// One epoch of the card's metrics.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
struct EpochRecord {
    epoch: usize,
    learning_rate: f64,
    train_loss: f64,
    validation_loss: f64,
    validation_threshold: f64,
    validation_f1: f64,
    validation_precision: f64,
    validation_recall: f64,
    validation_iou: f64,
    validation_f1_at_half: f64,
    /// Contact BCD on the validation frames at the chosen threshold, mm.
    #[serde(default)]
    validation_contact_bcd_mm: f64,
    /// Validation contact frames with no predicted contact.
    #[serde(default)]
    validation_miss_rate: f64,
    /// Validation frames without contact but with a prediction.
    #[serde(default)]
    validation_false_alarm_rate: f64,
    seconds: f64,
}

/// The hand a data set was simulated with, from its card.
pub(crate) fn dataset_hand(reader: &DatasetReader) -> Result<HandModel> {
    let params: RandomSceneParams = serde_json::from_value(
        reader
            .card()
            .generator
            .get("params")
            .cloned()
            .context("the data set card records no simulator parameters")?,
    )
    .context("the data set card's simulator parameters")?;
    let hand = HandModel::preset(params.preset, &params.finger)?;
    let counts: Vec<usize> = hand
        .fingers()
        .iter()
        .map(|f| f.model.mesh().num_vertices())
        .collect();
    if counts != reader.card().layout.finger_num_vertices {
        bail!(
            "the data set's layout ({:?} vertices per finger) is not its recorded hand's ({counts:?})",
            reader.card().layout.finger_num_vertices
        );
    }
    Ok(hand)
}

/// Name of the label rule of a data set's frames, from its card (`proximity` for data sets made
/// before the rule was recorded).
pub(crate) fn label_rule_of(reader: &DatasetReader) -> String {
    reader.card().generator["params"]["contact"]["label_rule"]
        .as_str()
        .unwrap_or("proximity")
        .to_owned()
}

fn frames(reader: &DatasetReader, split: Split, max: Option<usize>) -> Result<Vec<LabelledFrame>> {
    let mut out = Vec::new();
    for frame in reader.labelled_frames(Some(split), SplitFractions::default()) {
        out.push(frame?);
        if max.is_some_and(|m| out.len() >= m) {
            break;
        }
    }
    Ok(out)
}

/// Per-channel mean and standard deviation of the features of `frames`, accumulated frame by
/// frame (the raw features of a whole data set are not kept).
fn normalisation_of(builder: &FeatureBuilder, frames: &[LabelledFrame]) -> Result<Normalisation> {
    let c = builder.channels();
    let mut sum = vec![0.0; c];
    let mut sq = vec![0.0; c];
    let mut count = 0.0;
    for f in frames {
        for set in builder.input_sets_with(&f.shape, Some(&f.tendon_pull_m))? {
            for row in set.chunks_exact(c) {
                for (ch, &x) in row.iter().enumerate() {
                    sum[ch] += x;
                    sq[ch] += x * x;
                }
                count += 1.0;
            }
        }
    }
    let mean: Vec<f64> = sum.iter().map(|s| s / count).collect();
    // A channel constant over the training frames (the co-contraction of pulls that are always
    // antagonistic, say) is left unscaled: dividing by its zero spread would turn any value it
    // takes at run time into an enormous input.
    let std = sq
        .iter()
        .zip(&mean)
        .map(|(q, m)| {
            let sd = (q / count - m * m).max(0.0).sqrt();
            if sd < 1e-6 { 1.0 } else { sd }
        })
        .collect();
    Ok(Normalisation { mean, std })
}

/// Contact metrics of the validation frames from the probabilities `p` of their point sets
/// (frame after frame), contacts at `threshold`.
fn contact_report(
    builder: &FeatureBuilder,
    frames: &[LabelledFrame],
    p: &[f64],
    threshold: f64,
) -> Result<ContactReport> {
    let per_frame: usize = builder.point_sets().iter().map(|s| s.1).sum();
    if p.len() != per_frame * frames.len() {
        bail!(
            "{} probabilities for {} frames of {per_frame} points",
            p.len(),
            frames.len()
        );
    }
    let mut metrics = ContactMetrics::default();
    for (frame, values) in frames.iter().zip(p.chunks_exact(per_frame.max(1))) {
        let predicted: Vec<Vec<bool>> = builder
            .per_finger(values)?
            .into_iter()
            .map(|f| f.into_iter().map(|v| v >= threshold).collect())
            .collect();
        metrics.add(&frame.shape, &frame.contact, &predicted)?;
    }
    Ok(metrics.report())
}

/// Counters of a run, for the card.
struct RunRecord {
    started: Instant,
    train_seconds: f64,
    sets_trained: usize,
    train_sets: usize,
    validation_sets: usize,
    train_frames: usize,
    validation_frames: usize,
}

/// Writes `NAME.safetensors` and its card from the trainer's current weights.
fn write_model(
    args: &TrainArgs,
    readers: &[DatasetReader],
    arch: &DgcnnConfig,
    config: &TrainConfig,
    trainer: &Trainer,
    history: &[EpochRecord],
    run: &RunRecord,
) -> Result<()> {
    let last = history.last().context("no epoch was trained")?;
    let mut card = ModelCard::new(arch.clone());
    card.threshold = last.validation_threshold;
    let reader = &readers[0];
    card.hand = Some(CardHand {
        name: reader.card().generator["params"]["preset"]
            .as_str()
            .unwrap_or("unknown")
            .to_string(),
        finger_num_vertices: reader.card().layout.finger_num_vertices.clone(),
    });
    card.training = Some(serde_json::json!({
        "input_shape": args.input_shape,
        "marker_noise_m": args.marker_noise,
        "marker_dropout": args.marker_dropout,
        "marker_tip_occlusion": args.marker_tip_occlusion,
        "marker_tip_run": args.marker_tip_run,
        "init": args.init.as_ref().map(|p| p.display().to_string()),
        "config": config,
        "contact_weight": trainer.contact_weight(),
        "train_sets": run.train_sets,
        "validation_sets": run.validation_sets,
        "sets_per_second": run.sets_trained as f64 / run.train_seconds.max(1e-9),
        "train_seconds": run.train_seconds,
        "wall_time_s": run.started.elapsed().as_secs_f64(),
        "command": std::env::args().collect::<Vec<_>>().join(" "),
    }));
    // One data set: its record; several: the list of their records.
    let records: Vec<serde_json::Value> = readers
        .iter()
        .zip(&args.data)
        .map(|(reader, dir)| {
            serde_json::json!({
                "dir": dir.display().to_string(),
                "seed": reader.card().seed,
                "frames": reader.card().totals.frames,
                "trajectories": reader.card().totals.trajectories,
                "label_rule": label_rule_of(reader),
                // The command that regenerates the data set, with its generator parameters
                // (below) as a --params file when they are not the defaults.
                "regenerate": format!(
                    "cargo run --release -p xtask -- gen-data --out {} --trajectories {} --seed {} --fingers {}",
                    dir.display(),
                    reader.card().totals.trajectories,
                    reader.card().seed,
                    reader.card().layout.finger_num_vertices.len()
                ),
                "generator": reader.card().generator,
            })
        })
        .collect();
    let mut dataset = if records.len() == 1 {
        records[0].clone()
    } else {
        serde_json::json!({ "sets": records })
    };
    dataset["train_frames"] = serde_json::json!(run.train_frames);
    dataset["validation_frames"] = serde_json::json!(run.validation_frames);
    card.dataset = Some(dataset);
    card.metrics = Some(serde_json::json!({ "epochs": history }));
    let weights = ModelWeights::of(trainer.network())?.to_bytes()?;
    let weights_path = args.out.with_extension("safetensors");
    moe_io::write_model_files(&weights_path, &weights, Some(&card.to_json()?))?;
    Ok(())
}

/// The training and validation frames of one data set with the physics estimator's shapes
/// (the training ones from perturbed markers when `augmentation` is given).
fn physics_shapes(
    reader: &DatasetReader,
    hand: &HandModel,
    train: Vec<LabelledFrame>,
    validation: Vec<LabelledFrame>,
    augmentation: Option<&MarkerAugmentation>,
) -> Result<(Vec<LabelledFrame>, Vec<LabelledFrame>)> {
    let params: RandomSceneParams =
        serde_json::from_value(reader.card().generator["params"].clone())
            .context("the data set card's simulator parameters")?;
    let frame_secs = params.dt_secs * params.save_every_steps as Real;
    let material = moe_physics::HandMaterial::default();
    let config = moe_physics::PhysicsConfig::default();
    let t = Instant::now();
    let shapes = |frames: &[LabelledFrame], augmentation| {
        moe_touch::physics_eval::with_physics_shapes(
            hand,
            frames,
            frame_secs,
            &material,
            &config,
            augmentation,
        )
    };
    let train = shapes(&train, augmentation)?;
    let validation = shapes(&validation, None)?;
    eprintln!(
        "train: physics shapes of {} frames from their markers in {:.0} s",
        train.len() + validation.len(),
        t.elapsed().as_secs_f64()
    );
    Ok((train, validation))
}

/// The marker perturbation of the training frames' estimated shapes, if any, checked.
fn marker_augmentation(args: &TrainArgs) -> Result<Option<MarkerAugmentation>> {
    if args.marker_noise == 0.0 && args.marker_dropout == 0.0 && args.marker_tip_occlusion == 0.0 {
        return Ok(None);
    }
    if args.input_shape == InputShapeArg::Simulated {
        bail!(
            "--marker-noise, --marker-dropout and --marker-tip-occlusion perturb estimated shapes: use --input-shape sr-arap, both or physics"
        );
    }
    let augmentation = MarkerAugmentation {
        noise_sd_m: args.marker_noise,
        drop_probability: args.marker_dropout,
        distal_occlusion_probability: args.marker_tip_occlusion,
        max_distal_occluded: args.marker_tip_run,
        seed: args.seed,
    };
    augmentation.validate()?;
    Ok(Some(augmentation))
}

/// Steps between progress lines when stderr is not a terminal.
const LOG_EVERY: usize = 50;

fn checkpoint_path(out: &Path) -> PathBuf {
    out.with_extension("checkpoint.safetensors")
}

/// The input spec of `--init`'s card, checked against the run's: the run may add features
/// after the initial model's own (their weights start at zero), in the same frame and point
/// sets; it may not drop or reorder them, which would feed the initial weights other channels
/// than they were trained on. Weights without a card must take the run's channels as they are.
fn init_input_of(args: &TrainArgs, spec: &InputSpec) -> Result<Option<InputSpec>> {
    let Some(path) = &args.init else {
        return Ok(None);
    };
    let files = moe_io::read_model_files(path)?;
    let Some(text) = files.card else {
        let weights = ModelWeights::parse(&files.weights)
            .with_context(|| format!("initial weights {}", path.display()))?;
        let channels = weights.get("edge1.theta").map(|(shape, _)| shape[1]);
        if channels != Some(spec.channels()) {
            bail!(
                "--init {}: weights without a card take {} input channels, the run's features \
                 ({}) {}; give the card beside the weights",
                path.display(),
                channels.map_or("no".to_string(), |c| c.to_string()),
                spec.describe(),
                spec.channels()
            );
        }
        return Ok(None);
    };
    let input = ModelCard::from_json(&text)
        .with_context(|| format!("model card {}", files.card_path.display()))?
        .architecture
        .input;
    if input.features != spec.features
        && (!spec.features.starts_with(&input.features)
            || input.frame != spec.frame
            || input.point_set != spec.point_set)
    {
        bail!(
            "--init {}: its features ({}, {:?} frame, {:?} sets) are not the first of the run's \
             ({}, {:?} frame, {:?} sets); features can only be added after the initial model's, \
             in the same frame and point sets",
            path.display(),
            input.describe(),
            input.frame,
            input.point_set,
            spec.describe(),
            spec.frame,
            spec.point_set
        );
    }
    Ok(Some(input))
}

pub(crate) fn run(args: &TrainArgs) -> Result<()> {
    let started = Instant::now();
    // Options that clap cannot check alone, checked before any data loads.
    let edge_widths = widths("edge-widths", &args.edge_widths)?;
    let head_widths = widths("head-widths", &args.head_widths)?;
    let augmentation = marker_augmentation(args)?;
    let mut spec = InputSpec {
        features: args
            .features
            .iter()
            .map(|f| match f {
                FeatureArg::Xyz => InputFeature::Xyz,
                FeatureArg::RestXyz => InputFeature::RestXyz,
                FeatureArg::Deformation => InputFeature::Deformation,
                FeatureArg::TendonPull => InputFeature::TendonPull,
            })
            .collect(),
        frame: match args.point_set {
            PointSetArg::PerFinger => FeatureFrame::Finger,
            PointSetArg::WholeHand => FeatureFrame::Hand,
        },
        point_set: match args.point_set {
            PointSetArg::PerFinger => PointSet::PerFinger,
            PointSetArg::WholeHand => PointSet::WholeHand,
        },
        normalisation: None,
    };
    let init_input = init_input_of(args, &spec)?;
    let readers = args
        .data
        .iter()
        .map(|d| DatasetReader::open(d))
        .collect::<Result<Vec<_>, _>>()?;
    let hand = dataset_hand(&readers[0])?;
    let mut train_frames = Vec::new();
    let mut validation_frames = Vec::new();
    // Validation metrics take the contact points on the true surfaces (the design's definition).
    let mut validation_truth = Vec::new();
    for (reader, dir) in readers.iter().zip(&args.data) {
        let other = dataset_hand(reader)?;
        let same = other.num_fingers() == hand.num_fingers()
            && (0..hand.num_fingers())
                .all(|i| other.rest_vertices_in_hand(i) == hand.rest_vertices_in_hand(i));
        if !same {
            bail!(
                "{}: a data set of another hand than {}'s",
                dir.display(),
                args.data[0].display()
            );
        }
        let train = frames(reader, Split::Train, args.max_frames)?;
        let validation = frames(
            reader,
            Split::Validation,
            args.max_frames.map(|m| m / 4 + 1),
        )?;
        if train.is_empty() {
            bail!("{}: no training frames", dir.display());
        }
        if validation.is_empty() {
            bail!(
                "{}: no validation frames (too few trajectories)",
                dir.display()
            );
        }
        validation_truth.extend(validation.iter().cloned());
        let (train, validation) = if args.input_shape == InputShapeArg::Physics {
            physics_shapes(reader, &hand, train, validation, augmentation.as_ref())?
        } else {
            (train, validation)
        };
        train_frames.extend(train);
        validation_frames.extend(validation);
    }
    let (train_frames, validation_frames) = if matches!(
        args.input_shape,
        InputShapeArg::Simulated | InputShapeArg::Physics
    ) {
        (train_frames, validation_frames)
    } else {
        let t = Instant::now();
        let options = moe_arap::ShapeConfig::default();
        let mut train =
            with_estimated_shapes(&hand, &train_frames, &options, augmentation.as_ref())?;
        let validation = with_estimated_shapes(&hand, &validation_frames, &options, None)?;
        eprintln!(
            "train: SR-ARAP shapes of {} frames from their markers in {:.0} s",
            train.len() + validation.len(),
            t.elapsed().as_secs_f64()
        );
        if args.input_shape == InputShapeArg::Both {
            train.extend(train_frames);
        }
        (train, validation)
    };
    // Normalise every channel by the training frames' statistics — or, fine-tuning, keep the
    // normalisation the initial weights were trained with for the channels they were trained
    // on (the features listed first), and the training frames' for any added after them.
    let kept = init_input.as_ref().and_then(|input| {
        spec.features
            .starts_with(&input.features)
            .then_some(input.normalisation.as_ref())
            .flatten()
    });
    spec.normalisation = Some(match kept {
        Some(n) if n.mean.len() == spec.channels() => n.clone(),
        kept => {
            let mut fresh = normalisation_of(&FeatureBuilder::new(&spec, &hand)?, &train_frames)?;
            if let Some(n) = kept {
                fresh.mean[..n.mean.len()].copy_from_slice(&n.mean);
                fresh.std[..n.std.len()].copy_from_slice(&n.std);
            }
            fresh
        }
    });
    let builder = FeatureBuilder::new(&spec, &hand)?;
    let train = TrainingSets::from_frames(&builder, &train_frames)?;
    let validation = TrainingSets::from_frames(&builder, &validation_frames)?;
    let arch = DgcnnConfig {
        k: args.k,
        edge_widths,
        head_widths,
        aggregation: args.aggregation,
        input: spec,
        ..DgcnnConfig::default()
    };
    let config = TrainConfig {
        epochs: args.epochs,
        batch_size: args.batch_size,
        optimizer: match args.optimizer {
            OptimizerArg::Adamw => match TrainConfig::default().optimizer {
                OptimizerConfig::AdamW {
                    weight_decay,
                    beta1,
                    beta2,
                    eps,
                    ..
                } => OptimizerConfig::AdamW {
                    learning_rate: args.lr,
                    weight_decay,
                    beta1,
                    beta2,
                    eps,
                },
                other => other,
            },
            OptimizerArg::Sgd => OptimizerConfig::Sgd {
                learning_rate: args.lr,
                momentum: 0.3,
                weight_decay: 1e-4,
            },
        },
        contact_weight: args.contact_weight,
        seed: args.seed,
        negative_fraction: args.negative_fraction,
        lr_step_epochs: args.lr_step_epochs,
        ..TrainConfig::default()
    };
    let ckpt_path = checkpoint_path(&args.out);
    let history_path = args.out.with_extension("history.json");
    let (mut trainer, mut history): (Trainer, Vec<EpochRecord>) =
        if args.resume && ckpt_path.exists() {
            let bytes = std::fs::read(&ckpt_path)
                .with_context(|| format!("reading {}", ckpt_path.display()))?;
            let checkpoint = Checkpoint { bytes };
            let trainer = Trainer::resume(arch.clone(), config.clone(), &train, &checkpoint)
                .with_context(|| format!("resuming from {}", ckpt_path.display()))?;
            let history: Vec<EpochRecord> = if history_path.exists() {
                moe_io::read_json(&history_path)?
            } else {
                Vec::new()
            };
            eprintln!("train: resumed after epoch {}", trainer.epochs_done());
            (trainer, history)
        } else {
            let trainer = match &args.init {
                Some(path) => {
                    let files = moe_io::read_model_files(path)?;
                    // Features added after the initial weights' own start with zero weights.
                    let weights = ModelWeights::parse(&files.weights)
                        .and_then(|w| w.with_input_channels(train.channels()))
                        .with_context(|| format!("initial weights {}", path.display()))?;
                    eprintln!("train: starting from the weights of {}", path.display());
                    Trainer::from_weights(arch.clone(), config.clone(), &train, &weights)?
                }
                None => Trainer::new(arch.clone(), config.clone(), &train)?,
            };
            (trainer, Vec::new())
        };
    history.truncate(trainer.epochs_done());
    eprintln!(
        "train: {} training sets ({} frames), {} validation sets, {} points × {} channels, \
         contact weight {:.1}",
        train.len(),
        train_frames.len(),
        validation.len(),
        train.points(),
        train.channels(),
        trainer.contact_weight()
    );
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} epoch {prefix} [{elapsed_precise}] {bar:30} {pos}/{len} steps  {msg}  ETA {eta}",
        )
        .context("progress template")?,
    );
    bar.enable_steady_tick(Duration::from_millis(500));
    let mut train_seconds = 0.0;
    let mut sets_trained = 0usize;
    while trainer.epochs_done() < args.epochs {
        let epoch = trainer.epochs_done();
        bar.set_prefix(format!("{}/{}", epoch + 1, args.epochs));
        bar.set_position(0);
        let t0 = Instant::now();
        let batch = args.batch_size;
        let logging = !std::io::stderr().is_terminal();
        let mut recent = 0.0;
        let mut epoch_steps = 0;
        let train_loss = trainer.run_epoch(&train, &mut |step, steps, loss| {
            epoch_steps = steps;
            bar.set_length(steps as u64);
            bar.set_position(step as u64);
            let elapsed = t0.elapsed().as_secs_f64().max(1e-9);
            let rate = (step * batch) as f64 / elapsed;
            bar.set_message(format!("loss {loss:.4}  {rate:.1} sets/s"));
            // Without a terminal the bar is hidden: a line every LOG_EVERY steps instead.
            recent += loss;
            if logging && (step % LOG_EVERY == 0 || step == steps) {
                let n = (step - 1) % LOG_EVERY + 1;
                let left = elapsed / step as f64 * (steps - step) as f64;
                eprintln!(
                    "train: epoch {} step {step}/{steps}: loss {:.4} (last {n} steps), {rate:.1} \
                     sets/s, {:.0} s left in the epoch",
                    epoch + 1,
                    recent / n as f64,
                    left
                );
                recent = 0.0;
            }
        })?;
        let epoch_seconds = t0.elapsed().as_secs_f64();
        train_seconds += epoch_seconds;
        // The sets this epoch drew (all but the last batch are full).
        sets_trained += (epoch_steps * batch).min(train.len());
        let p = moe_contact::predict(trainer.network(), &validation, args.batch_size)?;
        let eval = evaluation_of(
            &p,
            (0..validation.len()).flat_map(|s| validation.labels_of(s)),
            trainer.contact_weight(),
        );
        let (threshold, best) = eval.best();
        let half = eval.at(0.5).unwrap_or_default();
        let contact = contact_report(&builder, &validation_truth, &p, threshold)?;
        let record = EpochRecord {
            epoch: epoch + 1,
            learning_rate: config.learning_rate_at(epoch),
            train_loss,
            validation_loss: eval.loss,
            validation_threshold: threshold,
            validation_f1: best.f1(),
            validation_precision: best.precision(),
            validation_recall: best.recall(),
            validation_iou: best.iou(),
            validation_f1_at_half: half.f1(),
            validation_contact_bcd_mm: contact.bcd_mm,
            validation_miss_rate: contact.miss_rate,
            validation_false_alarm_rate: contact.false_alarm_rate,
            seconds: t0.elapsed().as_secs_f64(),
        };
        let line = format!(
            "epoch {}: train loss {:.4}, validation loss {:.4}, F1 {:.3} at {:.2} (P {:.3}, R \
             {:.3}), F1 {:.3} at 0.5, contact BCD {:.2} mm, missed {:.1} %, false alarms {:.1} %, \
             {:.0} s",
            record.epoch,
            record.train_loss,
            record.validation_loss,
            record.validation_f1,
            record.validation_threshold,
            record.validation_precision,
            record.validation_recall,
            record.validation_f1_at_half,
            record.validation_contact_bcd_mm,
            100.0 * record.validation_miss_rate,
            100.0 * record.validation_false_alarm_rate,
            record.seconds
        );
        // Also when stderr is not a terminal (the bar is hidden then, and its println with it).
        bar.suspend(|| eprintln!("train: {line}"));
        history.push(record);
        // A checkpoint after every epoch, so an interrupted run resumes here.
        let checkpoint = trainer.checkpoint()?;
        moe_io::write_atomic(&ckpt_path, &checkpoint.bytes)?;
        moe_io::write_json(&history_path, &history)?;
        // The model and its card after every epoch, so that a stopped run leaves a usable model.
        let run = RunRecord {
            started,
            train_seconds,
            sets_trained,
            train_sets: train.len(),
            validation_sets: validation.len(),
            train_frames: train_frames.len(),
            validation_frames: validation_frames.len(),
        };
        write_model(args, &readers, &arch, &config, &trainer, &history, &run)?;
    }
    bar.finish_and_clear();
    let last = history.last().context("no epoch was trained")?;
    let weights_path = args.out.with_extension("safetensors");
    eprintln!(
        "train: wrote {} and its card ({} epochs, validation F1 {:.3} at threshold {:.2})",
        weights_path.display(),
        history.len(),
        last.validation_f1,
        last.validation_threshold
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::widths;

    #[test]
    fn widths_take_exactly_their_count() {
        assert_eq!(
            widths::<3>("edge-widths", &[8, 16, 32]).unwrap(),
            [8, 16, 32]
        );
        let err = widths::<2>("head-widths", &[8, 16, 32]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "--head-widths takes 2 comma-separated widths, got 3"
        );
        assert!(widths::<3>("edge-widths", &[8]).is_err());
    }

    /// Options that clap cannot check alone are refused before the data sets are opened: the
    /// missing data directory is not what the error names.
    #[test]
    fn bad_options_are_refused_before_any_data_loads() {
        use clap::Parser;
        let cases: [(&[&str], &str); 5] = [
            (
                &["--edge-widths", "8,8"],
                "--edge-widths takes 3 comma-separated widths, got 2",
            ),
            (
                &["--marker-noise", "0.02"],
                "marker noise sd (m) = 0.02: not between 0 and 0.005 m",
            ),
            (
                &["--marker-dropout", "1.5"],
                "marker drop probability = 1.5: not between 0 and 1",
            ),
            (
                &["--marker-tip-occlusion", "1.5"],
                "distal marker occlusion probability = 1.5: not between 0 and 1",
            ),
            (
                &[
                    "--marker-tip-occlusion",
                    "0.2",
                    "--input-shape",
                    "simulated",
                ],
                "--marker-noise, --marker-dropout and --marker-tip-occlusion perturb estimated shapes: use --input-shape sr-arap, both or physics",
            ),
        ];
        for (extra, expected) in cases {
            let mut argv = vec![
                "xtask",
                "train",
                "--data",
                "/nonexistent/data set",
                "--out",
                "/nonexistent/model",
            ];
            argv.extend_from_slice(extra);
            let cli = crate::Cli::try_parse_from(argv).unwrap();
            let crate::Command::Train(args) = cli.command else {
                panic!("not the train command");
            };
            let err = super::run(&args).unwrap_err();
            assert_eq!(format!("{err:#}"), expected, "{extra:?}");
        }
    }
}
