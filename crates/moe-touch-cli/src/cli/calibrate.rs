//! `moe-touch calibrate`: the hand's material (Young's modulus and damping) fitted to
//! contact-free frames of a recorded episode or of a data set, for the physics estimator
//! (`moe-touch contact --method physics --material`, `moe-touch run --contact physics
//! --material`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use moe_geom::HandModel;
use moe_io::DatasetReader;
use moe_lab::calibration_streams::{
    CalibrationRecord, CalibrationSource, dataset_calibration_source, episode_calibration_source,
    hand_difference,
};
use moe_physics::{CalibrationOptions, calibrate};

/// Where the markers of an episode come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum MarkerSource {
    /// Detected in the camera images when the episode has them, else the ground truth.
    Auto,
    /// Detected in the camera images by the perception stage (as `moe-touch run` does).
    Detected,
    /// The episode's ground-truth markers (a simulated episode).
    Truth,
}

/// Arguments of `moe-touch calibrate`.
#[derive(Debug, Args)]
pub(crate) struct CalibrateArgs {
    /// A recorded episode (MCAP) of the hand moving without touching anything: its frames'
    /// markers, tendon pulls, wrist poses and times. Frames the episode's ground truth marks in
    /// contact are left out (and split the episode into streams); an episode without ground
    /// truth (a real recording) is taken as contact-free throughout. Record it as
    /// fixtures/scenes/calibration.toml does: the hand held in a few orientations (fingers up
    /// and sideways, so that their weight bends them) while the tendons move.
    #[arg(long, value_name = "EP.mcap")]
    episode: Option<PathBuf>,
    /// A data set (as `moe-touch gen-data` writes it): each trajectory's contact-free
    /// frames before its first contact, with their true markers; frame times from the card's
    /// simulator settings.
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
    /// With --data: use at most this many trajectories (the first ones).
    #[arg(long, value_name = "N")]
    max_trajectories: Option<u64>,
    /// The hand: a preset (two-finger, three-finger, five-finger) or a hand config file; it
    /// must be the episode's or the data set's [default: two-finger for an episode, the data
    /// set's own hand for --data].
    #[arg(long, value_name = "PRESET|CONFIG")]
    hand: Option<String>,
    /// With --episode: where the markers come from (`auto`: detected in the camera images when
    /// the episode has them, else its ground truth).
    #[arg(long, value_enum, default_value = "auto")]
    markers: MarkerSource,
    /// With --episode: marker-detector parameters (TOML or JSON `DetectorConfig`).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// The material to start from (TOML or JSON; default: the nominal silicone). Only Young's
    /// modulus and the damping are fitted; the rest is kept.
    #[arg(long, value_name = "M.toml")]
    material: Option<PathBuf>,
    /// The physics estimator's settings (TOML or JSON `moe_physics::PhysicsConfig`): the
    /// model's mesh and the simulation of the free finger, as the estimator will use them.
    #[arg(long, value_name = "C.toml")]
    physics_config: Option<PathBuf>,
    /// Most evaluations of the objective (each simulates every contact-free stream).
    #[arg(long, value_name = "N", default_value_t = CalibrationOptions::default().max_evaluations)]
    max_evaluations: usize,
    /// Keep the initial damping; fit Young's modulus only.
    #[arg(long)]
    keep_damping: bool,
    /// The fitted material (TOML, or JSON for a `.json` name), written atomically; read it with
    /// `--material`.
    #[arg(long, value_name = "HAND_MATERIAL.toml")]
    out: PathBuf,
    /// Print the report as one JSON object.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: CalibrateArgs) -> Result<()> {
    let t0 = Instant::now();
    let ext = args
        .out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let json_out = match ext.as_deref() {
        Some("toml") => false,
        Some("json") => true,
        _ => bail!(
            "--out {}: name the material file .toml or .json (what --material reads)",
            args.out.display()
        ),
    };
    let (initial, initial_name) = super::load_material(args.material.as_deref())?;
    let (config, _) = super::load_physics_config(args.physics_config.as_deref())?;
    if args.max_evaluations == 0 {
        bail!("--max-evaluations must be at least 1");
    }
    let (streams, hand, hand_name) = match (&args.episode, &args.data) {
        (Some(episode), None) => {
            if args.max_trajectories.is_some() {
                bail!("--max-trajectories is for --data");
            }
            episode_streams(&args, episode)?
        }
        (None, Some(dir)) => {
            if args.markers != MarkerSource::Auto || args.config.is_some() {
                bail!(
                    "--markers and --config are for --episode (a data set's markers are its \
                     true marker vertices)"
                );
            }
            dataset_streams(&args, dir)?
        }
        _ => bail!("give either --episode EP.mcap or --data DIR"),
    };
    let frames = streams.chosen.frames();
    if frames == 0 {
        bail!(
            "{}: no contact-free frames to calibrate from ({} frames read, {} with contact)",
            streams.source,
            streams.chosen.frames_read,
            streams.chosen.frames_with_contact
        );
    }
    eprintln!(
        "calibrate: {} contact-free frames in {} streams from {} ({} markers)",
        frames,
        streams.chosen.streams.len(),
        streams.source,
        streams.markers
    );
    let options = CalibrationOptions {
        fit_damping: !args.keep_damping,
        max_evaluations: args.max_evaluations,
        ..CalibrationOptions::default()
    };
    let report = calibrate(&hand, &streams.chosen.streams, &initial, &config, &options)
        .with_context(|| format!("calibrating from {}", streams.source))?;
    if json_out {
        moe_io::write_json(&args.out, &report.material)?;
    } else {
        moe_io::write_toml(&args.out, &report.material)?;
    }
    let record = CalibrationRecord::new(
        streams,
        hand_name,
        (&initial, initial_name),
        &report,
        options.fit_damping,
        &args.out,
        t0.elapsed().as_secs_f64(),
    );
    if args.json {
        return super::print_json(&record);
    }
    super::print_text(&record.table());
    Ok(())
}

