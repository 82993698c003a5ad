//! Data sets from the simulator: the frame layout and frames of randomised trajectories, and the
//! simulator parameters and hand a data set records.

use moe_io::dataset::{DatasetFrame, DatasetLayout};
use moe_tendon_sim::HandBodies;
use moe_tendon_sim::randomize::{
    OBJECT_PARAM_LEN, ObjectFamily, RandomSceneParams, simulate_trajectory,
    simulate_trajectory_with,
};

use crate::error::LabError;

/// Draws per trajectory before a failing simulation is reported.
pub const MAX_DRAWS: u64 = 4;

/// The frame layout of a data set simulated with `params`, after checking the parameters (so
/// that a bad parameter file stops a run before it writes anything).
///
/// # Errors
/// [`LabError::Simulation`] naming an invalid randomisation parameter
/// ([`RandomSceneParams::validate`]); [`LabError::Touch`] for invalid finger parameters
/// or fingers with different numbers of tendons ([`moe_geom::HandModel::tendons_per_finger`]).
pub fn simulated_layout(params: &RandomSceneParams) -> Result<DatasetLayout, LabError> {
    params.validate()?;
    let hand = moe_geom::HandModel::preset(params.preset, &params.finger)?;
    let fingers = hand.fingers();
    let tendons_per_finger = hand.tendons_per_finger()?;
    Ok(DatasetLayout {
        finger_num_vertices: fingers
            .iter()
            .map(|f| f.model.mesh().num_vertices())
            .collect(),
        markers_per_finger: fingers
            .iter()
            .map(|f| f.model.marker_vertices().len())
            .collect(),
        tendons_per_finger,
        object_param_len: OBJECT_PARAM_LEN,
        object_families: ObjectFamily::ALL
            .iter()
            .map(|f| f.name().to_owned())
            .collect(),
    })
}

/// Simulates trajectory `trajectory_id` of a data set with `seed` and returns its labelled frames
/// (all fingers concatenated in the hand frame; markers are the marker vertices).
///
/// # Errors
/// [`LabError::Trajectory`] naming the trajectory and carrying the simulator's error of the
/// last draw (which names the step and element on divergence);
/// [`LabError::Simulation`] with [`moe_tendon_sim::SimError::ForceDriven`] for a scene whose
/// tendons are force-driven (a data set records pulls in metres).
pub fn simulated_frames(
    params: &RandomSceneParams,
    seed: u64,
    trajectory_id: u64,
) -> Result<Vec<DatasetFrame>, LabError> {
    simulated_frames_with(params, None, seed, trajectory_id)
}

