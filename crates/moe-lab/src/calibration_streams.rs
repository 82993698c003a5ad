//! The contact-free streams a material calibration fits (`moe_physics::calibrate`): chosen from
//! a recorded episode (frames its ground truth marks in contact left out, each run of
//! contact-free frames between them one stream) or from a data set (each trajectory's frames
//! before its first contact).

use moe_geom::{HandKeypoints, HandModel, OwnedObservation, Real};
use moe_io::{DatasetReader, SplitFractions};
use moe_physics::{CalibrationReport, HandMaterial};
use moe_record::Episode;
use moe_touch::perception::MarkerDetector;
use serde::Serialize;

use crate::datagen::dataset_params;
use crate::error::LabError;
use crate::markers::has_ground_truth;

/// Contact-free streams with what was read to choose them.
#[derive(Debug, Clone, Default)]
pub struct ContactFreeStreams {
    /// The streams, each in time order.
    pub streams: Vec<Vec<OwnedObservation>>,
    /// Frames read.
    pub frames_read: usize,
    /// Frames left out because something touched the hand.
    pub frames_with_contact: usize,
    /// Trajectories of a data set used (`None` for an episode).
    pub trajectories: Option<usize>,
}

impl ContactFreeStreams {
    /// The frames of every stream.
    pub fn frames(&self) -> usize {
        self.streams.iter().map(Vec::len).sum()
    }
}

/// Whether every frame of `episode` has its ground truth (a simulated episode; none of a real
/// recording, whose frames are then all taken as contact-free).
pub fn episode_has_ground_truth(episode: &Episode) -> bool {
    !episode.frames.is_empty()
        && episode
            .frames
            .iter()
            .all(|f| has_ground_truth(&episode.info, f))
}

/// Whether every frame of `episode` has its camera images.
pub fn episode_has_images(episode: &Episode) -> bool {
    !episode.frames.is_empty()
        && episode
            .frames
            .iter()
            .all(|f| !f.color_rgb8.is_empty() && !f.depth_m.is_empty())
}

/// The contact-free streams of an episode: every frame's markers (detected by `detector` when
/// given, which then sees every frame, contact or not, so that its marker tracks go on; the
/// ground truth otherwise), pulls, pose and time; frames with true contact left out.
///
/// # Errors
/// A frame the detector cannot read (naming its time).
pub fn episode_contact_free_streams(
    episode: &Episode,
    mut detector: Option<&mut MarkerDetector>,
) -> Result<ContactFreeStreams, LabError> {
    let truth = episode_has_ground_truth(episode);
    let mut streams = Vec::new();
    let mut current = Vec::new();
    let mut frames_with_contact = 0;
    for frame in &episode.frames {
        let keypoints = match detector.as_deref_mut() {
            Some(d) => {
                d.detect(&frame.color_rgb8, &frame.depth_m)
                    .map_err(|e| LabError::InvalidEvaluation {
                        reason: format!(
                            "frame at {} ns: {}",
                            frame.time_ns,
                            moe_touch::error::one_line(&e)
                        ),
                    })?
                    .keypoints
            }
            None => HandKeypoints {
                fingers: frame
                    .markers_in_hand
                    .iter()
                    .map(|m| m.iter().copied().map(Some).collect())
                    .collect(),
            },
        };
        if truth && frame.contact_vertices.iter().any(|c| !c.is_empty()) {
            frames_with_contact += 1;
            if !current.is_empty() {
                streams.push(std::mem::take(&mut current));
            }
            continue;
        }
        current.push(
            frame
                .observation()
                .to_owned_observation()
                .with_keypoints(keypoints),
        );
    }
    if !current.is_empty() {
        streams.push(current);
    }
    Ok(ContactFreeStreams {
        streams,
        frames_read: episode.frames.len(),
        frames_with_contact,
        trajectories: None,
    })
}

