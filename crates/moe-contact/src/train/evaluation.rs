//! The loss and the per-point counts: weighted cross-entropy, confusion counts at a range of
//! thresholds, and the network's predictions on a collection of sets.

use candle_core::{D, DType, Tensor};
use serde::{Deserialize, Serialize};

use super::sets::TrainingSets;
use crate::error::ContactError;
use crate::network::{Dgcnn, Mode};

/// Weighted cross-entropy, PyTorch's `CrossEntropyLoss(weight=[1, w])` with mean reduction:
/// `Σ w_y · (−log p_y) / Σ w_y`. `logits` `(M, 2)`, `labels` `(M)` u32.
///
/// # Errors
/// Tensors of the wrong shapes.
pub fn weighted_cross_entropy(
    logits: &Tensor,
    labels: &Tensor,
    contact_weight: f64,
) -> Result<Tensor, ContactError> {
    let logp = candle_nn::ops::log_softmax(logits, D::Minus1)?;
    let picked = logp.gather(&labels.unsqueeze(1)?, 1)?.squeeze(1)?;
    let w = labels
        .to_dtype(logits.dtype())?
        .affine(contact_weight - 1.0, 1.0)?;
    Ok(((picked * &w)?.sum_all()?.neg()? / w.sum_all()?)?)
}

/// Per-point counts at one threshold.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Confusion {
    /// Contact predicted and true.
    pub true_positives: u64,
    /// Contact predicted, not true.
    pub false_positives: u64,
    /// Contact true, not predicted.
    pub false_negatives: u64,
}

impl Confusion {
    /// Precision (1 when nothing is predicted).
    pub fn precision(&self) -> f64 {
        let p = self.true_positives + self.false_positives;
        if p == 0 {
            1.0
        } else {
            self.true_positives as f64 / p as f64
        }
    }

    /// Recall (1 when nothing is true).
    pub fn recall(&self) -> f64 {
        let t = self.true_positives + self.false_negatives;
        if t == 0 {
            1.0
        } else {
            self.true_positives as f64 / t as f64
        }
    }

    /// F1 score (0 when there are no true positives).
    pub fn f1(&self) -> f64 {
        let d = 2 * self.true_positives + self.false_positives + self.false_negatives;
        if d == 0 {
            1.0
        } else {
            2.0 * self.true_positives as f64 / d as f64
        }
    }

    /// Intersection over union of the predicted and true contact sets.
    pub fn iou(&self) -> f64 {
        let u = self.true_positives + self.false_positives + self.false_negatives;
        if u == 0 {
            1.0
        } else {
            self.true_positives as f64 / u as f64
        }
    }
}

/// Thresholds on the contact probability at which validation counts are kept.
pub const THRESHOLDS: [f64; 19] = [
    0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85,
    0.9, 0.95,
];

/// Loss and per-point counts of the network on a collection of sets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// Weighted cross-entropy with the trainer's contact weight.
    pub loss: f64,
    /// Counts at each of [`THRESHOLDS`].
    pub confusion: Vec<Confusion>,
}

impl Evaluation {
    /// The threshold with the highest F1, and its counts (the lower threshold on ties).
    pub fn best(&self) -> (f64, Confusion) {
        let mut best = 0;
        for (i, c) in self.confusion.iter().enumerate() {
            if c.f1() > self.confusion[best].f1() {
                best = i;
            }
        }
        (THRESHOLDS[best], self.confusion[best])
    }

    /// Counts at `threshold` if it is one of [`THRESHOLDS`].
    pub fn at(&self, threshold: f64) -> Option<Confusion> {
        THRESHOLDS
            .iter()
            .position(|&t| (t - threshold).abs() < 1e-12)
            .map(|i| self.confusion[i])
    }
}

/// Contact probability of every point of every set (`sets.len() × sets.points()`, set after
/// set), the network run without dropout, `batch_size` sets at a time.
///
/// # Errors
/// A failing tensor operation, or sets of another width.
pub fn predict(
    net: &Dgcnn,
    sets: &TrainingSets,
    batch_size: usize,
) -> Result<Vec<f64>, ContactError> {
    let mut out = Vec::with_capacity(sets.labels.len());
    let all: Vec<usize> = (0..sets.len()).collect();
    for chunk in all.chunks(batch_size.max(1)) {
        let (x, y) = sets.batch(chunk)?;
        let logits = net.forward_with(&x, Mode::Eval)?.logits;
        let logits = logits.reshape((y.dim(0)?, 2))?.to_dtype(DType::F64)?;
        let logp = candle_nn::ops::log_softmax(&logits, D::Minus1)?.to_vec2::<f64>()?;
        out.extend(logp.iter().map(|lp| lp[1].exp()));
    }
    Ok(out)
}

/// Loss and counts of `net` (no dropout) on `sets`.
///
/// # Errors
/// A failing tensor operation, or sets of another width.
pub fn evaluate(
    net: &Dgcnn,
    sets: &TrainingSets,
    contact_weight: f64,
    batch_size: usize,
) -> Result<Evaluation, ContactError> {
    Ok(evaluation_of(
        &predict(net, sets, batch_size)?,
        sets.labels.iter().map(|&l| l == 1),
        contact_weight,
    ))
}

/// Loss and counts of contact probabilities `p` against `labels`, point by point.
pub fn evaluation_of(
    p: &[f64],
    labels: impl IntoIterator<Item = bool>,
    contact_weight: f64,
) -> Evaluation {
    let mut confusion = vec![Confusion::default(); THRESHOLDS.len()];
    let (mut weighted_nll, mut weight) = (0.0, 0.0);
    for (&p, l) in p.iter().zip(labels) {
        let w = if l { contact_weight } else { 1.0 };
        let py = if l { p } else { 1.0 - p };
        weighted_nll -= w * py.max(f64::MIN_POSITIVE).ln();
        weight += w;
        for (c, &t) in confusion.iter_mut().zip(&THRESHOLDS) {
            match (p >= t, l) {
                (true, true) => c.true_positives += 1,
                (true, false) => c.false_positives += 1,
                (false, true) => c.false_negatives += 1,
                (false, false) => {}
            }
        }
    }
    Evaluation {
        loss: if weight > 0.0 {
            weighted_nll / weight
        } else {
            0.0
        },
        confusion,
    }
}
