//! `moe-touch eval physics` as one library call: the frames (a data set's, or trajectories
//! simulated afresh, perceived or not), the material (calibrated first if asked), the physics
//! estimator scored by [`crate::physics_eval`] on them and, if asked, on the plate scenes.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use moe_arap::ShapeConfig;
use moe_contact::{ContactReport, DgcnnEstimator};
use moe_geom::{HandModel, MarkerLayoutPreset, OwnedObservation, Real};
use moe_io::{DatasetReader, Split, SplitFractions};
use moe_physics::{
    CalibrationOptions, CalibrationReport, HandMaterial, PhysicsConfig, PhysicsEstimator, calibrate,
};
use moe_tendon_sim::SceneConfig;
use moe_tendon_sim::randomize::{RandomSceneParams, sample_scene};
use serde::Serialize;

use crate::contact_eval::FrameSet;
use crate::datagen::{dataset_hand, dataset_params};
use crate::error::LabError;
use crate::physics_eval::{
    Comparison, MarkerSource, PerceivedFrame, PhysicsEvaluation, PhysicsPlateTrial, StreamFrame,
    evaluate_physics, evaluate_plates_physics, simulate_perceived, simulate_stream,
};

/// Where the frames of [`physics_study`] come from.
#[derive(Debug, Clone, PartialEq)]
pub enum PhysicsFrames {
    /// A data set's frames, exact (or with noise, [`PhysicsStudyOptions::marker_noise_m`]).
    Dataset {
        /// The data set's directory.
        dir: PathBuf,
        /// Which of its frames.
        frames: FrameSet,
    },
    /// Trajectories `0..trajectories` of the seed simulated afresh.
    Simulated {
        /// How many.
        trajectories: u64,
        /// Their randomisation.
        params: Box<RandomSceneParams>,
        /// Markers detected in the rendered frames rather than read off the surface.
        perceived: bool,
        /// The wrist camera that renders those frames (`None`: the scene's).
        camera: Option<moe_tendon_sim::camera::RgbdCamera>,
        /// The marker detector's parameters for perceived frames.
        detector: Box<moe_touch::perception::DetectorConfig>,
    },
}

/// Options of [`physics_study`].
#[derive(Debug, Clone)]
pub struct PhysicsStudyOptions {
    /// The frames.
    pub frames: PhysicsFrames,
    /// At most this many trajectories (the first ones).
    pub max_trajectories: Option<u64>,
    /// Seed of the simulated trajectories, the marker noise and the plate perturbations.
    pub seed: u64,
    /// Another marker layout on the same fingers.
    pub marker_layout: Option<MarkerLayoutPreset>,
    /// Gaussian noise on every marker coordinate, metres.
    pub marker_noise_m: Option<Real>,
    /// The hand's material (the start of the calibration when there is one).
    pub material: HandMaterial,
    /// A contact-free scene to calibrate the material on first (simulated with the evaluated
    /// hand's material and mesh).
    pub calibration_scene: Option<SceneConfig>,
    /// The estimator's settings.
    pub config: PhysicsConfig,
    /// A contact model for the comparison rows.
    pub model: Option<PathBuf>,
    /// SR-ARAP's settings for the comparison rows: the paper's chain reads the markers only;
    /// on frames that carry a depth image a second row is registered to it as well, with these
    /// settings' depth part (enabled for that row).
    pub shape: ShapeConfig,
    /// Trials per plate scene (0: no Table 2).
    pub plates: u64,
    /// Every frame on its own (the estimator reset before each frame).
    pub no_memory: bool,
}

/// Mean ± sd over a region's trials of one estimator's UCD, with the share of contact frames
/// missed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsRegionStat {
    /// Share of the contact frames missed.
    pub missed_fraction: Real,
    /// Trials with a finite UCD.
    pub trials: usize,
    /// Mean UCD, mm.
    pub ucd_mean_mm: Real,
    /// Standard deviation of the UCD, mm.
    pub ucd_sd_mm: Real,
}

/// One region of the physics estimator's Table 2.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsRegion {
    /// The DGCNN on the physics shapes.
    pub dgcnn_on_physics: PhysicsRegionStat,
    /// The physics estimator.
    pub physics: PhysicsRegionStat,
}

