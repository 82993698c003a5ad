//! `moe-touch eval contact` as one library call: Table 1 on a data set's frames, Table 2 on the
//! plate scenes, optionally the physics estimator on both, with a typed report.

use std::path::{Path, PathBuf};

use moe_contact::KnnIndex;
use moe_geom::{HandModel, LabelledFrame, Real};
use moe_io::{DatasetReader, PlyData, SplitFractions};
use moe_physics::{HandMaterial, PhysicsConfig, PhysicsEstimator};
use serde::Serialize;

use super::{
    ContactEvalOptions, ContactTable, Estimators, FramePrediction, FrameSet, KnnIndexSource,
    PlateTrial, TruthLabels, contact_ply, evaluate_plates, evaluate_table1, knn_index,
    plate_scenes,
};
use crate::datagen::{dataset_hand, dataset_params, label_rule};
use crate::error::LabError;
use crate::physics_eval::{
    Comparison, MarkerSource, PhysicsEvaluation, StreamFrame, evaluate_physics,
    evaluate_plates_physics,
};
use crate::physics_study::{PhysicsPlateTable, load_model_on};

/// Frames whose estimates [`ContactStudyOptions::meshes`] keeps.
const SHOWN_FRAMES: usize = 4;

/// Distance of the proximity rule the first data sets used, metres.
const PROXIMITY_M: f32 = 1e-3;

/// The physics estimator's settings for [`ContactStudyOptions::physics`].
#[derive(Debug, Clone, Default)]
pub struct ContactStudyPhysics {
    /// The hand's material.
    pub material: HandMaterial,
    /// The estimator's settings.
    pub config: PhysicsConfig,
}

/// Options of [`contact_study`].
#[derive(Debug, Clone)]
pub struct ContactStudyOptions {
    /// The data set's directory.
    pub data: PathBuf,
    /// The contact model.
    pub model: PathBuf,
    /// The `KNN[All]` index file: read when it exists, else built and written there.
    pub knn_index: Option<PathBuf>,
    /// Which frames.
    pub frames: FrameSet,
    /// At most this many frames (the first ones).
    pub max_frames: Option<u64>,
    /// Trials per plate scene (0: no Table 2).
    pub trials: u64,
    /// Seed of the marker subsets, `KNN[Sub]` and the plate perturbations.
    pub seed: u64,
    /// The physics estimator and the DGCNN on its shapes on the same frames and plates.
    pub physics: Option<ContactStudyPhysics>,
    /// Keep, for a few frames with contact, the true and estimated meshes coloured by contact.
    pub meshes: bool,
}

/// What [`contact_study`] is about to do, for a caller that reports progress.
#[derive(Debug, Clone, Copy)]
pub enum ContactStudyProgress<'a> {
    /// The `KNN[All]` index is ready.
    KnnIndex {
        /// Its frames.
        frames: usize,
        /// Where it came from.
        source: KnnIndexSource,
        /// Its file, if any.
        path: Option<&'a Path>,
    },
    /// Table 1 starts.
    Table1 {
        /// Frames evaluated.
        frames: usize,
        /// Frames of `KNN[All]` (0 without it).
        knn_all: usize,
        /// Frames of `KNN[Sub]`.
        knn_sub: usize,
    },
    /// Table 2 starts.
    Plates {
        /// Plate scenes.
        scenes: usize,
        /// Trials each.
        trials: u64,
    },
    /// The physics estimator starts.
    Physics {
        /// Frames.
        frames: usize,
    },
}

/// Mean ± sd over a region's trials of one estimator's UCD (mm); trials whose every contact
/// frame was missed are left out of the mean and counted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlateRegionStat {
    /// Mean UCD, mm.
    pub mean_mm: Real,
    /// Standard deviation, mm.
    pub sd_mm: Real,
    /// Trials in the mean.
    pub trials: usize,
    /// Trials whose every contact frame was missed.
    pub trials_all_missed: usize,
}

/// One region of Table 2.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlateRegion {
    /// The DGCNN on SR-ARAP shapes.
    pub dgcnn: PlateRegionStat,
    /// `KNN[All]`.
    pub knn_all: PlateRegionStat,
}

/// Table 2 per region.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlateRegions {
    /// Plates at the base.
    pub base: PlateRegion,
    /// Plates at the middle.
    pub middle: PlateRegion,
    /// Plates at the tip.
    pub tip: PlateRegion,
}

impl PlateRegions {
    /// The regions in the paper's order, by name.
    pub fn in_order(&self) -> [(&'static str, &PlateRegion); 3] {
        [
            ("tip", &self.tip),
            ("middle", &self.middle),
            ("base", &self.base),
        ]
    }
}

/// Table 2: the trials and their summary per region.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlateTable {
    /// Every trial.
    pub trials: Vec<PlateTrial>,
    /// Per region.
    pub regions: PlateRegions,
}

