//! Table 1: shape and contact estimation scored frame by frame on held-out frames of a data set,
//! with the runtime of each estimator.

use std::time::Instant;

use moe_arap::{MultiShapeEstimator, ShapeConfig};
use moe_contact::{ContactMetrics, ContactReport, DgcnnEstimator, KnnIndex};
use moe_geom::{ContactInput, HandModel, HandShape, LabelledFrame, Point3, Real, SeededRng, bcd};
use serde::Serialize;

use super::augmentation::marker_subset;
use crate::error::LabError;

/// Options of the Table 1 evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactEvalOptions {
    /// Markers per finger kept in the reduced-marker shape rows (4 in the paper).
    pub subset_markers: usize,
    /// Seed of the marker subsets.
    pub seed: u64,
    /// SR-ARAP options (the paper's: 50 iterations, α = 0.01, cold start).
    pub shape: ShapeConfig,
}

impl Default for ContactEvalOptions {
    fn default() -> Self {
        Self {
            subset_markers: 4,
            seed: 0,
            shape: ShapeConfig::default(),
        }
    }
}

/// One shape-estimation row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShapeRow {
    /// Estimator (`SR-ARAP`, `KNN[All]`, `KNN[Sub]`, `rest`).
    pub method: String,
    /// Markers per finger it saw (0 for the rest shape).
    pub markers: usize,
    /// Frames evaluated.
    pub frames: u64,
    /// Mean BCD between the estimated and the true surface, mm.
    pub bcd_mm: Real,
    /// Standard deviation of the frames' BCD, mm.
    pub bcd_sd_mm: Real,
    /// Mean distance between vertex i of the estimate and vertex i of the truth, mm.
    pub vertex_mean_mm: Real,
    /// Largest such distance over all frames, mm.
    pub vertex_max_mm: Real,
    /// Mean time per observation, ms.
    pub ms_per_frame: Real,
}

/// One contact-estimation row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactRow {
    /// Estimator (`DGCNN (true shape)`, `DGCNN (SR-ARAP)`, `KNN[All]`, `KNN[Sub]`).
    pub method: String,
    /// Label rule of the ground truth the row is scored against.
    pub labels: String,
    /// The figures.
    pub report: ContactReport,
    /// Mean time per observation, ms (for DGCNN on SR-ARAP: the network only; add the
    /// SR-ARAP row's time for the whole chain).
    pub ms_per_frame: Real,
}

/// Table 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactTable {
    /// Frames evaluated.
    pub frames: usize,
    /// Trajectories they come from.
    pub trajectories: usize,
    /// Contact threshold of the DGCNN.
    pub threshold: Real,
    /// Shape rows.
    pub shape: Vec<ShapeRow>,
    /// Contact rows, for every label rule.
    pub contact: Vec<ContactRow>,
}

/// Ground-truth labels of the evaluated frames under a named rule.
#[derive(Debug, Clone, Copy)]
pub struct TruthLabels<'a> {
    /// Rule name.
    pub rule: &'a str,
    /// Per frame, per finger, per vertex.
    pub labels: &'a [Vec<Vec<bool>>],
}

/// The estimators of the study.
#[derive(Debug, Clone, Copy)]
pub struct Estimators<'a> {
    /// The trained network.
    pub dgcnn: &'a DgcnnEstimator,
    /// `KNN[All]` (every training frame; keeps shapes for its shape row) — the KNN rows are
    /// left out without it.
    pub knn_all: Option<&'a KnnIndex>,
    /// `KNN[Sub]` (a seeded 10 % of them).
    pub knn_sub: Option<&'a KnnIndex>,
}

/// What every estimator made of one frame, for a person to look at.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePrediction {
    /// Index of the frame in the evaluated list.
    pub frame: usize,
    /// SR-ARAP shape from every marker.
    pub arap_shape: HandShape,
    /// DGCNN contact probabilities on the SR-ARAP shape.
    pub dgcnn_on_arap: Vec<Vec<Real>>,
    /// `KNN[All]` contact labels (empty without the index).
    pub knn_all: Vec<Vec<bool>>,
}

