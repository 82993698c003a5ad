//! Patting a hidden body to reconstruct it (paper §5.3, §6.1): the two-finger hand pats a head
//! or an arm in the simulator, the wrist camera sees the hand at every pat's deepest press, the
//! pipeline (markers → SR-ARAP → contact model) turns each frame into contact points in the
//! world, and the contact points of all pats feed the surface reconstruction.
//!
//! [`simulate_patting`](crate::patting::simulate_patting) renders the pats as episode frames
//! with their ground truth, [`estimate_pat_contacts`](crate::patting::estimate_pat_contacts)
//! runs a pipeline over them ([`paper_pat_contacts`](crate::patting::paper_pat_contacts) and
//! [`physics_pat_contacts`](crate::patting::physics_pat_contacts) build it), and
//! [`true_pat_contacts`](crate::patting::true_pat_contacts)
//! gives the simulator's own contact vertices (the upper bound a perfect estimator would
//! reach). [`run_patting_study`](crate::patting::run_patting_study) is the paper's study over
//! them: contact points and reconstructed surfaces against the truth, per body and pair.

use moe_arap::{MultiShapeEstimator, ShapeConfig};
use moe_geom::bodies::{ArmParams, HeadParams};
use moe_geom::{ContactEstimator, HandEstimator, HandModel, Iso3, Point3, Real, Staged, TriMesh};
use moe_gpis::bench_scene::SceneKind;
use moe_record::{EpisodeFrame, EpisodeInfo};
use moe_tendon_sim::paper_scenes::{self, ARM_PATS, HEAD_PATS, pat_press_time};
use moe_tendon_sim::{Scene, SceneConfig, run_saving};
use serde::Serialize;

use crate::LabError;

mod study;

use crate::episode::{EpisodeRecorder, saved_frame_at};
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::pipeline::Pipeline;
use moe_touch::{PhysicsPipeline, TouchError};
pub use study::{
    DEFAULT_ESTIMATED_NOISE_FLOOR_M, DEFAULT_PRIOR_GATE_M, PatContactResult, PatPairReport,
    PattingBodyReport, PattingSize, PattingStudyOptions, PattingStudyReport, PattingSummary,
    PattingTable2, PattingTable3, SMALL_PATS, TABLE3_METHODS, body_name, body_seed,
    check_distances, pair_progress, patting_hand, run_patting_study,
};

/// The number of poses of a body's patting scene.
pub fn pats_of(body: SceneKind) -> usize {
    match body {
        SceneKind::Head => HEAD_PATS,
        SceneKind::Arm => ARM_PATS,
    }
}

/// The patting scene of the body of `seed`, with its first `pats` poses.
///
/// # Errors
/// `pats` out of range, mesh errors.
pub fn patting_scene(body: SceneKind, seed: u64, pats: usize) -> Result<SceneConfig, LabError> {
    Ok(match body {
        SceneKind::Head => paper_scenes::head_patting_of(seed, pats)?,
        SceneKind::Arm => paper_scenes::arm_patting_of(seed, pats)?,
    })
}

/// A member of the body's family as a closed mesh at icosphere `level`: the task prior
/// (another person's head, another arm).
///
/// # Errors
/// Mesh validation (never for the sampled families).
pub fn body_mesh(body: SceneKind, seed: u64, level: u32) -> Result<TriMesh, LabError> {
    Ok(match body {
        SceneKind::Head => HeadParams::sample(seed).mesh(level)?,
        SceneKind::Arm => ArmParams::sample(seed).mesh(level)?,
    })
}

/// The pats of one simulated body, one episode frame per pat at its deepest press.
#[derive(Debug, Clone)]
pub struct PattingEpisode {
    /// Which body.
    pub body: SceneKind,
    /// The camera, the hand and the finger meshes.
    pub info: EpisodeInfo,
    /// One frame per pat, rendered by the wrist camera with its noise, with the ground truth.
    pub frames: Vec<EpisodeFrame>,
    /// The patted surface as simulated, world frame.
    pub truth: TriMesh,
}

