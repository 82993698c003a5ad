//! The grasp study (paper §6.2, Table 4): seeded trials on each of the paper's inclines, with
//! the plane from one contact source, tallied beside the paper's figures.

use std::fmt::Write as _;
use std::path::PathBuf;

use moe_geom::{ContactPoint, FingerParams, HandModel, HandPreset, Point3, Real};
use moe_io::PlyData;
use moe_touch::pipeline::{check_contact_threshold, load_contact_model};
use serde::Serialize;

use super::{GraspContacts, GraspOptions, GraspTrial, PlaneSource, PressOutcome, run_grasp_trial};
use crate::LabError;

/// The paper's inclines, degrees, and its Table 4: successes of 5 with and without MOE-Touch.
pub const PAPER_INCLINES: [(Real, usize, usize); 3] = [(0.0, 5, 5), (30.0, 5, 1), (45.0, 4, 0)];

/// Where the study's planes come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum GraspStudySource {
    /// The pipeline's contacts with the physics estimator (the default of `moe-touch run`).
    Physics,
    /// The pipeline's contacts with SR-ARAP and the DGCNN (the paper's).
    Pipeline,
    /// The simulator's contact labels on the pipeline's estimated shape (SR-ARAP): a perfect
    /// contact classifier on the shape the markers give.
    TrueLabels,
    /// The simulator's own contact vertices (the upper bound a perfect estimator reaches).
    TrueContacts,
}

impl GraspStudySource {
    /// Its name, as serialised: `physics`, `pipeline`, `true-labels`, `true-contacts`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Physics => "physics",
            Self::Pipeline => "pipeline",
            Self::TrueLabels => "true-labels",
            Self::TrueContacts => "true-contacts",
        }
    }
}

/// Settings of the grasp study.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspStudyOptions {
    /// Seeded trials per incline (trial `k` is seeded by `k` and the incline).
    pub trials: u64,
    /// The contact model (per-finger, so that it runs on the three-finger hand), with its card
    /// beside it. Loaded whatever the source: its threshold is the default of
    /// [`GraspStudySource::Pipeline`].
    pub model: PathBuf,
    /// Seed of the wrist camera's noise.
    pub camera_seed: u64,
    /// Where the planes come from.
    pub source: GraspStudySource,
    /// Contact probability threshold of [`GraspStudySource::Pipeline`]'s contacts (default:
    /// the model card's); the physics estimator uses its own
    /// ([`moe_physics::CONTACT_THRESHOLD`]).
    pub threshold: Option<Real>,
    /// The trials' settings.
    pub grasp: GraspOptions,
    /// The physics estimator's settings, for [`GraspStudySource::Physics`].
    pub physics: moe_physics::PhysicsConfig,
    /// SR-ARAP's settings, for the sources that run the paper's pipeline.
    pub shape: moe_arap::ShapeConfig,
}

/// The trials on one incline.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GraspInclineRow {
    /// The plate's incline, degrees.
    pub incline_deg: Real,
    /// Trials run to the end (the counts below are of these).
    pub trials: u64,
    /// Trials that could not be run (a simulation that failed, a camera that could not be
    /// made), named with why; the others are counted without them.
    pub skipped_trials: Vec<SkippedTrial>,
    /// Trials whose judged press succeeded (with MOE-Touch).
    pub success_with: usize,
    /// Trials whose first press succeeded (without MOE-Touch).
    pub success_without: usize,
    /// The paper's successes of 5 with MOE-Touch.
    pub paper_with_of_5: usize,
    /// The paper's successes of 5 without.
    pub paper_without_of_5: usize,
    /// The largest difference between the estimated and the true incline over the trials
    /// with a plane, degrees.
    pub max_incline_error_deg: Option<Real>,
    /// Trials in which some plane could not be fitted.
    pub fits_failed: usize,
    /// Trials without a judged press (the first fit failed, or its press could not be made).
    pub without_judged_press: usize,
    /// Every trial.
    pub trials_detail: Vec<GraspTrial>,
}

impl GraspInclineRow {
    /// The progress line of this finished incline (which took `secs`), as `eval grasp`
    /// reports it.
    pub fn progress(&self, secs: f64) -> String {
        format!(
            "eval grasp: {}°: {} trials in {secs:.1} s",
            self.incline_deg, self.trials
        )
    }
}

/// A grasp trial the study left out because it could not be run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SkippedTrial {
    /// Its number (seed).
    pub trial: u64,
    /// Why.
    pub error: String,
}

