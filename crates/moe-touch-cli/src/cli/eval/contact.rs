//! `moe-touch eval contact`: the paper's simulation study of contact estimation (Tables 1–2)
//! on held-out trajectories of a data set — a thin command over `moe_lab::contact_eval`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use moe_arap::MultiShapeEstimator;
use moe_contact::{DgcnnEstimator, KnnIndex};
use moe_geom::{ContactInput, HandModel, LabelledFrame, Real};
use moe_io::{DatasetReader, Split, SplitFractions};
use moe_lab::contact_eval::{
    ContactEvalOptions, ContactTable, Estimators, KnnIndexSource, PlateTrial, TruthLabels,
    contact_ply, evaluate_plates, evaluate_table1,
};
use serde_json::json;

use crate::golden::workspace_root;
use moe_lab::datagen::{dataset_hand, dataset_params, label_rule};

/// Arguments of `moe-touch eval contact`.
#[derive(Debug, Args)]
pub(crate) struct ContactEvalArgs {
    /// Data set directory; its test trajectories are evaluated (its training trajectories make
    /// the KNN index).
    #[arg(long)]
    pub(crate) data: PathBuf,
    /// The contact model (`NAME.safetensors` with its card `NAME.json`).
    #[arg(long)]
    pub(crate) model: PathBuf,
    /// `KNN[All]` index file: loaded when it exists, otherwise built from the training
    /// trajectories and written there, so that the next evaluation does not rebuild it.
    #[arg(long, value_name = "K.safetensors")]
    pub(crate) knn_index: Option<PathBuf>,
    /// Which frames to evaluate: the data set's test trajectories, or all of them (a data set the
    /// model never saw, e.g. of another hand; the KNN rows then need `--knn-index` of an
    /// existing index and are left out without one).
    #[arg(long, value_enum, default_value = "test")]
    pub(crate) frames: FrameSet,
    /// Evaluate at most this many frames (the first ones, in data set order).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
    pub(crate) max_frames: Option<u64>,
    /// Trials per plate scene (Table 2; trial 0 is the scene as committed). 0 skips Table 2.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(0..=100))]
    pub(crate) trials: u64,
    /// Seed of the marker subsets, `KNN[Sub]` and the plate perturbations.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    pub(crate) json: bool,
    /// Write, for a few test frames with contact, the true and estimated meshes as PLY coloured
    /// by contact, and a figure of the per-region plate errors (SVG) to this directory.
    #[arg(long, value_name = "DIR")]
    pub(crate) out: Option<PathBuf>,
    /// Add the physics estimator and the DGCNN on its shapes to Table 1 (the same frames, as
    /// streams) and Table 2 (the same plate trials), with the force table; `moe-touch eval physics`
    /// has the noisy, perceived and calibrated variants.
    #[arg(long)]
    pub(crate) physics: bool,
    /// The hand's material for `--physics` (TOML, as `moe-touch calibrate` writes it).
    #[arg(long, requires = "physics")]
    pub(crate) material: Option<PathBuf>,
    /// The physics estimator's settings for `--physics` (e.g.
    /// fixtures/physics/exact-markers.toml, for the data set's exact markers).
    #[arg(long, requires = "physics")]
    pub(crate) physics_config: Option<PathBuf>,
}

/// Frames of `--frames`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum FrameSet {
    /// The test trajectories.
    Test,
    /// Every frame.
    All,
}

/// Frames whose estimates `--out` writes.
const SHOWN_FRAMES: usize = 4;

/// Distance of the proximity rule the first data sets used, metres.
const PROXIMITY_M: f32 = 1e-3;

pub(crate) fn load_estimator(path: &Path, hand: &HandModel) -> Result<DgcnnEstimator> {
    moe_touch::pipeline::load_contact_model(path, hand).with_context(|| {
        format!(
            "model {} on the data set's hand ({:?} vertices per finger)",
            path.display(),
            hand.fingers()
                .iter()
                .map(|f| f.model.mesh().num_vertices())
                .collect::<Vec<_>>()
        )
    })
}