/// Simulates patting the body of `truth_seed` with its first `pats` poses and renders every
/// pat's deepest press (camera noise seeded by `camera_seed`).
///
/// # Errors
/// `pats` out of range, a diverging simulation, a camera that cannot render.
pub fn simulate_patting(
    body: SceneKind,
    truth_seed: u64,
    pats: usize,
    camera_seed: u64,
) -> Result<PattingEpisode, LabError> {
    let config = patting_scene(body, truth_seed, pats)?;
    let truth = match config.obstacles.first().map(|o| &o.shape) {
        Some(moe_tendon_sim::ObstacleShape::TriangleMesh { vertices_m, faces }) => TriMesh::new(
            vertices_m.iter().map(|p| Point3::from(*p)).collect(),
            faces.clone(),
        )?,
        _ => {
            return Err(LabError::InvalidEvaluation {
                reason: "the patting scene's body is not a triangle mesh".into(),
            });
        }
    };
    let mut scene = Scene::new(config)?;
    let steps = scene.num_steps();
    let saved = run_saving(&mut scene, steps)?;
    let name = match body {
        SceneKind::Head => "head_patting",
        SceneKind::Arm => "arm_patting",
    };
    let recorder = EpisodeRecorder::new(&scene, name, camera_seed)?;
    let mut frames = Vec::with_capacity(pats);
    for k in 0..pats {
        let t = pat_press_time(k);
        let (index, frame) =
            saved_frame_at(&saved, t).ok_or_else(|| LabError::InvalidEvaluation {
                reason: format!("{name}: the simulation saved no frame"),
            })?;
        frames.push(recorder.frame(&scene, frame, index as u64)?);
    }
    Ok(PattingEpisode {
        body,
        info: recorder.info().clone(),
        frames,
        truth,
    })
}

/// The contact points a pipeline estimated over the pats.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PatContacts {
    /// Every estimated contact point of every pat, world frame.
    pub points_in_world: Vec<Point3>,
    /// Contact points per pat.
    pub per_pat: Vec<usize>,
    /// The pats whose frame the pipeline could not estimate (counted as pats without contact).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub failed_pats: Vec<FailedPat>,
}

/// A pat whose frame the pipeline could not estimate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FailedPat {
    /// The pat's index.
    pub pat: usize,
    /// Why (the failing stage and its error).
    pub error: String,
}

impl PatContacts {
    /// Pats in which no contact was estimated.
    pub fn pats_without_contact(&self) -> usize {
        self.per_pat.iter().filter(|&&n| n == 0).count()
    }
}

/// Runs `pipeline` on every pat of `episode`, each from a fresh stream (the pats are separate
/// touches), and collects the contact points in the world frame. A pat whose frame fails is
/// named in [`PatContacts::failed_pats`] and gives no contact; the others go on.
pub fn estimate_pat_contacts<E: HandEstimator>(
    pipeline: &mut Pipeline<E>,
    episode: &PattingEpisode,
) -> PatContacts {
    let mut out = PatContacts::default();
    for (pat, frame) in episode.frames.iter().enumerate() {
        pipeline.reset();
        let estimate = match pipeline.process(frame.rgbd(), &frame.observation()) {
            Ok(e) => e,
            Err(failure) => {
                out.per_pat.push(0);
                out.failed_pats.push(FailedPat {
                    pat,
                    error: failure.to_string(),
                });
                continue;
            }
        };
        out.per_pat.push(estimate.contacts_in_world.len());
        out.points_in_world
            .extend(estimate.contacts_in_world.iter().map(|c| c.point));
    }
    out
}

/// The contacts on every pat of the pipeline `build` makes around the episode's detector.
///
/// # Errors
/// A detector for another hand than the episode's, or a pipeline `build` cannot make.
pub fn pat_contacts<E: HandEstimator>(
    hand: &HandModel,
    episode: &PattingEpisode,
    build: impl FnOnce(MarkerDetector) -> Result<Pipeline<E>, TouchError>,
) -> Result<PatContacts, LabError> {
    let detector = MarkerDetector::for_episode(&episode.info, hand, DetectorConfig::default())?;
    Ok(estimate_pat_contacts(&mut build(detector)?, episode))
}

