//! The hand-level physics estimator: every finger read backwards, in the hand frame.

use moe_geom::depth::associate_depth;
use moe_geom::{
    ContactMap, DepthImage, HandEstimate, HandEstimator, HandKeypoints, HandModel, HandShape, Iso3,
    Observation, Point3, Real, Vector3, WorldFromHand,
};
use rayon::prelude::*;
use serde::Serialize;

use crate::config::{HandMaterial, PhysicsConfig};
use crate::error::PhysicsError;
use crate::finger::{Begun, FingerEstimate, FingerInverse, FingerObservation};

/// An observation with everything the physics estimator needs (hand frame).
#[derive(Debug, Clone, Copy)]
pub(crate) struct FullObservation<'a> {
    /// The observed markers, hand frame (`None` where unseen).
    pub(crate) keypoints: &'a HandKeypoints,
    /// `tendon_pull_m[f][t]`: pulled length of tendon `t` of finger `f`, metres.
    pub(crate) tendon_pull_m: &'a [Vec<Real>],
    /// Where the hand is: gravity's direction in the hand and, in a stream, the wrist's motion
    /// the free finger is simulated with.
    pub(crate) world_from_hand: WorldFromHand,
    /// Time of the observation, seconds: observations close in time form a stream (see
    /// [`PhysicsConfig::stream_horizon_secs`]); `None` for a lone frame.
    pub(crate) time_secs: Option<Real>,
    /// The wrist camera's depth image, when the observation has one.
    pub(crate) depth: Option<DepthImage<'a>>,
}

impl<'a> FullObservation<'a> {
    /// What the physics estimator needs of an observation: the markers, the tendon pulls and
    /// the wrist pose (the time where the frame is part of a stream).
    ///
    /// # Errors
    /// [`PhysicsError::Missing`] naming what is missing.
    pub(crate) fn of(obs: &Observation<'a>) -> Result<Self, PhysicsError> {
        Ok(Self {
            keypoints: obs.keypoints.ok_or(PhysicsError::Missing {
                what: "the observed markers (keypoints)",
            })?,
            tendon_pull_m: obs.tendon_pull_m.ok_or(PhysicsError::Missing {
                what: "the tendon pulls",
            })?,
            world_from_hand: obs.world_from_hand.ok_or(PhysicsError::Missing {
                what: "the hand's pose (world_from_hand), for the direction of gravity",
            })?,
            time_secs: obs.time_secs,
            depth: obs.depth,
        })
    }
}

/// The contact probability at or above which a vertex is in contact: where the logistic of the
/// likelihood-ratio statistic crosses one half, at the detection threshold itself.
pub const CONTACT_THRESHOLD: Real = 0.5;

/// A load the estimator found, hand frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ContactLoad {
    /// Finger index.
    pub finger: usize,
    /// The vertex at the centre of the loaded patch.
    pub vertex: u32,
    /// The load's place on the rest surface, hand frame, metres: the posterior mean of the
    /// place within [`PhysicsConfig::place_radius_m`] (an average of nearby surface points, so
    /// slightly under a curved surface), or the patch's centre vertex with a radius of 0.
    pub location_rest: Point3,
    /// The same point on the estimated (loaded) surface, hand frame, metres.
    pub location: Point3,
    /// The force the world exerts on the finger, hand frame, newtons.
    pub force_n: Vector3,
    /// Its magnitude, newtons.
    pub magnitude_n: Real,
    /// Standard deviation of the magnitude, newtons.
    pub magnitude_sd_n: Real,
    /// Posterior standard deviation of the location along the finger's axis and around it,
    /// metres (NaN for a second load of a finger).
    pub location_sd_m: [Real; 2],
    /// The patch: `(vertex, share of the force)`.
    pub patch: Vec<(u32, Real)>,
}

