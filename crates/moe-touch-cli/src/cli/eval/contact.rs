//! `moe-touch eval contact`: the paper's simulation study of contact estimation (Tables 1–2)
//! on held-out trajectories of a data set — a thin command over `moe_lab::contact_eval`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use moe_contact::DgcnnEstimator;
use moe_geom::{HandModel, LabelledFrame};
use moe_io::{DatasetReader, Split, SplitFractions};
use moe_lab::contact_eval::{
    ContactStudyOptions, ContactStudyPhysics, ContactStudyProgress, ContactTable, KnnIndexSource,
    PlateTable, arap_golden, contact_study, table1_golden,
};

use crate::golden::workspace_root;
use moe_lab::datagen::{dataset_hand, label_rule};

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

impl From<FrameSet> for moe_lab::contact_eval::FrameSet {
    fn from(f: FrameSet) -> Self {
        match f {
            FrameSet::Test => Self::Test,
            FrameSet::All => Self::All,
        }
    }
}

/// The contact model at `path` on `hand`, by the runtime's loader.
pub(crate) fn load_estimator(path: &Path, hand: &HandModel) -> Result<DgcnnEstimator> {
    Ok(moe_lab::physics_study::load_model_on(path, hand)?)
}

pub(crate) fn run(args: &ContactEvalArgs) -> Result<()> {
    // The physics files are read before any evaluation, so that a bad file is refused at once.
    let physics = if args.physics {
        Some(ContactStudyPhysics {
            material: crate::cli::load_material(args.material.as_deref())?.0,
            config: crate::cli::load_physics_config(args.physics_config.as_deref())?.0,
        })
    } else {
        None
    };
    let options = ContactStudyOptions {
        data: args.data.clone(),
        model: args.model.clone(),
        knn_index: args.knn_index.clone(),
        frames: args.frames.into(),
        max_frames: args.max_frames,
        trials: args.trials,
        seed: args.seed,
        physics,
        meshes: args.out.is_some(),
    };
    let study = contact_study(&options, &mut print_progress)?;
    let report = &study.report;
    if let Some(dir) = &args.out {
        write_out(dir, &study.meshes, &report.table2)?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&crate::cli::eval::sorted_json(report)?)?
        );
    } else {
        print!("{}", format_table1(&report.table1));
        if !report.table2.trials.is_empty() {
            print!("{}", format_table2(&report.table2));
        }
        if let Some(p) = &report.physics {
            print!(
                "\nContact from physics on the same frames:\n{}",
                crate::cli::eval::physics::table(&p.table1)
            );
            if !p.table2.trials.is_empty() {
                print!(
                    "{}",
                    crate::cli::eval::physics::plate_table(&p.table2.regions)
                );
            }
        }
    }
    Ok(())
}

/// The study's progress on stderr.
fn print_progress(p: ContactStudyProgress<'_>) {
    let shown = |path: Option<&Path>| path.map_or_else(String::new, |p| p.display().to_string());
    match p {
        ContactStudyProgress::KnnIndex {
            frames,
            source: KnnIndexSource::Read,
            path,
        } => eprintln!(
            "eval contact: KNN index of {frames} frames from {}",
            shown(path)
        ),
        ContactStudyProgress::KnnIndex {
            frames,
            source: KnnIndexSource::BuiltAndWritten,
            path,
        } => eprintln!(
            "eval contact: built the KNN index of {frames} training frames, wrote {}",
            shown(path)
        ),
        ContactStudyProgress::Table1 {
            frames,
            knn_all,
            knn_sub,
        } => eprintln!(
            "eval contact: {frames} frames; SR-ARAP, DGCNN, KNN[All] ({knn_all} frames), \
             KNN[Sub] ({knn_sub})"
        ),
        ContactStudyProgress::Plates { scenes, trials } => {
            eprintln!("eval contact: {scenes} plate scenes × {trials} trials");
        }
        ContactStudyProgress::Physics { frames } => {
            eprintln!("eval contact: the physics estimator on {frames} frames");
        }
        _ => {}
    }
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

fn format_table2(table: &PlateTable) -> String {
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
    for t in &table.trials {
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
    for (region, r) in table.regions.in_order() {
        let _ = writeln!(
            s,
            "{region:<8} DGCNN {:.2} ± {:.2} mm   KNN[All] {:.2} ± {:.2} mm",
            r.dgcnn.mean_mm, r.dgcnn.sd_mm, r.knn_all.mean_mm, r.knn_all.sd_mm,
        );
    }
    s
}

/// Writes the kept meshes and, with plate trials, the figure of the per-region errors.
fn write_out(dir: &Path, meshes: &[(String, moe_io::PlyData)], plates: &PlateTable) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (name, ply) in meshes {
        moe_io::write_ply(&dir.join(name), ply)?;
    }
    if !plates.trials.is_empty() {
        let svg = crate::figure::region_bars(&serde_json::to_value(&plates.regions)?);
        moe_io::write_atomic(&dir.join("plate_regions.svg"), svg.as_bytes())?;
    }
    eprintln!(
        "eval contact: wrote {} meshes to {}",
        meshes.len(),
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
    crate::cli::eval::sorted_json(&arap_golden(&hand, &frames)?)
}

/// Golden contact stage: Table 1 of the shipped model on the held-out frames (no KNN rows, no
/// timings), plus the network's summed contact probability per frame on the true shape.
pub(crate) fn golden_table1() -> Result<serde_json::Value> {
    let (hand, frames, rule) = heldout_frames()?;
    let dgcnn = load_estimator(&workspace_root().join(SHIPPED_MODEL), &hand)?;
    crate::cli::eval::sorted_json(&table1_golden(&hand, &frames, &rule, &dgcnn)?)
}
