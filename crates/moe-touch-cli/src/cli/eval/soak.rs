//! `moe-touch eval soak`: the pipeline on a long stream — an episode looped with advancing time
//! stamps, gaps beyond the memory horizon, resets and refused frames mixed in — reported window
//! by window (frame times, failures, restarts, resident memory). The study is
//! `moe_lab::soak::soak`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::HandEstimator;
use moe_lab::markers::check_hand;
use moe_lab::soak::{SoakOptions, SoakReport, soak};
use moe_touch::Pipeline;
use moe_touch::perception::MarkerDetector;
use moe_touch::pipeline::load_contact_model;

use crate::cli::ContactMethod;
use crate::cli::run::{DEFAULT_MODEL, EstimatorArgs};

/// Arguments of `moe-touch eval soak`.
#[derive(Debug, Args)]
pub(crate) struct SoakEvalArgs {
    /// The episode to loop (MCAP or a ROS 2 recording, as `run` reads it).
    #[arg(long, value_name = "EP.mcap|BAG")]
    episode: PathBuf,
    /// Frames to run.
    #[arg(long, default_value_t = SoakOptions::default().frames)]
    frames: usize,
    /// Frames per reported window.
    #[arg(long, default_value_t = SoakOptions::default().window)]
    window: usize,
    /// A gap beyond the memory horizon every this many frames.
    #[arg(long, default_value_t = SoakOptions::default().gap_every)]
    gap_every: usize,
    /// `reset()` every this many frames.
    #[arg(long, default_value_t = SoakOptions::default().reset_every)]
    reset_every: usize,
    /// A frame whose time repeats the previous one's (refused) every this many frames.
    #[arg(long, default_value_t = SoakOptions::default().refuse_every)]
    refuse_every: usize,
    #[command(flatten)]
    estimator: EstimatorArgs,
    /// The hand: a preset or a hand config file (the episode's).
    #[arg(long, value_name = "PRESET|CONFIG", default_value = "two-finger")]
    hand: String,
    /// Print the report as one JSON object.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: &SoakEvalArgs) -> Result<()> {
    args.estimator.check(&[], &[])?;
    let options = SoakOptions {
        frames: args.frames,
        window: args.window,
        gap_every: args.gap_every,
        reset_every: args.reset_every,
        refuse_every: args.refuse_every,
        ..SoakOptions::default()
    };
    options.validate()?;
    let hand = crate::cli::load_hand(&args.hand)?;
    let (episode, cut) = moe_record::ros2::read_recording(&args.episode, None, &hand)?;
    if let Some(err) = cut {
        eprintln!(
            "warning: {err}; looping the {} complete frames before the cut",
            episode.frames.len()
        );
    }
    check_hand(&hand, &episode.info)
        .with_context(|| format!("--hand {} for {}", args.hand, args.episode.display()))?;
    let detector = MarkerDetector::for_episode(&episode.info, &hand, Default::default())
        .with_context(|| format!("the camera of {}", args.episode.display()))?;
    let report = match args.estimator.contact {
        ContactMethod::Physics => {
            let (mut pipeline, _) = args.estimator.physics_pipeline(hand, detector)?;
            looped(&mut pipeline, &episode, &options)?
        }
        ContactMethod::Dgcnn => {
            let path = args
                .estimator
                .model
                .clone()
                .unwrap_or_else(|| PathBuf::from(DEFAULT_MODEL));
            let model = load_contact_model(&path, &hand)
                .with_context(|| format!("model {}", path.display()))?;
            let mut pipeline =
                Pipeline::paper(hand, detector, model, moe_arap::ShapeConfig::default())?;
            looped(&mut pipeline, &episode, &options)?
        }
    };
    if args.json {
        crate::cli::print_json(&report)
    } else {
        crate::cli::print_text(&report.summary());
        Ok(())
    }
}

fn looped<E: HandEstimator>(
    pipeline: &mut Pipeline<E>,
    episode: &moe_record::Episode,
    options: &SoakOptions,
) -> Result<SoakReport> {
    Ok(soak(pipeline, &episode.frames, options, &mut |k, n| {
        eprintln!("eval soak: {k} of {n} frames");
    })?)
}
