//! The keypoints file: one frame's markers in the hand frame (metres), as `moe-touch markers`
//! writes them (one JSON object per line) and `moe-touch shape` and `moe-touch contact` read
//! them: `{"time_ns": t, "fingers": [[[x, y, z] or null, ...], ...]}`, `null` for an unseen
//! marker, the time optional.

use std::path::Path;

use moe_geom::{HandKeypoints, HandModel, Point3};
use moe_io::IoError;
use serde::{Deserialize, Serialize};

use crate::error::LabError;

/// One frame of keypoints with the time of its frame when known.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeypointsFile {
    /// The frame's time, nanoseconds.
    #[serde(default)]
    pub time_ns: Option<u64>,
    /// Per finger, per marker: its place, or `None` when unseen.
    pub fingers: Vec<Vec<Option<Point3>>>,
}

impl KeypointsFile {
    /// Reads a keypoints file (JSON).
    ///
    /// # Errors
    /// [`IoError`] for a missing, unreadable or malformed file, naming it.
    pub fn read(path: &Path) -> Result<Self, LabError> {
        Ok(moe_io::read_json(path)?)
    }

    /// The keypoints, without the time.
    pub fn into_keypoints(self) -> HandKeypoints {
        HandKeypoints {
            fingers: self.fingers,
        }
    }

    /// Reads a keypoints file and checks it against `hand`: a list per finger, an entry per
    /// marker, finite coordinates.
    ///
    /// # Errors
    /// As [`KeypointsFile::read`], and [`IoError::InvalidData`] naming the file and the finger
    /// or marker that does not fit the hand.
    pub fn read_for_hand(path: &Path, hand: &HandModel) -> Result<HandKeypoints, LabError> {
        let file = Self::read(path)?;
        let invalid = |item: String, message: String| -> LabError {
            IoError::invalid(path, item, message).into()
        };
        if file.fingers.len() != hand.num_fingers() {
            return Err(invalid(
                "fingers".into(),
                format!(
                    "{} fingers, the hand has {}",
                    file.fingers.len(),
                    hand.num_fingers()
                ),
            ));
        }
        for (f, (markers, hf)) in file.fingers.iter().zip(hand.fingers()).enumerate() {
            let expected = hf.model.marker_vertices().len();
            if markers.len() != expected {
                return Err(invalid(
                    "fingers".into(),
                    format!(
                        "finger {f} has {} markers, the hand's finger has {expected}",
                        markers.len()
                    ),
                ));
            }
            if let Some(m) = markers
                .iter()
                .position(|p| p.is_some_and(|p| !p.iter().all(|c| c.is_finite())))
            {
                return Err(invalid(
                    format!("finger {f}, marker {m}"),
                    "not finite".into(),
                ));
            }
        }
        Ok(file.into_keypoints())
    }

    /// Frames of keypoints as a JSON Lines text: one keypoints file per line, in order.
    ///
    /// # Errors
    /// [`LabError::InvalidEvaluation`] for keypoints JSON cannot hold.
    pub fn lines<'a>(
        frames: impl IntoIterator<Item = (u64, &'a HandKeypoints)>,
    ) -> Result<String, LabError> {
        /// A line as written: the keypoints borrowed.
        #[derive(Serialize)]
        struct Line<'a> {
            time_ns: u64,
            fingers: &'a [Vec<Option<Point3>>],
        }
        let mut text = String::new();
        for (time_ns, keypoints) in frames {
            let line = serde_json::to_string(&Line {
                time_ns,
                fingers: &keypoints.fingers,
            })
            .map_err(|e| LabError::InvalidEvaluation {
                reason: format!("keypoints of the frame at {time_ns} ns as JSON: {e}"),
            })?;
            text.push_str(&line);
            text.push('\n');
        }
        Ok(text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::{FingerParams, HandPreset};

    fn scratch(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("moe-lab-keypoints-{}-{name}", std::process::id()))
    }

    #[test]
    fn a_written_line_reads_back_and_is_checked_against_the_hand() {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let mut keypoints = HandKeypoints {
            fingers: hand
                .fingers()
                .iter()
                .map(|f| vec![Some(Point3::new(0.0, 0.0, 0.05)); f.model.marker_vertices().len()])
                .collect(),
        };
        keypoints.fingers[1][2] = None;
        let text = KeypointsFile::lines([(7, &keypoints)]).unwrap();
        assert!(text.starts_with("{\"time_ns\":7,\"fingers\":"), "{text}");
        let path = scratch("line.json");
        std::fs::write(&path, text.trim_end()).unwrap();
        let file = KeypointsFile::read(&path).unwrap();
        assert_eq!(file.time_ns, Some(7));
        assert_eq!(
            KeypointsFile::read_for_hand(&path, &hand).unwrap(),
            keypoints
        );

        keypoints.fingers[0].pop();
        std::fs::write(&path, KeypointsFile::lines([(7, &keypoints)]).unwrap()).unwrap();
        let err = KeypointsFile::read_for_hand(&path, &hand)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("line.json") && err.contains("finger 0 has 6 markers"),
            "{err}"
        );
        keypoints.fingers.pop();
        std::fs::write(&path, KeypointsFile::lines([(7, &keypoints)]).unwrap()).unwrap();
        let err = KeypointsFile::read_for_hand(&path, &hand)
            .unwrap_err()
            .to_string();
        assert!(err.contains("1 fingers, the hand has 2"), "{err}");
        std::fs::write(&path, "{\"fingers\": [], \"extra\": 1}").unwrap();
        assert!(KeypointsFile::read(&path).is_err());
        std::fs::remove_file(&path).unwrap();
    }
}
