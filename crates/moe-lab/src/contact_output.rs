//! What `moe-touch contact` writes of one estimate, in memory: each finger's mesh coloured by
//! contact probability with its record, and the rows of `contacts.csv`.

use moe_geom::{ContactMap, ContactPoint, HandModel, HandShape, Real, Vector3};
use moe_io::PlyData;
use serde::Serialize;

use crate::contact_eval::contact_ply;
use crate::error::LabError;
use crate::run::finger_force_records;

/// The header of `contacts.csv` (hand frame, metres).
pub const CONTACTS_HEADER: [&str; 6] = ["finger", "vertex", "x", "y", "z", "probability"];

/// The rows of `contacts.csv`: finger, vertex, place and probability of each contact.
pub fn contact_rows(contacts: &[ContactPoint]) -> Vec<Vec<Real>> {
    contacts
        .iter()
        .map(|c| {
            vec![
                c.finger as f64,
                f64::from(c.vertex),
                c.point.x,
                c.point.y,
                c.point.z,
                c.probability,
            ]
        })
        .collect()
}

/// A mesh to write and the name of its file.
pub type NamedPly = (String, PlyData);

/// One finger of a contact map's summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FingerContactRecord {
    /// The finger's mesh file.
    pub mesh: String,
    /// Its vertices.
    pub vertices: usize,
    /// Its vertices at or above the threshold.
    pub contact_vertices: usize,
    /// Its largest contact probability.
    pub max_probability: f64,
}

/// Each finger of `shape` as `finger_<i>.ply` coloured by `map`'s probability, with its record.
///
/// # Errors
/// A map or shape that does not fit `hand`.
pub fn contact_fingers(
    hand: &HandModel,
    shape: &HandShape,
    map: &ContactMap,
    threshold: f64,
) -> Result<(Vec<NamedPly>, Vec<FingerContactRecord>), LabError> {
    let mut plys = Vec::with_capacity(hand.num_fingers());
    let mut fingers = Vec::with_capacity(hand.num_fingers());
    for (i, probs) in map.fingers.iter().enumerate() {
        let ply = contact_ply(hand, i, &shape.fingers[i], probs)?;
        let name = format!("finger_{i}.ply");
        fingers.push(FingerContactRecord {
            mesh: name.clone(),
            vertices: probs.len(),
            contact_vertices: probs.iter().filter(|&&p| p >= threshold).count(),
            max_probability: probs.iter().copied().fold(0.0, f64::max),
        });
        plys.push((name, ply));
    }
    Ok((plys, fingers))
}

/// One finger of the physics estimate's summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhysicsFingerRecord {
    /// The finger's mesh file.
    pub mesh: String,
    /// Its vertices.
    pub vertices: usize,
    /// Its vertices at or above the threshold.
    pub contact_vertices: usize,
    /// Its largest contact probability.
    pub max_probability: f64,
    /// Probability that the finger is pressed.
    pub pressed_probability: f64,
    /// The net force the world exerts on the finger, hand frame, newtons.
    pub force_n: Vector3,
    /// Its magnitude, newtons.
    pub force_magnitude_n: f64,
    /// Loads found on the finger.
    pub loads: usize,
    /// Likelihood-ratio statistic of the loads against none (χ² units).
    pub statistic: f64,
    /// Markers observed.
    pub observed_markers: usize,
    /// RMS of the observed markers about the unloaded finger, metres.
    pub free_rms_m: Option<f64>,
    /// RMS of the observed markers about the estimate, metres.
    pub fit_rms_m: Option<f64>,
    /// Why there is no estimate for this finger (it then keeps its rest shape, no contact).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Each finger of a physics estimate as `finger_<i>.ply`: the dented surface coloured by
/// contact probability with the force on each vertex (`force_n`), with its record.
///
/// # Errors
/// An estimate that does not fit `hand`.
pub fn physics_fingers(
    hand: &HandModel,
    estimate: &moe_physics::PhysicsEstimate,
    threshold: f64,
) -> Result<(Vec<NamedPly>, Vec<PhysicsFingerRecord>), LabError> {
    let forces = finger_force_records(&estimate.details);
    let mut plys = Vec::with_capacity(hand.num_fingers());
    let mut fingers = Vec::with_capacity(hand.num_fingers());
    for (i, probs) in estimate.contact.fingers.iter().enumerate() {
        let vertices = &estimate.shape.fingers[i];
        let force_magnitudes: Vec<f64> = estimate
            .vertex_force_n
            .as_ref()
            .and_then(|f| f.get(i))
            .map_or_else(
                || vec![0.0; vertices.len()],
                |f| f.iter().map(|v| v.norm()).collect(),
            );
        let ply = contact_ply(hand, i, vertices, probs)?
            .with_scalar("force_n", force_magnitudes.iter().copied());
        let name = format!("finger_{i}.ply");
        let report = &estimate.details.fingers[i];
        let finite = |x: f64| x.is_finite().then_some(x);
        fingers.push(PhysicsFingerRecord {
            mesh: name.clone(),
            vertices: probs.len(),
            contact_vertices: probs.iter().filter(|&&p| p >= threshold).count(),
            max_probability: probs.iter().copied().fold(0.0, f64::max),
            pressed_probability: report.pressed_probability,
            force_n: forces[i].force_n,
            force_magnitude_n: forces[i].magnitude_n,
            loads: forces[i].loads.unwrap_or(0),
            statistic: report.statistic,
            observed_markers: report.observed_markers,
            free_rms_m: finite(report.free_rms_m),
            fit_rms_m: finite(report.fit_rms_m),
            error: report.error.clone(),
        });
        plys.push((name, ply));
    }
    Ok((plys, fingers))
}
