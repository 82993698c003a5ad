//! Training a contact model on generated data sets: [`TrainingRun`](crate::training::TrainingRun) loads the frames, computes
//! the shapes the network learns from, normalises the features, and trains epoch by epoch with a
//! checkpoint, the learning curve and a usable model (weights and card) after every epoch, so
//! that a stopped run resumes where it stopped and leaves a model behind.
//!
//! ```no_run
//! use moe_lab::training::{InputShape, TrainingOptions, TrainingRun};
//!
//! let options = TrainingOptions::new(vec!["data/train".into()], "models/mine".into());
//! let mut run = TrainingRun::prepare(options, &mut |line| eprintln!("{line}"))?;
//! while run.epochs_done() < run.epochs() {
//!     let record = run.train_epoch(&mut |_step, _steps, _loss| {})?;
//!     eprintln!("epoch {}: validation F1 {:.3}", record.epoch, record.validation_f1);
//! }
//! # Ok::<(), moe_lab::LabError>(())
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use moe_contact::{
    CardDataSource, CardDataset, CardHand, CardMetrics, CardTraining, Checkpoint, ContactMetrics,
    ContactReport, DgcnnConfig, EpochRecord, FeatureBuilder, InputSpec, ModelCard, ModelWeights,
    Normalisation, TrainConfig, Trainer, TrainingSets, evaluation_of,
};
use moe_geom::{HandModel, LabelledFrame, Real};
use moe_io::{DatasetReader, Split, SplitFractions};
use serde::{Deserialize, Serialize};

use crate::LabError;
use crate::contact_eval::{
    MarkerAugmentation, with_depth_registered_shapes, with_estimated_shapes,
};
use crate::datagen::{dataset_hand, dataset_params, label_rule};
use moe_tendon_sim::camera::RgbdCamera;

/// The shapes the network learns from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InputShape {
    /// SR-ARAP from the frame's markers (the paper's 50 iterations from rest): what the network
    /// sees at run time.
    SrArap,
    /// The simulated surface.
    Simulated,
    /// Both: every training frame twice, as simulated and as SR-ARAP estimated; validation on
    /// the SR-ARAP shapes.
    Both,
    /// The physics estimator's dented shape from the frame's markers (nominal material, default
    /// settings; each trajectory run as a stream), for training and validation.
    Physics,
    /// SR-ARAP from the frame's markers registered to a depth image of its true fingers as the
    /// default wrist camera renders it with its noise (`ShapeDepth`'s defaults, enabled): what
    /// the network sees at run time with SR-ARAP's `[depth]` enabled. For training and
    /// validation.
    SrArapDepth,
}

impl InputShape {
    /// The name the card records (`sr-arap`, `simulated`, `both`, `physics`, `sr-arap-depth`).
    pub fn name(self) -> &'static str {
        match self {
            Self::SrArap => "sr-arap",
            Self::Simulated => "simulated",
            Self::Both => "both",
            Self::Physics => "physics",
            Self::SrArapDepth => "sr-arap-depth",
        }
    }
}

/// What a [`TrainingRun`] trains on, into what, and how.
#[derive(Debug, Clone)]
pub struct TrainingOptions {
    /// Data set directories of one hand; each is split into training, validation and test
    /// trajectories by its own seed, and the splits are pooled.
    pub data: Vec<PathBuf>,
    /// Output model path without extension: `NAME.safetensors` and its card `NAME.json`, with
    /// `NAME.checkpoint.safetensors` and `NAME.history.json` kept while training.
    pub out: PathBuf,
    /// Continue from the checkpoint when there is one.
    pub resume: bool,
    /// The network; its input spec's normalisation is computed from the training frames (or
    /// kept from `init`'s card for the features it was trained on).
    pub architecture: DgcnnConfig,
    /// Epochs, batch, optimiser, schedule, seed.
    pub train: TrainConfig,
    /// At most this many training frames (the first ones, in data set order), and a quarter as
    /// many validation frames.
    pub max_frames: Option<usize>,
    /// The shapes the network learns from.
    pub input_shape: InputShape,
    /// Start from these weights (`NAME.safetensors`, with its card when it has one) with fresh
    /// optimiser state: fine-tuning. Ignored when resuming.
    pub init: Option<PathBuf>,
    /// Perturbations of the training frames' markers before their shapes are estimated.
    pub augmentation: Option<MarkerAugmentation>,
    /// The command line that started the run, recorded in the card.
    pub command: String,
}

