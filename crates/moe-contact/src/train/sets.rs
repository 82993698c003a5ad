//! Labelled point sets held in memory, and their batches.

use candle_core::{Device, Tensor};
use moe_geom::LabelledFrame;

use crate::error::ContactError;
use crate::estimator::FeatureBuilder;

/// Labelled point sets of one size, in memory: the network's input features and a 0/1 label per
/// point.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrainingSets {
    points: usize,
    channels: usize,
    features: Vec<f32>,
    pub(super) labels: Vec<u32>,
}

impl TrainingSets {
    /// An empty collection of sets of `points` points with `channels` channels.
    pub fn new(points: usize, channels: usize) -> Self {
        Self {
            points,
            channels,
            features: Vec::new(),
            labels: Vec::new(),
        }
    }

    /// The point sets of labelled frames, as `features` makes them (every set of a frame, frame
    /// after frame).
    ///
    /// # Errors
    /// A frame that does not fit the hand (naming the finger and vertex), or point sets of
    /// different sizes (fingers with different vertex counts in per-finger sets).
    pub fn from_frames(
        features: &FeatureBuilder,
        frames: &[LabelledFrame],
    ) -> Result<Self, ContactError> {
        let sets = features.point_sets();
        let points = sets.first().map_or(0, |s| s.1);
        if let Some((_, n)) = sets.iter().find(|s| s.1 != points) {
            return Err(ContactError::InvalidBatch {
                message: format!(
                    "point sets of {points} and {n} points: training needs sets of one size                      (whole-hand sets, or fingers with equal vertex counts)"
                ),
            });
        }
        let mut out = Self::new(points, features.channels());
        for frame in frames {
            let inputs = features.input_sets_with(&frame.shape, Some(&frame.tendon_pull_m))?;
            let labels = features.arrange(&frame.contact);
            for (x, y) in inputs.iter().zip(&labels) {
                out.push(x, y)?;
            }
        }
        Ok(out)
    }

    /// Adds one set: row-major features `(points, channels)` and its labels.
    ///
    /// # Errors
    /// [`ContactError::InvalidBatch`] for sizes that do not fit, non-finite features or labels
    /// other than 0 and 1.
    pub fn push(&mut self, features: &[f64], labels: &[bool]) -> Result<(), ContactError> {
        if features.len() != self.points * self.channels || labels.len() != self.points {
            return Err(ContactError::InvalidBatch {
                message: format!(
                    "a training set has {} features and {} labels; sets here are {} points × {} \
                     channels",
                    features.len(),
                    labels.len(),
                    self.points,
                    self.channels
                ),
            });
        }
        if let Some(i) = features.iter().position(|v| !v.is_finite()) {
            return Err(ContactError::NonFinitePoint {
                set: self.len(),
                index: i / self.channels,
            });
        }
        self.features.extend(features.iter().map(|&v| v as f32));
        self.labels.extend(labels.iter().map(|&l| u32::from(l)));
        Ok(())
    }

    /// Number of sets.
    pub fn len(&self) -> usize {
        self.labels.len().checked_div(self.points).unwrap_or(0)
    }

    /// Whether there are no sets.
    pub fn is_empty(&self) -> bool {
        self.labels.is_empty()
    }

    /// Points per set.
    pub fn points(&self) -> usize {
        self.points
    }

    /// Channels per point.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Number of contact points over all sets.
    pub fn contact_points(&self) -> usize {
        self.labels.iter().filter(|&&l| l == 1).count()
    }

    /// Whether set `s` has at least one contact point.
    pub fn has_contact(&self, s: usize) -> bool {
        self.labels[s * self.points..(s + 1) * self.points].contains(&1)
    }

    /// The labels of set `s`.
    pub fn labels_of(&self, s: usize) -> impl Iterator<Item = bool> + '_ {
        self.labels[s * self.points..(s + 1) * self.points]
            .iter()
            .map(|&l| l == 1)
    }

    pub(super) fn batch(&self, sets: &[usize]) -> candle_core::Result<(Tensor, Tensor)> {
        let (n, c) = (self.points, self.channels);
        let mut x = Vec::with_capacity(sets.len() * n * c);
        let mut y = Vec::with_capacity(sets.len() * n);
        for &s in sets {
            x.extend_from_slice(&self.features[s * n * c..(s + 1) * n * c]);
            y.extend_from_slice(&self.labels[s * n..(s + 1) * n]);
        }
        Ok((
            Tensor::from_vec(x, (sets.len(), n, c), &Device::Cpu)?,
            Tensor::from_vec(y, sets.len() * n, &Device::Cpu)?,
        ))
    }
}
