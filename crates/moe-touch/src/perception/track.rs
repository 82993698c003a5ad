//! Marker identities over time: predictions with gates, and the state they come from.

use moe_geom::{HandModel, Point3, Real, Vector3};
use serde::Serialize;

use super::DetectorConfig;

/// Where a marker's expected position came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Prior {
    /// The rest pose (first frame, or tracking lost).
    Rest,
    /// The marker's own track, by constant velocity.
    Track,
    /// Extrapolated along its finger from neighbouring markers found in this frame.
    Chain,
}

/// The last estimate of one marker.
#[derive(Debug, Clone, Copy)]
struct Track {
    position: Point3,
    /// Displacement per frame, from the last two consecutive sightings (zero after a gap).
    velocity: Vector3,
    /// Frames since the marker was last found (0: found in the previous frame).
    missing: u32,
}

/// The tracker's memory: one optional track per marker, markers numbered finger by finger.
#[derive(Debug, Clone)]
pub(super) struct Tracker {
    /// Rest position of every marker in the hand frame.
    rest: Vec<Point3>,
    /// `(finger, marker)` of every flat index, and the flat index of each finger's marker 0.
    ids: Vec<(usize, usize)>,
    first: Vec<usize>,
    tracks: Vec<Option<Track>>,
}

impl Tracker {
    pub(super) fn new(hand: &HandModel) -> Self {
        let rest_kp = hand.rest_keypoints();
        let mut rest = Vec::new();
        let mut ids = Vec::new();
        let mut first = Vec::new();
        for (f, markers) in rest_kp.fingers.iter().enumerate() {
            first.push(rest.len());
            for (m, p) in markers.iter().enumerate() {
                rest.push(p.unwrap_or_else(Point3::origin));
                ids.push((f, m));
            }
        }
        Self {
            tracks: vec![None; rest.len()],
            rest,
            ids,
            first,
        }
    }

    pub(super) fn len(&self) -> usize {
        self.rest.len()
    }

    pub(super) fn num_fingers(&self) -> usize {
        self.first.len()
    }

    pub(super) fn id(&self, k: usize) -> (usize, usize) {
        self.ids[k]
    }

    pub(super) fn reset(&mut self) {
        self.tracks.fill(None);
    }

    /// Whether any marker has a track young enough to predict from.
    pub(super) fn has_prior(&self) -> bool {
        self.tracks.iter().any(Option::is_some)
    }

    /// The expected position and gate of every marker before this frame's matching: the own
    /// track if there is one, the rest pose otherwise; `None` for a marker with no track while
    /// others are tracked (it waits for the chain pass).
    pub(super) fn predictions(
        &self,
        config: &DetectorConfig,
    ) -> Vec<Option<(Point3, Real, Prior)>> {
        let lost = !self.has_prior();
        (0..self.len())
            .map(|k| match self.tracks[k] {
                Some(t) => {
                    // Constant velocity, extrapolated over at most three frames of absence.
                    let steps = Real::from((t.missing + 1).min(3));
                    let gate = config.track_gate_m + config.gate_growth_m * Real::from(t.missing);
                    Some((t.position + t.velocity * steps, gate, Prior::Track))
                }
                None if lost => Some((self.rest[k], config.rest_gate_m, Prior::Rest)),
                None => None,
            })
            .collect()
    }

    /// Expected position of marker `k` from the markers of its finger already found in this
    /// frame (`found`, flat indices): continue the finger's chain from the two nearest found
    /// neighbours on one side with the rest spacing, or shift the rest position by one
    /// neighbour's displacement; the rest position when the finger has nothing found.
    pub(super) fn chain_prediction(&self, k: usize, found: &[Option<Point3>]) -> Point3 {
        let (f, m) = self.ids[k];
        let base = self.first[f];
        let count = self.first.get(f + 1).copied().unwrap_or(self.len()) - base;
        let at = |mm: isize| -> Option<Point3> {
            (0..count as isize)
                .contains(&mm)
                .then(|| found[base + mm as usize])
                .flatten()
        };
        let m = m as isize;
        for dir in [-1isize, 1] {
            if let (Some(p1), Some(p2)) = (at(m + dir), at(m + 2 * dir)) {
                let step = p1 - p2;
                let rest_step =
                    (self.rest[k] - self.rest[(base as isize + m + dir) as usize]).norm();
                if step.norm() > 1e-9 {
                    return p1 + step.normalize() * rest_step;
                }
            }
        }
        for dir in [-1isize, 1] {
            if let Some(p1) = at(m + dir) {
                let n = (base as isize + m + dir) as usize;
                return self.rest[k] + (p1 - self.rest[n]);
            }
        }
        self.rest[k]
    }

    /// Takes this frame's estimates (`found`, flat indices) into the tracks; markers missing
    /// for more than `max_missing_frames` lose theirs.
    pub(super) fn update(&mut self, found: &[Option<Point3>], max_missing_frames: u32) {
        for (track, f) in self.tracks.iter_mut().zip(found) {
            *track = match (*track, f) {
                (Some(t), Some(p)) => Some(Track {
                    position: *p,
                    velocity: if t.missing == 0 {
                        p - t.position
                    } else {
                        Vector3::zeros()
                    },
                    missing: 0,
                }),
                (None, Some(p)) => Some(Track {
                    position: *p,
                    velocity: Vector3::zeros(),
                    missing: 0,
                }),
                (Some(t), None) if t.missing < max_missing_frames => Some(Track {
                    missing: t.missing + 1,
                    ..t
                }),
                _ => None,
            };
        }
    }
}
