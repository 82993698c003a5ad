//! `moe-touch eval markers`: marker perception on the paper's scenes rendered by the
//! simulator's wrist camera with its noise model — the six plate scenes of Table 2, head and
//! arm patting and the three inclined plates. Per scene: detection rate of the markers visible in
//! the ground truth, position error, false detections, identity swaps, and SR-ARAP shape BCD
//! from the detected keypoints against from every true marker.

use std::path::PathBuf;

use crate::overlay::draw_detection;
use anyhow::{Context, Result};
use clap::Args;
use moe_arap::ShapeConfig;
use moe_lab::episode::EpisodeRecorder;
use moe_lab::markers::{EpisodeMarkerReport, MarkerScore, evaluate_episode};
use moe_tendon_sim::camera::NoiseModel;
use moe_tendon_sim::{Scene, SceneConfig, run_saving};
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use serde_json::json;

use crate::golden::workspace_root;

/// The scenes, in the order of the report: Table 2's plates, head and arm patting, the inclines.
const SCENES: [&str; 11] = [
    "plate_tip_front",
    "plate_tip_side",
    "plate_middle_front",
    "plate_middle_side",
    "plate_base_front",
    "plate_base_side",
    "head_patting",
    "arm_patting",
    "inclined_plate_00",
    "inclined_plate_30",
    "inclined_plate_45",
];

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
    let names: Vec<&str> = if args.scenes.is_empty() {
        SCENES.to_vec()
    } else {
        for s in &args.scenes {
            anyhow::ensure!(
                SCENES.contains(&s.as_str()),
                "--scene {s}: not one of {}",
                SCENES.join(", ")
            );
        }
        args.scenes.iter().map(String::as_str).collect()
    };
    let config: DetectorConfig = match &args.config {
        Some(path) => moe_io::read_config(path)?,
        None => DetectorConfig::default(),
    };
    let dir = workspace_root().join("fixtures/scenes");
    let mut reports: Vec<EpisodeMarkerReport> = Vec::new();
    for name in &names {
        let path = dir.join(format!("{name}.toml"));
        let mut scene_config: SceneConfig =
            moe_io::read_config(&path).with_context(|| format!("scene {}", path.display()))?;
        if args.ideal {
            scene_config.camera.noise = NoiseModel::ideal();
        }
        let t = std::time::Instant::now();
        let mut scene = Scene::new(scene_config)?;
        let steps = scene.num_steps();
        let saved = run_saving(&mut scene, steps)?;
        let recorder = EpisodeRecorder::new(&scene, name, args.seed)?;
        let frames = saved
            .iter()
            .enumerate()
            .map(|(k, f)| recorder.frame(&scene, f, k as u64))
            .collect::<Result<Vec<_>, _>>()?;
        let camera = scene.config().camera;
        let mut detector = MarkerDetector::new(
            camera.intrinsics,
            camera.hand_from_camera,
            scene.hand(),
            config,
        )?;
        let (detections, report) = evaluate_episode(
            scene.hand(),
            recorder.info(),
            &frames,
            &mut detector,
            &ShapeConfig::default(),
        )?;
        let report = report.context("simulated frames carry ground truth")?;
        eprintln!(
            "eval markers: {name}: {} frames in {:.1} s",
            frames.len(),
            t.elapsed().as_secs_f64()
        );
        if let Some(out) = &args.out {
            std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
            for k in [0, frames.len() / 2] {
                if let (Some(frame), Some(det)) = (frames.get(k), detections.get(k)) {
                    let img = draw_detection(&detector, &frame.color_rgb8, det)?;
                    let file = out.join(format!("{name}_{k:03}.png"));
                    img.save(&file)
                        .with_context(|| format!("writing {}", file.display()))?;
                }
            }
        }
        reports.push(report);
    }
    let plates: Vec<&EpisodeMarkerReport> = reports
        .iter()
        .filter(|r| r.scene.starts_with("plate_"))
        .collect();
    let summary = summary_of(&plates);
    if args.json {
        println!(
            "{}",
            json!({"seed": args.seed, "ideal": args.ideal, "config": config,
                   "scenes": reports, "plates": summary})
        );
    } else {
        println!("{}", format_table(&reports, &summary));
    }
    Ok(())
}

/// The plate scenes pooled: the figures the targets are stated on.
fn summary_of(plates: &[&EpisodeMarkerReport]) -> serde_json::Value {
    if plates.is_empty() {
        return serde_json::Value::Null;
    }
    let n = plates.len() as f64;
    let mut pooled = MarkerScore::default();
    for r in plates {
        pooled.merge(&r.score);
    }
    let m = pooled.report();
    json!({
        "scenes": plates.len(),
        "frames": m.frames,
        "visible": m.visible,
        "detected": m.detected,
        "detection_rate": m.detection_rate,
        "mean_error_mm": m.mean_error_mm,
        "p95_error_mm": m.p95_error_mm,
        "max_error_mm": m.max_error_mm,
        "false_detections": m.false_detections,
        "identity_swaps": m.identity_swaps,
        "shape_bcd_detected_mm": plates.iter().map(|r| r.shape_bcd_detected_mm).sum::<f64>() / n,
        "shape_bcd_truth_mm": plates.iter().map(|r| r.shape_bcd_truth_mm).sum::<f64>() / n,
        "shape_bcd_truth_visible_mm": plates.iter().map(|r| r.shape_bcd_truth_visible_mm).sum::<f64>() / n,
        "shape_bcd_worst_excess_mm": plates.iter().map(|r| r.shape_bcd_worst_excess_mm).fold(f64::NEG_INFINITY, f64::max),
    })
}

fn format_table(reports: &[EpisodeMarkerReport], plates: &serde_json::Value) -> String {
    let mut s = String::new();
    s.push_str(
        "scene                frames  visible  detected   err mean/p95/max mm  false  swaps  BCD det / seen / all mm  ms/frame\n",
    );
    for r in reports {
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
    if !plates.is_null() {
        let f = |k: &str| plates[k].as_f64().unwrap_or(f64::NAN);
        s.push_str(&format!(
            "plates pooled: {:.2} % of {} visible markers detected, error mean {:.2} / p95 {:.2} / max {:.2} mm, {} false, {} swaps; shape BCD {:.3} mm from detections, {:.3} mm from the visible true markers, {:.3} mm from every true marker (worst frame +{:.3} mm)",
            100.0 * f("detection_rate"),
            f("visible"),
            f("mean_error_mm"),
            f("p95_error_mm"),
            f("max_error_mm"),
            f("false_detections"),
            f("identity_swaps"),
            f("shape_bcd_detected_mm"),
            f("shape_bcd_truth_visible_mm"),
            f("shape_bcd_truth_mm"),
            f("shape_bcd_worst_excess_mm"),
        ));
    }
    s
}
