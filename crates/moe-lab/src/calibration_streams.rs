//! The contact-free streams a material calibration fits (`moe_physics::calibrate`): chosen from
//! a recorded episode (frames its ground truth marks in contact left out, each run of
//! contact-free frames between them one stream) or from a data set (each trajectory's frames
//! before its first contact).

use moe_geom::{HandKeypoints, HandModel, OwnedObservation, Real};
use moe_io::{DatasetReader, SplitFractions};
use moe_record::Episode;
use moe_touch::perception::MarkerDetector;

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
