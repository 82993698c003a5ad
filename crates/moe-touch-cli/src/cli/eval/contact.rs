//! `moe-touch eval contact`: the paper's simulation study of contact estimation (Tables 1–2)
//! on held-out trajectories of a data set — a thin command over `moe_lab::contact_eval`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use moe_io::DatasetReader;
use moe_lab::contact_eval::{
    ContactStudyOptions, ContactStudyPhysics, PlateTable, contact_study, select_heldout_frames,
    write_heldout_set,
};
use moe_lab::golden::HELDOUT_DIR;

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
    let study = contact_study(&options, &mut |p| {
        if let Some(line) = p.message() {
            eprintln!("eval contact: {line}");
        }
    })?;
    if let Some(dir) = &args.out {
        write_out(dir, &study.meshes, &study.report.table2)?;
    }
    if args.json {
        super::print_json(&study.report, true)
    } else {
        crate::cli::print_text(&study.report.tables());
        Ok(())
    }
}

/// Writes the kept meshes and, with plate trials, the figure of the per-region errors.
fn write_out(dir: &Path, meshes: &[(String, moe_io::PlyData)], plates: &PlateTable) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (name, ply) in meshes {
        moe_io::write_ply(&dir.join(name), ply)?;
    }
    if !plates.trials.is_empty() {
        let svg = moe_lab::figure::region_bars(&plates.regions);
        moe_io::write_atomic(&dir.join("plate_regions.svg"), svg.as_bytes())?;
    }
    eprintln!(
        "eval contact: wrote {} meshes to {}",
        meshes.len(),
        dir.display()
    );
    Ok(())
}

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
    let frames = select_heldout_frames(&reader, args.trajectories, args.frames)?;
    if frames.is_empty() {
        bail!("{}: no test trajectory with contact", args.data.display());
    }
    write_heldout_set(&reader, &frames, &args.out)?;
    eprintln!(
        "heldout-shard: {} frames of {} trajectories to {}",
        frames.len(),
        args.trajectories,
        args.out.display()
    );
    Ok(())
}
