//! `moe-touch eval grasp`: grasping paper on an unknown incline (paper §6.2, Table 4). The
//! three-finger hand presses the inclined plates (0°, 30°, 45°) from a perturbed level start;
//! with MOE-Touch the pipeline's contacts give a RANSAC plane, the hand turns onto its normal
//! and presses again; without, it keeps its orientation. The simulator judges the final press
//! (`moe_lab::grasp::run_grasp_study`). Seeded trials per angle; the table beside the
//! paper's, and the estimated incline against the true one per trial.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::Real;
use moe_lab::golden::SHIPPED_MODEL;
use moe_lab::grasp::{
    GraspInclineRow, GraspOptions, GraspStudyOptions, GraspStudyReport, GraspStudySource,
    run_grasp_study, trial_point_clouds,
};
use moe_touch::pipeline::check_contact_threshold;

/// Arguments of `moe-touch eval grasp`.
#[derive(Debug, Args)]
pub(crate) struct GraspEvalArgs {
    /// Seeded trials per incline.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=100))]
    trials: u64,
    /// Contact model (per-finger, so that it runs on the three-finger hand).
    #[arg(long, value_name = "M.safetensors", default_value = SHIPPED_MODEL)]
    model: PathBuf,
    /// Seed of the camera noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The pipeline's contact estimation: `physics` (the default, as `moe-touch run`) or
    /// `dgcnn` (the paper's: SR-ARAP and the contact model).
    #[arg(long, value_enum, default_value = "physics")]
    contact: GraspMethod,
    /// Fit the plane to the simulator's own contacts instead of the pipeline's (the upper bound
    /// a perfect contact estimator reaches).
    #[arg(long, conflicts_with = "true_labels")]
    true_contacts: bool,
    /// Fit the plane to the simulator's contact vertices placed on the pipeline's estimated
    /// shape (a perfect contact classifier on the shape the markers give: separates the shape
    /// estimate's error from the contact model's).
    #[arg(long)]
    true_labels: bool,
    /// Contact probability threshold of the pipeline's contacts, in [0, 1] (default: the
    /// model card's); not with `--true-contacts` or `--true-labels`, which use none.
    #[arg(long, conflicts_with_all = ["true_contacts", "true_labels"])]
    threshold: Option<Real>,
    /// RANSAC inlier distance of the plane fit, metres (default 2 mm).
    #[arg(long)]
    plane_threshold: Option<Real>,
    /// Presses that refine the plane before the judged one (each turns onto the latest plane,
    /// presses and fits again); 0 is the paper's protocol, one fit and one reorientation.
    #[arg(long, default_value_t = GraspOptions::default().refinements as u64,
        value_parser = clap::value_parser!(u64).range(0..=5))]
    refinements: u64,
    /// Always fit the plane through the contact points, also when three or more fingers are
    /// loaded (by default their tips give the plane then).
    #[arg(long)]
    contact_plane_only: bool,
    /// The physics estimator's settings (TOML or JSON `moe_physics::PhysicsConfig`; default:
    /// the documented ones), for `--contact physics`.
    #[arg(long, value_name = "C.toml")]
    physics_config: Option<PathBuf>,
    /// SR-ARAP's settings (TOML or JSON `ShapeConfig`; its `[depth]` registers the shape to
    /// each frame's depth image), for `--contact dgcnn` and `--true-labels`.
    #[arg(long, value_name = "S.toml")]
    shape_config: Option<PathBuf>,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    json: bool,
    /// Write, per trial, the contact points of the last observed press's hold and the simulator's
    /// contact vertices of the same frames (world frame) as PLY:
    /// `DIR/incline_<deg>/trial_<k>/plane_points.ply`
    /// (vertex scalars `finger`, `probability`, `inlier`) and `true_contacts.ply` (`finger`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// The pipeline's contact estimation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum GraspMethod {
    /// The physics estimator.
    Physics,
    /// SR-ARAP and the DGCNN.
    Dgcnn,
}

