//! The marker study: marker perception on the paper's scenes rendered by the simulator's wrist
//! camera with its noise model — the six plate scenes of Table 2, head and arm patting and the
//! three inclined plates — scored per scene ([`evaluate_episode`]) and pooled over the plates.
//! The scenes are built in ([`marker_scene`]), so the study runs from any directory.

use std::fmt::Write as _;

use moe_arap::ShapeConfig;
use moe_record::EpisodeFrame;
use moe_tendon_sim::camera::NoiseModel;
use moe_tendon_sim::{Scene, SceneConfig, paper_scenes, run_saving};
use moe_touch::perception::{DetectorConfig, MarkerDetection, MarkerDetector};
use serde::Serialize;

use super::{EpisodeMarkerReport, MarkerScore, evaluate_episode};
use crate::LabError;
use crate::contact_eval::plate_scenes;
use crate::episode::EpisodeRecorder;

/// The study's scenes, in report order: Table 2's plates, head and arm patting, the inclines.
pub const MARKER_SCENES: [&str; 11] = [
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

/// Settings of the marker study.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerStudyOptions {
    /// Only these scenes of [`MARKER_SCENES`], in this order (empty: all eleven).
    pub scenes: Vec<String>,
    /// Seed of the camera noise.
    pub camera_seed: u64,
    /// Render without sensor noise.
    pub ideal: bool,
    /// Render with this wrist camera instead of each scene's own (`None`: the scene's).
    pub camera: Option<moe_tendon_sim::camera::RgbdCamera>,
    /// The detector's parameters.
    pub detector: DetectorConfig,
}

/// The plate scenes pooled: the figures the targets are stated on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PooledPlateMarkers {
    /// Plate scenes pooled.
    pub scenes: usize,
    /// Frames scored.
    pub frames: usize,
    /// Markers visible in the ground truth.
    pub visible: usize,
    /// Visible markers correctly detected.
    pub detected: usize,
    /// `detected / visible`.
    pub detection_rate: f64,
    /// Mean position error of the correct detections, mm.
    pub mean_error_mm: f64,
    /// Its 95th percentile, mm.
    pub p95_error_mm: f64,
    /// Its largest, mm.
    pub max_error_mm: f64,
    /// Reported markers near no true marker.
    pub false_detections: usize,
    /// Reported markers at another marker's true position.
    pub identity_swaps: usize,
    /// Mean over the scenes of the SR-ARAP shape BCD from the detected keypoints, mm.
    pub shape_bcd_detected_mm: f64,
    /// Mean over the scenes of the shape BCD from every true marker, mm.
    pub shape_bcd_truth_mm: f64,
    /// Mean over the scenes of the shape BCD from the visible true markers, mm.
    pub shape_bcd_truth_visible_mm: f64,
    /// The largest per-frame excess of the detected over the true BCD over the scenes, mm.
    pub shape_bcd_worst_excess_mm: f64,
}

/// The marker study's report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerStudyReport {
    /// Seed of the camera noise.
    pub seed: u64,
    /// Rendered without sensor noise.
    pub ideal: bool,
    /// The camera that rendered every scene (absent: each scene's own).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera: Option<moe_tendon_sim::camera::RgbdCamera>,
    /// The detector's parameters.
    pub config: DetectorConfig,
    /// Every scene, in order.
    pub scenes: Vec<EpisodeMarkerReport>,
    /// The plate scenes pooled (`None` without a plate scene).
    pub plates: Option<PooledPlateMarkers>,
}

/// One scene as the study saw it, for the caller to look at (draw detections, report
/// progress).
#[derive(Debug)]
pub struct MarkerSceneView<'a> {
    /// The scene's name.
    pub name: &'a str,
    /// The detector after the episode.
    pub detector: &'a MarkerDetector,
    /// The rendered frames.
    pub frames: &'a [EpisodeFrame],
    /// The detection of every frame.
    pub detections: &'a [MarkerDetection],
    /// The scene's report.
    pub report: &'a EpisodeMarkerReport,
}