/// The physics estimator's Table 2 per region.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsPlateRegions {
    /// Plates at the base.
    pub base: PhysicsRegion,
    /// Plates at the middle.
    pub middle: PhysicsRegion,
    /// Plates at the tip.
    pub tip: PhysicsRegion,
}

impl PhysicsPlateRegions {
    /// The regions in the paper's order, by name.
    pub fn in_order(&self) -> [(&'static str, &PhysicsRegion); 3] {
        [
            ("tip", &self.tip),
            ("middle", &self.middle),
            ("base", &self.base),
        ]
    }
}

impl PhysicsPlateRegions {
    /// Table 2 as the Markdown table `moe-touch eval physics` prints (a blank line first): per
    /// region, the UCD mean ± sd and the contact frames missed of the physics estimator and of
    /// the DGCNN on its shapes.
    pub fn table(&self) -> String {
        let mut s = String::from(
            "\n| region | physics UCD mm (missed) | DGCNN on the physics shape UCD mm (missed) |\n|---|---|---|\n",
        );
        let cell = |r: &PhysicsRegionStat| {
            format!(
                "{:.2} ± {:.2} ({:.0} %)",
                r.ucd_mean_mm,
                r.ucd_sd_mm,
                100.0 * r.missed_fraction
            )
        };
        for (name, region) in self.in_order() {
            let _ = writeln!(
                s,
                "| {name} | {} | {} |",
                cell(&region.physics),
                cell(&region.dgcnn_on_physics)
            );
        }
        s
    }
}

/// The physics estimator's Table 2: the trials and their summary per region.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsPlateTable {
    /// Per region.
    pub regions: PhysicsPlateRegions,
    /// Every trial.
    pub trials: Vec<PhysicsPlateTrial>,
}

impl PhysicsPlateTable {
    /// The trials with their summary per region.
    pub fn new(trials: Vec<PhysicsPlateTrial>) -> Self {
        let region = |name: &str| {
            let of: Vec<&PhysicsPlateTrial> = trials.iter().filter(|t| t.region == name).collect();
            let stat = |f: &dyn Fn(&PhysicsPlateTrial) -> Option<&ContactReport>| {
                let reports: Vec<&ContactReport> = of.iter().filter_map(|t| f(t)).collect();
                let v: Vec<Real> = reports
                    .iter()
                    .map(|r| r.ucd_mm)
                    .filter(|x| x.is_finite())
                    .collect();
                let n = v.len() as Real;
                let mean = v.iter().sum::<Real>() / n.max(1.0);
                let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<Real>() / n.max(1.0)).sqrt();
                let frames: u64 = reports.iter().map(|r| r.contact_frames).sum();
                let misses: u64 = reports.iter().map(|r| r.misses).sum();
                PhysicsRegionStat {
                    missed_fraction: misses as Real / frames.max(1) as Real,
                    trials: v.len(),
                    ucd_mean_mm: mean,
                    ucd_sd_mm: sd,
                }
            };
            PhysicsRegion {
                dgcnn_on_physics: stat(&|t| t.dgcnn_on_physics.as_ref()),
                physics: stat(&|t| Some(&t.physics)),
            }
        };
        Self {
            regions: PhysicsPlateRegions {
                base: region("base"),
                middle: region("middle"),
                tip: region("tip"),
            },
            trials,
        }
    }
}

/// The report of [`physics_study`] (`moe-touch eval physics --json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsStudyReport {
    /// Table 1 and the force table.
    pub evaluation: PhysicsEvaluation,
    /// Table 2 (no trials without plates).
    pub plates: PhysicsPlateTable,
    /// Simulated trajectories left out because their simulation failed (the figures are over
    /// the others).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub skipped_trajectories: Vec<SkippedTrajectory>,
}

/// What [`physics_study`] found: the report, and the calibration when there was one.
#[derive(Debug, Clone)]
pub struct PhysicsStudy {
    /// The report.
    pub report: PhysicsStudyReport,
    /// The calibration of the material.
    pub calibration: Option<CalibrationReport>,
}

