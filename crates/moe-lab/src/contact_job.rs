//! Contact estimated from files, as `moe-touch contact` runs it: the contact network on a point
//! cloud (a model file's check) or on a hand shape, or the physics estimator on one frame of
//! markers and tendon pulls; each with its typed record, its summary lines and its output
//! files (meshes coloured by contact probability, `contacts.csv`, `loads.json`,
//! `contact.json`).

use std::path::Path;
use std::time::Instant;

use moe_contact::{Aggregation, DgcnnEstimator, ForwardTimings};
use moe_geom::{
    ContactInput, HandEstimator as _, HandKeypoints, HandModel, HandShape, Observation, Real,
    WorldFromHand,
};
use moe_io::IoError;
use moe_physics::PhysicsEstimator;
use serde::Serialize;

use crate::contact_output::{
    CONTACTS_HEADER, FingerContactRecord, PhysicsFingerRecord, contact_fingers, contact_rows,
    physics_fingers,
};
use crate::error::LabError;
use crate::output_files::OutputFiles;
use crate::point_cloud::{NetworkPrecision, PointCloudContact, PointCloudModel};
use crate::run::LoadRecord;

/// The frame of every place and force written.
const FRAME: &str = "hand";

/// The units of the physics estimate's files.
const UNITS: &str = "metres, newtons";

/// Stage timings of the network, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TimingsMs {
    /// The kNN searches.
    pub knn: f64,
    /// The EdgeConv products and reductions.
    pub edgeconv: f64,
    /// Pooling and the per-point head.
    pub head: f64,
    /// The network in all.
    pub network: f64,
    /// Everything, from `started` on.
    pub total: f64,
}

impl TimingsMs {
    fn new(t: ForwardTimings, started: Instant) -> Self {
        Self {
            knn: t.knn_s * 1e3,
            edgeconv: t.edgeconv_s * 1e3,
            head: t.head_s * 1e3,
            network: t.total_s() * 1e3,
            total: started.elapsed().as_secs_f64() * 1e3,
        }
    }
}

/// The name of a float type in the reports.
fn precision_name(precision: NetworkPrecision) -> &'static str {
    match precision {
        NetworkPrecision::F32 => "f32",
        NetworkPrecision::F64 => "f64",
    }
}

/// The `moe-touch contact --points` report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PointsReport {
    /// Points of the cloud.
    pub points: usize,
    /// The model file.
    pub model: String,
    /// Whether it has a card.
    pub card: bool,
    /// The edge aggregation the network ran.
    pub aggregation: Aggregation,
    /// The float type it computed in.
    pub dtype: &'static str,
    /// The contact threshold.
    pub threshold: f64,
    /// Points at or above it.
    pub contact_points: usize,
    /// Wall times.
    pub timings_ms: TimingsMs,
    /// The CSV written.
    pub out: String,
}

/// Reads a point cloud: CSV rows `x,y,z` (metres), header optional.
///
/// # Errors
/// [`IoError`] naming the file: unreadable, malformed (rows of different widths), or rows of
/// four fields (a point cloud is `x,y,z` only).
pub fn read_point_cloud(path: &Path) -> Result<Vec<[Real; 3]>, LabError> {
    let rows = moe_io::read_points_csv(path)?;
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != 3) {
        let message = format!("{} fields; points are x,y,z", r.len());
        return Err(IoError::invalid(path, format!("row {}", i + 1), message).into());
    }
    Ok(rows.iter().map(|r| [r[0], r[1], r[2]]).collect())
}