/// The `KNN[All]` index of `--knn-index` or of the data set's training frames, saying which.
fn knn_index(args: &ContactEvalArgs, reader: &DatasetReader) -> Result<KnnIndex> {
    let path = args.knn_index.as_deref();
    let (index, source) = moe_lab::contact_eval::knn_index(reader, path)
        .with_context(|| format!("data set {}", args.data.display()))?;
    let shown = path.map_or_else(String::new, |p| p.display().to_string());
    match source {
        KnnIndexSource::Read => eprintln!(
            "eval contact: KNN index of {} frames from {shown}",
            index.len()
        ),
        KnnIndexSource::BuiltAndWritten => eprintln!(
            "eval contact: built the KNN index of {} training frames, wrote {shown}",
            index.len()
        ),
        KnnIndexSource::Built => {}
    }
    Ok(index)
}

pub(crate) fn run(args: &ContactEvalArgs) -> Result<()> {
    let reader = DatasetReader::open(&args.data)?;
    if reader.card().totals.frames == 0 {
        bail!("{}: the data set has no frames", args.data.display());
    }
    let hand = dataset_hand(&reader)?;
    let rule = label_rule(reader.card());
    let dgcnn = load_estimator(&args.model, &hand)?;
    let mut physics_estimator = if args.physics {
        Some(physics_estimator(args, &hand)?)
    } else {
        None
    };
    let layout = reader.card().layout.clone();
    let mut frames: Vec<LabelledFrame> = Vec::new();
    let mut streams: Vec<moe_lab::physics_eval::StreamFrame> = Vec::new();
    let params = dataset_params(reader.card())?;
    let frame_secs = params.dt_secs * params.save_every_steps as Real;
    let mut proximity: Vec<Vec<Vec<bool>>> = Vec::new();
    let split = match args.frames {
        FrameSet::Test => Some(Split::Test),
        FrameSet::All => None,
    };
    for f in reader.frames(split, SplitFractions::default()) {
        let f = f?;
        let labelled = f.to_labelled(&layout)?;
        frames.push(labelled);
        if args.physics {
            streams.push(moe_lab::physics_eval::StreamFrame::from_dataset(
                &f, &layout, frame_secs,
            )?);
        }
        proximity.push(layout.per_finger(&f.obstacle_distance_m, |&d| d < PROXIMITY_M));
        if args.max_frames.is_some_and(|m| frames.len() as u64 >= m) {
            break;
        }
    }
    if frames.is_empty() {
        bail!(
            "{}: no frames to evaluate (too few trajectories for a test split?)",
            args.data.display()
        );
    }
    // On all frames, an index built from the data set's own training frames would find them.
    let with_knn =
        args.frames == FrameSet::Test || args.knn_index.as_ref().is_some_and(|p| p.exists());
    let knn_all = if with_knn {
        Some(knn_index(args, &reader)?)
    } else {
        None
    };
    let knn_sub = knn_all
        .as_ref()
        .map(|k| k.subset(0.1, args.seed))
        .transpose()?;
    let options = ContactEvalOptions {
        seed: args.seed,
        ..ContactEvalOptions::default()
    };
    // Show the first frames with the most contact, spread over the set.
    let mut by_contact: Vec<(usize, usize)> = frames
        .iter()
        .enumerate()
        .map(|(k, f)| (f.contact_count(), k))
        .filter(|(c, _)| *c > 0)
        .collect();
    by_contact.sort_unstable_by(|a, b| b.cmp(a));
    let shown: Vec<usize> = by_contact
        .iter()
        .step_by((by_contact.len() / SHOWN_FRAMES).max(1))
        .take(SHOWN_FRAMES)
        .map(|&(_, k)| k)
        .collect();
    let other = (rule != "proximity").then_some(TruthLabels {
        rule: "proximity",
        labels: &proximity,
    });
    eprintln!(
        "eval contact: {} frames; SR-ARAP, DGCNN, KNN[All] ({} frames), KNN[Sub] ({})",
        frames.len(),
        knn_all.as_ref().map_or(0, KnnIndex::len),
        knn_sub.as_ref().map_or(0, KnnIndex::len)
    );
    let estimators = Estimators {
        dgcnn: &dgcnn,
        knn_all: knn_all.as_ref(),
        knn_sub: knn_sub.as_ref(),
    };
    let (table, kept) =
        evaluate_table1(&hand, &frames, &rule, other, estimators, &options, &|k| {
            shown.contains(&k)
        })?;
    let plates = if let (true, Some(knn_all)) = (args.trials > 0, &knn_all) {
        let scenes = moe_lab::contact_eval::plate_scenes()?;
        eprintln!(
            "eval contact: {} plate scenes × {} trials",
            scenes.len(),
            args.trials
        );
        evaluate_plates(
            &hand,
            &scenes,
            args.trials,
            args.seed,
            &dgcnn,
            knn_all,
            &options.shape,
        )?
    } else {
        Vec::new()
    };
    let physics = match physics_estimator.as_mut() {
        Some(estimator) => Some(physics_rows(args, &hand, &streams, &dgcnn, estimator)?),
        None => None,
    };
    if let Some(dir) = &args.out {
        write_out(dir, &hand, &frames, &kept, &plates)?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({
                "data": args.data.display().to_string(),
                "model": args.model.display().to_string(),
                "label_rule": rule,
                "table1": table,
                "table2": { "trials": plates, "regions": region_summary(&plates) },
                "physics": physics.as_ref().map(|(e, p)| json!({
                    "table1": e,
                    "table2": { "trials": p, "regions": crate::cli::eval::physics::plate_regions(p) },
                })),
            }))?
        );
    } else {
        print!("{}", format_table1(&table));
        if !plates.is_empty() {
            print!("{}", format_table2(&plates));
        }
        if let Some((e, p)) = &physics {
            print!(
                "\nContact from physics on the same frames:\n{}",
                crate::cli::eval::physics::table(e)
            );
            if !p.is_empty() {
                print!("{}", crate::cli::eval::physics::plate_table(p));
            }
        }
    }
    Ok(())
}