impl PlateTable {
    /// The trials with their summary per region.
    pub fn new(trials: Vec<PlateTrial>) -> Self {
        let region = |name: &str| {
            let of: Vec<&PlateTrial> = trials.iter().filter(|t| t.region == name).collect();
            let stat = |f: &dyn Fn(&PlateTrial) -> Real| {
                let v: Vec<Real> = of.iter().map(|t| f(t)).filter(|x| x.is_finite()).collect();
                let n = v.len() as Real;
                let mean = v.iter().sum::<Real>() / n.max(1.0);
                let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<Real>() / n.max(1.0)).sqrt();
                PlateRegionStat {
                    mean_mm: mean,
                    sd_mm: sd,
                    trials: v.len(),
                    trials_all_missed: of.len() - v.len(),
                }
            };
            PlateRegion {
                dgcnn: stat(&|t| t.dgcnn.ucd_mm),
                knn_all: stat(&|t| t.knn_all.ucd_mm),
            }
        };
        let regions = PlateRegions {
            base: region("base"),
            middle: region("middle"),
            tip: region("tip"),
        };
        Self { trials, regions }
    }
}

/// The physics estimator's rows of [`ContactStudyReport`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactStudyPhysicsTables {
    /// On the same frames, as streams.
    pub table1: PhysicsEvaluation,
    /// On the same plate trials.
    pub table2: PhysicsPlateTable,
}

/// The report of [`contact_study`] (`moe-touch eval contact --json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactStudyReport {
    /// The data set, as given.
    pub data: String,
    /// The model, as given.
    pub model: String,
    /// The data set's label rule.
    pub label_rule: String,
    /// Table 1.
    pub table1: ContactTable,
    /// Table 2.
    pub table2: PlateTable,
    /// The physics estimator's rows, when asked for.
    pub physics: Option<ContactStudyPhysicsTables>,
}

/// What [`contact_study`] found: the report, and the meshes kept.
#[derive(Debug, Clone)]
pub struct ContactStudy {
    /// The report.
    pub report: ContactStudyReport,
    /// File name and mesh of each kept estimate ([`ContactStudyOptions::meshes`]).
    pub meshes: Vec<(String, PlyData)>,
}