/// Runs the study with the flags' errors named: `threshold` and `ransac` are checked before any
/// trial runs; with `out`, every trial's points are written there (see [`GraspEvalArgs::out`]).
fn evaluate(options: &GraspStudyOptions, out: Option<&Path>) -> Result<GraspStudyReport> {
    if let Some(t) = options.threshold {
        check_contact_threshold(t).context("--threshold")?;
        if options.source == GraspStudySource::Physics {
            anyhow::bail!("--threshold is for --contact dgcnn");
        }
    }
    options
        .grasp
        .ransac
        .validate()
        .context("--plane-threshold")?;
    let mut started = std::time::Instant::now();
    run_grasp_study(options, |row: &GraspInclineRow| -> Result<()> {
        if let Some(dir) = out {
            for trial in &row.trials_detail {
                super::write_plys(dir, &trial_point_clouds(trial))?;
            }
        }
        eprintln!("{}", row.progress(started.elapsed().as_secs_f64()));
        started = std::time::Instant::now();
        Ok(())
    })
}

pub(crate) fn run(args: &GraspEvalArgs) -> Result<()> {
    let source = if args.true_contacts {
        GraspStudySource::TrueContacts
    } else if args.true_labels {
        GraspStudySource::TrueLabels
    } else {
        match args.contact {
            GraspMethod::Physics => GraspStudySource::Physics,
            GraspMethod::Dgcnn => GraspStudySource::Pipeline,
        }
    };
    let mut grasp = GraspOptions {
        refinements: usize::try_from(args.refinements)?,
        fingertip_plane: !args.contact_plane_only,
        ..GraspOptions::default()
    };
    if let Some(m) = args.plane_threshold {
        grasp.ransac.distance_threshold_m = m;
    }
    if args.physics_config.is_some() && source != GraspStudySource::Physics {
        anyhow::bail!("--physics-config is for --contact physics");
    }
    let (physics, _) = crate::cli::load_physics_config(args.physics_config.as_deref())?;
    if args.shape_config.is_some()
        && !matches!(
            source,
            GraspStudySource::Pipeline | GraspStudySource::TrueLabels
        )
    {
        anyhow::bail!("--shape-config is for the sources that run SR-ARAP (--contact dgcnn)");
    }
    let shape = crate::cli::load_shape_config(args.shape_config.as_deref())?;
    let options = GraspStudyOptions {
        trials: args.trials,
        model: args.model.clone(),
        camera_seed: args.seed,
        source,
        threshold: args.threshold,
        grasp,
        physics,
        shape,
    };
    let report = evaluate(&options, args.out.as_deref())?;
    if args.json {
        super::print_json(&report, false)
    } else {
        crate::cli::print_text(&report.table());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    /// A contact threshold outside [0, 1] or a plane threshold that is not a positive distance
    /// is refused before any trial runs, and a threshold where no model's contacts are used, or
    /// more than five refinements, are refused when parsed.
    #[test]
    fn bad_thresholds_are_refused_before_any_trial() {
        for t in [-0.5, 1.5, Real::NAN] {
            let options = GraspStudyOptions {
                threshold: Some(t),
                ..moe_lab::golden::grasp_fixture_options()
            };
            let e = format!("{:#}", evaluate(&options, None).unwrap_err());
            assert!(e.contains("--threshold") && e.contains("[0, 1]"), "{e}");
        }
        let parse = |args: &[&str]| {
            crate::Cli::try_parse_from(["xtask", "eval", "grasp"].iter().chain(args))
        };
        assert!(parse(&["--threshold", "0.5"]).is_ok());
        assert!(parse(&["--refinements", "0", "--contact-plane-only"]).is_ok());
        assert_eq!(
            parse(&["--refinements", "6"]).unwrap_err().kind(),
            clap::error::ErrorKind::ValueValidation
        );
        for source in ["--true-labels", "--true-contacts"] {
            let err = parse(&[source, "--threshold", "0.5"]).unwrap_err();
            assert_eq!(
                err.kind(),
                clap::error::ErrorKind::ArgumentConflict,
                "{source}"
            );
        }
        for m in [0.0, -0.001, Real::NAN] {
            let mut options = moe_lab::golden::grasp_fixture_options();
            options.grasp.ransac.distance_threshold_m = m;
            let e = format!("{:#}", evaluate(&options, None).unwrap_err());
            assert!(e.contains("--plane-threshold"), "{e}");
        }
    }
}
