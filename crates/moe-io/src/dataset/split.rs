//! Training, validation and test splits, by trajectory.

use serde::{Deserialize, Serialize};

/// Which part of a data set a trajectory belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Split {
    /// Training set.
    Train,
    /// Validation set.
    Validation,
    /// Test set.
    Test,
}

/// Fractions of trajectories in the training and validation sets; the rest is the test set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SplitFractions {
    /// Fraction for training. Default 0.8.
    pub train: f64,
    /// Fraction for validation. Default 0.1 (the test set gets the remaining 0.1, as the paper
    /// evaluates on 10 % of unseen trajectories).
    pub validation: f64,
}

impl Default for SplitFractions {
    fn default() -> Self {
        Self {
            train: 0.8,
            validation: 0.1,
        }
    }
}

/// The split of a trajectory: a hash of `(trajectory_id, seed)` mapped to `[0, 1)` and cut at
/// the fractions, so every frame of a trajectory lands in the same split, whatever shard it is in.
pub fn split_of(trajectory_id: u64, seed: u64, fractions: SplitFractions) -> Split {
    let mut rng = moe_geom::SeededRng::new(seed).split(trajectory_id);
    let u = rng.uniform();
    if u < fractions.train {
        Split::Train
    } else if u < fractions.train + fractions.validation {
        Split::Validation
    } else {
        Split::Test
    }
}