/// `moe-touch eval contact`: the paper's Tables 1–2 on a data set's frames and the plate
/// scenes, with the physics estimator beside them when asked for.
///
/// # Errors
/// An unreadable or empty data set, a model or index that does not fit its hand, a failing
/// simulation or estimate.
pub fn contact_study(
    options: &ContactStudyOptions,
    progress: &mut dyn FnMut(ContactStudyProgress<'_>),
) -> Result<ContactStudy, LabError> {
    let reader = DatasetReader::open(&options.data)?;
    if reader.card().totals.frames == 0 {
        return Err(LabError::InvalidEvaluation {
            reason: format!("{}: the data set has no frames", options.data.display()),
        });
    }
    let hand = dataset_hand(&reader)?;
    let rule = label_rule(reader.card());
    let dgcnn = load_model_on(&options.model, &hand)?;
    let mut physics_estimator = match &options.physics {
        Some(p) => Some(PhysicsEstimator::new(&hand, &p.material, &p.config)?),
        None => None,
    };
    let layout = reader.card().layout.clone();
    let params = dataset_params(reader.card())?;
    let frame_secs = params.dt_secs * params.save_every_steps as Real;
    let mut frames: Vec<LabelledFrame> = Vec::new();
    let mut streams: Vec<StreamFrame> = Vec::new();
    let mut proximity: Vec<Vec<Vec<bool>>> = Vec::new();
    for f in reader.frames(options.frames.split(), SplitFractions::default()) {
        let f = f?;
        frames.push(f.to_labelled(&layout)?);
        if options.physics.is_some() {
            streams.push(StreamFrame::from_dataset(&f, &layout, frame_secs)?);
        }
        proximity.push(layout.per_finger(&f.obstacle_distance_m, |&d| d < PROXIMITY_M));
        if options.max_frames.is_some_and(|m| frames.len() as u64 >= m) {
            break;
        }
    }
    if frames.is_empty() {
        return Err(LabError::InvalidEvaluation {
            reason: format!(
                "{}: no frames to evaluate (too few trajectories for a test split?)",
                options.data.display()
            ),
        });
    }
    // On all frames, an index built from the data set's own training frames would find them.
    let index_path = options.knn_index.as_deref();
    let with_knn = options.frames == FrameSet::Test || index_path.is_some_and(Path::exists);
    let knn_all = if with_knn {
        let (index, source) = knn_index(&reader, index_path)?;
        progress(ContactStudyProgress::KnnIndex {
            frames: index.len(),
            source,
            path: index_path,
        });
        Some(index)
    } else {
        None
    };
    let knn_sub = knn_all
        .as_ref()
        .map(|k| k.subset(0.1, options.seed))
        .transpose()?;
    let eval_options = ContactEvalOptions {
        seed: options.seed,
        ..ContactEvalOptions::default()
    };
    let shown = shown_frames(&frames, options.meshes);
    let other = (rule != "proximity").then_some(TruthLabels {
        rule: "proximity",
        labels: &proximity,
    });
    progress(ContactStudyProgress::Table1 {
        frames: frames.len(),
        knn_all: knn_all.as_ref().map_or(0, KnnIndex::len),
        knn_sub: knn_sub.as_ref().map_or(0, KnnIndex::len),
    });
    let estimators = Estimators {
        dgcnn: &dgcnn,
        knn_all: knn_all.as_ref(),
        knn_sub: knn_sub.as_ref(),
    };
    let (table1, kept) = evaluate_table1(
        &hand,
        &frames,
        &rule,
        other,
        estimators,
        &eval_options,
        &|k| shown.contains(&k),
    )?;
    let plates = if let (true, Some(knn_all)) = (options.trials > 0, &knn_all) {
        let scenes = plate_scenes()?;
        progress(ContactStudyProgress::Plates {
            scenes: scenes.len(),
            trials: options.trials,
        });
        evaluate_plates(
            &hand,
            &scenes,
            options.trials,
            options.seed,
            &dgcnn,
            knn_all,
            &eval_options.shape,
        )?
    } else {
        Vec::new()
    };
    let physics = match physics_estimator.as_mut() {
        Some(estimator) => {
            progress(ContactStudyProgress::Physics {
                frames: streams.len(),
            });
            let shape = moe_arap::ShapeConfig::default();
            let table1 = evaluate_physics(
                &hand,
                &streams,
                MarkerSource::Exact,
                estimator,
                Comparison {
                    dgcnn: Some(&dgcnn),
                    shape: &shape,
                    forget_between_frames: false,
                },
            )?;
            let trials = if options.trials > 0 {
                evaluate_plates_physics(
                    &hand,
                    &plate_scenes()?,
                    options.trials,
                    options.seed,
                    estimator,
                    Some(&dgcnn),
                )?
            } else {
                Vec::new()
            };
            Some(ContactStudyPhysicsTables {
                table1,
                table2: PhysicsPlateTable::new(trials),
            })
        }
        None => None,
    };
    let meshes = if options.meshes {
        kept_meshes(&hand, &frames, &kept)?
    } else {
        Vec::new()
    };
    Ok(ContactStudy {
        report: ContactStudyReport {
            data: options.data.display().to_string(),
            model: options.model.display().to_string(),
            label_rule: rule,
            table1,
            table2: PlateTable::new(plates),
            physics,
        },
        meshes,
    })
}

/// The first frames with the most contact, spread over the set (none unless `meshes`).
fn shown_frames(frames: &[LabelledFrame], meshes: bool) -> Vec<usize> {
    if !meshes {
        return Vec::new();
    }
    let mut by_contact: Vec<(usize, usize)> = frames
        .iter()
        .enumerate()
        .map(|(k, f)| (f.contact_count(), k))
        .filter(|(c, _)| *c > 0)
        .collect();
    by_contact.sort_unstable_by(|a, b| b.cmp(a));
    by_contact
        .iter()
        .step_by((by_contact.len() / SHOWN_FRAMES).max(1))
        .take(SHOWN_FRAMES)
        .map(|&(_, k)| k)
        .collect()
}

/// The true and estimated meshes of the kept frames, coloured by contact, with their file names.
fn kept_meshes(
    hand: &HandModel,
    frames: &[LabelledFrame],
    kept: &[FramePrediction],
) -> Result<Vec<(String, PlyData)>, LabError> {
    let labels = |l: &[bool]| -> Vec<Real> { l.iter().map(|&c| Real::from(u8::from(c))).collect() };
    let mut files = Vec::new();
    for k in kept {
        let f = &frames[k.frame];
        let name = format!("traj{}_frame{}", f.trajectory_id, f.frame_index);
        for i in 0..hand.num_fingers() {
            files.push((
                format!("{name}_true_finger{i}.ply"),
                contact_ply(hand, i, &f.shape.fingers[i], &labels(&f.contact[i]))?,
            ));
            files.push((
                format!("{name}_dgcnn_on_srarap_finger{i}.ply"),
                contact_ply(hand, i, &k.arap_shape.fingers[i], &k.dgcnn_on_arap[i])?,
            ));
            if let Some(knn) = k.knn_all.get(i) {
                files.push((
                    format!("{name}_knn_all_finger{i}.ply"),
                    contact_ply(hand, i, &f.shape.fingers[i], &labels(knn))?,
                ));
            }
        }
    }
    Ok(files)
}
