//! The paper's simulation study of contact estimation (§5.1–5.2) as library code: Table 1 on
//! held-out frames of a data set, and the controlled plate experiment of Table 2.
//!
//! Table 1 compares, frame by frame on the same frames:
//!
//! - shape estimation: SR-ARAP from the frame's markers (all 7 per finger, and a seeded random
//!   4 of 7 per finger), the KNN baselines' shapes (the matched training frame's surface), and the
//!   rest shape for reference; each by BCD against the simulated surface and by the per-vertex
//!   error (vertex i against vertex i), which BCD hides;
//! - contact estimation: the DGCNN on the true shape, the DGCNN on the SR-ARAP shape (the
//!   paper's setting), `KNN[All]` and `KNN[Sub]`, by [`moe_contact::metrics`]'s definitions, against
//!   the data set's labels and optionally a second labelling of the same frames;
//! - the runtime per observation of each (one frame at a time, as a robot runs them).
//!
//! Table 2 simulates each plate scene a few times with the plate's pose perturbed by a seeded
//! small offset and tilt, and reports the UCD from the predicted to the true contact points over
//! the frames that have contact, for the DGCNN on SR-ARAP shapes and for `KNN[All]`.

use std::time::Instant;

use moe_arap::{MultiShapeEstimator, ShapeConfig};
use moe_contact::{ContactMetrics, ContactReport, DgcnnEstimator, KnnIndex};
use moe_geom::math::UnitQuat;
use moe_geom::{
    ContactInput, HandKeypoints, HandModel, HandShape, LabelledFrame, Point3, Real, SeededRng,
    Vector3, bcd,
};
use moe_tendon_sim::SceneConfig;
use serde::Serialize;

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

/// `keypoints` with all but `keep` markers of every finger dropped (a seeded choice).
pub fn marker_subset(keypoints: &HandKeypoints, keep: usize, rng: &mut SeededRng) -> HandKeypoints {
    HandKeypoints {
        fingers: keypoints
            .fingers
            .iter()
            .map(|f| {
                let mut ids: Vec<usize> = (0..f.len()).collect();
                for i in (1..ids.len()).rev() {
                    ids.swap(i, rng.below(i as u64 + 1) as usize);
                }
                let kept = &ids[..keep.min(ids.len())];
                f.iter()
                    .enumerate()
                    .map(|(i, p)| if kept.contains(&i) { *p } else { None })
                    .collect()
            })
            .collect(),
    }
}

/// Perturbations of a frame's markers before SR-ARAP, of the kinds the perception stage makes:
/// detection noise and markers that are hidden or missed. A training-time augmentation, so that
/// a contact model learns from shapes like the ones it is given at run time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerAugmentation {
    /// Standard deviation of the Gaussian noise added to each coordinate of each kept marker, m.
    pub noise_sd_m: Real,
    /// Probability that an observed marker is dropped (treated as occluded).
    pub drop_probability: Real,
    /// Probability that a finger's most distal markers are hidden together, as a pressing
    /// fingertip's are from the wrist camera (behind the obstacle or the finger's own bulge):
    /// structured occlusion that independent drops almost never produce.
    pub distal_occlusion_probability: Real,
    /// Length of such a run: uniform from 1 to this many markers (at most all but one of the
    /// finger's markers are hidden).
    pub max_distal_occluded: usize,
    /// Seed; the `k`-th frame of a call draws from its own stream `k`.
    pub seed: u64,
}

impl Default for MarkerAugmentation {
    /// No perturbation; runs of up to 3 distal markers when the occlusion is switched on.
    fn default() -> Self {
        Self {
            noise_sd_m: 0.0,
            drop_probability: 0.0,
            distal_occlusion_probability: 0.0,
            max_distal_occluded: 3,
            seed: 0,
        }
    }
}

/// Each finger's marker indices from the most distal to the most proximal
/// ([`moe_geom::FingerModel::distal_marker_order`]): the order in which
/// [`MarkerAugmentation::distal_occlusion_probability`] hides them.
pub fn distal_marker_order(hand: &HandModel) -> Vec<Vec<usize>> {
    hand.fingers()
        .iter()
        .map(|f| f.model.distal_marker_order())
        .collect()
}

