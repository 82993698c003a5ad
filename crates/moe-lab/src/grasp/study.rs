//! The grasp study (paper §6.2, Table 4): seeded trials on each of the paper's inclines, with
//! the plane from one contact source, tallied beside the paper's figures.

use std::path::PathBuf;

use moe_geom::{FingerParams, HandModel, HandPreset, Real};
use moe_touch::pipeline::{check_contact_threshold, load_contact_model};
use serde::Serialize;

use super::{GraspContacts, GraspOptions, GraspTrial, run_grasp_trial};
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
}

/// The trials on one incline.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GraspInclineRow {
    /// The plate's incline, degrees.
    pub incline_deg: Real,
    /// Trials run.
    pub trials: u64,
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
/// # Errors
/// A threshold outside [0, 1], an invalid RANSAC configuration, a model that cannot be loaded
/// for the three-finger hand, a trial's error ([`run_grasp_trial`]), or `after_incline`'s.
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
    for (incline, paper_with, paper_without) in PAPER_INCLINES {
        let results: Vec<GraspTrial> = (0..trials)
            .map(|k| {
                let contacts = match source {
                    GraspStudySource::Physics => GraspContacts::Physics {
                        material: moe_physics::HandMaterial::default(),
                        config: moe_physics::PhysicsConfig::default(),
                    },
                    GraspStudySource::Pipeline => GraspContacts::Pipeline {
                        contact: &estimator,
                        threshold,
                    },
                    GraspStudySource::TrueLabels => {
                        GraspContacts::SimulatorLabelsOnEstimatedShape {
                            contact: &estimator,
                        }
                    }
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
            })
            .collect::<Result<_, _>>()?;
        let max_incline_error_deg = results
            .iter()
            .filter_map(|r| r.estimated_incline_deg.map(|e| (e - incline).abs()))
            .fold(None, |m: Option<Real>, e| Some(m.map_or(e, |m| m.max(e))));
        let row = GraspInclineRow {
            incline_deg: incline,
            trials,
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
    Ok(GraspStudyReport {
        options: options.grasp,
        threshold,
        contacts: source,
        rows,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grasp::PlaneSource;

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
}
