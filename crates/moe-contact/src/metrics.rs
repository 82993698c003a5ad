//! Contact metrics by the project's definitions, for every estimator in every report.
//!
//! On the frames whose ground truth has contact: contact BCD and UCD (predicted → true) in mm
//! between the predicted contact points and the true ones, both taken as vertex positions of the
//! same frame's ground-truth surface. A frame whose prediction is empty is a *miss* (counted,
//! left out of the distances); a frame with predictions but no true contact is a *false alarm*.
//! Beside the distances, per-vertex precision, recall, F1 and IoU pooled over all frames.

use moe_geom::{HandShape, Point3, Real, bcd, ucd};
use serde::Serialize;

use crate::error::ContactError;
use crate::train::Confusion;

/// Running sums of the contact metrics over frames.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactMetrics {
    frames: u64,
    contact_frames: u64,
    misses: u64,
    false_alarms: u64,
    scored: u64,
    bcd_sum_m: Real,
    bcd_sq_m2: Real,
    ucd_sum_m: Real,
    ucd_sq_m2: Real,
    confusion: Confusion,
}

/// The figures of a [`ContactMetrics`], distances in mm.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ContactReport {
    /// Frames seen.
    pub frames: u64,
    /// Frames whose ground truth has contact.
    pub contact_frames: u64,
    /// Contact frames with an empty prediction.
    pub misses: u64,
    /// `misses / contact_frames`.
    pub miss_rate: Real,
    /// Frames without true contact but with a prediction.
    pub false_alarms: u64,
    /// `false_alarms / (frames − contact_frames)`.
    pub false_alarm_rate: Real,
    /// Mean contact BCD over the contact frames that are not misses, mm (NaN if none).
    pub bcd_mm: Real,
    /// Standard deviation of the frames' BCD, mm.
    pub bcd_sd_mm: Real,
    /// Mean UCD from predicted to true contact points, mm (NaN if none).
    pub ucd_mm: Real,
    /// Standard deviation of the frames' UCD, mm.
    pub ucd_sd_mm: Real,
    /// Per-vertex precision pooled over all frames.
    pub precision: Real,
    /// Per-vertex recall.
    pub recall: Real,
    /// Per-vertex F1.
    pub f1: Real,
    /// Per-vertex IoU.
    pub iou: Real,
}

fn points_of(shape: &HandShape, labels: &[Vec<bool>]) -> Vec<Point3> {
    shape
        .fingers
        .iter()
        .zip(labels)
        .flat_map(|(f, l)| f.iter().zip(l).filter(|(_, l)| **l).map(|(p, _)| *p))
        .collect()
}

impl ContactMetrics {
    /// Adds one frame: `truth` and `predicted` labels per finger and vertex, with the positions
    /// taken from `shape` (the frame's ground-truth surface).
    ///
    /// # Errors
    /// [`ContactError::InvalidBatch`] when the label lists do not match the shape, finger by
    /// finger.
    pub fn add(
        &mut self,
        shape: &HandShape,
        truth: &[Vec<bool>],
        predicted: &[Vec<bool>],
    ) -> Result<(), ContactError> {
        let fits = |l: &[Vec<bool>]| {
            l.len() == shape.fingers.len()
                && l.iter()
                    .zip(&shape.fingers)
                    .all(|(a, b)| a.len() == b.len())
        };
        for (what, l) in [("true", truth), ("predicted", predicted)] {
            if !fits(l) {
                return Err(ContactError::InvalidBatch {
                    message: format!(
                        "{what} contact labels of {:?} vertices per finger for a shape of {:?}",
                        l.iter().map(Vec::len).collect::<Vec<_>>(),
                        shape.fingers.iter().map(Vec::len).collect::<Vec<_>>()
                    ),
                });
            }
        }
        self.frames += 1;
        for (t, p) in truth.iter().flatten().zip(predicted.iter().flatten()) {
            match (*p, *t) {
                (true, true) => self.confusion.true_positives += 1,
                (true, false) => self.confusion.false_positives += 1,
                (false, true) => self.confusion.false_negatives += 1,
                (false, false) => {}
            }
        }
        let t = points_of(shape, truth);
        let p = points_of(shape, predicted);
        match (t.is_empty(), p.is_empty()) {
            (true, true) => {}
            (true, false) => self.false_alarms += 1,
            (false, true) => {
                self.contact_frames += 1;
                self.misses += 1;
            }
            (false, false) => {
                self.contact_frames += 1;
                self.scored += 1;
                let b = bcd(&p, &t)?;
                let u = ucd(&p, &t)?;
                self.bcd_sum_m += b;
                self.bcd_sq_m2 += b * b;
                self.ucd_sum_m += u;
                self.ucd_sq_m2 += u * u;
            }
        }
        Ok(())
    }