/// Largest accepted [`MarkerAugmentation::noise_sd_m`]: 5 mm, several times any detector's error.
pub const MAX_MARKER_NOISE_M: Real = 5e-3;

impl MarkerAugmentation {
    /// Checks the noise (finite, 0 to [`MAX_MARKER_NOISE_M`]) and the probability (0 to 1).
    ///
    /// # Errors
    /// [`LabError::InvalidParameter`] naming the bad field.
    pub fn validate(&self) -> Result<(), LabError> {
        if !(0.0..=MAX_MARKER_NOISE_M).contains(&self.noise_sd_m) {
            return Err(LabError::InvalidParameter {
                name: "marker noise sd (m)",
                value: self.noise_sd_m,
                reason: "not between 0 and 0.005 m",
            });
        }
        if !(0.0..=1.0).contains(&self.drop_probability) {
            return Err(LabError::InvalidParameter {
                name: "marker drop probability",
                value: self.drop_probability,
                reason: "not between 0 and 1",
            });
        }
        if !(0.0..=1.0).contains(&self.distal_occlusion_probability) {
            return Err(LabError::InvalidParameter {
                name: "distal marker occlusion probability",
                value: self.distal_occlusion_probability,
                reason: "not between 0 and 1",
            });
        }
        if self.distal_occlusion_probability > 0.0 && self.max_distal_occluded == 0 {
            return Err(LabError::InvalidParameter {
                name: "distal markers occluded at most",
                value: 0.0,
                reason: "must be at least 1 when distal occlusion is on",
            });
        }
        Ok(())
    }

    /// `keypoints` perturbed with `rng`: each observed marker dropped with the drop probability,
    /// the others moved by the noise; then, finger by finger with the distal occlusion
    /// probability, a run of the most distal markers hidden (`distal_order` as
    /// [`distal_marker_order`] gives it; draws for it are made only when the probability is
    /// positive, so that switching it off reproduces the plain perturbation). Occluded markers
    /// stay occluded.
    /// Indices in `distal_order` beyond a finger's markers are skipped.
    pub fn apply(
        &self,
        keypoints: &HandKeypoints,
        distal_order: &[Vec<usize>],
        rng: &mut SeededRng,
    ) -> HandKeypoints {
        let fingers = keypoints
            .fingers
            .iter()
            .enumerate()
            .map(|(fi, f)| {
                let mut out: Vec<Option<Point3>> = f
                    .iter()
                    .map(|p| {
                        let p = (*p)?;
                        if rng.uniform() < self.drop_probability {
                            return None;
                        }
                        let n = Vector3::new(rng.normal(), rng.normal(), rng.normal());
                        Some(p + n * self.noise_sd_m)
                    })
                    .collect();
                if self.distal_occlusion_probability > 0.0
                    && rng.uniform() < self.distal_occlusion_probability
                {
                    let most = self.max_distal_occluded.min(out.len().saturating_sub(1));
                    if most > 0 {
                        let run = 1 + ((rng.uniform() * most as Real) as usize).min(most - 1);
                        let order = distal_order.get(fi).map_or(&[][..], Vec::as_slice);
                        for &m in order.iter().take(run) {
                            if let Some(slot) = out.get_mut(m) {
                                *slot = None;
                            }
                        }
                    }
                }
                out
            })
            .collect();
        HandKeypoints { fingers }
    }
}