impl TrainingOptions {
    /// The paper's network and the default schedule on `data`, into `out`.
    pub fn new(data: Vec<PathBuf>, out: PathBuf) -> Self {
        Self {
            data,
            out,
            resume: false,
            architecture: DgcnnConfig::default(),
            train: TrainConfig::default(),
            max_frames: None,
            input_shape: InputShape::Both,
            init: None,
            augmentation: None,
            command: String::new(),
        }
    }

    /// Checks what can be checked before any data loads.
    ///
    /// # Errors
    /// [`LabError::Training`] for no data set or marker perturbations of simulated shapes, and
    /// the perturbation's own check.
    pub fn validate(&self) -> Result<(), LabError> {
        if self.data.is_empty() {
            return Err(training("no data set given"));
        }
        if let Some(a) = &self.augmentation {
            if self.input_shape == InputShape::Simulated {
                return Err(training(
                    "--marker-noise, --marker-dropout and --marker-tip-occlusion perturb \
                     estimated shapes: use --input-shape sr-arap, both, physics or \
                     sr-arap-depth",
                ));
            }
            a.validate()?;
        }
        Ok(())
    }

    /// Where the checkpoint is kept.
    pub fn checkpoint_path(&self) -> PathBuf {
        self.out.with_extension("checkpoint.safetensors")
    }

    /// Where the learning curve is kept.
    pub fn history_path(&self) -> PathBuf {
        self.out.with_extension("history.json")
    }

    /// Where the weights go (their card beside them).
    pub fn weights_path(&self) -> PathBuf {
        self.out.with_extension("safetensors")
    }
}

fn training(reason: impl Into<String>) -> LabError {
    LabError::Training {
        reason: reason.into(),
    }
}

/// The frames a run learns from and is validated on.
struct RunFrames {
    /// Training frames with the shapes the network learns from.
    train: Vec<LabelledFrame>,
    /// Validation frames with the shapes the network sees.
    validation: Vec<LabelledFrame>,
    /// Validation frames with their true surfaces (contact metrics take the true contacts).
    validation_truth: Vec<LabelledFrame>,
}

/// A training run in progress; see the module documentation.
pub struct TrainingRun {
    options: TrainingOptions,
    readers: Vec<DatasetReader>,
    arch: DgcnnConfig,
    builder: FeatureBuilder,
    train: TrainingSets,
    validation: TrainingSets,
    validation_truth: Vec<LabelledFrame>,
    train_frames: usize,
    validation_frames: usize,
    trainer: Trainer,
    history: Vec<EpochRecord>,
    started: Instant,
    train_seconds: f64,
    sets_trained: usize,
    card_hand: CardHand,
}

impl std::fmt::Debug for TrainingRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TrainingRun")
            .field("out", &self.options.out)
            .field("epochs_done", &self.trainer.epochs_done())
            .field("train_sets", &self.train.len())
            .field("validation_sets", &self.validation.len())
            .finish_non_exhaustive()
    }
}