/// The grasp study's report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GraspStudyReport {
    /// The trials' settings.
    pub options: GraspOptions,
    /// The contact threshold used (the physics estimator's, the given one or the model
    /// card's).
    pub threshold: Real,
    /// Where the planes came from.
    pub contacts: GraspStudySource,
    /// One row per incline of [`PAPER_INCLINES`], in order.
    pub rows: Vec<GraspInclineRow>,
}

/// Runs the grasp study: [`GraspStudyOptions::trials`] trials ([`run_grasp_trial`]) on each
/// incline of [`PAPER_INCLINES`] with the three-finger hand, calling `after_incline` with each
/// incline's row as it is done (to report progress or write its trials; its error ends the
/// study).
///
/// A trial that cannot be run ([`run_grasp_trial`]'s error) is named among its incline's
/// [`GraspInclineRow::skipped_trials`] and the study goes on.
///
/// # Errors
/// A threshold outside [0, 1], an invalid RANSAC configuration, a model that cannot be loaded
/// for the three-finger hand, every trial failing (the first one's error), or
/// `after_incline`'s.
pub fn run_grasp_study<E: From<LabError>>(
    options: &GraspStudyOptions,
    mut after_incline: impl FnMut(&GraspInclineRow) -> Result<(), E>,
) -> Result<GraspStudyReport, E> {
    if let Some(t) = options.threshold {
        check_contact_threshold(t).map_err(LabError::from)?;
    }
    options.grasp.ransac.validate().map_err(LabError::from)?;
    let hand = HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default())
        .map_err(LabError::from)?;
    let estimator = load_contact_model(&options.model, &hand).map_err(LabError::from)?;
    let source = options.source;
    let threshold = match source {
        GraspStudySource::Physics => moe_physics::CONTACT_THRESHOLD,
        _ => options.threshold.unwrap_or_else(|| estimator.threshold()),
    };
    let trials = options.trials;
    let mut rows = Vec::new();
    let mut first_error = None;
    for (incline, paper_with, paper_without) in PAPER_INCLINES {
        let each = crate::run_each(0..trials, |k| {
            let contacts = match source {
                GraspStudySource::Physics => GraspContacts::Physics {
                    material: moe_physics::HandMaterial::default(),
                    config: options.physics.clone(),
                },
                GraspStudySource::Pipeline => GraspContacts::Pipeline {
                    contact: &estimator,
                    threshold,
                    shape: options.shape.clone(),
                },
                GraspStudySource::TrueLabels => GraspContacts::SimulatorLabelsOnEstimatedShape {
                    contact: &estimator,
                    shape: options.shape.clone(),
                },
                GraspStudySource::TrueContacts => GraspContacts::Simulator,
            };
            run_grasp_trial(
                &hand,
                contacts,
                incline,
                k,
                options.camera_seed,
                &options.grasp,
            )
        });
        if let Some(e) = each.first_error {
            first_error.get_or_insert(e);
        }
        let results: Vec<GraspTrial> = each.ran;
        let skipped_trials = each
            .failed
            .into_iter()
            .map(|(trial, error)| SkippedTrial { trial, error })
            .collect();
        let max_incline_error_deg = results
            .iter()
            .filter_map(|r| r.estimated_incline_deg.map(|e| (e - incline).abs()))
            .fold(None, |m: Option<Real>, e| Some(m.map_or(e, |m| m.max(e))));
        let row = GraspInclineRow {
            incline_deg: incline,
            trials: results.len() as u64,
            skipped_trials,
            success_with: results.iter().filter(|r| r.success_with).count(),
            success_without: results.iter().filter(|r| r.success_without).count(),
            paper_with_of_5: paper_with,
            paper_without_of_5: paper_without,
            max_incline_error_deg,
            fits_failed: results
                .iter()
                .filter(|r| r.fits.iter().any(|f| f.source.is_none()))
                .count(),
            without_judged_press: results.iter().filter(|r| r.final_press.is_none()).count(),
            trials_detail: results,
        };
        after_incline(&row)?;
        rows.push(row);
    }
    if let Some(e) = first_error
        && rows.iter().all(|r| r.trials == 0)
    {
        return Err(e.into());
    }
    Ok(GraspStudyReport {
        options: options.grasp,
        threshold,
        contacts: source,
        rows,
    })
}