/// `frames` with every shape replaced by its SR-ARAP estimate from the frame's markers (what a
/// contact model sees at run time), perturbed first by `augmentation` if given; labels and
/// everything else kept. Frames are solved in parallel, one estimator per worker; the result
/// does not depend on the thread count.
///
/// # Errors
/// An invalid `augmentation`; as [`MultiShapeEstimator::new`] and [`MultiShapeEstimator::estimate`].
pub fn with_estimated_shapes(
    hand: &HandModel,
    frames: &[LabelledFrame],
    options: &ShapeConfig,
    augmentation: Option<&MarkerAugmentation>,
) -> Result<Vec<LabelledFrame>, LabError> {
    use rayon::prelude::*;
    if let Some(a) = augmentation {
        a.validate()?;
    }
    let distal_order = distal_marker_order(hand);
    frames
        .par_iter()
        .enumerate()
        .map_init(
            || MultiShapeEstimator::new(hand.clone(), options.clone()),
            |arap, (k, frame)| {
                let arap = arap.as_mut().map_err(|e| LabError::from(e.clone()))?;
                let shape = match augmentation {
                    Some(a) => {
                        let mut rng = SeededRng::new(a.seed).split(k as u64);
                        arap.estimate(&a.apply(&frame.markers, &distal_order, &mut rng))?
                            .shape
                    }
                    None => arap.estimate(&frame.markers)?.shape,
                };
                Ok(LabelledFrame {
                    shape,
                    ..frame.clone()
                })
            },
        )
        .collect()
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

/// A plate scene of Table 2.
#[derive(Debug, Clone)]
pub struct PlateScene {
    /// Name (`plate_tip_front`, ...).
    pub name: String,
    /// Region pressed (`tip`, `middle`, `base`).
    pub region: String,
    /// The scene.
    pub config: SceneConfig,
}

/// One trial of one plate scene.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlateTrial {
    /// Scene name.
    pub scene: String,
    /// Region pressed.
    pub region: String,
    /// Trial number (0-based).
    pub trial: u64,
    /// Offset of the plate, metres.
    pub offset_m: [Real; 3],
    /// Tilt of the plate, degrees.
    pub tilt_deg: Real,
    /// Frames with true contact.
    pub contact_frames: u64,
    /// DGCNN on SR-ARAP shapes over those frames.
    pub dgcnn: ContactReport,
    /// `KNN[All]` over those frames.
    pub knn_all: ContactReport,
}

/// Largest offset of the plate in a trial, metres (uniform per axis).
pub const PLATE_OFFSET_M: Real = 5e-4;
/// Largest tilt of the plate in a trial, degrees (about a random axis).
pub const PLATE_TILT_DEG: Real = 3.0;

/// One trial of a plate scene: trial 0 as committed, the others perturbed.
#[derive(Debug, Clone)]
pub struct PlateTrialScene<'a> {
    /// The scene.
    pub scene: &'a PlateScene,
    /// The trial, from 0.
    pub trial: u64,
    /// Its configuration ([`perturbed_plate`]).
    pub config: SceneConfig,
    /// The plate's offset, metres.
    pub offset_m: [Real; 3],
    /// The plate's tilt, degrees.
    pub tilt_deg: Real,
}

/// Every trial of every plate scene, `trials` each, scene after scene: the one definition of
/// the trials Table 2 runs (each scene's trials drawn from its own stream of `seed`).
pub fn plate_trials(
    scenes: &[PlateScene],
    trials: u64,
    seed: u64,
) -> impl Iterator<Item = PlateTrialScene<'_>> {
    scenes.iter().enumerate().flat_map(move |(s, scene)| {
        (0..trials).map(move |trial| {
            let (config, offset_m, tilt_deg) =
                perturbed_plate(&scene.config, seed ^ (s as u64) << 32, trial);
            PlateTrialScene {
                scene,
                trial,
                config,
                offset_m,
                tilt_deg,
            }
        })
    })
}