impl TrainingRun {
    /// Loads the data sets, computes the shapes and the normalisation, and builds the trainer
    /// (seeded, from `init`'s weights, or resumed from the checkpoint). `log` receives progress
    /// lines.
    ///
    /// # Errors
    /// Invalid options ([`TrainingOptions::validate`]), unreadable or inconsistent data sets
    /// (another hand, no training or validation frames), an `init` model whose features are not
    /// the first of the run's, or a failing shape estimation or trainer.
    pub fn prepare(options: TrainingOptions, log: &mut dyn FnMut(&str)) -> Result<Self, LabError> {
        let started = Instant::now();
        options.validate()?;
        let mut spec = options.architecture.input.clone();
        spec.normalisation = None;
        let init_input = init_input_of(options.init.as_deref(), &spec)?;
        let readers = options
            .data
            .iter()
            .map(|d| DatasetReader::open(d))
            .collect::<Result<Vec<_>, _>>()?;
        let hand = dataset_hand(&readers[0])?;
        let frames = load_frames(&options, &readers, &hand, log)?;
        spec.normalisation = Some(normalisation(
            &spec,
            init_input.as_ref(),
            &hand,
            &frames.train,
        )?);
        let builder = FeatureBuilder::new(&spec, &hand)?;
        let train = TrainingSets::from_frames(&builder, &frames.train)?;
        let validation = TrainingSets::from_frames(&builder, &frames.validation)?;
        let arch = DgcnnConfig {
            input: spec,
            ..options.architecture.clone()
        };
        let (trainer, history) = start_trainer(&options, &arch, &train, log)?;
        log(&format!(
            "train: {} training sets ({} frames), {} validation sets, {} points × {} channels, \
             contact weight {:.1}",
            train.len(),
            frames.train.len(),
            validation.len(),
            train.points(),
            train.channels(),
            trainer.contact_weight()
        ));
        let hand_name = readers[0].card().generator["params"]["preset"]
            .as_str()
            .unwrap_or("unknown")
            .to_owned();
        Ok(Self {
            card_hand: CardHand::of(&hand_name, &hand),
            train_frames: frames.train.len(),
            validation_frames: frames.validation.len(),
            validation_truth: frames.validation_truth,
            options,
            readers,
            arch,
            builder,
            train,
            validation,
            trainer,
            history,
            started,
            train_seconds: 0.0,
            sets_trained: 0,
        })
    }

    /// Epochs trained so far (a resumed run counts the earlier ones).
    pub fn epochs_done(&self) -> usize {
        self.trainer.epochs_done()
    }

    /// Epochs of the whole run.
    pub fn epochs(&self) -> usize {
        self.options.train.epochs
    }

    /// The learning curve so far.
    pub fn history(&self) -> &[EpochRecord] {
        &self.history
    }

    /// The options.
    pub fn options(&self) -> &TrainingOptions {
        &self.options
    }

    /// Trains one epoch (`progress` sees each step: step, steps, loss), measures it on the
    /// validation frames, and writes the checkpoint, the learning curve and the model with its
    /// card.
    ///
    /// # Errors
    /// A failing training step or evaluation, or a file that cannot be written.
    pub fn train_epoch(
        &mut self,
        progress: &mut dyn FnMut(usize, usize, f64),
    ) -> Result<&EpochRecord, LabError> {
        let epoch = self.trainer.epochs_done();
        let t0 = Instant::now();
        let mut epoch_steps = 0;
        let train_loss = self
            .trainer
            .run_epoch(&self.train, &mut |step, steps, loss| {
                epoch_steps = steps;
                progress(step, steps, loss);
            })?;
        self.train_seconds += t0.elapsed().as_secs_f64();
        // The sets this epoch drew (all but the last batch are full).
        let batch = self.options.train.batch_size;
        self.sets_trained += (epoch_steps * batch).min(self.train.len());
        let record = self.validate_epoch(epoch, train_loss, t0)?;
        self.history.push(record);
        self.save()?;
        self.history
            .last()
            .ok_or_else(|| training("no epoch was trained"))
    }

    /// The epoch's record: losses and the validation metrics at the threshold of best F1.
    fn validate_epoch(
        &self,
        epoch: usize,
        train_loss: f64,
        t0: Instant,
    ) -> Result<EpochRecord, LabError> {
        let net = self.trainer.network();
        let p = moe_contact::predict(net, &self.validation, self.options.train.batch_size)?;
        let eval = evaluation_of(
            &p,
            (0..self.validation.len()).flat_map(|s| self.validation.labels_of(s)),
            self.trainer.contact_weight(),
        );
        let (threshold, best) = eval.best();
        let half = eval.at(0.5).unwrap_or_default();
        let contact = contact_report(&self.builder, &self.validation_truth, &p, threshold)?;
        Ok(EpochRecord {
            epoch: epoch + 1,
            learning_rate: self.options.train.learning_rate_at(epoch),
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
        })
    }

    /// The checkpoint (so that an interrupted run resumes here), the learning curve, and the
    /// model with its card (so that a stopped run leaves a usable model).
    fn save(&self) -> Result<(), LabError> {
        let checkpoint = self.trainer.checkpoint()?;
        moe_io::write_atomic(&self.options.checkpoint_path(), &checkpoint.bytes)?;
        moe_io::write_json(&self.options.history_path(), &self.history)?;
        let card = self.card()?;
        let weights = ModelWeights::of(self.trainer.network())?.to_bytes()?;
        moe_io::write_model_files(
            &self.options.weights_path(),
            &weights,
            Some(&card.to_json()?),
        )?;
        Ok(())
    }