/// An episode's contact-free streams, its hand and the hand's name.
fn episode_streams(
    args: &CalibrateArgs,
    path: &Path,
) -> Result<(CalibrationSource, HandModel, String)> {
    let (episode, cut) = moe_record::read_episode_prefix(path)?;
    if let Some(err) = cut {
        eprintln!(
            "warning: {err}; calibrating from the {} complete frames before the cut",
            episode.frames.len()
        );
    }
    let hand_name = args.hand.clone().unwrap_or_else(|| "two-finger".to_owned());
    let hand = super::load_hand(&hand_name)?;
    moe_lab::markers::check_hand(&hand, &episode.info)
        .with_context(|| format!("--hand {hand_name} for {}", path.display()))?;
    let markers = match args.markers {
        MarkerSource::Auto => moe_lab::calibration_streams::MarkerSource::Auto,
        MarkerSource::Detected => moe_lab::calibration_streams::MarkerSource::Detected,
        MarkerSource::Truth => moe_lab::calibration_streams::MarkerSource::Truth,
    };
    let config = match &args.config {
        Some(path) => Some(super::load_detector_config(Some(path), "--config")?),
        None => None,
    };
    let source = path.display().to_string();
    let streams =
        episode_calibration_source(&source, &episode, &hand, markers, config).map_err(|e| {
            match args.markers {
                MarkerSource::Truth => anyhow::anyhow!("--markers truth: {e}"),
                _ => anyhow::Error::from(e),
            }
        })?;
    Ok((streams, hand, hand_name))
}

/// The contact-free prefix of each trajectory of a data set, its hand and the hand's name.
fn dataset_streams(
    args: &CalibrateArgs,
    dir: &Path,
) -> Result<(CalibrationSource, HandModel, String)> {
    let reader = DatasetReader::open(dir)?;
    let params = moe_lab::datagen::dataset_params(reader.card())
        .with_context(|| dir.display().to_string())?;
    let data_hand =
        moe_lab::datagen::dataset_hand(&reader).with_context(|| dir.display().to_string())?;
    let (hand, hand_name) = match &args.hand {
        Some(spec) => {
            let hand = super::load_hand(spec)?;
            if let Some(diff) = hand_difference(&hand, &data_hand) {
                bail!(
                    "--hand {spec}: {} is a data set of another hand ({diff}; the data set's is \
                     the {} preset)",
                    dir.display(),
                    params.preset
                );
            }
            (hand, spec.clone())
        }
        None => (data_hand, params.preset.to_string()),
    };
    let streams =
        dataset_calibration_source(&dir.display().to_string(), &reader, args.max_trajectories)?;
    Ok((streams, hand, hand_name))
}
