//! `moe-touch run`: the whole pipeline over every frame of an episode; a result MCAP for
//! Foxglove (input image, detected markers, estimated meshes coloured by contact probability,
//! contact points in the world, and the ground truth beside them) and a report.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_arap::ShapeConfig;
use moe_touch::Pipeline;
use moe_touch::filter::{ContactSmoother, KalmanConfig, KeypointFilter};
use moe_touch::perception::score::check_hand;
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::pipeline::load_contact_model;
use moe_touch::run::{RunReport, run_episode, run_info};

/// Arguments of `moe-touch run`.
#[derive(Debug, Args)]
pub(crate) struct RunArgs {
    /// Episode to read (MCAP, as `moe-touch sim --out EP.mcap` records it). An episode cut
    /// short runs up to its last complete frame, and the cut is reported.
    #[arg(long, value_name = "EP.mcap")]
    episode: PathBuf,
    /// Trained contact model (`NAME.safetensors` with its card `NAME.json`).
    #[arg(
        long,
        value_name = "M.safetensors",
        default_value = "models/contact-two-finger.safetensors"
    )]
    model: PathBuf,
    /// Result file (MCAP; open it in Foxglove with fixtures/foxglove/run_layout.json).
    #[arg(long, value_name = "RESULT.mcap")]
    out: PathBuf,
    /// Also write the report (per-frame and overall figures) as JSON here.
    #[arg(long, value_name = "R.json")]
    report: Option<PathBuf>,
    /// The hand: a preset (two-finger, three-finger, five-finger) or a hand config file; it
    /// must be the episode's hand and the model's.
    #[arg(long, value_name = "PRESET|CONFIG", default_value = "two-finger")]
    hand: String,
    /// Marker-detector parameters (TOML or JSON `DetectorConfig`).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// SR-ARAP iterations per frame.
    #[arg(long, default_value_t = ShapeConfig::default().iterations)]
    iterations: usize,
    /// Start each frame's shape from the previous one (tracking; the paper starts from rest).
    #[arg(long)]
    warm_start: bool,
    /// Filter the keypoints over time with a constant-velocity Kalman filter per marker
    /// (default noise levels of `KalmanConfig`).
    #[arg(long)]
    kalman: bool,
    /// Smooth the contact map over time with this weight on the new frame, in (0, 1].
    #[arg(long, value_name = "ALPHA")]
    smooth_contact: Option<f64>,
    /// Print the report (without the per-frame list) as one JSON object.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: RunArgs) -> Result<()> {
    let config: DetectorConfig = match &args.config {
        Some(path) => moe_io::read_config(path)?,
        None => DetectorConfig::default(),
    };
    let bytes = std::fs::read(&args.episode)
        .with_context(|| format!("reading {}", args.episode.display()))?;
    let (episode, cut) = moe_io::parse_episode_prefix(&args.episode, &bytes);
    let Some(episode) = episode else {
        return Err(match cut {
            Some(err) => err.into(),
            None => anyhow::anyhow!("{}: holds no episode", args.episode.display()),
        });
    };
    let truncated = cut.map(|err| {
        eprintln!(
            "warning: {err}; running the {} complete frames before the cut",
            episode.frames.len()
        );
        err.to_string()
    });
    let hand = super::load_hand(&args.hand)?;
    check_hand(&hand, &episode.info)
        .with_context(|| format!("--hand {} for {}", args.hand, args.episode.display()))?;
    let model = load_contact_model(&args.model, &hand)
        .with_context(|| format!("model {} on hand '{}'", args.model.display(), args.hand))?;
    let threshold = model.threshold();
    let detector = MarkerDetector::for_episode(&episode.info, &hand, config)
        .with_context(|| format!("the camera of {}", args.episode.display()))?;
    let options = ShapeConfig {
        iterations: args.iterations,
        warm_start: args.warm_start,
        ..ShapeConfig::default()
    };
    let shape = moe_touch::contact_eval::study_shape_estimator(&hand, &options)?;
    let mut pipeline = Pipeline::new(hand, detector, shape, model, threshold)?;
    if args.kalman {
        pipeline = pipeline.with_keypoint_filter(KeypointFilter::new(KalmanConfig::default())?);
    }
    if let Some(alpha) = args.smooth_contact {
        pipeline = pipeline.with_contact_smoothing(ContactSmoother::new(alpha)?);
    }
    let (frames, report) = run_episode(&mut pipeline, &episode.info, &episode.frames, truncated)
        .with_context(|| format!("episode {}", args.episode.display()))?;
    let model_name = args
        .model
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let info = run_info(&episode.info, &model_name, threshold);
    // The report is built before anything is written; the result file is written whole.
    let report_text = serde_json::to_string_pretty(&report)?;
    moe_io::write_run(&args.out, &info, &frames)?;
    if let Some(path) = &args.report {
        moe_io::write_atomic(path, report_text.as_bytes())?;
    }
    if args.json {
        let mut value = serde_json::to_value(&report)?;
        if let Some(obj) = value.as_object_mut() {
            obj.remove("per_frame");
            obj.insert("out".into(), args.out.display().to_string().into());
        }
        return super::print_json(&value);
    }
    print_summary(&report, &args);
    Ok(())
}

fn print_summary(r: &RunReport, args: &RunArgs) {
    super::outln!(
        "{} frames{}: {:.1} frames/s (per frame: markers {:.2} ms, shape {:.2} ms, contact {:.2} ms, total {:.2} ms median); wrote {}",
        r.frames,
        if r.truncated.is_some() {
            " (episode cut short)"
        } else {
            ""
        },
        r.frames_per_second,
        r.markers_ms.median_ms,
        r.shape_ms.median_ms,
        r.contact_ms.median_ms,
        r.total_ms.median_ms,
        args.out.display()
    );
    if let (Some(m), Some(bcd), Some(c)) = (&r.markers, r.shape_bcd_mm, &r.contact) {
        super::outln!(
            "against the ground truth: markers {:.1} % of {} visible found (error {:.2} mm mean); shape BCD {:.3} mm; contact BCD {:.1} mm, UCD {:.1} mm, F1 {:.3}, {} of {} contact frames missed, {} false alarms",
            100.0 * m.detection_rate,
            m.visible,
            m.mean_error_mm,
            bcd,
            c.bcd_mm,
            c.ucd_mm,
            c.f1,
            c.misses,
            c.contact_frames,
            c.false_alarms
        );
    }
}