#[derive(Debug, Clone, Copy, Default)]
struct ShapeAcc {
    frames: u64,
    bcd_sum: Real,
    bcd_sq: Real,
    vertex_sum: Real,
    vertex_count: u64,
    vertex_max: Real,
    seconds: Real,
}

impl ShapeAcc {
    fn add(
        &mut self,
        estimate: &HandShape,
        truth: &HandShape,
        seconds: Real,
    ) -> Result<(), LabError> {
        let a: Vec<Point3> = estimate.fingers.iter().flatten().copied().collect();
        let b: Vec<Point3> = truth.fingers.iter().flatten().copied().collect();
        if a.len() != b.len() {
            return Err(LabError::InvalidEvaluation {
                reason: format!(
                    "an estimated shape of {} vertices for a true one of {}",
                    a.len(),
                    b.len()
                ),
            });
        }
        let d = bcd(&a, &b)?;
        self.frames += 1;
        self.bcd_sum += d;
        self.bcd_sq += d * d;
        for (p, q) in a.iter().zip(&b) {
            let e = (p - q).norm();
            self.vertex_sum += e;
            self.vertex_max = self.vertex_max.max(e);
        }
        self.vertex_count += a.len() as u64;
        self.seconds += seconds;
        Ok(())
    }

    fn row(&self, method: &str, markers: usize) -> ShapeRow {
        let n = self.frames.max(1) as Real;
        let mean = self.bcd_sum / n;
        ShapeRow {
            method: method.to_owned(),
            markers,
            frames: self.frames,
            bcd_mm: 1e3 * mean,
            bcd_sd_mm: 1e3 * (self.bcd_sq / n - mean * mean).max(0.0).sqrt(),
            vertex_mean_mm: 1e3 * self.vertex_sum / self.vertex_count.max(1) as Real,
            vertex_max_mm: 1e3 * self.vertex_max,
            ms_per_frame: 1e3 * self.seconds / n,
        }
    }
}

/// The shape estimates Table 1 scores, in its row order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ShapeMethod {
    /// The rest shape (the error of not estimating).
    Rest,
    /// SR-ARAP from every marker.
    Arap,
    /// SR-ARAP from a subset of the markers.
    ArapSubset,
    /// The shape of `KNN[All]`'s nearest training frame.
    KnnAll,
    /// The shape of `KNN[Sub]`'s nearest training frame.
    KnnSub,
}

/// The contact estimators Table 1 scores, in its row order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ContactMethod {
    /// The network on the true shape.
    DgcnnTrue,
    /// The network on the SR-ARAP shape (what runs).
    DgcnnArap,
    /// The nearest training frame's labels, every training frame.
    KnnAll,
    /// The same from a seeded 10 % of them.
    KnnSub,
}

impl ContactMethod {
    const ALL: [Self; 4] = [Self::DgcnnTrue, Self::DgcnnArap, Self::KnnAll, Self::KnnSub];

    fn name(self) -> &'static str {
        match self {
            Self::DgcnnTrue => "DGCNN (true shape)",
            Self::DgcnnArap => "DGCNN (SR-ARAP)",
            Self::KnnAll => "KNN[All]",
            Self::KnnSub => "KNN[Sub]",
        }
    }
}

/// One value per method, looked up by the method.
#[derive(Debug, Clone)]
struct ByMethod<K, T, const N: usize> {
    values: [T; N],
    key: std::marker::PhantomData<K>,
}

impl<K, T: Default, const N: usize> Default for ByMethod<K, T, N> {
    fn default() -> Self {
        Self {
            values: std::array::from_fn(|_| T::default()),
            key: std::marker::PhantomData,
        }
    }
}

impl<T> std::ops::Index<ShapeMethod> for ByMethod<ShapeMethod, T, 5> {
    type Output = T;
    fn index(&self, m: ShapeMethod) -> &T {
        &self.values[m as usize]
    }
}

impl<T> std::ops::IndexMut<ShapeMethod> for ByMethod<ShapeMethod, T, 5> {
    fn index_mut(&mut self, m: ShapeMethod) -> &mut T {
        &mut self.values[m as usize]
    }
}