/// What the estimator says of one finger.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FingerReport {
    /// Probability that the finger is pressed.
    pub pressed_probability: Real,
    /// Likelihood-ratio statistic of the loads against none (χ² units).
    pub statistic: Real,
    /// RMS of the observed marker coordinates about the free shape, metres.
    pub free_rms_m: Real,
    /// RMS about the estimate, metres.
    pub fit_rms_m: Real,
    /// Markers used.
    pub observed_markers: usize,
    /// Depth observations used: patches of the surface the depth image saw, each pooling
    /// pixels (0 without a depth image or with depth off).
    pub depth_rows: usize,
    /// Depth pixels pooled into them.
    pub depth_pixels: usize,
    /// Linear solves of the frame (static Newton iterations, dynamic steps, tangents;
    /// those of solves that did not converge as well).
    pub solves: usize,
    /// Whether the load search stopped short of its converged answer: it spent
    /// [`PhysicsConfig::frame_solve_budget`], or the model could carry no part of the loads it
    /// proposed. The loads are the best it found.
    pub degraded: bool,
    /// Why there is no estimate for this finger in this frame (too few markers, a static solve
    /// that did not converge); its shape is then the rest shape and its map zero.
    pub error: Option<String>,
}

/// What the physics estimator says beyond shape and contact: the loads it found and, per
/// finger, the decision's figures (its [`HandEstimator::Details`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicsDetails {
    /// The loads found, finger by finger.
    pub loads: Vec<ContactLoad>,
    /// Per finger: the decision's figures.
    pub fingers: Vec<FingerReport>,
}

impl PhysicsDetails {
    /// The total force on each finger (the sum of its loads), hand frame, newtons.
    pub fn finger_forces_n(&self) -> Vec<Vector3> {
        let mut out = vec![Vector3::zeros(); self.fingers.len()];
        for l in &self.loads {
            out[l.finger] += l.force_n;
        }
        out
    }
}

/// Everything the physics estimator estimates about one instant: the dented shape, contact
/// probability and force per vertex (always given), and the loads and finger reports.
pub type PhysicsEstimate = HandEstimate<PhysicsDetails>;

/// Checks that an observation fits `hand`: one marker list and one pull list per finger, of
/// the finger's lengths, finite, and a finite pose.
///
/// # Errors
/// [`PhysicsError::LengthMismatch`], [`PhysicsError::FingerLengthMismatch`] or
/// [`PhysicsError::NonFinite`] naming the finger and the item, or
/// [`PhysicsError::InvalidParameter`] for the pose.
pub(crate) fn check_observation(
    hand: &HandModel,
    obs: &FullObservation<'_>,
) -> Result<(), PhysicsError> {
    let n = hand.num_fingers();
    for (what, got) in [
        ("fingers of the keypoints", obs.keypoints.fingers.len()),
        ("fingers of the tendon pulls", obs.tendon_pull_m.len()),
    ] {
        if got != n {
            return Err(PhysicsError::LengthMismatch {
                what,
                expected: n,
                got,
            });
        }
    }
    for (f, hf) in hand.fingers().iter().enumerate() {
        let markers = &obs.keypoints.fingers[f];
        let pulls = &obs.tendon_pull_m[f];
        for (what, expected, got) in [
            ("markers", hf.model.marker_vertices().len(), markers.len()),
            ("tendon pulls", hf.model.tendon_routes().len(), pulls.len()),
        ] {
            if got != expected {
                return Err(PhysicsError::FingerLengthMismatch {
                    what,
                    finger: f,
                    expected,
                    got,
                });
            }
        }
        for (tendon, (route, &pull_m)) in hf.model.tendon_routes().iter().zip(pulls).enumerate() {
            let limit_m = MAX_PULL_FRACTION * route.length();
            if pull_m.is_finite() && pull_m.abs() > limit_m {
                return Err(PhysicsError::PullOutOfRange {
                    finger: f,
                    tendon,
                    pull_m,
                    limit_m,
                });
            }
        }
        let bad_marker = markers
            .iter()
            .position(|m| m.is_some_and(|p| !p.coords.iter().all(|c| c.is_finite())));
        let bad_pull = pulls.iter().position(|p| !p.is_finite());
        for (what, index) in [("marker", bad_marker), ("tendon pull", bad_pull)] {
            if let Some(index) = index {
                return Err(PhysicsError::NonFinite {
                    what,
                    finger: f,
                    index,
                });
            }
        }
    }
    let iso = obs.world_from_hand.iso();
    if !(iso.translation.vector.iter().all(|v| v.is_finite())
        && iso.rotation.coords.iter().all(|v| v.is_finite()))
    {
        return Err(PhysicsError::InvalidParameter {
            name: "world_from_hand",
            value: Real::NAN,
            reason: "must be finite",
        });
    }
    // A rotation whose quaternion is not of unit length scales as it turns: not a rigid pose.
    let norm = iso.rotation.coords.norm();
    if (norm - 1.0).abs() > 1e-6 {
        return Err(PhysicsError::InvalidParameter {
            name: "world_from_hand",
            value: norm,
            reason: "its rotation's quaternion must have unit length (a rigid pose)",
        });
    }
    Ok(())
}

