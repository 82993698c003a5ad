//! `moe-touch eval markers`: marker perception on the paper's scenes rendered by the
//! simulator's wrist camera with its noise model — the six plate scenes of Table 2, head and
//! arm patting and the three inclined plates. Per scene: detection rate of the markers visible in
//! the ground truth, position error, false detections, identity swaps, and SR-ARAP shape BCD
//! from the detected keypoints against from every true marker. The study is
//! `moe_lab::markers::run_marker_study`; this command draws the overlays and prints.

use std::path::PathBuf;

use crate::overlay::draw_detection;
use anyhow::{Context, Result};
use clap::Args;
use moe_lab::markers::{
    MARKER_SCENES, MarkerSceneView, MarkerStudyOptions, MarkerStudyReport, PooledPlateMarkers,
    run_marker_study,
};

use crate::golden::workspace_root;

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
    let detector = crate::cli::load_detector_config(args.config.as_deref())?;
    let options = MarkerStudyOptions {
        scenes: args.scenes.clone(),
        scene_dir: workspace_root().join("fixtures/scenes"),
        camera_seed: args.seed,
        ideal: args.ideal,
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
        // Keys sorted, as the report has always been printed.
        println!("{}", serde_json::to_value(&report)?);
    } else {
        println!("{}", format_table(&report));
    }
    Ok(())
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

fn format_table(report: &MarkerStudyReport) -> String {
    let mut s = String::new();
    s.push_str(
        "scene                frames  visible  detected   err mean/p95/max mm  false  swaps  BCD det / seen / all mm  ms/frame\n",
    );
    for r in &report.scenes {
        let m = &r.markers;
        s.push_str(&format!(
            "{:<20} {:>6} {:>8} {:>8.2} %   {:>5.2} / {:>4.2} / {:>4.2}   {:>5} {:>6}     {:>5.3} / {:>5.3} / {:>5.3}   {:>7.2}\n",
            r.scene,
            m.frames,
            m.visible,
            100.0 * m.detection_rate,
            m.mean_error_mm,
            m.p95_error_mm,
            m.max_error_mm,
            m.false_detections,
            m.identity_swaps,
            r.shape_bcd_detected_mm,
            r.shape_bcd_truth_visible_mm,
            r.shape_bcd_truth_mm,
            r.detect_ms,
        ));
    }
    if let Some(p) = &report.plates {
        s.push_str(&plates_line(p));
    }
    s
}

fn plates_line(p: &PooledPlateMarkers) -> String {
    format!(
        "plates pooled: {:.2} % of {} visible markers detected, error mean {:.2} / p95 {:.2} / max {:.2} mm, {} false, {} swaps; shape BCD {:.3} mm from detections, {:.3} mm from the visible true markers, {:.3} mm from every true marker (worst frame +{:.3} mm)",
        100.0 * p.detection_rate,
        p.visible,
        p.mean_error_mm,
        p.p95_error_mm,
        p.max_error_mm,
        p.false_detections,
        p.identity_swaps,
        p.shape_bcd_detected_mm,
        p.shape_bcd_truth_visible_mm,
        p.shape_bcd_truth_mm,
        p.shape_bcd_worst_excess_mm,
    )
}