/// `config` with its obstacles moved by a seeded offset of up to [`PLATE_OFFSET_M`] per axis
/// and tilted by up to [`PLATE_TILT_DEG`] about a random axis through their first keyframe;
/// trial 0 of any seed is the scene as given.
pub fn perturbed_plate(
    config: &SceneConfig,
    seed: u64,
    trial: u64,
) -> (SceneConfig, [Real; 3], Real) {
    if trial == 0 {
        return (config.clone(), [0.0; 3], 0.0);
    }
    let mut rng = SeededRng::new(seed).split(trial);
    let offset = [
        rng.uniform_range(-PLATE_OFFSET_M, PLATE_OFFSET_M),
        rng.uniform_range(-PLATE_OFFSET_M, PLATE_OFFSET_M),
        rng.uniform_range(-PLATE_OFFSET_M, PLATE_OFFSET_M),
    ];
    let tilt = rng.uniform_range(-PLATE_TILT_DEG, PLATE_TILT_DEG);
    let axis = Vector3::new(rng.normal(), rng.normal(), rng.normal());
    let axis = if axis.norm() > 1e-9 {
        axis.normalize()
    } else {
        Vector3::x()
    };
    let rotation = UnitQuat::from_scaled_axis(axis * tilt.to_radians());
    let mut out = config.clone();
    for o in &mut out.obstacles {
        let Some(pivot) = o
            .trajectory
            .keyframes
            .first()
            .map(|k| Vector3::from(k.translation_m))
        else {
            continue;
        };
        for k in &mut o.trajectory.keyframes {
            let r = rotation * UnitQuat::from_scaled_axis(Vector3::from(k.rotation_rad));
            let t =
                pivot + rotation * (Vector3::from(k.translation_m) - pivot) + Vector3::from(offset);
            k.translation_m = [t.x, t.y, t.z];
            let a = r.scaled_axis();
            k.rotation_rad = [a.x, a.y, a.z];
        }
    }
    (out, offset, tilt)
}

/// The labelled frames of a simulated scene (markers are the marker vertices of the surface,
/// tendon pulls the commanded ones).
///
/// # Errors
/// Divergence of the simulation, a scene whose hand is not `hand`'s layout, or one with a
/// force-driven tendon (whose command is a tension, not a pull).
pub fn simulate_labelled(
    config: &SceneConfig,
    hand: &HandModel,
) -> Result<Vec<LabelledFrame>, LabError> {
    Ok(crate::physics_eval::simulate_stream(config, hand, 0)?
        .into_iter()
        .map(|s| s.frame)
        .collect())
}

/// Table 2: every plate scene, `trials` trials each (trial 0 unperturbed), UCD from predicted to
/// true contact points over the frames with true contact, for the DGCNN on SR-ARAP shapes and
/// `KNN[All]`.
///
/// # Errors
/// As [`simulate_labelled`] and the estimators.
pub fn evaluate_plates(
    hand: &HandModel,
    scenes: &[PlateScene],
    trials: u64,
    seed: u64,
    dgcnn: &DgcnnEstimator,
    knn_all: &KnnIndex,
    shape: &ShapeConfig,
) -> Result<Vec<PlateTrial>, LabError> {
    let mut arap = MultiShapeEstimator::new(hand.clone(), shape.clone())?;
    let threshold = dgcnn.threshold();
    let mut out = Vec::new();
    for t in plate_trials(scenes, trials, seed) {
        let frames = simulate_labelled(&t.config, hand)?;
        let (mut d, mut k) = (ContactMetrics::default(), ContactMetrics::default());
        let mut contact_frames = 0;
        for frame in frames.iter().filter(|f| f.contact_count() > 0) {
            contact_frames += 1;
            let estimated = arap.estimate(&frame.markers)?.shape;
            let p = dgcnn.estimate_map(&ContactInput::of_frame(frame, &estimated))?;
            d.add(&frame.shape, &frame.contact, &p.labels_at(threshold))?;
            let m = knn_all.nearest(&frame.markers)?;
            k.add(
                &frame.shape,
                &frame.contact,
                &knn_all.contact_map(m).labels_at(0.5),
            )?;
        }
        out.push(PlateTrial {
            scene: t.scene.name.clone(),
            region: t.scene.region.clone(),
            trial: t.trial,
            offset_m: t.offset_m,
            tilt_deg: t.tilt_deg,
            contact_frames,
            dgcnn: d.report(),
            knn_all: k.report(),
        });
    }
    Ok(out)
}

/// Blue (0) to red (1) colour of a contact probability, for meshes a person looks at (the
/// colours of the `run` output's meshes too).
pub use moe_io::probability_colour;