impl PhysicsStudyReport {
    /// The report as the Markdown tables `moe-touch eval physics` prints: Table 1 and the
    /// force table ([`PhysicsEvaluation::table`]), then Table 2 when plates were run.
    pub fn tables(&self) -> String {
        let mut s = String::new();
        if !self.skipped_trajectories.is_empty() {
            let named: Vec<String> = self
                .skipped_trajectories
                .iter()
                .map(|t| format!("{} ({})", t.trajectory, t.error))
                .collect();
            s.push_str(&format!(
                "{} trajectories skipped, their simulation failed: {}\n\n",
                named.len(),
                named.join("; ")
            ));
        }
        s.push_str(&self.evaluation.table());
        if !self.plates.trials.is_empty() {
            s.push_str(&self.plates.regions.table());
        }
        s
    }
}

impl PhysicsStudy {
    /// The calibration in one line (no line break): the fitted material, how well the frames
    /// pin it down and the residual before and after; `None` without a calibration.
    pub fn calibration_summary(&self) -> Option<String> {
        self.calibration.as_ref().map(|report| {
            format!(
                "calibrated on {} frames: E {:.0} Pa (resolution {:.1} %), damping {:.4} s, RMS \
                 {:.4} -> {:.4} mm ({} evaluations)",
                report.frames,
                report.material.material.youngs_modulus_pa,
                100.0 * report.youngs_modulus_resolution,
                report.material.material.rayleigh_stiffness,
                report.rms_initial_m * 1e3,
                report.rms_fitted_m * 1e3,
                report.evaluations
            )
        })
    }
}

/// The frames to evaluate and what they were made with.
#[derive(Debug, Clone)]
pub struct Streams {
    /// The hand (with the study's marker layout).
    pub hand: HandModel,
    /// The frames, trajectory after trajectory.
    pub frames: Vec<StreamFrame>,
    /// Per frame, the markers detected in the rendered images and the depth images (perceived
    /// frames).
    pub perceived: Option<Vec<PerceivedFrame>>,
    /// The randomisation the frames were made with.
    pub params: RandomSceneParams,
    /// Simulated trajectories that failed and are not among the frames.
    pub skipped: Vec<SkippedTrajectory>,
}

/// A simulated trajectory a study left out because its simulation (or its rendering) failed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SkippedTrajectory {
    /// Its id (of the study's seed).
    pub trajectory: u64,
    /// Why.
    pub error: String,
}

/// A data set's frames as streams; with `marker_layout`, that layout's markers read off each
/// frame's true surface.
///
/// # Errors
/// An unreadable data set, a layout whose fingers' meshes differ from the data set's, or no
/// frames.
pub fn dataset_streams(
    dir: &Path,
    marker_layout: Option<MarkerLayoutPreset>,
    split: Option<Split>,
    max_trajectories: Option<u64>,
) -> Result<Streams, LabError> {
    let reader = DatasetReader::open(dir)?;
    let data_hand = dataset_hand(&reader)?;
    let layout = reader.card().layout.clone();
    let mut params = dataset_params(reader.card())?;
    let hand = match marker_layout {
        Some(preset) => {
            params.finger.marker_layout = preset.layout();
            let hand = HandModel::preset(params.preset, &params.finger)?;
            for (a, b) in hand.fingers().iter().zip(data_hand.fingers()) {
                if a.model.mesh().vertices() != b.model.mesh().vertices() {
                    return Err(LabError::InvalidEvaluation {
                        reason: format!(
                            "marker layout {preset}: the fingers' meshes differ from the data \
                             set's"
                        ),
                    });
                }
            }
            hand
        }
        None => data_hand,
    };
    let frame_secs = params.dt_secs * params.save_every_steps as Real;
    let mut out: Vec<StreamFrame> = Vec::new();
    let mut trajectories = 0u64;
    for f in reader.frames(split, SplitFractions::default()) {
        let f = f?;
        let new = out
            .last()
            .is_none_or(|l| l.frame.trajectory_id != f.trajectory_id);
        if new {
            if max_trajectories.is_some_and(|m| trajectories >= m) {
                break;
            }
            trajectories += 1;
        }
        let mut stream = StreamFrame::from_dataset(&f, &layout, frame_secs)?;
        if marker_layout.is_some() {
            stream.frame.markers = hand.keypoints_on(&stream.frame.shape.fingers);
        }
        out.push(stream);
    }
    if out.is_empty() {
        return Err(LabError::InvalidEvaluation {
            reason: format!("{}: no frames to evaluate", dir.display()),
        });
    }
    Ok(Streams {
        hand,
        frames: out,
        perceived: None,
        params,
        skipped: Vec::new(),
    })
}