/// [`simulated_frames`], on the finger bodies the data set's trajectories share when `bodies`
/// are given (built once by [`moe_tendon_sim::randomize::hand_bodies`]): the same frames,
/// without voxelising the fingers again for every trajectory.
///
/// # Errors
/// As [`simulated_frames`].
pub fn simulated_frames_with(
    params: &RandomSceneParams,
    bodies: Option<&HandBodies>,
    seed: u64,
    trajectory_id: u64,
) -> Result<Vec<DatasetFrame>, LabError> {
    // A draw whose simulation diverges (an element inverted by an extreme press, say) is
    // replaced by a redraw from a derived seed; the redraws are part of the pure function of
    // (seed, trajectory), so determinism holds.
    let mut attempt: u64 = 0;
    let (sampled, scene, frames) = loop {
        let attempt_seed = seed ^ attempt.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        attempt += 1;
        let simulated = match bodies {
            Some(bodies) => simulate_trajectory_with(params, bodies, attempt_seed, trajectory_id),
            None => simulate_trajectory(params, attempt_seed, trajectory_id),
        };
        match simulated {
            Ok(r) => break r,
            Err(source) if attempt == MAX_DRAWS => {
                return Err(LabError::Trajectory {
                    trajectory: trajectory_id,
                    draws: MAX_DRAWS,
                    source,
                });
            }
            Err(_) => {}
        }
    };
    let hand = scene.hand();
    let object_params: Vec<f32> = sampled.object_params.iter().map(|&v| v as f32).collect();
    frames
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let pulls = f.tendon_pulls_m()?;
            let to32 = |p: &moe_geom::Point3| [p.x as f32, p.y as f32, p.z as f32];
            let vertices = f
                .fingers
                .iter()
                .flat_map(|g| g.vertices_in_hand.iter().map(to32))
                .collect();
            let contact = f
                .fingers
                .iter()
                .flat_map(|g| g.labels.iter().map(|&l| u8::from(l)))
                .collect();
            let contact_force_n = f
                .fingers
                .iter()
                .flat_map(|g| g.contact_force_n.iter().map(|&v| v as f32))
                .collect();
            let obstacle_distance_m = f
                .fingers
                .iter()
                .flat_map(|g| g.distances_m.iter().map(|&v| v as f32))
                .collect();
            let finger_force_n = f
                .fingers
                .iter()
                .map(|g| {
                    let n = g.force_in_hand_n;
                    [n.x as f32, n.y as f32, n.z as f32]
                })
                .collect();
            let markers = f
                .fingers
                .iter()
                .zip(hand.fingers())
                .flat_map(|(g, hf)| {
                    hf.model
                        .marker_vertices()
                        .iter()
                        .map(|&m| to32(&g.vertices_in_hand[m as usize]))
                })
                .collect();
            let iso = f.world_from_hand;
            let (t, q) = (iso.translation.vector, iso.rotation.quaternion());
            Ok(DatasetFrame {
                trajectory_id,
                frame_index: k as u32,
                vertices,
                contact,
                contact_force_n,
                obstacle_distance_m,
                finger_force_n: Some(finger_force_n),
                markers,
                world_from_hand: [t.x, t.y, t.z, q.i, q.j, q.k, q.w],
                tendon_pull_m: pulls.iter().flatten().map(|&v| v as f32).collect(),
                object_family: sampled.family.code(),
                object_params: object_params.clone(),
            })
        })
        .collect()
}

/// The generator parameters a data set was simulated with, from its card.
///
/// # Errors
/// [`LabError::DatasetCard`] when the card records none or they do not parse.
pub fn dataset_params(card: &moe_io::DatasetCard) -> Result<RandomSceneParams, LabError> {
    let params = card
        .generator
        .get("params")
        .cloned()
        .ok_or_else(|| LabError::DatasetCard {
            reason: "it records no simulator parameters".into(),
        })?;
    serde_json::from_value(params).map_err(|e| LabError::DatasetCard {
        reason: format!("its simulator parameters: {e}"),
    })
}

/// The hand a data set was simulated with, from its card, checked against its layout.
///
/// # Errors
/// As [`dataset_params`]; [`LabError::DatasetCard`] when the hand does not fit the layout.
pub fn dataset_hand(reader: &moe_io::DatasetReader) -> Result<moe_geom::HandModel, LabError> {
    let card = reader.card();
    let params = dataset_params(card)?;
    let hand = moe_geom::HandModel::preset(params.preset, &params.finger)?;
    let counts: Vec<usize> = hand
        .fingers()
        .iter()
        .map(|f| f.model.mesh().num_vertices())
        .collect();
    if counts != card.layout.finger_num_vertices {
        return Err(LabError::DatasetCard {
            reason: format!(
                "the data set's layout ({:?} vertices per finger) is not its recorded hand's \
                 ({counts:?})",
                card.layout.finger_num_vertices
            ),
        });
    }
    Ok(hand)
}

/// Name of the rule that labelled a data set's contacts, from its card (`proximity` for data
/// sets made before the rule was recorded).
pub fn label_rule(card: &moe_io::DatasetCard) -> String {
    card.generator["params"]["contact"]["label_rule"]
        .as_str()
        .unwrap_or("proximity")
        .to_owned()
}