impl<T> std::ops::Index<ContactMethod> for ByMethod<ContactMethod, T, 4> {
    type Output = T;
    fn index(&self, m: ContactMethod) -> &T {
        &self.values[m as usize]
    }
}

impl<T> std::ops::IndexMut<ContactMethod> for ByMethod<ContactMethod, T, 4> {
    fn index_mut(&mut self, m: ContactMethod) -> &mut T {
        &mut self.values[m as usize]
    }
}

/// What Table 1 accumulates over its frames.
#[derive(Debug, Default)]
struct Table1Acc {
    shapes: ByMethod<ShapeMethod, ShapeAcc, 5>,
    /// Contact metrics against the frames' own labels, and against the other labels if given.
    metrics: [ByMethod<ContactMethod, ContactMetrics, 4>; 2],
    seconds: ByMethod<ContactMethod, Real, 4>,
}

/// Table 1's inputs that stay fixed over its frames.
struct Table1Run<'a> {
    hand: &'a HandModel,
    rest: HandShape,
    estimators: Estimators<'a>,
    other: Option<TruthLabels<'a>>,
    options: &'a ContactEvalOptions,
    rng: SeededRng,
}

impl Table1Run<'_> {
    /// Scores every method on frame `k`; its predictions when `keep`.
    fn score_frame(
        &self,
        arap: &mut MultiShapeEstimator,
        acc: &mut Table1Acc,
        k: usize,
        frame: &LabelledFrame,
        keep: bool,
    ) -> Result<Option<FramePrediction>, LabError> {
        frame.shape.check_against(self.hand)?;
        acc.shapes[ShapeMethod::Rest].add(&self.rest, &frame.shape, 0.0)?;
        let t = Instant::now();
        let arap_shape = arap.estimate(&frame.markers)?.shape;
        acc.shapes[ShapeMethod::Arap].add(&arap_shape, &frame.shape, t.elapsed().as_secs_f64())?;
        let subset = marker_subset(
            &frame.markers,
            self.options.subset_markers,
            &mut self.rng.split(k as u64),
        );
        let t = Instant::now();
        let subset_shape = arap.estimate(&subset)?.shape;
        acc.shapes[ShapeMethod::ArapSubset].add(
            &subset_shape,
            &frame.shape,
            t.elapsed().as_secs_f64(),
        )?;

        let dgcnn = self.estimators.dgcnn;
        let threshold = dgcnn.threshold();
        let mut predictions: ByMethod<ContactMethod, Vec<Vec<bool>>, 4> = ByMethod::default();
        let t = Instant::now();
        let on_true = dgcnn.estimate_map(&ContactInput::of_frame(frame, &frame.shape))?;
        acc.seconds[ContactMethod::DgcnnTrue] += t.elapsed().as_secs_f64();
        predictions[ContactMethod::DgcnnTrue] = on_true.labels_at(threshold);
        let t = Instant::now();
        let on_arap = dgcnn.estimate_map(&ContactInput::of_frame(frame, &arap_shape))?;
        acc.seconds[ContactMethod::DgcnnArap] += t.elapsed().as_secs_f64();
        predictions[ContactMethod::DgcnnArap] = on_arap.labels_at(threshold);
        for (method, index, shape_method) in [
            (
                ContactMethod::KnnAll,
                self.estimators.knn_all,
                ShapeMethod::KnnAll,
            ),
            (
                ContactMethod::KnnSub,
                self.estimators.knn_sub,
                ShapeMethod::KnnSub,
            ),
        ] {
            let Some(index) = index else { continue };
            let t = Instant::now();
            let m = index.nearest(&frame.markers)?;
            let map = index.contact_map(m);
            let elapsed = t.elapsed().as_secs_f64();
            acc.seconds[method] += elapsed;
            predictions[method] = map.labels_at(0.5);
            if let Some(shape) = index.shape_of(m.frame) {
                acc.shapes[shape_method].add(&shape, &frame.shape, elapsed)?;
            }
        }
        for method in ContactMethod::ALL {
            let p = &predictions[method];
            if p.is_empty() {
                continue;
            }
            acc.metrics[0][method].add(&frame.shape, &frame.contact, p)?;
            if let Some(o) = self.other {
                acc.metrics[1][method].add(&frame.shape, &o.labels[k], p)?;
            }
        }
        Ok(keep.then(|| FramePrediction {
            frame: k,
            arap_shape,
            dgcnn_on_arap: on_arap.fingers,
            knn_all: std::mem::take(&mut predictions[ContactMethod::KnnAll]),
        }))
    }

    /// The table from the accumulators over `frames`.
    fn table(&self, acc: &Table1Acc, frames: &[LabelledFrame], rule: &str) -> ContactTable {
        let markers = self
            .hand
            .fingers()
            .first()
            .map_or(0, |f| f.model.marker_vertices().len());
        let subset = self.options.subset_markers.min(markers);
        let mut shape_rows = vec![
            acc.shapes[ShapeMethod::Rest].row("rest", 0),
            acc.shapes[ShapeMethod::Arap].row("SR-ARAP", markers),
            acc.shapes[ShapeMethod::ArapSubset].row("SR-ARAP", subset),
        ];
        for (method, name) in [
            (ShapeMethod::KnnAll, "KNN[All]"),
            (ShapeMethod::KnnSub, "KNN[Sub]"),
        ] {
            if acc.shapes[method].frames > 0 {
                shape_rows.push(acc.shapes[method].row(name, markers));
            }
        }
        let n = frames.len() as Real;
        let truths = [Some(rule), self.other.map(|o| o.rule)];
        let mut contact = Vec::new();
        for (metrics, label_rule) in acc.metrics.iter().zip(truths) {
            let Some(label_rule) = label_rule else {
                continue;
            };
            for method in ContactMethod::ALL {
                let report = metrics[method].report();
                if report.frames == 0 {
                    continue;
                }
                contact.push(ContactRow {
                    method: method.name().to_owned(),
                    labels: label_rule.to_owned(),
                    report,
                    ms_per_frame: 1e3 * acc.seconds[method] / n,
                });
            }
        }
        let mut trajectories: Vec<u64> = frames.iter().map(|f| f.trajectory_id).collect();
        trajectories.sort_unstable();
        trajectories.dedup();
        ContactTable {
            frames: frames.len(),
            trajectories: trajectories.len(),
            threshold: self.estimators.dgcnn.threshold(),
            shape: shape_rows,
            contact,
        }
    }
}