/// The network's output on a point cloud written to `out`, one row per point in input order
/// (`logit0,logit1,probability`), and its report; `model_file` names the model, `started` is
/// when the command started.
///
/// # Errors
/// [`IoError`] naming `out` when it cannot be written.
pub fn write_points_contact(
    model: &PointCloudModel,
    model_file: &Path,
    precision: NetworkPrecision,
    contact: &PointCloudContact,
    threshold: f64,
    out: &Path,
    started: Instant,
) -> Result<PointsReport, LabError> {
    let table: Vec<Vec<Real>> = contact
        .logits
        .iter()
        .zip(&contact.probability)
        .map(|(l, &p)| vec![l[0], l[1], p])
        .collect();
    moe_io::write_csv(out, &["logit0", "logit1", "probability"], &table)?;
    Ok(PointsReport {
        points: contact.probability.len(),
        model: model_file.display().to_string(),
        card: model.has_card(),
        aggregation: model.aggregation(),
        dtype: precision_name(precision),
        threshold,
        contact_points: contact
            .probability
            .iter()
            .filter(|&&p| p >= threshold)
            .count(),
        timings_ms: TimingsMs::new(contact.timings, started),
        out: out.display().to_string(),
    })
}

impl PointsReport {
    /// The one line `moe-touch contact --points` prints.
    pub fn line(&self) -> String {
        let t = &self.timings_ms;
        format!(
            "{} points, {} at or above {}; network {:.1} ms (kNN {:.1}, EdgeConv {:.1}, head \
             {:.1}); wrote {}",
            self.points,
            self.contact_points,
            self.threshold,
            t.network,
            t.knn,
            t.edgeconv,
            t.head,
            self.out
        )
    }
}

/// Reads a hand shape as `moe-touch shape` writes it: `finger_<i>.obj` in `dir` for every
/// finger of `hand`.
///
/// # Errors
/// [`IoError`] naming a finger's mesh that is missing, unreadable or malformed.
pub fn read_hand_shape(hand: &HandModel, dir: &Path) -> Result<HandShape, LabError> {
    let fingers = (0..hand.num_fingers())
        .map(|i| {
            Ok(moe_io::read_mesh(&dir.join(format!("finger_{i}.obj")))?
                .vertices()
                .to_vec())
        })
        .collect::<Result<_, LabError>>()?;
    Ok(HandShape { fingers })
}

/// `contact.json` of the network on a hand shape, also its `--json` report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShapeContactRecord {
    /// The hand, as given.
    pub hand: String,
    /// The shape's directory.
    pub shape: String,
    /// The model file.
    pub model: String,
    /// Whether it has a card (always: the runtime needs it).
    pub card: bool,
    /// The edge aggregation the network ran.
    pub aggregation: Aggregation,
    /// The float type it computed in (`f32`, as the runtime runs it).
    pub dtype: &'static str,
    /// The contact threshold.
    pub threshold: f64,
    /// The frame of the places.
    pub frame: &'static str,
    /// Every finger.
    pub fingers: Vec<FingerContactRecord>,
    /// Vertices at or above the threshold.
    pub contact_vertices: usize,
    /// Wall times.
    pub timings_ms: TimingsMs,
}

/// What names the inputs of a contact estimate in its record.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactSources {
    /// The hand, as given (a preset's name or a config file).
    pub hand: String,
    /// The observation: the shape's directory or the keypoints file.
    pub input: String,
    /// What estimates: the network's model file, or the physics estimator's material (a file,
    /// or `nominal`).
    pub model: String,
}

/// A contact estimate's record and files: `finger_<i>.ply` coloured by contact probability,
/// `contacts.csv`, (physics: `loads.json`), `contact.json`.
#[derive(Debug)]
pub struct ContactOutput<R> {
    /// The record, also `contact.json`.
    pub record: R,
    /// The files to write.
    pub files: OutputFiles,
}