    /// The model card of the weights as they are now.
    ///
    /// # Errors
    /// [`LabError::Training`] before the first epoch.
    pub fn card(&self) -> Result<ModelCard, LabError> {
        let last = self
            .history
            .last()
            .ok_or_else(|| training("no epoch was trained"))?;
        let o = &self.options;
        let a = o.augmentation.unwrap_or_default();
        let mut card = ModelCard::new(self.arch.clone());
        card.threshold = last.validation_threshold;
        card.hand = Some(self.card_hand.clone());
        card.training = Some(CardTraining {
            command: o.command.clone(),
            config: o.train.clone(),
            contact_weight: self.trainer.contact_weight(),
            init: o.init.as_ref().map(|p| p.display().to_string()),
            input_shape: o.input_shape.name().to_owned(),
            marker_noise_m: a.noise_sd_m,
            marker_dropout: a.drop_probability,
            marker_tip_occlusion: a.distal_occlusion_probability,
            marker_tip_run: a.max_distal_occluded,
            sets_per_second: self.sets_trained as f64 / self.train_seconds.max(1e-9),
            train_seconds: self.train_seconds,
            train_sets: self.train.len(),
            validation_sets: self.validation.len(),
            wall_time_s: self.started.elapsed().as_secs_f64(),
        });
        card.dataset = Some(CardDataset {
            sets: self
                .readers
                .iter()
                .zip(&o.data)
                .map(|(reader, dir)| data_source(reader, dir))
                .collect(),
            train_frames: self.train_frames,
            validation_frames: self.validation_frames,
        });
        card.metrics = Some(CardMetrics {
            epochs: self.history.clone(),
        });
        Ok(card)
    }
}

/// The card's record of one data set, with the command that regenerates it.
fn data_source(reader: &DatasetReader, dir: &Path) -> CardDataSource {
    let card = reader.card();
    CardDataSource {
        dir: dir.display().to_string(),
        seed: card.seed,
        frames: card.totals.frames,
        trajectories: card.totals.trajectories,
        label_rule: label_rule(card),
        // Its generator parameters (recorded below) go in a --params file when they are not
        // the defaults.
        regenerate: format!(
            "moe-touch gen-data --out {} --trajectories {} --seed {} --fingers {}",
            dir.display(),
            card.totals.trajectories,
            card.seed,
            card.layout.finger_num_vertices.len()
        ),
        generator: card.generator.clone(),
    }
}

/// The trainer: resumed from the checkpoint, started from `init`'s weights, or seeded; and the
/// learning curve so far.
fn start_trainer(
    options: &TrainingOptions,
    arch: &DgcnnConfig,
    train: &TrainingSets,
    log: &mut dyn FnMut(&str),
) -> Result<(Trainer, Vec<EpochRecord>), LabError> {
    let config = &options.train;
    let ckpt_path = options.checkpoint_path();
    let history_path = options.history_path();
    if options.resume && ckpt_path.exists() {
        let bytes = moe_io::read_bytes(&ckpt_path)?;
        let trainer =
            Trainer::resume(arch.clone(), config.clone(), train, &Checkpoint { bytes })
                .map_err(|e| training(format!("resuming from {}: {e}", ckpt_path.display())))?;
        let mut history: Vec<EpochRecord> = if history_path.exists() {
            moe_io::read_json(&history_path)?
        } else {
            Vec::new()
        };
        history.truncate(trainer.epochs_done());
        log(&format!(
            "train: resumed after epoch {}",
            trainer.epochs_done()
        ));
        return Ok((trainer, history));
    }
    let trainer = match &options.init {
        Some(path) => {
            let files = moe_io::read_model_files(path)?;
            // Features added after the initial weights' own start with zero weights.
            let weights = ModelWeights::parse(&files.weights)
                .and_then(|w| w.with_input_channels(train.channels()))
                .map_err(|e| training(format!("initial weights {}: {e}", path.display())))?;
            log(&format!(
                "train: starting from the weights of {}",
                path.display()
            ));
            Trainer::from_weights(arch.clone(), config.clone(), train, &weights)?
        }
        None => Trainer::new(arch.clone(), config.clone(), train)?,
    };
    Ok((trainer, Vec::new()))
}