/// The contact-free prefix of each trajectory of a data set (its frames before the first with
/// a contact label or a contact force), with its true markers and the frame times of the
/// card's simulator settings; at most `max_trajectories` trajectories (the first ones).
///
/// # Errors
/// An unreadable data set or card, or a frame that does not fit its layout.
pub fn dataset_contact_free_streams(
    reader: &DatasetReader,
    max_trajectories: Option<u64>,
) -> Result<ContactFreeStreams, LabError> {
    let card = reader.card();
    let params = dataset_params(card)?;
    let frame_secs = params.dt_secs * params.save_every_steps as Real;
    let layout = card.layout.clone();
    let mut streams: Vec<Vec<OwnedObservation>> = Vec::new();
    let mut current_id = None;
    let mut touched = false;
    let (mut frames_read, mut frames_with_contact, mut trajectories) = (0, 0, 0usize);
    for f in reader.frames(None, SplitFractions::default()) {
        let f = f?;
        if current_id != Some(f.trajectory_id) {
            if max_trajectories.is_some_and(|m| trajectories as u64 >= m) {
                break;
            }
            current_id = Some(f.trajectory_id);
            trajectories += 1;
            touched = false;
            streams.push(Vec::new());
        }
        frames_read += 1;
        touched |= f.contact_count() > 0 || f.contact_force_n.iter().any(|&v| v > 0.0);
        if touched {
            frames_with_contact += 1;
            continue;
        }
        let labelled = f.to_labelled(&layout)?;
        if let Some(stream) = streams.last_mut() {
            stream.push(
                labelled
                    .observation()
                    .with_time(Real::from(f.frame_index) * frame_secs)
                    .to_owned_observation(),
            );
        }
    }
    streams.retain(|s| !s.is_empty());
    Ok(ContactFreeStreams {
        streams,
        frames_read,
        frames_with_contact,
        trajectories: Some(trajectories),
    })
}

/// How two hands differ, if they do, in words: [`HandModel::difference`] (finger count,
/// vertex, marker and tendon counts, rest meshes, marker vertices, placement on the palm).
pub fn hand_difference(a: &HandModel, b: &HandModel) -> Option<String> {
    a.difference(b).map(|d| d.to_string())
}

/// Where an episode's calibration markers come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MarkerSource {
    /// Detected when the episode has camera images or no ground truth; the true markers
    /// otherwise.
    Auto,
    /// Detected in the camera images.
    Detected,
    /// The episode's ground-truth markers (simulated episodes).
    Truth,
}

/// The contact-free streams of one source, with the words a report gives them.
#[derive(Debug, Clone)]
pub struct CalibrationSource {
    /// The episode or data set, as named.
    pub source: String,
    /// Whose markers they are: "detected" or "ground truth".
    pub markers: &'static str,
    /// How contact was told apart.
    pub contact: &'static str,
    /// The streams.
    pub chosen: ContactFreeStreams,
}

/// The contact-free streams of `episode` (named `source`) of `hand`, with markers from
/// `markers` (a detector made with `config` when detected; the default config without one).
///
/// # Errors
/// [`LabError::Calibration`] when the true markers are asked of an episode without
/// ground truth, when a detector config is given for true markers, or when the detector
/// cannot use the episode's camera or read a frame; the hand check's errors.
pub fn episode_calibration_source(
    source: &str,
    episode: &Episode,
    hand: &HandModel,
    markers: MarkerSource,
    config: Option<moe_touch::perception::DetectorConfig>,
) -> Result<CalibrationSource, LabError> {
    crate::markers::check_hand(hand, &episode.info)?;
    let invalid = |reason: String| LabError::Calibration { reason };
    let truth = episode_has_ground_truth(episode);
    let detected = match markers {
        MarkerSource::Auto => episode_has_images(episode) || !truth,
        MarkerSource::Detected => true,
        MarkerSource::Truth if !truth => {
            return Err(invalid(format!(
                "{source} has no ground-truth markers (a real recording); use the detected ones"
            )));
        }
        MarkerSource::Truth => false,
    };
    let mut detector = match (detected, config) {
        (true, config) => Some(
            MarkerDetector::for_episode(&episode.info, hand, config.unwrap_or_default()).map_err(
                |e| {
                    invalid(format!(
                        "the camera of {source}: {}",
                        moe_touch::error::one_line(&e)
                    ))
                },
            )?,
        ),
        (false, None) => None,
        (false, Some(_)) => {
            return Err(invalid(
                "a detector config is for detected markers, not the true ones".into(),
            ));
        }
    };
    let chosen = episode_contact_free_streams(episode, detector.as_mut())
        .map_err(|e| invalid(format!("{source}: {}", moe_touch::error::one_line(&e))))?;
    Ok(CalibrationSource {
        source: source.to_owned(),
        markers: if detected { "detected" } else { "ground truth" },
        contact: if truth {
            "from the ground truth"
        } else {
            "no ground truth: every frame taken as contact-free"
        },
        chosen,
    })
}

/// The contact-free prefix of each trajectory of the data set `reader` reads (named
/// `source`), at most `max_trajectories` of them, with its true markers.
///
/// # Errors
/// [`LabError::Calibration`]: [`dataset_contact_free_streams`]'s errors, naming `source`.
pub fn dataset_calibration_source(
    source: &str,
    reader: &DatasetReader,
    max_trajectories: Option<u64>,
) -> Result<CalibrationSource, LabError> {
    let chosen = dataset_contact_free_streams(reader, max_trajectories).map_err(|e| {
        LabError::Calibration {
            reason: format!("{source}: {}", moe_touch::error::one_line(&e)),
        }
    })?;
    Ok(CalibrationSource {
        source: source.to_owned(),
        markers: "ground truth",
        contact: "from the data set's labels and contact forces (each trajectory's frames \
                  before its first contact)",
        chosen,
    })
}

