//! `moe-touch eval patting`: the paper's patting applications end to end (§5.3, §6.1). The
//! two-finger hand pats a head (30 poses) and a long arm (15 poses) in the simulator; every
//! pat's deepest press is rendered by the wrist camera with its noise and run through the
//! pipeline (detected markers, SR-ARAP, a contact estimator) to contact points in the world;
//! the contact points of all pats feed the surface reconstruction with a task prior (another
//! body of the same family).
//!
//! Reported per body, as mean ± sd over several seeded truth/prior pairs:
//! - Table 2: UCD from the estimated contact points to the true surface, for the DGCNN and for
//!   `KNN[All]` (both on the same SR-ARAP shapes; the KNN gives the contact vertices of the
//!   training frame whose markers are nearest), and for the simulator's own contact vertices;
//! - Table 3: UCD from each reconstruction to the true surface (GP with the prior, GP with a
//!   sphere, the non-probabilistic baseline, the prior alone), from the DGCNN's contacts and,
//!   as the upper bound, from the true contacts.
//!
//! The study is `moe_lab::patting::run_patting_study`; this command parses the flags, loads the
//! `KNN[All]` index and prints the report.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use moe_contact::KnnIndex;
use moe_geom::Real;
use moe_gpis::HyperBounds;
use moe_gpis::bench_scene::SceneKind;
use moe_lab::contact_eval::{heldout_knn_index, read_knn_index};
use moe_lab::golden::SHIPPED_MODEL;
use moe_lab::patting::{
    DEFAULT_ESTIMATED_NOISE_FLOOR_M, DEFAULT_PRIOR_GATE_M, PattingSize, PattingStudyOptions,
    PattingStudyReport, pair_progress, patting_hand, run_patting_study,
};

use crate::cli::eval::Size;

/// A body to pat.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Body {
    /// The head of §5.3 (30 pats).
    Head,
    /// The arm under a gown of §6.1 (15 pats).
    Arm,
}

impl Body {
    fn kind(self) -> SceneKind {
        match self {
            Self::Head => SceneKind::Head,
            Self::Arm => SceneKind::Arm,
        }
    }
}

/// Arguments of `moe-touch eval patting`.
#[derive(Debug, Args)]
pub(crate) struct PattingEvalArgs {
    /// Size: small = one pair, 3 pats per body, 24³ grid, level-4 priors (the golden-checked
    /// configuration); full = every pat, 64³ grid, level-5 priors.
    #[arg(long, value_enum, default_value = "full")]
    size: Size,
    /// Truth/prior pairs per body (pair k pats the body of seed `S + 10k` with the prior of
    /// seed `S + 10k + 1`); default 3 at full size, 1 at small size.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=100))]
    pairs: Option<u64>,
    /// Only these bodies (repeatable; default both).
    #[arg(long = "body", value_enum)]
    bodies: Vec<Body>,
    /// Contact model (with its card beside it).
    #[arg(long, value_name = "M.safetensors", default_value = SHIPPED_MODEL)]
    model: PathBuf,
    /// `KNN[All]` index (as `moe-touch eval contact --knn-index` writes it from a data set's
    /// training frames). Without it the index is built from the committed held-out set, a
    /// small stand-in for the comparison at small size.
    #[arg(long, value_name = "FILE")]
    knn_index: Option<PathBuf>,
    /// Seed of the camera noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Write the first pair of each body to `DIR/<body>/`: the truth, the prior, the contact
    /// points of each estimator, and every surface (the GP's with its posterior variance).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    json: bool,
    /// The GP with the prior and the non-probabilistic baseline leave out contacts farther than
    /// this from the prior (metres; 0 keeps every contact): false contacts would otherwise
    /// raise bubbles of surface where nothing is.
    #[arg(long, value_name = "M", default_value_t = DEFAULT_PRIOR_GATE_M)]
    prior_gate: Real,
    /// Lower bound of the GP's noise standard deviation on the estimated contacts (metres; 0
    /// leaves the fit's own bound): how far an estimated contact may be from the surface
    /// without the GP taking it for shape. The true contacts keep the fit's own bound.
    #[arg(long, value_name = "M", default_value_t = DEFAULT_ESTIMATED_NOISE_FLOOR_M)]
    estimated_noise_floor: Real,
    /// The physics estimator's settings (TOML or JSON `moe_physics::PhysicsConfig`; default:
    /// the documented ones).
    #[arg(long, value_name = "C.toml")]
    physics_config: Option<PathBuf>,
    /// SR-ARAP's settings of the paper's pipeline rows (TOML or JSON `ShapeConfig`; its
    /// `[depth]` registers the shape to each frame's depth image; default: the paper's).
    #[arg(long, value_name = "S.toml")]
    shape_config: Option<PathBuf>,
}

/// The `KNN[All]` index: from a file (of the patting hand, the two-finger preset), or built
/// from the committed held-out set (built in).
fn knn_index(path: Option<&Path>) -> Result<KnnIndex> {
    Ok(match path {
        Some(path) => read_knn_index(path, &patting_hand()?.signature().vertices_per_finger)?,
        None => heldout_knn_index()?,
    })
}

/// The study's options from the arguments.
fn options(
    args: &PattingEvalArgs,
    physics: moe_physics::PhysicsConfig,
    shape: moe_arap::ShapeConfig,
) -> PattingStudyOptions {
    PattingStudyOptions {
        size: match args.size {
            Size::Small => PattingSize::Small,
            Size::Full => PattingSize::Full,
        },
        pairs: args.pairs,
        bodies: args.bodies.iter().map(|b| b.kind()).collect(),
        model: args.model.clone(),
        camera_seed: args.seed,
        out: args.out.clone(),
        prior_gate_m: args.prior_gate,
        estimated_noise_floor_m: args.estimated_noise_floor,
        physics,
        shape,
    }
}

/// Every body's pairs and summary (the flags checked before any work).
fn evaluate(args: &PattingEvalArgs) -> Result<PattingStudyReport> {
    HyperBounds::default()
        .with_noise_floor(args.estimated_noise_floor)
        .context("--estimated-noise-floor")?;
    if !(args.prior_gate.is_finite() && args.prior_gate >= 0.0) {
        anyhow::bail!(
            "--prior-gate {} must be a distance in metres (0 for none)",
            args.prior_gate
        );
    }
    let (physics, _) = crate::cli::load_physics_config(args.physics_config.as_deref())?;
    let shape = crate::cli::load_shape_config(args.shape_config.as_deref())?;
    let knn = knn_index(args.knn_index.as_deref())?;
    let mut started = std::time::Instant::now();
    run_patting_study(
        &options(args, physics, shape),
        &knn,
        |body, k, pair| -> Result<()> {
            let secs = started.elapsed().as_secs_f64();
            eprintln!("{}", pair_progress(body, k, pair, secs));
            started = std::time::Instant::now();
            Ok(())
        },
    )
}

pub(crate) fn run(args: &PattingEvalArgs) -> Result<()> {
    let report = evaluate(args)?;
    if args.json {
        super::print_json(&report, false)
    } else {
        crate::cli::print_text(&report.table());
        Ok(())
    }
}
