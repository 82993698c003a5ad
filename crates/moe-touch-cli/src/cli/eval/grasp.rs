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
use moe_io::PlyData;
use moe_lab::grasp::{
    GraspInclineRow, GraspOptions, GraspStudyOptions, GraspStudyReport, GraspStudySource,
    GraspTrial, PlaneSource, PressOutcome, run_grasp_study,
};
use moe_touch::pipeline::check_contact_threshold;
use serde_json::Value;

use crate::cli::eval::contact::SHIPPED_MODEL;
use crate::golden::workspace_root;

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

/// Writes one trial's points under `dir` (see [`GraspEvalArgs::out`]).
fn write_trial(dir: &Path, trial: &GraspTrial) -> Result<()> {
    let dir = dir
        .join(format!("incline_{}", trial.incline_deg))
        .join(format!("trial_{}", trial.trial));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let cloud = |points: &[moe_geom::ContactPoint]| {
        let xyz: Vec<moe_geom::Point3> = points.iter().map(|c| c.point).collect();
        PlyData::from_points(&xyz).with_scalar("finger", points.iter().map(|c| c.finger as Real))
    };
    let mut inlier = vec![0.0; trial.plane_points.len()];
    for &i in &trial.inlier_indices {
        inlier[i] = 1.0;
    }
    let plane = cloud(&trial.plane_points)
        .with_scalar(
            "probability",
            trial.plane_points.iter().map(|c| c.probability),
        )
        .with_scalar("inlier", inlier);
    moe_io::write_ply(&dir.join("plane_points.ply"), &plane)?;
    moe_io::write_ply(&dir.join("true_contacts.ply"), &cloud(&trial.true_points))?;
    Ok(())
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
                write_trial(dir, trial)?;
            }
        }
        eprintln!(
            "eval grasp: {}°: {} trials in {:.1} s",
            row.incline_deg,
            row.trials,
            started.elapsed().as_secs_f64()
        );
        started = std::time::Instant::now();
        Ok(())
    })
}

/// The study's tables: successes per incline beside the paper's, then every trial's planes.
fn print_table(r: &GraspStudyReport) {
    println!("plane from: {}", r.contacts.name());
    println!(
        "incline   with MOE-Touch  (paper)   without  (paper)   incline error max   fits failed"
    );
    for row in &r.rows {
        println!(
            "{:?}°    {} / {}      ({} / 5)    {} / {} ({} / 5)    {:>8}          {}",
            row.incline_deg,
            row.success_with,
            row.trials,
            row.paper_with_of_5,
            row.success_without,
            row.trials,
            row.paper_without_of_5,
            row.max_incline_error_deg
                .map_or("—".to_owned(), |e| format!("{e:.2}°")),
            row.fits_failed,
        );
    }
    println!(
        "\nper trial: true incline → estimated incline (per fit: plane through, error of the normal; \
         fingers touching at each press)"
    );
    let touching = |p: &PressOutcome| {
        p.contact_vertices
            .iter()
            .filter(|&&n| n >= r.options.min_contact_vertices)
            .count()
    };
    for row in &r.rows {
        for t in &row.trials_detail {
            let fits: Vec<String> = t
                .fits
                .iter()
                .map(|f| {
                    format!(
                        "{} {}{}",
                        f.source.map_or("no fit", PlaneSource::name),
                        f.normal_error_deg
                            .map_or("—".to_owned(), |e| format!("{e:.1}°")),
                        if f.press_depth_m > r.options.press_m + 1e-9 {
                            format!(" (pressed {:.0} mm)", f.press_depth_m * 1e3)
                        } else {
                            String::new()
                        }
                    )
                })
                .collect();
            let presses: Vec<String> = std::iter::once(&t.first_press)
                .chain(t.fits.iter().filter_map(|f| f.press.as_ref()))
                .map(|p| touching(p).to_string())
                .collect();
            println!(
                "  {:?}° trial {}: {:>7}  ({}; presses {}) {}",
                t.incline_deg,
                t.trial,
                t.estimated_incline_deg
                    .map_or("no fit".to_owned(), |e| format!("{e:.2}°")),
                fits.join(", "),
                presses.join(" → "),
                if t.success_with { "success" } else { "failed" }
            );
        }
    }
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
    let options = GraspStudyOptions {
        trials: args.trials,
        model: args.model.clone(),
        camera_seed: args.seed,
        source,
        threshold: args.threshold,
        grasp,
    };
    let report = evaluate(&options, args.out.as_deref())?;
    if args.json {
        // Keys sorted, as the report has always been printed.
        println!("{}", serde_json::to_value(&report)?);
    } else {
        print_table(&report);
    }
    Ok(())
}