    /// Adds the frames of `other`.
    pub fn merge(&mut self, other: &Self) {
        self.frames += other.frames;
        self.contact_frames += other.contact_frames;
        self.misses += other.misses;
        self.false_alarms += other.false_alarms;
        self.scored += other.scored;
        self.bcd_sum_m += other.bcd_sum_m;
        self.bcd_sq_m2 += other.bcd_sq_m2;
        self.ucd_sum_m += other.ucd_sum_m;
        self.ucd_sq_m2 += other.ucd_sq_m2;
        self.confusion.true_positives += other.confusion.true_positives;
        self.confusion.false_positives += other.confusion.false_positives;
        self.confusion.false_negatives += other.confusion.false_negatives;
    }

    /// The pooled per-vertex counts.
    pub fn confusion(&self) -> Confusion {
        self.confusion
    }

    /// The figures so far.
    pub fn report(&self) -> ContactReport {
        let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as Real / b as Real };
        let n = self.scored as Real;
        let mean_sd = |sum: Real, sq: Real| {
            if self.scored == 0 {
                (Real::NAN, Real::NAN)
            } else {
                let m = sum / n;
                (1e3 * m, 1e3 * (sq / n - m * m).max(0.0).sqrt())
            }
        };
        let (bcd_mm, bcd_sd_mm) = mean_sd(self.bcd_sum_m, self.bcd_sq_m2);
        let (ucd_mm, ucd_sd_mm) = mean_sd(self.ucd_sum_m, self.ucd_sq_m2);
        ContactReport {
            frames: self.frames,
            contact_frames: self.contact_frames,
            misses: self.misses,
            miss_rate: ratio(self.misses, self.contact_frames),
            false_alarms: self.false_alarms,
            false_alarm_rate: ratio(self.false_alarms, self.frames - self.contact_frames),
            bcd_mm,
            bcd_sd_mm,
            ucd_mm,
            ucd_sd_mm,
            precision: self.confusion.precision(),
            recall: self.confusion.recall(),
            f1: self.confusion.f1(),
            iou: self.confusion.iou(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape() -> HandShape {
        // Finger 0: four vertices 1 cm apart on x; finger 1: two vertices on y.
        HandShape {
            fingers: vec![
                (0..4)
                    .map(|i| Point3::new(0.01 * Real::from(i), 0.0, 0.0))
                    .collect(),
                (0..2)
                    .map(|i| Point3::new(0.0, 0.01 * Real::from(i + 1), 0.0))
                    .collect(),
            ],
        }
    }

    fn labels(a: [bool; 4], b: [bool; 2]) -> Vec<Vec<bool>> {
        vec![a.to_vec(), b.to_vec()]
    }

    #[test]
    fn hand_made_frames_give_the_defined_figures() {
        let s = shape();
        let mut m = ContactMetrics::default();
        // Frame 1: truth {x=0}, predicted {x=0, x=2 cm}: UCD(p→t) = (0 + 20)/2 = 10 mm,
        // UCD(t→p) = 0, BCD = 5 mm.
        m.add(
            &s,
            &labels([true, false, false, false], [false, false]),
            &labels([true, false, true, false], [false, false]),
        )
        .unwrap();
        // Frame 2: a miss.
        m.add(
            &s,
            &labels([false, true, false, false], [false, false]),
            &labels([false; 4], [false, false]),
        )
        .unwrap();
        // Frame 3: a false alarm; frame 4: nothing anywhere.
        m.add(
            &s,
            &labels([false; 4], [false, false]),
            &labels([false; 4], [true, false]),
        )
        .unwrap();
        m.add(
            &s,
            &labels([false; 4], [false; 2]),
            &labels([false; 4], [false; 2]),
        )
        .unwrap();
        let r = m.report();
        assert_eq!(
            (r.frames, r.contact_frames, r.misses, r.false_alarms),
            (4, 2, 1, 1)
        );
        assert!((r.miss_rate - 0.5).abs() < 1e-15);
        assert!((r.false_alarm_rate - 0.5).abs() < 1e-15);
        assert!((r.bcd_mm - 5.0).abs() < 1e-9, "{}", r.bcd_mm);
        assert!((r.ucd_mm - 10.0).abs() < 1e-9, "{}", r.ucd_mm);
        assert!(r.bcd_sd_mm.abs() < 1e-9);
        // Pooled: TP 1, FP 2 (x=2 cm, finger 1), FN 1.
        assert_eq!(
            m.confusion(),
            Confusion {
                true_positives: 1,
                false_positives: 2,
                false_negatives: 1
            }
        );
        assert!((r.precision - 1.0 / 3.0).abs() < 1e-12);
        assert!((r.recall - 0.5).abs() < 1e-12);
        let mut twice = m;
        twice.merge(&m);
        assert_eq!(twice.report().frames, 8);
        assert!((twice.report().bcd_mm - 5.0).abs() < 1e-9);
        // Labels of the wrong size are named.
        let err = m
            .add(&s, &labels([false; 4], [false; 2]), &[vec![false; 4]])
            .unwrap_err();
        assert!(err.to_string().contains("predicted"), "{err}");
    }
}