/// The figures of a material that calibration fits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FittedFigures {
    /// Young's modulus, pascals.
    pub youngs_modulus_pa: Real,
    /// Stiffness-proportional (Rayleigh) damping coefficient, seconds.
    pub rayleigh_stiffness: Real,
}

impl FittedFigures {
    /// The fitted figures of `m`.
    pub fn of(m: &HandMaterial) -> Self {
        Self {
            youngs_modulus_pa: m.material.youngs_modulus_pa,
            rayleigh_stiffness: m.material.rayleigh_stiffness,
        }
    }
}

/// A calibration's report (`moe-touch calibrate` prints it, or writes it with `--json`).
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationRecord {
    /// The episode or the data set.
    pub source: String,
    /// The hand, as given.
    pub hand: String,
    /// Where the markers came from ("detected", "ground truth").
    pub markers: &'static str,
    /// How contact was told apart.
    pub contact: &'static str,
    /// Frames read.
    pub frames_read: usize,
    /// Frames left out for contact.
    pub frames_with_contact: usize,
    /// Trajectories used (data sets).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trajectories: Option<usize>,
    /// Contact-free streams fitted.
    pub streams: usize,
    /// Frames in them.
    pub frames: usize,
    /// The material started from (a file, or "nominal").
    pub initial_material: String,
    /// Its figures.
    pub initial: FittedFigures,
    /// The fitted figures.
    pub fitted: FittedFigures,
    /// Whether the damping was fitted (else kept).
    pub fit_damping: bool,
    /// RMS marker residual with the initial material, metres.
    pub rms_initial_m: Real,
    /// The same with the fitted material.
    pub rms_fitted_m: Real,
    /// Relative change of Young's modulus that raises the residual by 1 %.
    pub youngs_modulus_resolution: Real,
    /// Evaluations of the objective.
    pub evaluations: usize,
    /// The material file written.
    pub out: String,
    /// Wall time, seconds.
    pub wall_secs: Real,
}

impl CalibrationRecord {
    /// The record of a calibration from `source` of the hand named `hand` that started from
    /// `initial` (named `initial_material`), ended as `report` says, wrote `out` and took
    /// `wall_secs`.
    pub fn new(
        source: CalibrationSource,
        hand: String,
        (initial, initial_material): (&HandMaterial, String),
        report: &CalibrationReport,
        fit_damping: bool,
        out: &std::path::Path,
        wall_secs: Real,
    ) -> Self {
        Self {
            source: source.source,
            hand,
            markers: source.markers,
            contact: source.contact,
            frames_read: source.chosen.frames_read,
            frames_with_contact: source.chosen.frames_with_contact,
            trajectories: source.chosen.trajectories,
            streams: report.streams,
            frames: report.frames,
            initial_material,
            initial: FittedFigures::of(initial),
            fitted: FittedFigures::of(&report.material),
            fit_damping,
            rms_initial_m: report.rms_initial_m,
            rms_fitted_m: report.rms_fitted_m,
            youngs_modulus_resolution: report.youngs_modulus_resolution,
            evaluations: report.evaluations,
            out: out.display().to_string(),
            wall_secs,
        }
    }

    /// The report as text, lines ending in `\n`.
    pub fn table(&self) -> String {
        let r = self;
        let kept = if r.fit_damping { "" } else { " (kept)" };
        format!(
            "calibrated hand '{}' from {}: {} contact-free frames in {} streams ({} markers; {} of \
             {} frames left out for contact, {})\n  Young's modulus E        {:.0} Pa -> {:.0} Pa \
             (a {:.1} % change of E raises the residual by 1 %)\n  damping (Rayleigh beta)  \
             {:.4} s -> {:.4} s{kept}\n  RMS marker residual      {:.3} mm -> {:.3} mm ({} \
             evaluations)\nwrote {}\n",
            r.hand,
            r.source,
            r.frames,
            r.streams,
            r.markers,
            r.frames_with_contact,
            r.frames_read,
            r.contact,
            r.initial.youngs_modulus_pa,
            r.fitted.youngs_modulus_pa,
            100.0 * r.youngs_modulus_resolution,
            r.initial.rayleigh_stiffness,
            r.fitted.rayleigh_stiffness,
            1e3 * r.rms_initial_m,
            1e3 * r.rms_fitted_m,
            r.evaluations,
            r.out
        )
    }
}