/// The frames of a split of one data set, at most `max`.
fn split_frames(
    reader: &DatasetReader,
    split: Split,
    max: Option<usize>,
) -> Result<Vec<LabelledFrame>, LabError> {
    let mut out = Vec::new();
    for frame in reader.labelled_frames(Some(split), SplitFractions::default()) {
        out.push(frame?);
        if max.is_some_and(|m| out.len() >= m) {
            break;
        }
    }
    Ok(out)
}

/// The training and validation frames of every data set (all of `hand`), with the shapes the
/// network learns from.
fn load_frames(
    options: &TrainingOptions,
    readers: &[DatasetReader],
    hand: &HandModel,
    log: &mut dyn FnMut(&str),
) -> Result<RunFrames, LabError> {
    let augmentation = options.augmentation.as_ref();
    let mut frames = RunFrames {
        train: Vec::new(),
        validation: Vec::new(),
        validation_truth: Vec::new(),
    };
    for (reader, dir) in readers.iter().zip(&options.data) {
        let other = dataset_hand(reader)?;
        let same = other.num_fingers() == hand.num_fingers()
            && (0..hand.num_fingers())
                .all(|i| other.rest_vertices_in_hand(i) == hand.rest_vertices_in_hand(i));
        if !same {
            return Err(training(format!(
                "{}: a data set of another hand than {}'s",
                dir.display(),
                options.data[0].display()
            )));
        }
        let max = options.max_frames;
        let train = split_frames(reader, Split::Train, max)?;
        let validation = split_frames(reader, Split::Validation, max.map(|m| m / 4 + 1))?;
        if train.is_empty() {
            return Err(training(format!("{}: no training frames", dir.display())));
        }
        if validation.is_empty() {
            return Err(training(format!(
                "{}: no validation frames (too few trajectories)",
                dir.display()
            )));
        }
        frames.validation_truth.extend(validation.iter().cloned());
        let (train, validation) = if options.input_shape == InputShape::Physics {
            physics_shapes(reader, hand, &train, &validation, augmentation, log)?
        } else {
            (train, validation)
        };
        frames.train.extend(train);
        frames.validation.extend(validation);
    }
    if matches!(options.input_shape, InputShape::SrArap | InputShape::Both) {
        let t = Instant::now();
        let shape = moe_arap::ShapeConfig::default();
        let mut train = with_estimated_shapes(hand, &frames.train, &shape, augmentation)?;
        let validation = with_estimated_shapes(hand, &frames.validation, &shape, None)?;
        log(&format!(
            "train: SR-ARAP shapes of {} frames from their markers in {:.0} s",
            train.len() + validation.len(),
            t.elapsed().as_secs_f64()
        ));
        if options.input_shape == InputShape::Both {
            train.append(&mut frames.train);
        }
        frames.train = train;
        frames.validation = validation;
    }
    if options.input_shape == InputShape::SrArapDepth {
        let t = Instant::now();
        let shape = moe_arap::ShapeConfig {
            depth: moe_arap::ShapeDepth {
                enabled: true,
                ..moe_arap::ShapeDepth::default()
            },
            ..moe_arap::ShapeConfig::default()
        };
        let camera = RgbdCamera::default();
        let seed = options.train.seed;
        frames.train =
            with_depth_registered_shapes(hand, &frames.train, &shape, augmentation, &camera, seed)?;
        frames.validation =
            with_depth_registered_shapes(hand, &frames.validation, &shape, None, &camera, seed)?;
        log(&format!(
            "train: SR-ARAP shapes registered to rendered depth of {} frames in {:.0} s",
            frames.train.len() + frames.validation.len(),
            t.elapsed().as_secs_f64()
        ));
    }
    Ok(frames)
}