/// The network on a hand shape with the observation's tendon pulls, when the model takes them;
/// `started` is when the command started.
///
/// # Errors
/// A shape or pulls that do not fit the hand or the model, a failing network.
pub fn shape_contact(
    estimator: &DgcnnEstimator,
    hand: &HandModel,
    shape: &HandShape,
    tendon_pull_m: Option<&[Vec<Real>]>,
    threshold: f64,
    sources: ContactSources,
    started: Instant,
) -> Result<ContactOutput<ShapeContactRecord>, LabError> {
    let mut observation = Observation::new();
    observation.tendon_pull_m = tendon_pull_m;
    let (maps, timings) = estimator.estimate_inputs(&[ContactInput::new(shape, observation)])?;
    let map = maps.into_iter().next().ok_or(LabError::InvalidEvaluation {
        reason: "the network gave no contact map".into(),
    })?;
    let (plys, fingers) = contact_fingers(hand, shape, &map, threshold)?;
    let contacts = map.contacts_above(threshold, shape)?;
    let record = ShapeContactRecord {
        hand: sources.hand,
        shape: sources.input,
        model: sources.model,
        card: true,
        aggregation: estimator.network().config().aggregation,
        dtype: precision_name(NetworkPrecision::F32),
        threshold,
        frame: FRAME,
        contact_vertices: contacts.len(),
        fingers,
        timings_ms: TimingsMs::new(timings, started),
    };
    let mut files = OutputFiles::new();
    for (name, ply) in plys {
        files.add_ply(name, ply);
    }
    files.add_csv("contacts.csv", &CONTACTS_HEADER, contact_rows(&contacts));
    files.add_json("contact.json", record.clone());
    Ok(ContactOutput { record, files })
}

impl ShapeContactRecord {
    /// The lines `moe-touch contact --shape` prints: the hand, then a line per finger.
    pub fn summary(&self) -> String {
        let mut text = format!(
            "hand '{}': {} contact vertices at or above {}; network {:.1} ms",
            self.hand, self.contact_vertices, self.threshold, self.timings_ms.network
        );
        for (i, f) in self.fingers.iter().enumerate() {
            text.push_str(&format!(
                "\n  finger {i}: {} of {} vertices, max probability {:.3}, wrote {}",
                f.contact_vertices, f.vertices, f.max_probability, f.mesh
            ));
        }
        text
    }
}

/// The physics `contact.json`, also its `--json` report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsContactRecord {
    /// `physics`.
    pub method: &'static str,
    /// The hand, as given.
    pub hand: String,
    /// The keypoints file.
    pub keypoints: String,
    /// The tendon pulls, metres, per finger.
    pub tendon_pull_m: Vec<Vec<Real>>,
    /// The hand's pose in the world, `x, y, z, qx, qy, qz, qw`.
    pub world_from_hand: [Real; 7],
    /// The material: a file, or `nominal`.
    pub material: String,
    /// The estimator's settings: a file, or `default`.
    pub physics_config: String,
    /// The contact threshold.
    pub threshold: f64,
    /// The frame of places and forces.
    pub frame: &'static str,
    /// Their units.
    pub units: &'static str,
    /// Every finger.
    pub fingers: Vec<PhysicsFingerRecord>,
    /// Vertices at or above the threshold.
    pub contact_vertices: usize,
    /// Loads found.
    pub loads: usize,
    /// The file that lists them.
    pub loads_file: &'static str,
    /// Wall times.
    pub timings_ms: PhysicsTimingsMs,
}

/// Wall times of the physics estimate, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PhysicsTimingsMs {
    /// From the start of the command to the estimate: reading inputs, building the finger
    /// models.
    pub setup_ms: f64,
    /// The estimate.
    pub estimate_ms: f64,
    /// Everything.
    pub total_ms: f64,
}

/// `loads.json`.
#[derive(Debug, Serialize)]
struct LoadsFile<'a> {
    frame: &'static str,
    units: &'static str,
    loads: &'a [LoadRecord],
}

/// The physics estimate with every load found.
#[derive(Debug)]
pub struct PhysicsContactOutput {
    /// The record and the files.
    pub output: ContactOutput<PhysicsContactRecord>,
    /// Every load found.
    pub loads: Vec<LoadRecord>,
}