/// Trajectories `0..n` of `seed` simulated afresh; with `perceived` = (camera, detector), each
/// rendered by that camera (`None`: the scene's) and its markers detected; `progress(t, n)`
/// after each. A trajectory whose simulation or rendering fails is left out and named in
/// [`Streams::skipped`]; the others are kept.
///
/// # Errors
/// A hand the parameters do not make, or every trajectory failing (the first one's error).
fn simulated_streams(
    mut params: RandomSceneParams,
    marker_layout: Option<MarkerLayoutPreset>,
    n: u64,
    seed: u64,
    perceived: Option<(
        Option<moe_tendon_sim::camera::RgbdCamera>,
        moe_touch::perception::DetectorConfig,
    )>,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Streams, LabError> {
    if let Some(preset) = marker_layout {
        params.finger.marker_layout = preset.layout();
    }
    let hand = HandModel::preset(params.preset, &params.finger)?;
    let kept = keep_trajectories(n, progress, |t| {
        let mut sampled = sample_scene(&params, seed, t)?;
        Ok(match perceived {
            Some((camera, detector)) => {
                if let Some(camera) = camera {
                    sampled.config.camera = camera;
                }
                let (s, k) = simulate_perceived(&sampled.config, &hand, t, seed ^ t, detector)?;
                (s, Some(k))
            }
            None => (simulate_stream(&sampled.config, &hand, t)?, None),
        })
    })?;
    let (frames, seen, skipped) = kept;
    Ok(Streams {
        hand,
        frames,
        perceived: perceived.map(|_| seen),
        params,
        skipped,
    })
}

/// The frames kept of a study's trajectories, their perceived frames, and the trajectories
/// skipped.
type Kept<F, P> = (Vec<F>, Vec<P>, Vec<SkippedTrajectory>);

/// The frames of trajectories `0..n`, `simulate(t)` each, with their perceived frames where
/// it gives them; a trajectory that fails is named among the skipped ones and the others are
/// kept. `progress(t, n)` after each.
///
/// # Errors
/// Every trajectory failing: the first one's error.
fn keep_trajectories<F, P>(
    n: u64,
    progress: &mut dyn FnMut(u64, u64),
    mut simulate: impl FnMut(u64) -> Result<(Vec<F>, Option<Vec<P>>), LabError>,
) -> Result<Kept<F, P>, LabError> {
    let each = crate::run_each(0..n, |t| {
        let simulated = simulate(t);
        progress(t + 1, n);
        simulated
    });
    let mut frames = Vec::new();
    let mut seen = Vec::new();
    for (s, k) in each.ran {
        frames.extend(s);
        seen.extend(k.into_iter().flatten());
    }
    let skipped = each
        .failed
        .into_iter()
        .map(|(trajectory, error)| SkippedTrajectory { trajectory, error })
        .collect();
    match each.first_error {
        Some(e) if frames.is_empty() => Err(e),
        _ => Ok((frames, seen, skipped)),
    }
}

/// The material fitted to `scene` simulated with the hand's own material and mesh (`params`),
/// from `initial`.
fn calibrated(
    scene: &SceneConfig,
    hand: &HandModel,
    params: &RandomSceneParams,
    initial: &HandMaterial,
    config: &PhysicsConfig,
) -> Result<CalibrationReport, LabError> {
    let mut scene = scene.clone();
    scene.material = params.material.clone();
    scene.voxel = params.voxel.clone();
    let stream = simulate_stream(&scene, hand, 0)?;
    let frames: Vec<OwnedObservation> = stream
        .iter()
        .map(|s| {
            s.frame
                .observation()
                .with_time(s.time_secs)
                .to_owned_observation()
        })
        .collect();
    Ok(calibrate(
        hand,
        &[frames],
        initial,
        config,
        &CalibrationOptions::default(),
    )?)
}

/// A contact model on `hand` by the runtime's loader, the model's path in its error.
///
/// # Errors
/// [`LabError::InvalidEvaluation`] naming the model and why it does not load on `hand`.
pub fn load_model_on(path: &Path, hand: &HandModel) -> Result<DgcnnEstimator, LabError> {
    moe_touch::pipeline::load_contact_model(path, hand).map_err(|e| LabError::InvalidEvaluation {
        reason: format!(
            "model {} on the data set's hand ({:?} vertices per finger): {}",
            path.display(),
            hand.fingers()
                .iter()
                .map(|f| f.model.mesh().num_vertices())
                .collect::<Vec<_>>(),
            moe_touch::error::one_line(&e)
        ),
    })
}

/// `moe-touch eval physics`: contact from physics on the frames of `options`, as tactile sensors
/// are specified, beside the paper's metrics; `progress(t, n)` after each simulated trajectory.
///
/// # Errors
/// Unreadable or unfit data, a model that does not fit the hand, a failing simulation,
/// calibration or estimate.
pub fn physics_study(
    options: &PhysicsStudyOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<PhysicsStudy, LabError> {
    let Streams {
        hand,
        frames,
        perceived,
        params,
        skipped,
    } = match &options.frames {
        PhysicsFrames::Dataset { dir, frames } => dataset_streams(
            dir,
            options.marker_layout,
            frames.split(),
            options.max_trajectories,
        )?,
        PhysicsFrames::Simulated {
            trajectories,
            params,
            perceived,
            camera,
            detector,
        } => simulated_streams(
            (**params).clone(),
            options.marker_layout,
            options.max_trajectories.unwrap_or(*trajectories),
            options.seed,
            perceived.then_some((*camera, **detector)),
            progress,
        )?,
    };
    let calibration = match &options.calibration_scene {
        Some(scene) => Some(calibrated(
            scene,
            &hand,
            &params,
            &options.material,
            &options.config,
        )?),
        None => None,
    };
    let material = calibration
        .as_ref()
        .map_or(&options.material, |c| &c.material);
    let mut estimator = PhysicsEstimator::new(&hand, material, &options.config)?;
    let dgcnn = options
        .model
        .as_deref()
        .map(|m| load_model_on(m, &hand))
        .transpose()?;
    let source = match (&perceived, options.marker_noise_m) {
        (Some(seen), _) => MarkerSource::Given(seen),
        (None, Some(sigma_m)) => MarkerSource::Noisy {
            sigma_m,
            seed: options.seed,
        },
        (None, None) => MarkerSource::Exact,
    };
    let evaluation = evaluate_physics(
        &hand,
        &frames,
        source,
        &mut estimator,
        Comparison {
            dgcnn: dgcnn.as_ref(),
            shape: &options.shape,
            forget_between_frames: options.no_memory,
        },
    )?;
    let trials = if options.plates > 0 {
        evaluate_plates_physics(
            &hand,
            &crate::contact_eval::plate_scenes()?,
            options.plates,
            options.seed,
            &mut estimator,
            dgcnn.as_ref(),
        )?
    } else {
        Vec::new()
    };
    Ok(PhysicsStudy {
        report: PhysicsStudyReport {
            evaluation,
            plates: PhysicsPlateTable::new(trials),
            skipped_trajectories: skipped,
        },
        calibration,
    })
}

/// One load of a frame of [`PhysicsGolden`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsGoldenLoad {
    /// The finger.
    pub finger: usize,
    /// The vertex it acts at.
    pub vertex: u32,
    /// Its force, hand frame, newtons.
    pub force_n: [Real; 3],
}

/// One frame of [`PhysicsGolden`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsGoldenFrame {
    /// The loads found.
    pub loads: Vec<PhysicsGoldenLoad>,
    /// Every finger's likelihood-ratio statistic.
    pub statistic: Vec<Real>,
}