/// The physics estimator of `--physics`, from `--material` and `--physics-config` (read before
/// any evaluation, so that a bad file is refused at once).
fn physics_estimator(
    args: &ContactEvalArgs,
    hand: &HandModel,
) -> Result<moe_physics::PhysicsEstimator> {
    let material: moe_physics::HandMaterial = match &args.material {
        Some(p) => moe_io::read_config(p)?,
        None => moe_physics::HandMaterial::default(),
    };
    let config: moe_physics::PhysicsConfig = match &args.physics_config {
        Some(p) => moe_io::read_config(p)?,
        None => moe_physics::PhysicsConfig::default(),
    };
    Ok(moe_physics::PhysicsEstimator::new(
        hand, &material, &config,
    )?)
}

/// The physics estimator's rows on the same frames (streams) and plate trials.
fn physics_rows(
    args: &ContactEvalArgs,
    hand: &HandModel,
    streams: &[moe_lab::physics_eval::StreamFrame],
    dgcnn: &DgcnnEstimator,
    estimator: &mut moe_physics::PhysicsEstimator,
) -> Result<(
    moe_lab::physics_eval::PhysicsEvaluation,
    Vec<moe_lab::physics_eval::PhysicsPlateTrial>,
)> {
    eprintln!(
        "eval contact: the physics estimator on {} frames",
        streams.len()
    );
    let shape = moe_arap::ShapeConfig::default();
    let eval = moe_lab::physics_eval::evaluate_physics(
        hand,
        streams,
        moe_lab::physics_eval::MarkerSource::Exact,
        estimator,
        moe_lab::physics_eval::Comparison {
            dgcnn: Some(dgcnn),
            shape: &shape,
            forget_between_frames: false,
        },
    )?;
    let plates = if args.trials > 0 {
        moe_lab::physics_eval::evaluate_plates_physics(
            hand,
            &moe_lab::contact_eval::plate_scenes()?,
            args.trials,
            args.seed,
            estimator,
            Some(dgcnn),
        )?
    } else {
        Vec::new()
    };
    Ok((eval, plates))
}

/// Mean ± sd of the trials' UCD per region, for DGCNN and `KNN[All]` (mm); trials whose every
/// contact frame was missed are left out of the mean and counted.
fn region_summary(plates: &[PlateTrial]) -> serde_json::Value {
    let mut out = serde_json::Map::new();
    for region in ["tip", "middle", "base"] {
        let trials: Vec<&PlateTrial> = plates.iter().filter(|t| t.region == region).collect();
        let stat = |f: &dyn Fn(&PlateTrial) -> Real| {
            let v: Vec<Real> = trials
                .iter()
                .map(|t| f(t))
                .filter(|x| x.is_finite())
                .collect();
            let n = v.len() as Real;
            let mean = v.iter().sum::<Real>() / n.max(1.0);
            let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<Real>() / n.max(1.0)).sqrt();
            json!({ "mean_mm": mean, "sd_mm": sd, "trials": v.len(),
                    "trials_all_missed": trials.len() - v.len() })
        };
        out.insert(
            region.to_owned(),
            json!({
                "dgcnn": stat(&|t| t.dgcnn.ucd_mm),
                "knn_all": stat(&|t| t.knn_all.ucd_mm),
            }),
        );
    }
    serde_json::Value::Object(out)
}