/// The largest tendon pull taken either way, as a fraction of the tendon's length.
pub const MAX_PULL_FRACTION: Real = 0.25;

/// One finger's observed markers (finger frame) and its estimate.
type FingerResult = (Vec<Option<Point3>>, Result<FingerEstimate, PhysicsError>);

/// What one finger's estimate is given, in the finger frame.
struct FingerInput<'a> {
    hand_from_finger: Iso3,
    markers: Vec<Option<Point3>>,
    gravity: Vector3,
    world_from_finger: Iso3,
    pulls: &'a [Real],
    time_secs: Option<Real>,
}

impl FingerInput<'_> {
    fn observation<'b>(
        &'b self,
        depth: &'b [crate::finger::DepthRow],
        covered: &'b [bool],
        seen_through: &'b [bool],
        image: Option<(moe_geom::depth::DepthImage<'b>, Iso3)>,
    ) -> FingerObservation<'b> {
        FingerObservation {
            markers: &self.markers,
            gravity: self.gravity,
            world_from_finger: self.world_from_finger,
            pulls: self.pulls,
            time_secs: self.time_secs,
            depth,
            covered,
            seen_through,
            image,
        }
    }
}

/// Per marker (its predicted place, hand frame): whether the depth image sees something in
/// front of it by more than `front_gate_m` (not the finger's own surface) and at most
/// `reach_m` (an object close to the finger, not one passing far in front); the nearest depth
/// in the 3 × 3 pixels about its projection.
fn covered_markers(
    depth: &DepthImage<'_>,
    markers_in_hand: impl Iterator<Item = Point3>,
    front_gate_m: Real,
    reach_m: Real,
) -> Vec<bool> {
    let camera_from_hand = depth.hand_from_camera().iso().inverse();
    markers_in_hand
        .map(|p| {
            let p = camera_from_hand * p;
            crate::finger::nearest_depth(depth, &p).is_some_and(|nearest| {
                let ahead = p.z - nearest;
                ahead > front_gate_m && ahead <= reach_m
            })
        })
        .collect()
}

/// The physics estimator of a hand: per finger, the loads that explain its markers through its
/// FEM model, and the shape they produce.
#[derive(Debug)]
pub struct PhysicsEstimator {
    hand: HandModel,
    material: HandMaterial,
    config: PhysicsConfig,
    fingers: Vec<FingerInverse>,
}