/// The paper's pipeline's contacts on every pat: SR-ARAP with `shape` and `contact` at
/// `threshold`.
///
/// # Errors
/// As [`pat_contacts`].
pub fn paper_pat_contacts<C: ContactEstimator>(
    hand: &HandModel,
    episode: &PattingEpisode,
    shape: &ShapeConfig,
    contact: C,
    threshold: Real,
) -> Result<PatContacts, LabError> {
    pat_contacts(hand, episode, |detector| {
        let shape = MultiShapeEstimator::new(hand.clone(), shape.clone())?;
        Pipeline::new(
            hand.clone(),
            detector,
            Staged::new(shape, contact),
            threshold,
        )
    })
}

/// The physics pipeline's contacts on every pat, with `material` and `config`.
///
/// # Errors
/// As [`pat_contacts`].
pub fn physics_pat_contacts(
    hand: &HandModel,
    episode: &PattingEpisode,
    material: &moe_physics::HandMaterial,
    config: &moe_physics::PhysicsConfig,
) -> Result<PatContacts, LabError> {
    pat_contacts(hand, episode, |detector| {
        PhysicsPipeline::physics(hand.clone(), detector, material, config)
    })
}

/// The simulator's contact vertices of every pat, world frame: the contacts a perfect estimator
/// would report.
pub fn true_pat_contacts(episode: &PattingEpisode) -> PatContacts {
    let mut out = PatContacts::default();
    for frame in &episode.frames {
        let before = out.points_in_world.len();
        out.points_in_world
            .extend(true_contacts_in_world(frame, &frame.world_from_hand));
        out.per_pat.push(out.points_in_world.len() - before);
    }
    out
}

fn true_contacts_in_world(frame: &EpisodeFrame, world_from_hand: &Iso3) -> Vec<Point3> {
    frame
        .contact_vertices
        .iter()
        .zip(&frame.finger_vertices_in_hand)
        .flat_map(|(ids, vertices)| {
            ids.iter()
                .filter_map(|&v| vertices.get(v as usize))
                .map(|p| world_from_hand * p)
        })
        .collect()
}