/// One frame for the physics estimator: the markers, the tendon pulls and the hand's pose.
#[derive(Debug, Clone, Copy)]
pub struct PhysicsFrame<'a> {
    /// The markers in the hand frame.
    pub keypoints: &'a HandKeypoints,
    /// The tendon pulls, metres, per finger.
    pub tendon_pull_m: &'a [Vec<Real>],
    /// The hand's pose in the world (for the direction of gravity).
    pub world_from_hand: WorldFromHand,
}

/// The physics estimate of one frame: loads with their force and uncertainty, the dented
/// shape, per-vertex contact; `sources.model` names the material and `physics_config` the
/// estimator's settings (a file, or `default`); `started` is when the command started.
///
/// # Errors
/// An observation the estimator refuses (markers or pulls that do not fit the hand).
pub fn physics_contact(
    estimator: &mut PhysicsEstimator,
    frame: PhysicsFrame<'_>,
    threshold: f64,
    sources: ContactSources,
    physics_config: String,
    started: Instant,
) -> Result<PhysicsContactOutput, LabError> {
    let t_setup = Instant::now();
    let estimate = estimator.estimate(
        &Observation::from_keypoints(frame.keypoints)
            .with_tendon_pulls(frame.tendon_pull_m)
            .with_world_from_hand(frame.world_from_hand),
    )?;
    let t_estimate = Instant::now();
    let hand = estimator.hand();
    let (plys, fingers) = physics_fingers(hand, &estimate, threshold)?;
    let contacts = estimate
        .contact
        .contacts_above(threshold, &estimate.shape)?;
    let loads: Vec<LoadRecord> = estimate
        .details
        .loads
        .iter()
        .map(LoadRecord::from)
        .collect();
    let loads_text = serde_json::to_string_pretty(&LoadsFile {
        frame: FRAME,
        units: UNITS,
        loads: &loads,
    })
    .map_err(|e| IoError::Serialize {
        path: "loads.json".into(),
        message: e.to_string(),
    })?;
    let iso = frame.world_from_hand.iso();
    let (t, q) = (iso.translation.vector, iso.rotation.quaternion());
    let end = Instant::now();
    let ms = |a: Instant, b: Instant| 1e3 * (b - a).as_secs_f64();
    let record = PhysicsContactRecord {
        method: "physics",
        hand: sources.hand,
        keypoints: sources.input,
        tendon_pull_m: frame.tendon_pull_m.to_vec(),
        world_from_hand: [t.x, t.y, t.z, q.i, q.j, q.k, q.w],
        material: sources.model,
        physics_config,
        threshold,
        frame: FRAME,
        units: UNITS,
        contact_vertices: contacts.len(),
        loads: loads.len(),
        loads_file: "loads.json",
        fingers,
        timings_ms: PhysicsTimingsMs {
            setup_ms: ms(started, t_setup),
            estimate_ms: ms(t_setup, t_estimate),
            total_ms: ms(started, end),
        },
    };
    let mut files = OutputFiles::new();
    for (name, ply) in plys {
        files.add_ply(name, ply);
    }
    files.add_csv("contacts.csv", &CONTACTS_HEADER, contact_rows(&contacts));
    files.add_bytes("loads.json", loads_text.into_bytes());
    files.add_json("contact.json", record.clone());
    Ok(PhysicsContactOutput {
        output: ContactOutput { record, files },
        loads,
    })
}

impl PhysicsContactOutput {
    /// A warning for every finger the estimator has no estimate for.
    pub fn warnings(&self) -> Vec<String> {
        self.output
            .record
            .fingers
            .iter()
            .enumerate()
            .filter_map(|(i, f)| {
                let e = f.error.as_ref()?;
                Some(format!(
                    "finger {i}: no estimate ({e}); left at its rest shape"
                ))
            })
            .collect()
    }