/// The golden physics stage: the physics estimator (nominal material) on a data set's
/// trajectories as streams, from their exact markers: [`PhysicsEvaluation`] without its
/// timings, and per frame the loads and every finger's statistic.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsGolden {
    /// The evaluation's fields but its wall times and work counts ([`PHYSICS_TIMING_KEYS`]).
    #[serde(flatten)]
    pub evaluation: serde_json::Map<String, serde_json::Value>,
    /// Per frame, the loads and statistics.
    pub per_frame: Vec<PhysicsGoldenFrame>,
}

/// The fields of [`PhysicsEvaluation`] that are wall times, and the counts of the work done
/// (solves, searches stopped at their budget): a Newton iteration more or less on another
/// machine's round-off moves them without moving a result.
pub const PHYSICS_TIMING_KEYS: [&str; 4] = [
    "physics_ms_median",
    "physics_ms_p90",
    "solves",
    "degraded_fingers",
];

/// [`PhysicsGolden`] of the physics estimator with `config` on the data set at `dir`.
///
/// # Errors
/// An unreadable data set or a failing estimate.
pub fn physics_golden(dir: &Path, config: &PhysicsConfig) -> Result<PhysicsGolden, LabError> {
    use moe_geom::HandEstimator as _;
    let Streams { hand, frames, .. } = dataset_streams(dir, None, None, None)?;
    let mut estimator = PhysicsEstimator::new(&hand, &HandMaterial::default(), config)?;
    let shape = ShapeConfig::default();
    let e = evaluate_physics(
        &hand,
        &frames,
        MarkerSource::Exact,
        &mut estimator,
        Comparison {
            dgcnn: None,
            shape: &shape,
            forget_between_frames: false,
        },
    )?;
    // The loads frame by frame, the estimator reset at each trajectory as above.
    let mut per_frame = Vec::with_capacity(frames.len());
    let mut previous = None;
    for sf in &frames {
        if previous != Some(sf.frame.trajectory_id) {
            estimator.reset();
            previous = Some(sf.frame.trajectory_id);
        }
        let est = estimator.estimate(&sf.frame.observation().with_time(sf.time_secs))?;
        per_frame.push(PhysicsGoldenFrame {
            loads: est
                .details
                .loads
                .iter()
                .map(|l| PhysicsGoldenLoad {
                    finger: l.finger,
                    vertex: l.vertex,
                    force_n: [l.force_n.x, l.force_n.y, l.force_n.z],
                })
                .collect(),
            statistic: est.details.fingers.iter().map(|f| f.statistic).collect(),
        });
    }
    let serde_json::Value::Object(evaluation) = crate::without_keys(&e, &PHYSICS_TIMING_KEYS)?
    else {
        return Err(LabError::InvalidEvaluation {
            reason: "the physics evaluation is not a JSON object".into(),
        });
    };
    Ok(PhysicsGolden {
        evaluation,
        per_frame,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trajectory whose simulation fails is named and left out, the others kept in order;
    /// only a study of which every trajectory fails fails, with the first error.
    #[test]
    fn a_failed_trajectory_is_skipped_and_named_and_the_others_are_kept() {
        let fail = |t: u64| LabError::InvalidPlan {
            reason: format!("trajectory {t} diverged"),
        };
        let mut calls = Vec::new();
        let (frames, seen, skipped) = keep_trajectories(4, &mut |t, n| calls.push((t, n)), |t| {
            if t == 1 || t == 2 {
                Err(fail(t))
            } else {
                Ok((vec![10 * t, 10 * t + 1], Some(vec![t])))
            }
        })
        .unwrap();
        assert_eq!(frames, [0, 1, 30, 31]);
        assert_eq!(seen, [0, 3]);
        assert_eq!(
            skipped,
            [
                SkippedTrajectory {
                    trajectory: 1,
                    error: "invalid generation plan: trajectory 1 diverged".into()
                },
                SkippedTrajectory {
                    trajectory: 2,
                    error: "invalid generation plan: trajectory 2 diverged".into()
                }
            ]
        );
        assert_eq!(calls, [(1, 4), (2, 4), (3, 4), (4, 4)]);
        let all = keep_trajectories::<u64, u64>(3, &mut |_, _| {}, |t| Err(fail(t)));
        assert!(
            matches!(&all, Err(LabError::InvalidPlan { reason }) if reason == "trajectory 0 diverged"),
            "{all:?}"
        );
    }
}
