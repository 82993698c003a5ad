//! Marker perturbations: seeded marker subsets, detection noise, dropped markers and occluded
//! fingertips, and frames whose shapes are estimated from the perturbed markers.

use moe_arap::{MultiShapeEstimator, ShapeConfig};
use moe_geom::depth::DepthImage;
use moe_geom::{HandKeypoints, HandModel, LabelledFrame, Point3, Real, SeededRng, Vector3};
use moe_tendon_sim::camera::{FINGER_ALBEDO, RenderItem, RgbdCamera, RgbdImage};

use crate::error::LabError;

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
    estimated_shapes(hand, frames, options, augmentation, None)
}

/// As [`with_estimated_shapes`], with SR-ARAP registered to the frame's markers and to a depth
/// image of its true fingers that `camera` renders with its noise (seeded by `seed`, the
/// trajectory and the frame): what a contact model sees at run time with `options.depth`
/// enabled. The object that touches a finger is not in the image (a data set does not keep
/// it); at run time it is mostly left out by the front gate.
///
/// # Errors
/// As [`with_estimated_shapes`], and a camera that cannot render.
pub fn with_depth_registered_shapes(
    hand: &HandModel,
    frames: &[LabelledFrame],
    options: &ShapeConfig,
    augmentation: Option<&MarkerAugmentation>,
    camera: &RgbdCamera,
    seed: u64,
) -> Result<Vec<LabelledFrame>, LabError> {
    estimated_shapes(hand, frames, options, augmentation, Some((camera, seed)))
}

fn estimated_shapes(
    hand: &HandModel,
    frames: &[LabelledFrame],
    options: &ShapeConfig,
    augmentation: Option<&MarkerAugmentation>,
    camera: Option<(&RgbdCamera, u64)>,
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
                let markers = match augmentation {
                    Some(a) => {
                        let mut rng = SeededRng::new(a.seed).split(k as u64);
                        a.apply(&frame.markers, &distal_order, &mut rng)
                    }
                    None => frame.markers.clone(),
                };
                let shape = match camera {
                    Some((camera, seed)) => {
                        let image = render_fingers(hand, frame, camera, seed)?;
                        let depth = DepthImage::new(
                            &image.depth_m,
                            camera.intrinsics,
                            camera.hand_from_camera,
                        )?;
                        arap.estimate_with(&markers, Some(&depth))?.shape
                    }
                    None => arap.estimate(&markers)?.shape,
                };
                Ok(LabelledFrame {
                    shape,
                    ..frame.clone()
                })
            },
        )
        .collect()
}

/// The fingers of `frame` (its true surface) as `camera` renders them, with its noise seeded by
/// `seed`, the frame's trajectory and its index.
pub(crate) fn render_fingers(
    hand: &HandModel,
    frame: &LabelledFrame,
    camera: &RgbdCamera,
    seed: u64,
) -> Result<RgbdImage, LabError> {
    let items: Vec<RenderItem<'_>> = frame
        .shape
        .fingers
        .iter()
        .zip(hand.fingers())
        .map(|(vertices, f)| RenderItem {
            vertices_in_hand: vertices,
            faces: f.model.mesh().faces(),
            albedo: FINGER_ALBEDO,
            markers_in_hand: &[],
            marker_radius_m: 0.0,
        })
        .collect();
    let stream = SeededRng::new(seed)
        .split(frame.trajectory_id)
        .split(u64::from(frame.frame_index))
        .next_u64();
    Ok(camera.render(&items, stream)?)
}