fn format_table1(t: &ContactTable) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Table 1 — {} held-out frames of {} trajectories (DGCNN threshold {:.2})",
        t.frames, t.trajectories, t.threshold
    );
    let _ = writeln!(
        s,
        "{:<12} {:>7} {:>10} {:>10} {:>13} {:>12} {:>9}",
        "shape", "markers", "BCD mm", "sd", "vertex mean", "vertex max", "ms/frame"
    );
    for r in &t.shape {
        let _ = writeln!(
            s,
            "{:<12} {:>7} {:>10.3} {:>10.3} {:>13.3} {:>12.3} {:>9.2}",
            r.method,
            r.markers,
            r.bcd_mm,
            r.bcd_sd_mm,
            r.vertex_mean_mm,
            r.vertex_max_mm,
            r.ms_per_frame
        );
    }
    let _ = writeln!(
        s,
        "{:<20} {:<10} {:>8} {:>8} {:>7} {:>7} {:>6} {:>6} {:>6} {:>6} {:>9}",
        "contact",
        "labels",
        "BCD mm",
        "UCD mm",
        "missed",
        "f.alarm",
        "P",
        "R",
        "F1",
        "IoU",
        "ms/frame"
    );
    for r in &t.contact {
        let p = &r.report;
        let _ = writeln!(
            s,
            "{:<20} {:<10} {:>8.3} {:>8.3} {:>6.1}% {:>6.1}% {:>6.3} {:>6.3} {:>6.3} {:>6.3} {:>9.2}",
            r.method,
            r.labels,
            p.bcd_mm,
            p.ucd_mm,
            100.0 * p.miss_rate,
            100.0 * p.false_alarm_rate,
            p.precision,
            p.recall,
            p.f1,
            p.iou,
            r.ms_per_frame
        );
    }
    s
}

fn format_table2(plates: &[PlateTrial]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Table 2 — plate scenes, UCD predicted → true contact points, mm"
    );
    let _ = writeln!(
        s,
        "{:<20} {:>5} {:>9} {:>8} {:>10} {:>8} {:>10} {:>8}",
        "scene", "trial", "contact", "DGCNN", "missed", "KNN[All]", "missed", "tilt°"
    );
    for t in plates {
        let _ = writeln!(
            s,
            "{:<20} {:>5} {:>9} {:>8.2} {:>9.0}% {:>8.2} {:>9.0}% {:>8.2}",
            t.scene,
            t.trial,
            t.contact_frames,
            t.dgcnn.ucd_mm,
            100.0 * t.dgcnn.miss_rate,
            t.knn_all.ucd_mm,
            100.0 * t.knn_all.miss_rate,
            t.tilt_deg
        );
    }
    let summary = region_summary(plates);
    for region in ["tip", "middle", "base"] {
        let r = &summary[region];
        let _ = writeln!(
            s,
            "{region:<8} DGCNN {:.2} ± {:.2} mm   KNN[All] {:.2} ± {:.2} mm",
            r["dgcnn"]["mean_mm"].as_f64().unwrap_or(f64::NAN),
            r["dgcnn"]["sd_mm"].as_f64().unwrap_or(f64::NAN),
            r["knn_all"]["mean_mm"].as_f64().unwrap_or(f64::NAN),
            r["knn_all"]["sd_mm"].as_f64().unwrap_or(f64::NAN),
        );
    }
    s
}