impl PhysicsEstimator {
    /// Builds the model of every finger of `hand`.
    ///
    /// # Errors
    /// Invalid material or settings, or a finger the FEM cannot mesh (naming the finger).
    pub fn new(
        hand: &HandModel,
        material: &HandMaterial,
        config: &PhysicsConfig,
    ) -> Result<Self, PhysicsError> {
        material.validate()?;
        material.check_hand(hand)?;
        config.validate()?;
        let fingers = hand
            .fingers()
            .iter()
            .enumerate()
            .map(|(i, f)| FingerInverse::new(i, &f.model, material, config))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            hand: hand.clone(),
            material: material.clone(),
            config: config.clone(),
            fingers,
        })
    }

    /// The hand.
    pub fn hand(&self) -> &HandModel {
        &self.hand
    }

    /// The material.
    pub fn material(&self) -> &HandMaterial {
        &self.material
    }

    /// The settings.
    pub fn config(&self) -> &PhysicsConfig {
        &self.config
    }

    /// Finger `f`'s estimator.
    pub(crate) fn finger_mut(&mut self, f: usize) -> &mut FingerInverse {
        &mut self.fingers[f]
    }

    /// Forgets the stream (warm starts and the previous observation).
    pub fn reset(&mut self) {
        self.fingers.iter_mut().for_each(FingerInverse::reset);
    }

    /// Checks an observation against the hand.
    fn check(&self, obs: &FullObservation<'_>) -> Result<(), PhysicsError> {
        check_observation(&self.hand, obs)
    }

    /// The estimate of an observation with everything the estimator needs.
    fn estimate_full(
        &mut self,
        obs: &FullObservation<'_>,
    ) -> Result<PhysicsEstimate, PhysicsError> {
        self.check(obs)?;
        let (keypoints, pulls) = (obs.keypoints, obs.tendon_pull_m);
        let mut out = Parts::default();
        let world_from_hand: Iso3 = *obs.world_from_hand.iso();
        let gravity_in_hand =
            world_from_hand.inverse_transform_vector(&Vector3::from(self.config.gravity_m_s2));
        // The fingers are independent: each is estimated on its own thread (the results are
        // those of a sequential loop, bit for bit), then gathered in finger order.
        let inputs: Vec<FingerInput<'_>> = self
            .hand
            .fingers()
            .iter()
            .enumerate()
            .map(|(f, hf)| {
                let hand_from_finger: Iso3 = *hf.hand_from_finger.iso();
                let finger_from_hand = hand_from_finger.inverse();
                FingerInput {
                    hand_from_finger,
                    markers: keypoints.fingers[f]
                        .iter()
                        .map(|m| m.map(|p| finger_from_hand * p))
                        .collect(),
                    gravity: finger_from_hand * gravity_in_hand,
                    world_from_finger: world_from_hand * hand_from_finger,
                    pulls: &pulls[f],
                    time_secs: obs.time_secs,
                }
            })
            .collect();
        let results = match obs.depth.filter(|_| self.config.depth.enabled) {
            Some(depth) => self.estimate_with_depth(&inputs, &depth)?,
            None => self
                .fingers
                .par_iter_mut()
                .zip(&inputs)
                .map(|(inverse, input)| {
                    let est = inverse.estimate(&input.observation(&[], &[], &[], None));
                    (input.markers.clone(), est)
                })
                .collect(),
        };
        for (f, (markers, result)) in results.into_iter().enumerate() {
            let hf = &self.hand.fingers()[f];
            let hand_from_finger: Iso3 = *hf.hand_from_finger.iso();
            let nv = hf.model.mesh().num_vertices();
            match result {
                Ok(est) => self.push_finger(&mut out, f, &hand_from_finger, hf, est),
                Err(e) => {
                    out.shape.push(self.hand.rest_vertices_in_hand(f));
                    out.contact.push(vec![0.0; nv]);
                    out.vertex_force_n.push(vec![Vector3::zeros(); nv]);
                    out.fingers.push(FingerReport {
                        pressed_probability: 0.0,
                        statistic: 0.0,
                        free_rms_m: Real::NAN,
                        fit_rms_m: Real::NAN,
                        observed_markers: markers.iter().filter(|m| m.is_some()).count(),
                        depth_rows: 0,
                        depth_pixels: 0,
                        solves: 0,
                        degraded: false,
                        error: Some(e.to_string()),
                    });
                }
            }
        }
        Ok(PhysicsEstimate {
            shape: HandShape { fingers: out.shape },
            contact: ContactMap {
                fingers: out.contact,
            },
            vertex_force_n: Some(out.vertex_force_n),
            details: PhysicsDetails {
                loads: out.loads,
                fingers: out.fingers,
            },
        })
    }

    /// Every finger's estimate with the depth image: the free fingers first, which predict
    /// where the camera sees each finger's surface (a finger whose start fails is predicted at
    /// rest, for the others' occlusion); the pixels are associated with the predicted meshes and
    /// pooled into each finger's depth observations; then each finger's estimate is finished.
    fn estimate_with_depth(
        &mut self,
        inputs: &[FingerInput<'_>],
        depth: &DepthImage<'_>,
    ) -> Result<Vec<FingerResult>, PhysicsError> {
        let begun: Vec<Result<Begun, PhysicsError>> = self
            .fingers
            .par_iter_mut()
            .zip(inputs)
            .map(|(inverse, input)| inverse.begin(&input.observation(&[], &[], &[], None)))
            .collect();
        let predicted: Vec<Option<Vec<Point3>>> = self
            .fingers
            .iter()
            .zip(&begun)
            .map(|(inverse, b)| b.as_ref().ok().map(|b| inverse.predicted_surface(b)))
            .collect();
        let shape = HandShape {
            fingers: predicted
                .iter()
                .zip(inputs)
                .enumerate()
                .map(|(f, (p, input))| match p {
                    Some(p) => p.iter().map(|q| input.hand_from_finger * q).collect(),
                    None => self.hand.rest_vertices_in_hand(f),
                })
                .collect(),
        };
        let found = associate_depth(&self.hand, &shape, depth, &self.config.depth.association())?;
        let settings = self.config.depth.clone();
        let noise = settings.noise;
        Ok(self
            .fingers
            .par_iter_mut()
            .zip(inputs)
            .zip(
                begun
                    .into_iter()
                    .zip(predicted)
                    .zip(&found)
                    .collect::<Vec<_>>(),
            )
            .map(|((inverse, input), ((begun, predicted), found))| {
                let est = begun.and_then(|begun| {
                    let finger_from_hand = input.hand_from_finger.inverse();
                    let predicted = predicted.as_deref().unwrap_or(&[]);
                    let pixels = moe_geom::depth::surface_pixels(
                        &found.points,
                        depth,
                        &noise,
                        &finger_from_hand,
                    );
                    let rows = inverse.depth_rows(&pixels, predicted);
                    let (covered, seen_through) = if predicted.is_empty() {
                        (Vec::new(), Vec::new())
                    } else {
                        let covered = covered_markers(
                            depth,
                            inverse
                                .marker_vertices()
                                .iter()
                                .map(|&v| input.hand_from_finger * predicted[v as usize]),
                            settings.front_gate_m,
                            settings.reach_m,
                        );
                        let seen_through = if settings.seen_through_prior < 1.0 {
                            inverse.seen_through(depth, predicted, &input.hand_from_finger, true)
                        } else {
                            Vec::new()
                        };
                        (covered, seen_through)
                    };
                    inverse.finish(
                        &input.observation(
                            &rows,
                            &covered,
                            &seen_through,
                            Some((*depth, input.hand_from_finger)),
                        ),
                        begun,
                    )
                });
                (input.markers.clone(), est)
            })
            .collect())
    }

    fn push_finger(
        &self,
        out: &mut Parts,
        f: usize,
        hand_from_finger: &Iso3,
        hf: &moe_geom::HandFinger,
        est: FingerEstimate,
    ) {
        let rest = hf.model.mesh().vertices();
        let surface: Vec<Point3> = est.surface.iter().map(|p| hand_from_finger * p).collect();
        for l in &est.loads {
            let force_n = hand_from_finger * l.force;
            out.loads.push(ContactLoad {
                finger: f,
                vertex: l.vertex,
                location_rest: hand_from_finger * weighted(&l.place, rest),
                location: weighted(&l.place, &surface),
                force_n,
                magnitude_n: force_n.norm(),
                magnitude_sd_n: l.force_sd_n,
                location_sd_m: l.location_sd_m,
                patch: l.patch.clone(),
            });
        }
        out.shape.push(surface);
        out.contact.push(est.probability);
        out.vertex_force_n.push(
            est.vertex_force
                .iter()
                .map(|v| hand_from_finger * v)
                .collect(),
        );
        out.fingers.push(FingerReport {
            pressed_probability: est.pressed_probability,
            statistic: est.statistic,
            free_rms_m: est.free_rms_m,
            fit_rms_m: est.fit_rms_m,
            observed_markers: est.observed_markers,
            depth_rows: est.depth_rows,
            depth_pixels: est.depth_pixels,
            solves: est.solves,
            degraded: est.degraded,
            error: None,
        });
    }
}