impl GraspStudyReport {
    /// The report as the tables `moe-touch eval grasp` prints: successes per incline beside
    /// the paper's, then every trial's planes (what each fit went through, the error of its
    /// normal, the fingers touching at each press).
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "plane from: {}", self.contacts.name());
        let _ = writeln!(
            s,
            "incline   with MOE-Touch  (paper)   without  (paper)   incline error max   fits failed"
        );
        for row in &self.rows {
            let _ = writeln!(
                s,
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
        for row in &self.rows {
            for skipped in &row.skipped_trials {
                let _ = writeln!(
                    s,
                    "skipped: {:?}° trial {}, it could not be run: {}",
                    row.incline_deg, skipped.trial, skipped.error
                );
            }
        }
        let _ = writeln!(
            s,
            "\nper trial: true incline → estimated incline (per fit: plane through, error of the normal; \
             fingers touching at each press)"
        );
        let touching = |p: &PressOutcome| {
            p.contact_vertices
                .iter()
                .filter(|&&n| n >= self.options.min_contact_vertices)
                .count()
        };
        for row in &self.rows {
            for t in &row.trials_detail {
                let fits: Vec<String> = t
                    .fits
                    .iter()
                    .map(|f| {
                        format!(
                            "{} {}{}{}",
                            f.source.map_or("no fit", PlaneSource::name),
                            f.normal_error_deg
                                .map_or("—".to_owned(), |e| format!("{e:.1}°")),
                            if f.press_depth_m > self.options.press_m + 1e-9 {
                                format!(" (pressed {:.0} mm)", f.press_depth_m * 1e3)
                            } else {
                                String::new()
                            },
                            match f.failed_frames.len() {
                                0 => String::new(),
                                n => format!(" ({n} hold frames failed)"),
                            }
                        )
                    })
                    .collect();
                let presses: Vec<String> = std::iter::once(&t.first_press)
                    .chain(t.fits.iter().filter_map(|f| f.press.as_ref()))
                    .map(|p| touching(p).to_string())
                    .collect();
                let _ = writeln!(
                    s,
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
        s
    }
}

/// A trial's points to look at, each named by its path under an output directory:
/// `incline_<deg>/trial_<k>/plane_points.ply`, the contact points of the last observed press's
/// hold (vertex scalars `finger`, `probability` and `inlier`, 1 for the plane fit's RANSAC
/// inliers), and `true_contacts.ply`, the simulator's contact vertices of the same frames
/// (`finger`); world frame.
pub fn trial_point_clouds(trial: &GraspTrial) -> Vec<(PathBuf, PlyData)> {
    let dir = PathBuf::from(format!("incline_{}", trial.incline_deg))
        .join(format!("trial_{}", trial.trial));
    let cloud = |points: &[ContactPoint]| {
        let xyz: Vec<Point3> = points.iter().map(|c| c.point).collect();
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
    vec![
        (dir.join("plane_points.ply"), plane),
        (dir.join("true_contacts.ply"), cloud(&trial.true_points)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The names the tables print are the names the reports serialise.
    #[test]
    fn names_are_the_serialised_names() {
        for source in [
            GraspStudySource::Physics,
            GraspStudySource::Pipeline,
            GraspStudySource::TrueLabels,
            GraspStudySource::TrueContacts,
        ] {
            assert_eq!(serde_json::json!(source), source.name());
        }
        for source in [
            PlaneSource::ContactPoints,
            PlaneSource::LoadedFingertips,
            PlaneSource::TwoFingertipsAndAxis,
            PlaneSource::LoadedFingersAxis,
        ] {
            assert_eq!(serde_json::json!(source), source.name());
        }
    }

    /// A trial's plane points carry their finger, probability and inlier flag, and the
    /// simulator's contacts their finger, under the trial's directory.
    #[test]
    fn a_trials_points_carry_finger_probability_and_inlier() {
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
            first_press: press,
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
        let clouds = trial_point_clouds(&trial);
        let base = std::path::Path::new("incline_30").join("trial_2");
        let [(plane_path, plane), (truth_path, truth)] = clouds.as_slice() else {
            panic!("{} clouds", clouds.len());
        };
        assert_eq!(plane_path, &base.join("plane_points.ply"));
        assert_eq!(truth_path, &base.join("true_contacts.ply"));
        assert_eq!(plane.points.len(), 3);
        assert!((plane.points[1].x - 0.001).abs() < 1e-9);
        assert_eq!(plane.scalar("finger").unwrap(), &[0.0, 1.0, 2.0]);
        assert_eq!(plane.scalar("probability").unwrap(), &[0.7, 0.9, 0.8]);
        assert_eq!(plane.scalar("inlier").unwrap(), &[1.0, 0.0, 1.0]);
        assert_eq!(truth.points.len(), 1);
        assert_eq!(truth.scalar("finger").unwrap(), &[1.0]);
    }
}
