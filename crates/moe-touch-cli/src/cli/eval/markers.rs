//! `moe-touch eval markers`: marker perception on the paper's scenes rendered by the
//! simulator's wrist camera with its noise model — the six plate scenes of Table 2, head and
//! arm patting and the three inclined plates. Per scene: detection rate of the markers visible in
//! the ground truth, position error, false detections, identity swaps, and SR-ARAP shape BCD
//! from the detected keypoints against from every true marker. The study is
//! `moe_lab::markers::run_marker_study`, its scenes built in (so an installed binary runs it
//! from any directory); this command draws the overlays and prints.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_lab::markers::{MARKER_SCENES, MarkerSceneView, MarkerStudyOptions, run_marker_study};
use moe_lab::overlay::draw_detection;

/// Arguments of `moe-touch eval markers`.
#[derive(Debug, Args)]
pub(crate) struct MarkersEvalArgs {
    /// Only these scenes (repeatable; default: all eleven).
    #[arg(long = "scene", value_name = "NAME")]
    scenes: Vec<String>,
    /// Seed of the camera noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Render without sensor noise.
    #[arg(long)]
    ideal: bool,
    /// Render with this wrist camera (TOML or JSON `RgbdCamera`, e.g.
    /// fixtures/cameras/d405-wrist.toml) instead of each scene's own.
    #[arg(long, value_name = "CAMERA.toml")]
    camera: Option<PathBuf>,
    /// Detector parameters (TOML or JSON `DetectorConfig`; default: the documented defaults).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Write the first and middle frame of every scene with the detections drawn on it
    /// (`DIR/<scene>_<frame>.png`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Print one JSON object on stdout instead of a table.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: &MarkersEvalArgs) -> Result<()> {
    for s in &args.scenes {
        anyhow::ensure!(
            MARKER_SCENES.contains(&s.as_str()),
            "--scene {s}: not one of {}",
            MARKER_SCENES.join(", ")
        );
    }
    let detector = crate::cli::load_detector_config(args.config.as_deref(), "--config")?;
    let options = MarkerStudyOptions {
        scenes: args.scenes.clone(),
        camera_seed: args.seed,
        ideal: args.ideal,
        camera: crate::cli::eval_camera(args.camera.as_deref(), false)?,
        detector,
    };
    let mut started = std::time::Instant::now();
    let report = run_marker_study(&options, |scene: &MarkerSceneView<'_>| -> Result<()> {
        eprintln!(
            "eval markers: {}: {} frames in {:.1} s",
            scene.name,
            scene.frames.len(),
            started.elapsed().as_secs_f64()
        );
        if let Some(out) = &args.out {
            write_overlays(out, scene)?;
        }
        started = std::time::Instant::now();
        Ok(())
    })?;
    if args.json {
        super::print_json(&report, false)
    } else {
        crate::cli::print_text(&report.table());
        Ok(())
    }
}

/// The first and middle frame of a scene with its detections drawn, as
/// `out/<scene>_<frame>.png`.
fn write_overlays(out: &std::path::Path, scene: &MarkerSceneView<'_>) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    for k in [0, scene.frames.len() / 2] {
        if let (Some(frame), Some(det)) = (scene.frames.get(k), scene.detections.get(k)) {
            let img = draw_detection(scene.detector, &frame.color_rgb8, det)?;
            let file = out.join(format!("{}_{k:03}.png", scene.name));
            img.save(&file)
                .with_context(|| format!("writing {}", file.display()))?;
        }
    }
    Ok(())
}