impl HandEstimator for PhysicsEstimator {
    type Details = PhysicsDetails;
    type Error = PhysicsError;

    /// Estimates the loads and the shape of every finger from the observation's markers,
    /// tendon pulls, wrist pose and time. A finger whose estimate fails (too few markers, a
    /// static solve that does not converge) is reported in its [`FingerReport::error`] with the
    /// rest shape and no contact; the others go on.
    ///
    /// # Errors
    /// [`PhysicsError::Missing`] for an observation without markers, pulls or pose, and an
    /// observation that does not fit the hand (counts, non-finite values).
    fn estimate(&mut self, observation: &Observation<'_>) -> Result<PhysicsEstimate, PhysicsError> {
        self.estimate_full(&FullObservation::of(observation)?)
    }

    /// Forgets the stream (warm starts and the previous observation).
    fn reset(&mut self) {
        PhysicsEstimator::reset(self);
    }
}

/// An estimate's values, finger by finger, as they are gathered.
#[derive(Debug, Default)]
struct Parts {
    loads: Vec<ContactLoad>,
    shape: Vec<Vec<Point3>>,
    contact: Vec<Vec<Real>>,
    vertex_force_n: Vec<Vec<Vector3>>,
    fingers: Vec<FingerReport>,
}

/// The point `Σ w·points[v]` of a place's vertices and weights.
fn weighted(place: &[(u32, Real)], points: &[Point3]) -> Point3 {
    place
        .iter()
        .map(|&(v, w)| points[v as usize].coords * w)
        .sum::<Vector3>()
        .into()
}