/// The plate scenes (names starting `plate_`) of `reports` pooled; `None` without one.
pub fn pool_plates(reports: &[EpisodeMarkerReport]) -> Option<PooledPlateMarkers> {
    let plates: Vec<&EpisodeMarkerReport> = reports
        .iter()
        .filter(|r| r.scene.starts_with("plate_"))
        .collect();
    if plates.is_empty() {
        return None;
    }
    let n = plates.len() as f64;
    let mut pooled = MarkerScore::default();
    for r in &plates {
        pooled.merge(&r.score);
    }
    let m = pooled.report();
    let mean = |f: fn(&EpisodeMarkerReport) -> f64| plates.iter().map(|r| f(r)).sum::<f64>() / n;
    Some(PooledPlateMarkers {
        scenes: plates.len(),
        frames: m.frames,
        visible: m.visible,
        detected: m.detected,
        detection_rate: m.detection_rate,
        mean_error_mm: m.mean_error_mm,
        p95_error_mm: m.p95_error_mm,
        max_error_mm: m.max_error_mm,
        false_detections: m.false_detections,
        identity_swaps: m.identity_swaps,
        shape_bcd_detected_mm: mean(|r| r.shape_bcd_detected_mm),
        shape_bcd_truth_mm: mean(|r| r.shape_bcd_truth_mm),
        shape_bcd_truth_visible_mm: mean(|r| r.shape_bcd_truth_visible_mm),
        shape_bcd_worst_excess_mm: plates
            .iter()
            .map(|r| r.shape_bcd_worst_excess_mm)
            .fold(f64::NEG_INFINITY, f64::max),
    })
}

/// The scene of the study named `name` (one of [`MARKER_SCENES`]), built in: the plates from
/// [`plate_scenes`], head and arm patting and the inclined plates from
/// [`moe_tendon_sim::paper_scenes`] — the scenes the workspace's `fixtures/scenes/<name>.toml`
/// hold.
///
/// # Errors
/// [`LabError::InvalidEvaluation`] for a name not in [`MARKER_SCENES`]; a scene that cannot be
/// built.
pub fn marker_scene(name: &str) -> Result<SceneConfig, LabError> {
    if let Some(plate) = plate_scenes()?.into_iter().find(|p| p.name == name) {
        return Ok(plate.config);
    }
    let incline = |deg: f64| paper_scenes::inclined_plate(deg).map_err(LabError::from);
    match name {
        "head_patting" => Ok(paper_scenes::head_patting()?),
        "arm_patting" => Ok(paper_scenes::arm_patting()?),
        "inclined_plate_00" => incline(0.0),
        "inclined_plate_30" => incline(30.0),
        "inclined_plate_45" => incline(45.0),
        _ => Err(LabError::InvalidEvaluation {
            reason: format!("scene {name}: not one of {}", MARKER_SCENES.join(", ")),
        }),
    }
}

impl MarkerStudyReport {
    /// The report as the table `moe-touch eval markers` prints: one row per scene (detection
    /// rate, position error, false detections, swaps, shape BCD, time per frame), then the
    /// plates pooled.
    pub fn table(&self) -> String {
        let mut s = String::from(
            "scene                frames  visible  detected   err mean/p95/max mm  false  swaps  BCD det / seen / all mm  ms/frame\n",
        );
        for r in &self.scenes {
            let m = &r.markers;
            let _ = writeln!(
                s,
                "{:<20} {:>6} {:>8} {:>8.2} %   {:>5.2} / {:>4.2} / {:>4.2}   {:>5} {:>6}     {:>5.3} / {:>5.3} / {:>5.3}   {:>7.2}",
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
            );
        }
        if let Some(p) = &self.plates {
            s.push_str(&p.line());
        }
        s.push('\n');
        s
    }
}

impl PooledPlateMarkers {
    /// The pooled plates in one line (no line break).
    pub fn line(&self) -> String {
        format!(
            "plates pooled: {:.2} % of {} visible markers detected, error mean {:.2} / p95 {:.2} / max {:.2} mm, {} false, {} swaps; shape BCD {:.3} mm from detections, {:.3} mm from the visible true markers, {:.3} mm from every true marker (worst frame +{:.3} mm)",
            100.0 * self.detection_rate,
            self.visible,
            self.mean_error_mm,
            self.p95_error_mm,
            self.max_error_mm,
            self.false_detections,
            self.identity_swaps,
            self.shape_bcd_detected_mm,
            self.shape_bcd_truth_visible_mm,
            self.shape_bcd_truth_mm,
            self.shape_bcd_worst_excess_mm,
        )
    }
}

