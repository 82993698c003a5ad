//! Table 2: the plate scenes simulated with the plate's pose perturbed, and the contact estimates
//! scored over the frames with contact.

use moe_arap::{MultiShapeEstimator, ShapeConfig};
use moe_contact::{ContactMetrics, ContactReport, DgcnnEstimator, KnnIndex};
use moe_geom::math::UnitQuat;
use moe_geom::{ContactInput, HandModel, LabelledFrame, Real, SeededRng, Vector3};
use moe_tendon_sim::SceneConfig;
use serde::Serialize;

use crate::error::LabError;

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

/// The paper's plate scenes of Table 2 (Fig. 5), in the paper's order: name and region
/// pressed. Their scene files, `fixtures/scenes/<name>.toml`, are hand-written and built into
/// this crate, so that every study finds the same scenes wherever it runs.
pub const PLATE_SCENES: [(&str, &str); 6] = [
    ("plate_tip_front", "tip"),
    ("plate_tip_side", "tip"),
    ("plate_middle_front", "middle"),
    ("plate_middle_side", "middle"),
    ("plate_base_front", "base"),
    ("plate_base_side", "base"),
];

/// The text of each of [`PLATE_SCENES`]' files, in its order.
const PLATE_SCENE_FILES: [&str; 6] = [
    include_str!("../../../../fixtures/scenes/plate_tip_front.toml"),
    include_str!("../../../../fixtures/scenes/plate_tip_side.toml"),
    include_str!("../../../../fixtures/scenes/plate_middle_front.toml"),
    include_str!("../../../../fixtures/scenes/plate_middle_side.toml"),
    include_str!("../../../../fixtures/scenes/plate_base_front.toml"),
    include_str!("../../../../fixtures/scenes/plate_base_side.toml"),
];

/// The one registry of the paper's plate scenes: [`PLATE_SCENES`] with their configurations, in
/// the paper's order (the scenes of [`evaluate_plates`] and the physics study's Table 2).
///
/// # Errors
/// A scene file that does not parse (a build from an edited checkout).
pub fn plate_scenes() -> Result<Vec<PlateScene>, LabError> {
    PLATE_SCENES
        .iter()
        .zip(PLATE_SCENE_FILES)
        .map(|(&(name, region), text)| {
            let path = std::path::PathBuf::from(format!("fixtures/scenes/{name}.toml"));
            Ok(PlateScene {
                name: name.to_owned(),
                region: region.to_owned(),
                config: moe_io::parse_toml(text.as_bytes(), &path)?,
            })
        })
        .collect()
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
