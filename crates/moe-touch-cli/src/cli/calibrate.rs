//! `moe-touch calibrate`: the hand's material (Young's modulus and damping) fitted to
//! contact-free frames of a recorded episode or of a data set, for the physics estimator
//! (`moe-touch contact --method physics --material`, `moe-touch run --contact physics
//! --material`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use moe_geom::{HandModel, Real};
use moe_io::DatasetReader;
use moe_lab::calibration_streams::{
    ContactFreeStreams, dataset_contact_free_streams, episode_contact_free_streams,
    episode_has_ground_truth, episode_has_images, hand_difference,
};
use moe_lab::markers::check_hand;
use moe_physics::{CalibrationOptions, HandMaterial, calibrate};
use moe_touch::perception::MarkerDetector;
use serde::Serialize;

/// Where the markers of an episode come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
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

/// The figures of a material that calibration fits.
#[derive(Debug, Clone, Copy, Serialize)]
struct Fitted {
    /// Young's modulus, pascals.
    youngs_modulus_pa: Real,
    /// Stiffness-proportional (Rayleigh) damping coefficient, seconds.
    rayleigh_stiffness: Real,
}

impl Fitted {
    fn of(m: &HandMaterial) -> Self {
        Self {
            youngs_modulus_pa: m.material.youngs_modulus_pa,
            rayleigh_stiffness: m.material.rayleigh_stiffness,
        }
    }
}

/// The report, printed and with `--json`.
#[derive(Debug, Serialize)]
struct CalibrateRecord {
    /// The episode or the data set.
    source: String,
    hand: String,
    /// `detected` or `ground truth`.
    markers: &'static str,
    /// How contact frames were found: from the ground truth, or not at all (assumed none).
    contact: &'static str,
    /// Frames read.
    frames_read: usize,
    /// Frames left out because something touched the hand.
    frames_with_contact: usize,
    /// Trajectories of a data set used.
    #[serde(skip_serializing_if = "Option::is_none")]
    trajectories: Option<usize>,
    /// Contact-free streams and frames fitted.
    streams: usize,
    frames: usize,
    initial_material: String,
    initial: Fitted,
    fitted: Fitted,
    fit_damping: bool,
    /// RMS marker coordinate residual with the initial and with the fitted material, metres.
    rms_initial_m: Real,
    rms_fitted_m: Real,
    /// Relative change of E that raises the residual by 1 %: how well the frames pin E down.
    youngs_modulus_resolution: Real,
    evaluations: usize,
    out: String,
    wall_secs: Real,
}