/// The training and validation frames of one data set with the physics estimator's shapes
/// (the training ones from perturbed markers when `augmentation` is given).
fn physics_shapes(
    reader: &DatasetReader,
    hand: &HandModel,
    train: &[LabelledFrame],
    validation: &[LabelledFrame],
    augmentation: Option<&MarkerAugmentation>,
    log: &mut dyn FnMut(&str),
) -> Result<(Vec<LabelledFrame>, Vec<LabelledFrame>), LabError> {
    let params = dataset_params(reader.card())?;
    let frame_secs = params.dt_secs * params.save_every_steps as Real;
    let material = moe_physics::HandMaterial::default();
    let config = moe_physics::PhysicsConfig::default();
    let t = Instant::now();
    let shapes = |frames: &[LabelledFrame], augmentation| {
        crate::physics_eval::with_physics_shapes(
            hand,
            frames,
            frame_secs,
            &material,
            &config,
            augmentation,
        )
    };
    let train = shapes(train, augmentation)?;
    let validation = shapes(validation, None)?;
    log(&format!(
        "train: physics shapes of {} frames from their markers in {:.0} s",
        train.len() + validation.len(),
        t.elapsed().as_secs_f64()
    ));
    Ok((train, validation))
}

/// Every channel normalised by the training frames' statistics — or, fine-tuning, by the
/// normalisation the initial weights were trained with for the channels they were trained on
/// (the features listed first), and the training frames' for any added after them.
fn normalisation(
    spec: &InputSpec,
    init_input: Option<&InputSpec>,
    hand: &HandModel,
    train: &[LabelledFrame],
) -> Result<Normalisation, LabError> {
    let kept = init_input.and_then(|input| {
        spec.features
            .starts_with(&input.features)
            .then_some(input.normalisation.as_ref())
            .flatten()
    });
    Ok(match kept {
        Some(n) if n.mean.len() == spec.channels() => n.clone(),
        kept => {
            let mut fresh = normalisation_of(&FeatureBuilder::new(spec, hand)?, train)?;
            if let Some(n) = kept {
                fresh.mean[..n.mean.len()].copy_from_slice(&n.mean);
                fresh.std[..n.std.len()].copy_from_slice(&n.std);
            }
            fresh
        }
    })
}

/// Per-channel mean and standard deviation of the features of `frames`, accumulated frame by
/// frame (the raw features of a whole data set are not kept).
fn normalisation_of(
    builder: &FeatureBuilder,
    frames: &[LabelledFrame],
) -> Result<Normalisation, LabError> {
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
) -> Result<ContactReport, LabError> {
    let per_frame: usize = builder.point_sets().iter().map(|s| s.1).sum();
    if p.len() != per_frame * frames.len() {
        return Err(training(format!(
            "{} probabilities for {} frames of {per_frame} points",
            p.len(),
            frames.len()
        )));
    }
    let mut metrics = ContactMetrics::default();
    for (frame, values) in frames.iter().zip(p.chunks_exact(per_frame.max(1))) {
        let map = moe_geom::ContactMap {
            fingers: builder.per_finger(values)?,
        };
        metrics.add(&frame.shape, &frame.contact, &map.labels_at(threshold))?;
    }
    Ok(metrics.report())
}

/// The input spec of `init`'s card, checked against the run's: the run may add features after
/// the initial model's own (their weights start at zero), in the same frame and point sets; it
/// may not drop or reorder them, which would feed the initial weights other channels than they
/// were trained on. Weights without a card must take the run's channels as they are.
fn init_input_of(init: Option<&Path>, spec: &InputSpec) -> Result<Option<InputSpec>, LabError> {
    let Some(path) = init else {
        return Ok(None);
    };
    let files = moe_io::read_model_files(path)?;
    let Some(text) = files.card else {
        let weights = ModelWeights::parse(&files.weights)
            .map_err(|e| training(format!("initial weights {}: {e}", path.display())))?;
        let channels = weights.get("edge1.theta").map(|(shape, _)| shape[1]);
        if channels != Some(spec.channels()) {
            return Err(training(format!(
                "--init {}: weights without a card take {} input channels, the run's features \
                 ({}) {}; give the card beside the weights",
                path.display(),
                channels.map_or("no".to_string(), |c| c.to_string()),
                spec.describe(),
                spec.channels()
            )));
        }
        return Ok(None);
    };
    let input = ModelCard::from_json(&text)
        .map_err(|e| training(format!("model card {}: {e}", files.card_path.display())))?
        .architecture
        .input;
    if input.features != spec.features
        && (!spec.features.starts_with(&input.features)
            || input.frame != spec.frame
            || input.point_set != spec.point_set)
    {
        return Err(training(format!(
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
        )));
    }
    Ok(Some(input))
}
