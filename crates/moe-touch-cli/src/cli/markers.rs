//! `moe-touch markers`: detect and track the markers of every frame of an episode; write the
//! keypoints (one JSON line per frame) and, for an episode with ground truth, report detection
//! and its effect on shape estimation.

use std::io::Cursor;
use std::path::PathBuf;

use crate::overlay::draw_detection;
use anyhow::{Context, Result};
use clap::Args;
use moe_arap::ShapeConfig;
use moe_geom::Point3;
use moe_lab::markers::{EpisodeMarkerReport, check_hand, evaluate_episode};
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use serde::Serialize;

/// Arguments of `moe-touch markers`.
#[derive(Debug, Args)]
pub(crate) struct MarkersArgs {
    /// Episode to read (MCAP, as `moe-touch sim --out EP.mcap` writes it).
    #[arg(long, value_name = "EP.mcap")]
    episode: PathBuf,
    /// Keypoints out: one JSON object per line and frame, {"time_ns": t, "fingers": [[[x, y, z]
    /// or null, ...], ...]} in the hand frame (metres) — each line is a `moe-touch shape
    /// --keypoints` file.
    #[arg(long, value_name = "KP.jsonl")]
    out: PathBuf,
    /// The hand whose markers to look for: a preset (two-finger, three-finger, five-finger) or
    /// a hand config file; it must be the episode's hand.
    #[arg(long, value_name = "PRESET|CONFIG", default_value = "two-finger")]
    hand: String,
    /// Detector parameters (TOML or JSON; fields of `DetectorConfig`, the rest default).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Also write every frame's colour image with the detected markers ringed and labelled
    /// `finger.marker` (and rejected clusters crossed) as DIR/frame_<k>.png.
    #[arg(long, value_name = "DIR")]
    overlay: Option<PathBuf>,
    /// Print the report as one JSON object.
    #[arg(long)]
    json: bool,
}

/// One line of the keypoints file.
#[derive(Debug, Serialize)]
struct KeypointsLine<'a> {
    time_ns: u64,
    fingers: &'a [Vec<Option<Point3>>],
}

/// The `--json` report.
#[derive(Debug, Serialize)]
struct MarkersRecord {
    episode: String,
    out: String,
    frames: usize,
    markers_per_frame: usize,
    found_per_frame: Vec<usize>,
    tracking_lost_frames: Vec<usize>,
    config: DetectorConfig,
    ground_truth: Option<EpisodeMarkerReport>,
}

pub(crate) fn run(args: MarkersArgs) -> Result<()> {
    let config = super::load_detector_config(args.config.as_deref())?;
    let episode = moe_record::read_episode(&args.episode)?;
    let hand = super::load_hand(&args.hand)?;
    check_hand(&hand, &episode.info)
        .with_context(|| format!("--hand {} for {}", args.hand, args.episode.display()))?;
    let mut detector = MarkerDetector::for_episode(&episode.info, &hand, config)
        .with_context(|| format!("the camera of {}", args.episode.display()))?;
    let (detections, report) = evaluate_episode(
        &hand,
        &episode.info,
        &episode.frames,
        &mut detector,
        &ShapeConfig::default(),
    )
    .with_context(|| format!("episode {}", args.episode.display()))?;

    // Everything is built in memory before anything is written.
    let mut lines = String::new();
    for (frame, det) in episode.frames.iter().zip(&detections) {
        lines.push_str(&serde_json::to_string(&KeypointsLine {
            time_ns: frame.time_ns,
            fingers: &det.keypoints.fingers,
        })?);
        lines.push('\n');
    }
    let overlays: Vec<Vec<u8>> = match &args.overlay {
        Some(_) => episode
            .frames
            .iter()
            .zip(&detections)
            .map(|(frame, det)| -> Result<Vec<u8>> {
                let img = draw_detection(&detector, &frame.color_rgb8, det)?;
                let mut png = Vec::new();
                img.write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)
                    .context("encoding an overlay PNG")?;
                Ok(png)
            })
            .collect::<Result<_>>()?,
        None => Vec::new(),
    };
    moe_io::write_atomic(&args.out, lines.as_bytes())?;
    if let Some(dir) = &args.overlay {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating overlay directory {}", dir.display()))?;
        for (k, png) in overlays.iter().enumerate() {
            moe_io::write_atomic(&dir.join(format!("frame_{k:04}.png")), png)?;
        }
    }

    let record = MarkersRecord {
        episode: args.episode.display().to_string(),
        out: args.out.display().to_string(),
        frames: detections.len(),
        markers_per_frame: hand
            .fingers()
            .iter()
            .map(|f| f.model.marker_vertices().len())
            .sum(),
        found_per_frame: detections.iter().map(|d| d.diagnostics.found).collect(),
        tracking_lost_frames: detections
            .iter()
            .enumerate()
            .filter(|(_, d)| d.diagnostics.tracking_lost)
            .map(|(k, _)| k)
            .collect(),
        config,
        ground_truth: report,
    };
    if args.json {
        return super::print_json(&record);
    }
    let found: usize = record.found_per_frame.iter().sum();
    super::outln!(
        "{} frames, {} of {} markers found per frame on average, wrote {}",
        record.frames,
        found as f64 / record.frames.max(1) as f64,
        record.markers_per_frame,
        record.out
    );
    if let Some(r) = &record.ground_truth {
        let m = &r.markers;
        super::outln!(
            "against the ground truth: {:.1} % of {} visible markers detected, error mean {:.2} / p95 {:.2} / max {:.2} mm, {} false detections, {} identity swaps",
            100.0 * m.detection_rate,
            m.visible,
            m.mean_error_mm,
            m.p95_error_mm,
            m.max_error_mm,
            m.false_detections,
            m.identity_swaps
        );
        super::outln!(
            "SR-ARAP shape BCD {:.3} mm from the detected keypoints, {:.3} mm from every true marker; detection {:.2} ms per frame",
            r.shape_bcd_detected_mm,
            r.shape_bcd_truth_mm,
            r.detect_ms
        );
    }
    Ok(())
}