/// Contact-free streams and what was read to make them.
struct Streams {
    source: String,
    hand: HandModel,
    hand_name: String,
    markers: &'static str,
    contact: &'static str,
    chosen: ContactFreeStreams,
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
    let streams = match (&args.episode, &args.data) {
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
    let report = calibrate(
        &streams.hand,
        &streams.chosen.streams,
        &initial,
        &config,
        &options,
    )
    .with_context(|| format!("calibrating from {}", streams.source))?;
    let record = CalibrateRecord {
        source: streams.source,
        hand: streams.hand_name,
        markers: streams.markers,
        contact: streams.contact,
        frames_read: streams.chosen.frames_read,
        frames_with_contact: streams.chosen.frames_with_contact,
        trajectories: streams.chosen.trajectories,
        streams: report.streams,
        frames: report.frames,
        initial_material: initial_name,
        initial: Fitted::of(&initial),
        fitted: Fitted::of(&report.material),
        fit_damping: options.fit_damping,
        rms_initial_m: report.rms_initial_m,
        rms_fitted_m: report.rms_fitted_m,
        youngs_modulus_resolution: report.youngs_modulus_resolution,
        evaluations: report.evaluations,
        out: args.out.display().to_string(),
        wall_secs: t0.elapsed().as_secs_f64(),
    };
    if json_out {
        moe_io::write_json(&args.out, &report.material)?;
    } else {
        moe_io::write_toml(&args.out, &report.material)?;
    }
    if args.json {
        return super::print_json(&record);
    }
    print_report(&record);
    Ok(())
}

fn print_report(r: &CalibrateRecord) {
    super::outln!(
        "calibrated hand '{}' from {}: {} contact-free frames in {} streams ({} markers; {} of {} \
         frames left out for contact, {})",
        r.hand,
        r.source,
        r.frames,
        r.streams,
        r.markers,
        r.frames_with_contact,
        r.frames_read,
        r.contact
    );
    super::outln!(
        "  Young's modulus E        {:.0} Pa -> {:.0} Pa (a {:.1} % change of E raises the \
         residual by 1 %)",
        r.initial.youngs_modulus_pa,
        r.fitted.youngs_modulus_pa,
        100.0 * r.youngs_modulus_resolution
    );
    super::outln!(
        "  damping (Rayleigh beta)  {:.4} s -> {:.4} s{}",
        r.initial.rayleigh_stiffness,
        r.fitted.rayleigh_stiffness,
        if r.fit_damping { "" } else { " (kept)" }
    );
    super::outln!(
        "  RMS marker residual      {:.3} mm -> {:.3} mm ({} evaluations)",
        1e3 * r.rms_initial_m,
        1e3 * r.rms_fitted_m,
        r.evaluations
    );
    super::outln!("wrote {}", r.out);
}

/// The contact-free streams of an episode: every frame's markers (detected or true), pulls,
/// pose and time; frames with true contact left out, each run of contact-free frames between
/// them one stream.
fn episode_streams(args: &CalibrateArgs, path: &Path) -> Result<Streams> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let (episode, cut) = moe_record::parse_episode_prefix(path, &bytes);
    let Some(episode) = episode else {
        return Err(match cut {
            Some(err) => err.into(),
            None => anyhow::anyhow!("{}: holds no episode", path.display()),
        });
    };
    if let Some(err) = cut {
        eprintln!(
            "warning: {err}; calibrating from the {} complete frames before the cut",
            episode.frames.len()
        );
    }
    let hand_name = args.hand.clone().unwrap_or_else(|| "two-finger".to_owned());
    let hand = super::load_hand(&hand_name)?;
    check_hand(&hand, &episode.info)
        .with_context(|| format!("--hand {hand_name} for {}", path.display()))?;
    let truth = episode_has_ground_truth(&episode);
    let images = episode_has_images(&episode);
    let detected = match args.markers {
        MarkerSource::Auto => images || !truth,
        MarkerSource::Detected => true,
        MarkerSource::Truth => {
            if !truth {
                bail!(
                    "--markers truth: {} has no ground-truth markers (a real recording); use \
                     the detected ones",
                    path.display()
                );
            }
            false
        }
    };
    if !detected && args.config.is_some() {
        bail!("--config is for detected markers (--markers detected)");
    }
    let mut detector = if detected {
        let config = super::load_detector_config(args.config.as_deref())?;
        Some(
            MarkerDetector::for_episode(&episode.info, &hand, config)
                .with_context(|| format!("the camera of {}", path.display()))?,
        )
    } else {
        None
    };
    let chosen = episode_contact_free_streams(&episode, detector.as_mut())
        .with_context(|| path.display().to_string())?;
    Ok(Streams {
        source: path.display().to_string(),
        hand,
        hand_name,
        markers: if detected { "detected" } else { "ground truth" },
        contact: if truth {
            "from the ground truth"
        } else {
            "no ground truth: every frame taken as contact-free"
        },
        chosen,
    })
}

/// The contact-free prefix of each trajectory of a data set, with its true markers.
fn dataset_streams(args: &CalibrateArgs, dir: &Path) -> Result<Streams> {
    let reader = DatasetReader::open(dir)?;
    let card = reader.card();
    let params =
        moe_lab::datagen::dataset_params(card).with_context(|| dir.display().to_string())?;
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
    let chosen = dataset_contact_free_streams(&reader, args.max_trajectories)
        .with_context(|| dir.display().to_string())?;
    Ok(Streams {
        source: dir.display().to_string(),
        hand,
        hand_name,
        markers: "ground truth",
        contact: "from the data set's labels and contact forces (each trajectory's frames \
                  before its first contact)",
        chosen,
    })
}