/// Finger `finger` of `hand` deformed to `vertices`, as PLY with the per-vertex scalar
/// `contact_probability` and colours from [`probability_colour`].
///
/// # Errors
/// `vertices` or `probabilities` of another length than the finger's mesh, or non-finite
/// vertices.
pub fn contact_ply(
    hand: &HandModel,
    finger: usize,
    vertices: &[Point3],
    probabilities: &[Real],
) -> Result<moe_io::PlyData, LabError> {
    let Some(f) = hand.fingers().get(finger) else {
        return Err(LabError::InvalidEvaluation {
            reason: format!("finger {finger} of a {}-finger hand", hand.num_fingers()),
        });
    };
    let mesh = f.model.mesh().with_vertices(vertices.to_vec())?;
    if probabilities.len() != vertices.len() {
        return Err(LabError::InvalidEvaluation {
            reason: format!(
                "{} contact probabilities for finger {finger}'s {} vertices",
                probabilities.len(),
                vertices.len()
            ),
        });
    }
    let mut ply = moe_io::PlyData::from_mesh(&mesh)
        .with_scalar("contact_probability", probabilities.iter().copied());
    ply.colors = Some(
        probabilities
            .iter()
            .map(|&p| probability_colour(p))
            .collect(),
    );
    Ok(ply)
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::{FingerParams, HandPreset, WorldFromHand};
    use moe_tendon_sim::{ObstacleConfig, ObstacleShape, PoseKeyframe, PoseTrajectory};

    #[test]
    fn marker_subsets_keep_the_asked_number_per_finger_and_are_seeded() {
        let hand = HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default()).unwrap();
        let all = hand.rest_keypoints();
        let rng = SeededRng::new(4);
        let a = marker_subset(&all, 4, &mut rng.split(1));
        for (f, g) in a.fingers.iter().zip(&all.fingers) {
            assert_eq!(f.iter().flatten().count(), 4);
            // Kept markers are unchanged.
            for (p, q) in f.iter().zip(g) {
                if let Some(p) = p {
                    assert_eq!(Some(*p), *q);
                }
            }
        }
        assert_eq!(a, marker_subset(&all, 4, &mut rng.split(1)));
        assert_ne!(a, marker_subset(&all, 4, &mut rng.split(2)));
        assert_eq!(marker_subset(&all, 9, &mut rng.split(1)), all);
    }

    #[test]
    fn marker_augmentation_moves_and_drops_markers_at_the_asked_rates() {
        let hand = HandModel::preset(HandPreset::FiveFinger, &FingerParams::default()).unwrap();
        let mut all = hand.rest_keypoints();
        // An occluded marker stays occluded.
        all.fingers[0][0] = None;
        let order = distal_marker_order(&hand);
        let none = MarkerAugmentation {
            seed: 1,
            ..MarkerAugmentation::default()
        };
        assert_eq!(none.apply(&all, &order, &mut SeededRng::new(3)), all);
        let aug = MarkerAugmentation {
            noise_sd_m: 2e-4,
            drop_probability: 0.25,
            seed: 1,
            ..MarkerAugmentation::default()
        };
        let (mut kept, mut dropped, mut sq) = (0usize, 0usize, 0.0);
        for k in 0..400 {
            let out = aug.apply(&all, &order, &mut SeededRng::new(7).split(k));
            assert_eq!(
                out,
                aug.apply(&all, &order, &mut SeededRng::new(7).split(k))
            );
            assert_eq!(out.fingers[0][0], None);
            for (f, g) in out.fingers.iter().zip(&all.fingers) {
                for (p, q) in f.iter().zip(g).skip(1) {
                    match p {
                        Some(p) => {
                            kept += 1;
                            sq += (p - q.unwrap()).norm_squared();
                        }
                        None => dropped += 1,
                    }
                }
            }
        }
        let rate = dropped as Real / (kept + dropped) as Real;
        assert!((rate - 0.25).abs() < 0.02, "drop rate {rate}");
        // E‖n‖² = 3σ² for isotropic noise.
        let sd = (sq / (3 * kept) as Real).sqrt();
        assert!((sd - 2e-4).abs() < 5e-6, "noise sd {sd}");
        for bad in [
            MarkerAugmentation {
                noise_sd_m: Real::NAN,
                ..aug
            },
            MarkerAugmentation {
                noise_sd_m: 0.01,
                ..aug
            },
            MarkerAugmentation {
                drop_probability: 1.5,
                ..aug
            },
            MarkerAugmentation {
                drop_probability: -0.1,
                ..aug
            },
            MarkerAugmentation {
                distal_occlusion_probability: 1.1,
                ..aug
            },
            MarkerAugmentation {
                distal_occlusion_probability: 0.5,
                max_distal_occluded: 0,
                ..aug
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }

    /// Distal occlusion hides a run of the most distal markers (never all of them) of the asked
    /// share of fingers, with run lengths spread from 1 to the maximum; switched off, it draws
    /// nothing, so the plain perturbation is reproduced draw for draw.
    #[test]
    fn distal_occlusion_hides_runs_of_tip_markers_at_the_asked_rate() {
        let hand = HandModel::preset(HandPreset::ThreeFinger, &FingerParams::default()).unwrap();
        let all = hand.rest_keypoints();
        let order = distal_marker_order(&hand);
        // The built-in finger's markers run base to tip, so the tip's is the last.
        for o in &order {
            assert_eq!(o.len(), 7);
            assert_eq!(o[0], 6);
            assert_eq!(o[6], 0);
        }
        let aug = MarkerAugmentation {
            distal_occlusion_probability: 0.3,
            max_distal_occluded: 3,
            ..MarkerAugmentation::default()
        };
        let mut runs = [0usize; 4];
        let mut fingers = 0;
        for k in 0..600 {
            let out = aug.apply(&all, &order, &mut SeededRng::new(11).split(k));
            for (f, o) in out.fingers.iter().zip(&order) {
                fingers += 1;
                let hidden = f.iter().filter(|p| p.is_none()).count();
                assert!(hidden <= 3, "{f:?}");
                // The hidden ones are exactly the `hidden` most distal.
                for (rank, &m) in o.iter().enumerate() {
                    assert_eq!(f[m].is_none(), rank < hidden, "{f:?}");
                }
                runs[hidden] += 1;
            }
        }
        let rate = (fingers - runs[0]) as Real / fingers as Real;
        assert!((rate - 0.3).abs() < 0.03, "occluded fingers {rate}");
        for (len, &n) in runs.iter().enumerate().skip(1) {
            let share = n as Real / (fingers - runs[0]) as Real;
            assert!((share - 1.0 / 3.0).abs() < 0.06, "runs of {len}: {share}");
        }
        // A run never hides a finger's last marker: a finger of one marker keeps it, a finger
        // of two loses exactly its distal one, whatever the draws.
        let m = all.fingers[0][0];
        let small = HandKeypoints {
            fingers: vec![vec![m], vec![m, m]],
        };
        let small_order = vec![vec![0], vec![1, 0]];
        let every = MarkerAugmentation {
            distal_occlusion_probability: 1.0,
            ..aug
        };
        for k in 0..50 {
            let out = every.apply(&small, &small_order, &mut SeededRng::new(1).split(k));
            assert_eq!(out.fingers[0], vec![m]);
            assert_eq!(out.fingers[1], vec![m, None]);
        }
        // Off: exactly the draws of the plain perturbation (drop, then three normals, per
        // observed marker), and none more.
        let plain = MarkerAugmentation {
            noise_sd_m: 1e-4,
            drop_probability: 0.2,
            ..MarkerAugmentation::default()
        };
        let mut rng = SeededRng::new(5);
        let out = plain.apply(&all, &order, &mut rng);
        let mut reference = SeededRng::new(5);
        for (f, g) in out.fingers.iter().zip(&all.fingers) {
            for (p, q) in f.iter().zip(g) {
                let q = q.unwrap();
                let expected = if reference.uniform() < 0.2 {
                    None
                } else {
                    let n =
                        Vector3::new(reference.normal(), reference.normal(), reference.normal());
                    Some(q + n * 1e-4)
                };
                assert_eq!(*p, expected);
            }
        }
        assert_eq!(rng.uniform(), reference.uniform());
    }

    #[test]
    fn estimated_shapes_with_every_marker_dropped_are_the_rest_shapes() {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let rest = HandShape::rest(&hand);
        let mut bent = hand.rest_keypoints();
        for p in bent.fingers.iter_mut().flatten().flatten() {
            p.x += 0.2 * (p.z - 0.01).max(0.0);
        }
        let frame = LabelledFrame {
            trajectory_id: 0,
            frame_index: 0,
            shape: rest.clone(),
            contact: rest.fingers.iter().map(|f| vec![false; f.len()]).collect(),
            markers: bent,
            world_from_hand: WorldFromHand::identity(),
            tendon_pull_m: vec![vec![0.0; 4]; rest.fingers.len()],
        };
        let frames = vec![frame.clone(), frame];
        let options = ShapeConfig::default();
        let largest_move = |shape: &HandShape| {
            shape
                .fingers
                .iter()
                .zip(&rest.fingers)
                .flat_map(|(a, b)| a.iter().zip(b).map(|(p, q)| (p - q).norm()))
                .fold(0.0, Real::max)
        };
        let plain = with_estimated_shapes(&hand, &frames, &options, None).unwrap();
        assert!(
            largest_move(&plain[0].shape) > 1e-3,
            "the bend moves the shape"
        );
        let drop_all = MarkerAugmentation {
            noise_sd_m: 1e-4,
            drop_probability: 1.0,
            ..MarkerAugmentation::default()
        };
        let dropped = with_estimated_shapes(&hand, &frames, &options, Some(&drop_all)).unwrap();
        for f in &dropped {
            assert!(largest_move(&f.shape) < 1e-12);
        }
        // Noise alone: the two identical frames get different draws, and a repeat is identical.
        let noisy = MarkerAugmentation {
            drop_probability: 0.0,
            ..drop_all
        };
        let a = with_estimated_shapes(&hand, &frames, &options, Some(&noisy)).unwrap();
        assert_ne!(a[0].shape, a[1].shape);
        assert_eq!(
            a,
            with_estimated_shapes(&hand, &frames, &options, Some(&noisy)).unwrap()
        );
        let bad = MarkerAugmentation {
            drop_probability: 2.0,
            ..noisy
        };
        assert!(with_estimated_shapes(&hand, &frames, &options, Some(&bad)).is_err());
    }

    #[test]
    fn plate_perturbations_are_small_seeded_and_rigid() {
        let config = SceneConfig {
            obstacles: vec![ObstacleConfig {
                shape: ObstacleShape::Cuboid {
                    half_extents_m: [0.001, 0.02, 0.015],
                },
                trajectory: PoseTrajectory {
                    keyframes: vec![
                        PoseKeyframe::at(0.0, [0.01, 0.0, 0.08]),
                        PoseKeyframe::at(1.0, [0.0, 0.0, 0.08]),
                    ],
                },
            }],
            ..SceneConfig::default()
        };
        assert_eq!(perturbed_plate(&config, 3, 0).0, config);
        let (moved, offset, tilt) = perturbed_plate(&config, 3, 1);
        assert_eq!(perturbed_plate(&config, 3, 1).0, moved);
        assert!(offset.iter().all(|o| o.abs() <= PLATE_OFFSET_M));
        assert!(tilt.abs() <= PLATE_TILT_DEG && tilt != 0.0);
        let k = &moved.obstacles[0].trajectory.keyframes;
        // The first keyframe moves by the offset only (the tilt is about it); the distance
        // between the keyframes is kept; the rotation is the tilt.
        let d0: Vec<Real> = (0..3)
            .map(|i| k[0].translation_m[i] - [0.01, 0.0, 0.08][i])
            .collect();
        assert!(d0.iter().zip(&offset).all(|(a, b)| (a - b).abs() < 1e-15));
        let gap = Vector3::from(k[1].translation_m) - Vector3::from(k[0].translation_m);
        assert!((gap.norm() - 0.01).abs() < 1e-12);
        let angle = Vector3::from(k[1].rotation_rad).norm().to_degrees();
        assert!((angle - tilt.abs()).abs() < 1e-9, "{angle} vs {tilt}");
    }
}