#[cfg(test)]
mod tests {
    use moe_geom::{CameraIntrinsics, HandFromCamera};

    use super::*;

    /// A marker is covered by what the image sees in front of it beyond the front gate and
    /// within the reach: not by its own surface, not by an object far in front, not by a hole.
    #[test]
    fn a_marker_is_covered_by_an_object_just_in_front_of_it() {
        let k = CameraIntrinsics::default();
        let mount = HandFromCamera::identity();
        // Markers 5 cm in front of the camera: on the axis and off it.
        let markers = [Point3::new(0.0, 0.0, 0.05), Point3::new(0.01, -0.005, 0.05)];
        let covered = |plate_m: f32| {
            let pixels = vec![plate_m; (k.width * k.height) as usize];
            let image = DepthImage::new(&pixels, k, mount).unwrap();
            covered_markers(&image, markers.iter().copied(), 0.003, 0.01)
        };
        assert_eq!(covered(0.045), [true, true], "5 mm in front");
        assert_eq!(
            covered(0.0495),
            [false, false],
            "within the front gate: the surface"
        );
        assert_eq!(
            covered(0.03),
            [false, false],
            "2 cm in front: passing, not touching"
        );
        assert_eq!(covered(0.06), [false, false], "behind");
        assert_eq!(covered(0.0), [false, false], "holes");
        assert_eq!(covered(f32::NAN), [false, false], "holes");
    }
}