/// The study of the golden fixture: one trial per incline, the paper's pipeline, defaults.
fn fixture_options() -> GraspStudyOptions {
    GraspStudyOptions {
        trials: 1,
        model: workspace_root().join(SHIPPED_MODEL),
        camera_seed: 0,
        source: GraspStudySource::Pipeline,
        threshold: None,
        grasp: GraspOptions::default(),
    }
}

/// The golden content of one trial per incline, rounded to 1e-3.
pub(crate) fn grasp_fixture() -> Result<Value> {
    let mut v = serde_json::to_value(evaluate(&fixture_options(), None)?)?;
    crate::cli::eval::patting::round3(&mut v);
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use moe_geom::{ContactPoint, Point3};

    /// `--out` writes a trial's plane points with their finger, probability and inlier flag,
    /// and the simulator's contacts, and they read back as written.
    #[test]
    fn a_trials_points_are_written_and_read_back() {
        let point = |finger, x: Real, probability| ContactPoint {
            finger,
            vertex: 3,
            point: Point3::new(x, 0.01, -0.02),
            probability,
        };
        let press = PressOutcome {
            contact_vertices: vec![0, 4, 0],
            axis_error_deg: 30.0,
            success: false,
        };
        let trial = GraspTrial {
            incline_deg: 30.0,
            trial: 2,
            first_press: press.clone(),
            fits: Vec::new(),
            estimated_incline_deg: None,
            normal_error_deg: None,
            final_press: None,
            success_with: false,
            success_without: false,
            plane_points: vec![
                point(0, 0.0, 0.7),
                point(1, 0.001, 0.9),
                point(2, 0.002, 0.8),
            ],
            inlier_indices: vec![0, 2],
            true_points: vec![point(1, 0.005, 1.0)],
        };
        let dir = std::env::temp_dir().join(format!("xtask-grasp-out-{}", std::process::id()));
        write_trial(&dir, &trial).unwrap();
        let base = dir.join("incline_30").join("trial_2");
        let plane = moe_io::read_ply(&base.join("plane_points.ply")).unwrap();
        assert_eq!(plane.points.len(), 3);
        assert!((plane.points[1].x - 0.001).abs() < 1e-9);
        assert_eq!(plane.scalar("finger").unwrap(), &[0.0, 1.0, 2.0]);
        assert_eq!(plane.scalar("probability").unwrap(), &[0.7, 0.9, 0.8]);
        assert_eq!(plane.scalar("inlier").unwrap(), &[1.0, 0.0, 1.0]);
        let truth = moe_io::read_ply(&base.join("true_contacts.ply")).unwrap();
        assert_eq!(truth.points.len(), 1);
        assert_eq!(truth.scalar("finger").unwrap(), &[1.0]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A contact threshold outside [0, 1] or a plane threshold that is not a positive distance
    /// is refused before any trial runs, and a threshold where no model's contacts are used, or
    /// more than five refinements, are refused when parsed.
    #[test]
    fn bad_thresholds_are_refused_before_any_trial() {
        for t in [-0.5, 1.5, Real::NAN] {
            let options = GraspStudyOptions {
                threshold: Some(t),
                ..fixture_options()
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
            let mut options = fixture_options();
            options.grasp.ransac.distance_threshold_m = m;
            let e = format!("{:#}", evaluate(&options, None).unwrap_err());
            assert!(e.contains("--plane-threshold"), "{e}");
        }
    }
}
