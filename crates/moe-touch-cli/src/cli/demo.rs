//! `moe-touch demo`: the whole pipeline on the committed example episode with the shipped
//! model, no arguments needed — a short table, the result MCAP, the meshes of the frame with
//! the most contact, and a picture. The episode, model and settings are built into
//! `moe_lab::demo`, which runs it.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_arap::ShapeConfig;
use moe_geom::{HandEstimator, HandModel};
use moe_lab::demo::{EPISODE_NAME, MODEL_NAME, OCCLUDING_SETTINGS_NAME, run_demo};
use moe_lab::draw::png_bytes;
use moe_lab::markers::check_hand;
use moe_lab::run::RunDetails;
use moe_touch::Pipeline;
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::pipeline::load_contact_model;

use super::ContactMethod;

/// Arguments of `moe-touch demo`.
#[derive(Debug, Args)]
pub(crate) struct DemoArgs {
    /// Output directory: result.mcap, report.json, the meshes of the frame with the most
    /// contact (PLY coloured by contact probability, estimate and truth) and figure.png.
    #[arg(long, value_name = "DIR", default_value = "out/demo")]
    out: PathBuf,
    /// Episode (default: the committed example, plate pressing the tip of finger 0).
    #[arg(long, value_name = "EP.mcap")]
    episode: Option<PathBuf>,
    #[command(flatten)]
    estimator: super::run::EstimatorArgs,
}

pub(crate) fn run(args: DemoArgs) -> Result<()> {
    args.estimator.check(&[], &[])?;
    let episode = match &args.episode {
        Some(path) => moe_record::read_episode(path)?,
        None => moe_lab::demo::episode()?,
    };
    let episode_name = args
        .episode
        .as_ref()
        .map_or_else(|| EPISODE_NAME.to_owned(), |p| p.display().to_string());
    let hand = moe_lab::demo::hand()?;
    check_hand(&hand, &episode.info)
        .with_context(|| format!("the demo's two-finger hand for {episode_name}"))?;
    let detector = MarkerDetector::for_episode(&episode.info, &hand, DetectorConfig::default())?;
    match args.estimator.contact {
        ContactMethod::Dgcnn => {
            let (model, model_name) = match &args.estimator.model {
                Some(path) => (
                    load_contact_model(path, &hand)
                        .with_context(|| format!("model {}", path.display()))?,
                    path.file_name()
                        .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
                ),
                None => (
                    moe_lab::demo::model(&hand)
                        .with_context(|| format!("model {MODEL_NAME} (built in)"))?,
                    MODEL_NAME.to_owned(),
                ),
            };
            let pipeline = Pipeline::paper(hand.clone(), detector, model, ShapeConfig::default())?;
            let settings = "the paper's pipeline: SR-ARAP and the contact model";
            demo(&args, &hand, &episode, pipeline, &model_name, settings)
        }
        ContactMethod::Physics => {
            // The committed episode's plate stands between the camera and the pressed tip: the
            // physics estimator runs with the settings for an occluding object unless told
            // otherwise.
            let built_in = if args.episode.is_none() && args.estimator.physics_config().is_none() {
                let config = moe_lab::demo::occluding_settings()?;
                config
                    .validate()
                    .with_context(|| OCCLUDING_SETTINGS_NAME.to_owned())?;
                Some(config)
            } else {
                None
            };
            let settings = match (&built_in, args.estimator.physics_config()) {
                (Some(_), _) => format!(
                    "the physics estimator with {OCCLUDING_SETTINGS_NAME} (the plate hides the \
                     pressed tip's markers; --physics-config FILE for others)"
                ),
                (None, Some(p)) => format!("the physics estimator with {}", p.display()),
                (None, None) => "the physics estimator, default settings".to_owned(),
            };
            let (pipeline, name) =
                args.estimator
                    .physics_pipeline_with(hand.clone(), detector, built_in)?;
            demo(&args, &hand, &episode, pipeline, &name, &settings)
        }
    }
}

/// Runs the demo's pipeline over the episode, writes its outputs and prints its table.
fn demo<E>(
    args: &DemoArgs,
    hand: &HandModel,
    episode: &moe_record::Episode,
    pipeline: Pipeline<E>,
    model_name: &str,
    settings: &str,
) -> Result<()>
where
    E: HandEstimator,
    E::Details: RunDetails,
{
    let outputs =
        run_demo(hand, episode, pipeline, model_name)?.context("the episode has no frames")?;
    let png = png_bytes(&outputs.figure).context("encoding the figure")?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    outputs.write(&args.out)?;
    moe_io::write_atomic(&args.out.join("figure.png"), &png)?;
    super::print_text(&outputs.summary(&args.out, settings));
    Ok(())
}