/// Mean unsigned distance of `points` to the surface `truth`, mm (`None` without points).
///
/// # Errors
/// A truth that is not watertight.
pub fn ucd_to_truth_mm(points: &[Point3], truth: &TriMesh) -> Result<Option<Real>, LabError> {
    if points.is_empty() {
        return Ok(None);
    }
    let sdf = moe_gpis::MeshSdfMean::new(truth)?;
    Ok(Some(moe_gpis::bench_scene::ucd_to_surface_mm(
        points, &sdf,
    )?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_contact::ContactError;
    use moe_geom::{
        ContactEstimate, ContactInput, ContactMap, FingerParams, HandModel, HandPreset, HandShape,
        Observation, ShapeEstimator,
    };
    use moe_touch::perception::{DetectorConfig, MarkerDetector};

    /// The simulator's own shape of one frame, whatever the keypoints.
    struct TrueShape(HandShape);

    impl ShapeEstimator for TrueShape {
        type Error = ContactError;
        fn estimate_shape(&mut self, _: &Observation<'_>) -> Result<HandShape, ContactError> {
            Ok(self.0.clone())
        }
    }

    /// The simulator's own contact labels of one frame.
    struct TrueContact(ContactMap);

    impl ContactEstimator for TrueContact {
        type Error = ContactError;
        fn estimate(&mut self, _: &ContactInput<'_>) -> Result<ContactEstimate, ContactError> {
            Ok(ContactEstimate::from_map(self.0.clone()))
        }
    }

    #[test]
    fn true_shapes_and_labels_put_the_world_contacts_on_the_patted_surface() {
        let episode = simulate_patting(SceneKind::Head, paper_scenes::HEAD_SEED, 2, 0).unwrap();
        assert_eq!(episode.frames.len(), 2);
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let sdf = moe_gpis::MeshSdfMean::new(&episode.truth).unwrap();
        let truth = true_pat_contacts(&episode);
        assert!(truth.per_pat.iter().all(|&n| n > 0), "{:?}", truth.per_pat);
        let mut all = Vec::new();
        for frame in &episode.frames {
            let labels: Vec<Vec<bool>> = frame
                .finger_vertices_in_hand
                .iter()
                .zip(&frame.contact_vertices)
                .map(|(v, ids)| {
                    let mut l = vec![false; v.len()];
                    ids.iter().for_each(|&i| l[i as usize] = true);
                    l
                })
                .collect();
            let detector =
                MarkerDetector::for_episode(&episode.info, &hand, DetectorConfig::default())
                    .unwrap();
            let mut pipeline = Pipeline::new(
                hand.clone(),
                detector,
                Staged::new(
                    TrueShape(HandShape {
                        fingers: frame.finger_vertices_in_hand.clone(),
                    }),
                    TrueContact(ContactMap::from_labels(&labels)),
                ),
                0.5,
            )
            .unwrap();
            let one = PattingEpisode {
                frames: vec![frame.clone()],
                ..episode.clone()
            };
            all.extend(estimate_pat_contacts(&mut pipeline, &one).points_in_world);
        }
        // The frame chain (finger → hand → world) reproduces the simulator's contacts, and they
        // lie within the press rule's distance (1 mm) of the body's surface.
        assert_eq!(all.len(), truth.points_in_world.len());
        for (a, b) in all.iter().zip(&truth.points_in_world) {
            assert!((a - b).norm() < 1e-12);
        }
        let worst = all
            .iter()
            .map(|p| moe_gpis::MeanFunction::value(&sdf, p).abs())
            .fold(0.0, Real::max);
        assert!(worst <= 1.0e-3 + 1e-6, "worst distance {worst} m");
        let ucd = ucd_to_truth_mm(&all, &episode.truth).unwrap().unwrap();
        assert!(ucd < 1.0, "{ucd} mm");
    }

    /// A pat presses the fingertip along its axis, which moves the markers little: from them
    /// and the finger's own depth pixels the physics estimator places some contacts on the
    /// finger's flank, far from the head. The head is in view beyond the fingertips, and along
    /// the flank the camera sees past the finger to it: no object fills the space there. With
    /// that evidence the contacts of the first three pats of the head come within a few
    /// millimetres of it (14.8 → 3.8 mm at this change).
    #[test]
    fn the_space_seen_empty_about_the_finger_moves_a_pat_onto_the_fingertip() {
        let episode = simulate_patting(SceneKind::Head, paper_scenes::HEAD_SEED, 3, 0).unwrap();
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let ucd = |prior: Real| {
            let mut config = moe_physics::PhysicsConfig::default();
            config.depth.enabled = true;
            config.depth.seen_through_prior = prior;
            let contacts = physics_pat_contacts(
                &hand,
                &episode,
                &moe_physics::HandMaterial::default(),
                &config,
            )
            .unwrap();
            ucd_to_truth_mm(&contacts.points_in_world, &episode.truth)
                .unwrap()
                .unwrap()
        };
        let (without, with) = (ucd(1.0), ucd(0.02));
        assert!(without > 12.0, "without the evidence: {without:.2} mm");
        assert!(
            with < 6.0,
            "with it: {with:.2} mm, without: {without:.2} mm"
        );
    }

    #[test]
    fn pat_counts_out_of_range_are_refused() {
        moe_geom::assert_err!(
            patting_scene(SceneKind::Head, 1, 0),
            LabError::Simulation(moe_tendon_sim::SimError::InvalidParameter {
                name: "pats",
                value: 0.0,
                ..
            })
        );
        moe_geom::assert_err!(
            patting_scene(SceneKind::Arm, 1, ARM_PATS + 1),
            LabError::Simulation(moe_tendon_sim::SimError::InvalidParameter {
                name: "pats",
                value,
                ..
            }) if *value == (ARM_PATS + 1) as Real
        );
        let arm = patting_scene(SceneKind::Arm, paper_scenes::ARM_SEED, ARM_PATS).unwrap();
        assert_eq!(arm.wrist.keyframes.len(), 5 * ARM_PATS);
    }
}