/// Table 1 on `frames` (held-out frames of one hand), scored against the frames' own labels
/// (`rule` names their rule) and, if given, against `other` labels of the same frames.
/// `keep(k)` selects the frames whose predictions are returned for display.
///
/// # Errors
/// Frames that do not fit the hand or the estimators, a failing solve or network pass, or
/// `other` labels for another number of frames.
pub fn evaluate_table1(
    hand: &HandModel,
    frames: &[LabelledFrame],
    rule: &str,
    other: Option<TruthLabels<'_>>,
    estimators: Estimators<'_>,
    options: &ContactEvalOptions,
    keep: &dyn Fn(usize) -> bool,
) -> Result<(ContactTable, Vec<FramePrediction>), LabError> {
    if frames.is_empty() {
        return Err(LabError::InvalidEvaluation {
            reason: "no frames to evaluate".into(),
        });
    }
    if let Some(o) = other
        && o.labels.len() != frames.len()
    {
        return Err(LabError::InvalidEvaluation {
            reason: format!(
                "{} '{}' label sets for {} frames",
                o.labels.len(),
                o.rule,
                frames.len()
            ),
        });
    }
    let mut arap = MultiShapeEstimator::new(hand.clone(), options.shape.clone())?;
    let run = Table1Run {
        hand,
        rest: HandShape::rest(hand),
        estimators,
        other,
        options,
        rng: SeededRng::new(options.seed),
    };
    let mut acc = Table1Acc::default();
    let mut kept = Vec::new();
    for (k, frame) in frames.iter().enumerate() {
        if let Some(p) = run.score_frame(&mut arap, &mut acc, k, frame, keep(k))? {
            kept.push(p);
        }
    }
    Ok((run.table(&acc, frames, rule), kept))
}
