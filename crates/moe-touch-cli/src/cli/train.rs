//! `moe-touch train`: trains the contact network on generated data sets — a thin command over
//! `moe_lab::training::TrainingRun`, with a progress bar.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use moe_contact::{
    Aggregation, DgcnnConfig, EpochRecord, FeatureFrame, InputFeature, InputSpec, OptimizerConfig,
    PointSet, TrainConfig,
};
use moe_lab::contact_eval::MarkerAugmentation;
use moe_lab::training::{InputShape, TrainingOptions, TrainingRun};

/// Arguments of `moe-touch train`.
#[derive(Debug, Args)]
pub(crate) struct TrainArgs {
    /// Data set directory (as `moe-touch gen-data` writes it); repeat to train on several data
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

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
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
    /// SR-ARAP from the frame's markers registered to a depth image of the true fingers as the
    /// default wrist camera renders it (SR-ARAP's `[depth]` defaults, enabled), for training
    /// and validation: run the model with `--shape-config` enabling `[depth]`.
    SrArapDepth,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum PointSetArg {
    PerFinger,
    WholeHand,
}

/// The run's options from the arguments, checked before any data loads.
fn options_of(args: &TrainArgs) -> Result<TrainingOptions> {
    let edge_widths = widths("edge-widths", &args.edge_widths)?;
    let head_widths = widths("head-widths", &args.head_widths)?;
    let input = InputSpec {
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
    let perturbed =
        args.marker_noise != 0.0 || args.marker_dropout != 0.0 || args.marker_tip_occlusion != 0.0;
    let options = TrainingOptions {
        data: args.data.clone(),
        out: args.out.clone(),
        resume: args.resume,
        architecture: DgcnnConfig {
            k: args.k,
            edge_widths,
            head_widths,
            aggregation: args.aggregation,
            input,
            ..DgcnnConfig::default()
        },
        train: TrainConfig {
            epochs: args.epochs,
            batch_size: args.batch_size,
            optimizer: optimizer_of(args),
            contact_weight: args.contact_weight,
            seed: args.seed,
            negative_fraction: args.negative_fraction,
            lr_step_epochs: args.lr_step_epochs,
            ..TrainConfig::default()
        },
        max_frames: args.max_frames,
        input_shape: match args.input_shape {
            InputShapeArg::SrArap => InputShape::SrArap,
            InputShapeArg::Simulated => InputShape::Simulated,
            InputShapeArg::Both => InputShape::Both,
            InputShapeArg::Physics => InputShape::Physics,
            InputShapeArg::SrArapDepth => InputShape::SrArapDepth,
        },
        init: args.init.clone(),
        augmentation: perturbed.then_some(MarkerAugmentation {
            noise_sd_m: args.marker_noise,
            drop_probability: args.marker_dropout,
            distal_occlusion_probability: args.marker_tip_occlusion,
            max_distal_occluded: args.marker_tip_run,
            seed: args.seed,
        }),
        command: std::env::args().collect::<Vec<_>>().join(" "),
    };
    options.validate()?;
    Ok(options)
}

/// The optimiser of `--optimizer` at `--lr` (AdamW's other settings, and the paper's SGD
/// momentum and weight decay).
fn optimizer_of(args: &TrainArgs) -> OptimizerConfig {
    match args.optimizer {
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
    }
}

/// Steps between progress lines when stderr is not a terminal.
const LOG_EVERY: usize = 50;

/// One line of an epoch's record.
fn epoch_line(r: &EpochRecord) -> String {
    format!(
        "epoch {}: train loss {:.4}, validation loss {:.4}, F1 {:.3} at {:.2} (P {:.3}, R \
         {:.3}), F1 {:.3} at 0.5, contact BCD {:.2} mm, missed {:.1} %, false alarms {:.1} %, \
         {:.0} s",
        r.epoch,
        r.train_loss,
        r.validation_loss,
        r.validation_f1,
        r.validation_threshold,
        r.validation_precision,
        r.validation_recall,
        r.validation_f1_at_half,
        r.validation_contact_bcd_mm,
        100.0 * r.validation_miss_rate,
        100.0 * r.validation_false_alarm_rate,
        r.seconds
    )
}

pub(crate) fn run(args: &TrainArgs) -> Result<()> {
    let options = options_of(args)?;
    let mut run = TrainingRun::prepare(options, &mut |line| eprintln!("{line}"))?;
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} epoch {prefix} [{elapsed_precise}] {bar:30} {pos}/{len} steps  {msg}  ETA {eta}",
        )
        .context("progress template")?,
    );
    bar.enable_steady_tick(Duration::from_millis(500));
    let logging = !std::io::stderr().is_terminal();
    let batch = args.batch_size;
    while run.epochs_done() < run.epochs() {
        let epoch = run.epochs_done();
        bar.set_prefix(format!("{}/{}", epoch + 1, run.epochs()));
        bar.set_position(0);
        let t0 = Instant::now();
        let mut recent = 0.0;
        let record = run.train_epoch(&mut |step, steps, loss| {
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
        let line = epoch_line(record);
        // Also when stderr is not a terminal (the bar is hidden then, and its println with it).
        bar.suspend(|| eprintln!("train: {line}"));
    }
    bar.finish_and_clear();
    let last = run.history().last().context("no epoch was trained")?;
    eprintln!(
        "train: wrote {} and its card ({} epochs, validation F1 {:.3} at threshold {:.2})",
        run.options().weights_path().display(),
        run.history().len(),
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
                "--marker-noise, --marker-dropout and --marker-tip-occlusion perturb estimated shapes: use --input-shape sr-arap, both, physics or sr-arap-depth",
            ),
        ];
        for (extra, expected) in cases {
            let mut argv = vec![
                "moe-touch",
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