/// Runs the marker study: each scene simulated, rendered (camera noise seeded by
/// [`MarkerStudyOptions::camera_seed`]) and scored with [`evaluate_episode`]; `after_scene`
/// sees each scene as it is done (its error ends the study).
///
/// # Errors
/// A scene not in [`MARKER_SCENES`], a scene that cannot be built, a diverging simulation,
/// a detector that does not fit the camera, a failing solve, or `after_scene`'s error.
pub fn run_marker_study<E: From<LabError>>(
    options: &MarkerStudyOptions,
    mut after_scene: impl FnMut(&MarkerSceneView<'_>) -> Result<(), E>,
) -> Result<MarkerStudyReport, E> {
    let names: Vec<&str> = if options.scenes.is_empty() {
        MARKER_SCENES.to_vec()
    } else {
        options.scenes.iter().map(String::as_str).collect()
    };
    if let Some(s) = names.iter().find(|s| !MARKER_SCENES.contains(s)) {
        return Err(LabError::InvalidEvaluation {
            reason: format!("scene {s}: not one of {}", MARKER_SCENES.join(", ")),
        }
        .into());
    }
    let mut reports: Vec<EpisodeMarkerReport> = Vec::new();
    for name in names {
        let mut scene_config = marker_scene(name)?;
        if let Some(camera) = options.camera {
            scene_config.camera = camera;
        }
        if options.ideal {
            scene_config.camera.noise = NoiseModel::ideal();
        }
        let (frames, detector, detections, report) = score_scene(scene_config, name, options)?;
        after_scene(&MarkerSceneView {
            name,
            detector: &detector,
            frames: &frames,
            detections: &detections,
            report: &report,
        })?;
        reports.push(report);
    }
    Ok(MarkerStudyReport {
        seed: options.camera_seed,
        ideal: options.ideal,
        camera: options.camera,
        config: options.detector,
        plates: pool_plates(&reports),
        scenes: reports,
    })
}

/// One scene simulated, rendered and scored.
type ScoredScene = (
    Vec<EpisodeFrame>,
    MarkerDetector,
    Vec<MarkerDetection>,
    EpisodeMarkerReport,
);

fn score_scene(
    config: SceneConfig,
    name: &str,
    options: &MarkerStudyOptions,
) -> Result<ScoredScene, LabError> {
    let mut scene = Scene::new(config)?;
    let steps = scene.num_steps();
    let saved = run_saving(&mut scene, steps)?;
    let recorder = EpisodeRecorder::new(&scene, name, options.camera_seed)?;
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
        options.detector,
    )?;
    let (detections, report) = evaluate_episode(
        scene.hand(),
        recorder.info(),
        &frames,
        &mut detector,
        &ShapeConfig::default(),
    )?;
    let report = report.ok_or_else(|| LabError::InvalidEvaluation {
        reason: format!("{name}: simulated frames carry ground truth, these do not"),
    })?;
    Ok((frames, detector, detections, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One plate scene rendered without noise: it is seen once by the caller, its markers are
    /// nearly all detected, and the plates pooled over it are its own figures; a scene that is
    /// not the study's is refused before any work.
    #[test]
    fn one_plate_scene_is_scored_and_pooled_as_itself() {
        let options = MarkerStudyOptions {
            scenes: vec!["plate_tip_front".into()],
            camera_seed: 0,
            ideal: true,
            camera: None,
            detector: DetectorConfig::default(),
        };
        let mut seen = Vec::new();
        let report = run_marker_study(&options, |scene: &MarkerSceneView<'_>| {
            assert_eq!(scene.frames.len(), scene.detections.len());
            seen.push(scene.name.to_owned());
            Ok::<(), LabError>(())
        })
        .unwrap();
        assert_eq!(seen, ["plate_tip_front"]);
        let [scene] = report.scenes.as_slice() else {
            panic!("{:?}", report.scenes);
        };
        assert!(scene.markers.detection_rate > 0.95, "{:?}", scene.markers);
        let plates = report.plates.unwrap();
        assert_eq!(plates.scenes, 1);
        assert_eq!(plates.visible, scene.markers.visible);
        assert_eq!(plates.detection_rate, scene.markers.detection_rate);
        assert_eq!(plates.shape_bcd_detected_mm, scene.shape_bcd_detected_mm);
        let unknown = MarkerStudyOptions {
            scenes: vec!["plate_nowhere".into()],
            ..options
        };
        let err = run_marker_study(&unknown, |_: &MarkerSceneView<'_>| Ok::<(), LabError>(()))
            .unwrap_err();
        assert!(err.to_string().contains("plate_nowhere"), "{err}");
    }

    /// The built-in scenes are the committed scene files, to the bit, so the study finds the
    /// scenes it always did.
    #[test]
    fn the_built_in_scenes_are_the_committed_files() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes");
        for name in MARKER_SCENES {
            let file: SceneConfig = moe_io::read_config(&dir.join(format!("{name}.toml"))).unwrap();
            let built_in = marker_scene(name).unwrap();
            assert_eq!(
                serde_json::to_string(&built_in).unwrap(),
                serde_json::to_string(&file).unwrap(),
                "{name}"
            );
        }
        let err = marker_scene("plate_nowhere").unwrap_err();
        assert!(err.to_string().contains("plate_nowhere"), "{err}");
    }
}