    /// The lines `moe-touch contact --method physics` prints: the hand, each finger, each load.
    pub fn summary(&self) -> String {
        let r = &self.output.record;
        let loads = |n: usize| crate::count(n, "load");
        let mut lines = vec![format!(
            "hand '{}' (physics, material {}): {}, {} contact vertices at or above {}; estimate \
             {:.1} ms",
            r.hand,
            r.material,
            loads(r.loads),
            r.contact_vertices,
            r.threshold,
            r.timings_ms.estimate_ms
        )];
        for (i, f) in r.fingers.iter().enumerate() {
            lines.push(format!(
                "  finger {i}: force {:.3} N ({:+.3}, {:+.3}, {:+.3}) from {}, pressed with \
                 probability {:.3}, {} contact vertices, wrote {}",
                f.force_magnitude_n,
                f.force_n.x,
                f.force_n.y,
                f.force_n.z,
                loads(f.loads),
                f.pressed_probability,
                f.contact_vertices,
                f.mesh
            ));
        }
        for l in &self.loads {
            lines.push(format!(
                "  load on finger {} at vertex {} ({:.1}, {:.1}, {:.1}) mm: {:.3} ± {:.3} N",
                l.finger,
                l.vertex,
                1e3 * l.location_m.x,
                1e3 * l.location_m.y,
                1e3 * l.location_m.z,
                l.magnitude_n,
                l.magnitude_sd_n
            ));
        }
        lines.join("\n")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::{FingerParams, HandPreset};
    use moe_physics::{HandMaterial, PhysicsConfig};

    fn fixtures() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures")
    }

    #[test]
    fn a_point_cloud_row_of_another_width_is_named() {
        let path = std::env::temp_dir().join(format!("moe-lab-cloud-{}.csv", std::process::id()));
        std::fs::write(&path, "x,y,z\n0,0,0\n0,0,1\n").unwrap();
        assert_eq!(read_point_cloud(&path).unwrap().len(), 2);
        // Rows of 4 fields read as points with a value; a point cloud takes x,y,z only.
        std::fs::write(&path, "0,0,0,1\n0,0,1,2\n").unwrap();
        let err = read_point_cloud(&path).unwrap_err().to_string();
        assert!(
            err.contains("row 1") && err.contains("points are x,y,z"),
            "{err}"
        );
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn the_physics_estimate_of_a_press_has_its_files_loads_and_lines() {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let kp_path = fixtures().join("keypoints/plate_tip_front_frame4.json");
        let keypoints =
            crate::keypoints_file::KeypointsFile::read_for_hand(&kp_path, &hand).unwrap();
        let pulls = vec![vec![0.0; 4]; 2];
        let mut estimator =
            PhysicsEstimator::new(&hand, &HandMaterial::default(), &PhysicsConfig::default())
                .unwrap();
        let frame = PhysicsFrame {
            keypoints: &keypoints,
            tendon_pull_m: &pulls,
            world_from_hand: WorldFromHand::identity(),
        };
        let sources = ContactSources {
            hand: "two-finger".into(),
            input: "kp.json".into(),
            model: "nominal".into(),
        };
        let out = physics_contact(
            &mut estimator,
            frame,
            0.5,
            sources,
            "default".into(),
            Instant::now(),
        )
        .unwrap();
        let record = &out.output.record;
        assert_eq!(record.loads, out.loads.len());
        assert!(record.loads >= 1 && out.loads.iter().all(|l| l.finger == 0));
        assert_eq!(
            out.output.files.names().collect::<Vec<_>>(),
            [
                "finger_0.ply",
                "finger_1.ply",
                "contacts.csv",
                "loads.json",
                "contact.json"
            ]
        );
        assert!(out.warnings().is_empty());
        let text = out.summary();
        assert!(
            text.starts_with("hand 'two-finger' (physics, material nominal): "),
            "{text}"
        );
        assert_eq!(text.lines().count(), 3 + record.loads);
    }
}