fn write_out(
    dir: &Path,
    hand: &HandModel,
    frames: &[LabelledFrame],
    kept: &[moe_lab::contact_eval::FramePrediction],
    plates: &[PlateTrial],
) -> Result<()> {
    // Everything in memory first, so that a failure leaves nothing half-written.
    let mut files: Vec<(PathBuf, moe_io::PlyData)> = Vec::new();
    for k in kept {
        let f = &frames[k.frame];
        let name = format!("traj{}_frame{}", f.trajectory_id, f.frame_index);
        for i in 0..hand.num_fingers() {
            let truth: Vec<Real> = f.contact[i]
                .iter()
                .map(|&c| Real::from(u8::from(c)))
                .collect();
            files.push((
                dir.join(format!("{name}_true_finger{i}.ply")),
                contact_ply(hand, i, &f.shape.fingers[i], &truth)?,
            ));
            files.push((
                dir.join(format!("{name}_dgcnn_on_srarap_finger{i}.ply")),
                contact_ply(hand, i, &k.arap_shape.fingers[i], &k.dgcnn_on_arap[i])?,
            ));
            if let Some(labels) = k.knn_all.get(i) {
                let knn: Vec<Real> = labels.iter().map(|&c| Real::from(u8::from(c))).collect();
                files.push((
                    dir.join(format!("{name}_knn_all_finger{i}.ply")),
                    contact_ply(hand, i, &f.shape.fingers[i], &knn)?,
                ));
            }
        }
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (path, ply) in &files {
        moe_io::write_ply(path, ply)?;
    }
    if !plates.is_empty() {
        let svg = crate::figure::region_bars(&region_summary(plates));
        moe_io::write_atomic(&dir.join("plate_regions.svg"), svg.as_bytes())?;
    }
    eprintln!(
        "eval contact: wrote {} meshes to {}",
        files.len(),
        dir.display()
    );
    Ok(())
}

/// The committed held-out frames of the golden regression (a data set directory).
pub(crate) const HELDOUT_DIR: &str = "fixtures/contact/heldout";
/// The shipped contact model.
pub(crate) const SHIPPED_MODEL: &str = "models/contact-two-finger.safetensors";

/// Arguments of `moe-touch heldout-shard`.
#[derive(Debug, Args)]
pub(crate) struct HeldoutArgs {
    /// Data set to take test frames from.
    #[arg(long)]
    pub(crate) data: PathBuf,
    /// Output data set directory.
    #[arg(long, default_value = HELDOUT_DIR)]
    pub(crate) out: PathBuf,
    /// Test trajectories to take frames from (the first ones with contact), at least 1.
    #[arg(long, default_value_t = 2, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub(crate) trajectories: usize,
    /// Frames per trajectory (every other frame from the first contact on), at least 1.
    #[arg(long, default_value_t = 6, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub(crate) frames: usize,
}

/// Writes a small data set of held-out frames: of each of the first test trajectories with
/// contact, every other frame from one before the first contact.
pub(crate) fn write_heldout(args: &HeldoutArgs) -> Result<()> {
    let reader = DatasetReader::open(&args.data)?;
    let mut by_trajectory: Vec<(u64, Vec<moe_io::DatasetFrame>)> = Vec::new();
    for f in reader.frames(Some(Split::Test), SplitFractions::default()) {
        let f = f?;
        match by_trajectory.last_mut() {
            Some((t, v)) if *t == f.trajectory_id => v.push(f),
            _ => by_trajectory.push((f.trajectory_id, vec![f])),
        }
    }
    let mut frames = Vec::new();
    for (_, traj) in by_trajectory
        .iter()
        .filter(|(_, v)| v.iter().any(|f| f.contact_count() > 0))
        .take(args.trajectories)
    {
        let first = traj.iter().position(|f| f.contact_count() > 0).unwrap_or(0);
        frames.extend(
            traj.iter()
                .skip(first.saturating_sub(1))
                .step_by(2)
                .take(args.frames)
                .cloned(),
        );
    }
    if frames.is_empty() {
        bail!("{}: no test trajectory with contact", args.data.display());
    }
    let layout = reader.card().layout.clone();
    std::fs::create_dir_all(&args.out)?;
    let file = moe_io::dataset::shard_file_name(0, 1);
    moe_io::dataset::write_shard(&args.out.join(&file), &layout, &frames)?;
    let (stats, families) = moe_io::dataset::shard_stats(&layout, &frames);
    let card = moe_io::dataset::DatasetCard::new(
        layout,
        reader.card().seed,
        reader.card().generator.clone(),
        vec![(moe_io::dataset::ShardEntry { file, stats }, families)],
    );
    moe_io::write_json(&args.out.join(moe_io::dataset::CARD_FILE), &card)?;
    eprintln!(
        "heldout-shard: {} frames of {} trajectories to {}",
        frames.len(),
        args.trajectories,
        args.out.display()
    );
    Ok(())
}

fn heldout_frames() -> Result<(HandModel, Vec<LabelledFrame>, String)> {
    let reader = DatasetReader::open(&workspace_root().join(HELDOUT_DIR))?;
    let hand = dataset_hand(&reader)?;
    let frames = reader
        .labelled_frames(None, SplitFractions::default())
        .collect::<Result<Vec<_>, _>>()?;
    Ok((hand, frames, label_rule(reader.card())))
}

/// Golden ARAP stage: SR-ARAP shapes of the held-out frames' keypoints (all markers and the
/// seeded 4 of 7): per frame the BCD and per-vertex errors against the true surface and a
/// sample of estimated vertices (mm).
pub(crate) fn golden_arap() -> Result<serde_json::Value> {
    let (hand, frames, _) = heldout_frames()?;
    let options = ContactEvalOptions::default();
    let mut arap = MultiShapeEstimator::new(hand.clone(), options.shape.clone())?;
    let rng = moe_geom::SeededRng::new(options.seed);
    let mut out = Vec::new();
    for (k, f) in frames.iter().enumerate() {
        let subset = moe_lab::contact_eval::marker_subset(
            &f.markers,
            options.subset_markers,
            &mut rng.split(k as u64),
        );
        let mut rows = serde_json::Map::new();
        for (name, keypoints) in [("all_markers", &f.markers), ("four_markers", &subset)] {
            let shape = arap.estimate(keypoints)?.shape;
            let est: Vec<moe_geom::Point3> = shape.fingers.iter().flatten().copied().collect();
            let truth: Vec<moe_geom::Point3> = f.shape.fingers.iter().flatten().copied().collect();
            let errors: Vec<Real> = est
                .iter()
                .zip(&truth)
                .map(|(a, b)| (a - b).norm())
                .collect();
            let samples: Vec<[Real; 3]> = shape
                .fingers
                .iter()
                .flat_map(|v| {
                    (0..5).map(move |j| {
                        let p = v[j * (v.len() - 1) / 4];
                        [1e3 * p.x, 1e3 * p.y, 1e3 * p.z]
                    })
                })
                .collect();
            rows.insert(
                name.to_owned(),
                json!({
                    "bcd_mm": 1e3 * moe_geom::bcd(&est, &truth)?,
                    "vertex_mean_mm": 1e3 * errors.iter().sum::<Real>() / errors.len() as Real,
                    "vertex_max_mm": 1e3 * errors.iter().copied().fold(0.0, Real::max),
                    "sample_vertices_mm": samples,
                }),
            );
        }
        out.push(json!({
            "trajectory": f.trajectory_id,
            "frame": f.frame_index,
            "shapes": rows,
        }));
    }
    Ok(json!({ "frames": out }))
}

/// Golden contact stage: Table 1 of the shipped model on the held-out frames (no KNN rows, no
/// timings), plus the network's summed contact probability per frame on the true shape.
pub(crate) fn golden_table1() -> Result<serde_json::Value> {
    let (hand, frames, rule) = heldout_frames()?;
    let dgcnn = load_estimator(&workspace_root().join(SHIPPED_MODEL), &hand)?;
    let estimators = Estimators {
        dgcnn: &dgcnn,
        knn_all: None,
        knn_sub: None,
    };
    let (table, _) = evaluate_table1(
        &hand,
        &frames,
        &rule,
        None,
        estimators,
        &ContactEvalOptions::default(),
        &|_| false,
    )?;
    let mut value = serde_json::to_value(&table)?;
    for rows in ["shape", "contact"] {
        if let Some(rows) = value[rows].as_array_mut() {
            for r in rows {
                if let Some(o) = r.as_object_mut() {
                    o.remove("ms_per_frame");
                }
            }
        }
    }
    let sums = frames
        .iter()
        .map(|f| {
            let map = dgcnn.estimate_map(&ContactInput::of_frame(f, &f.shape))?;
            Ok(map.fingers.iter().flatten().sum::<Real>())
        })
        .collect::<Result<Vec<Real>>>()?;
    value["probability_sum_per_frame"] = json!(sums);
    Ok(value)
}
