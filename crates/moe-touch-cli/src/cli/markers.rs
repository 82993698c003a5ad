//! `moe-touch markers`: detect and track the markers of every frame of an episode; write the
//! keypoints (one JSON line per frame) and, for an episode with ground truth, report detection
//! and its effect on shape estimation.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_lab::marker_job::track_markers;
use moe_lab::markers::check_hand;
use moe_lab::output_files::OutputFiles;
use moe_touch::perception::MarkerDetector;

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

pub(crate) fn run(args: MarkersArgs) -> Result<()> {
    let config = super::load_detector_config(args.config.as_deref(), "--config")?;
    let episode = moe_record::read_episode(&args.episode)?;
    let hand = super::load_hand(&args.hand)?;
    check_hand(&hand, &episode.info)
        .with_context(|| format!("--hand {} for {}", args.hand, args.episode.display()))?;
    let mut detector = MarkerDetector::for_episode(&episode.info, &hand, config)
        .with_context(|| format!("the camera of {}", args.episode.display()))?;
    let tracking = track_markers(&hand, &episode, &mut detector, &args.episode, &args.out)
        .with_context(|| format!("episode {}", args.episode.display()))?;
    // Everything is built in memory before anything is written.
    let overlays = match &args.overlay {
        Some(_) => tracking.overlays(&detector, &episode)?,
        None => OutputFiles::new(),
    };
    moe_io::write_atomic(&args.out, tracking.keypoints_lines.as_bytes())?;
    if let Some(dir) = &args.overlay {
        overlays.write(dir)?;
    }
    if args.json {
        return super::print_json(&tracking.record);
    }
    super::outln!("{}", tracking.record.summary());
    Ok(())
}
