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

mod augmentation;
mod golden;
mod heldout;
mod knn;
mod plates;
mod study;
mod table;
#[cfg(test)]
mod tests;
mod text;

pub use augmentation::{
    MAX_MARKER_NOISE_M, MarkerAugmentation, distal_marker_order, marker_subset,
    with_depth_registered_shapes, with_estimated_shapes,
};
pub use golden::{
    ArapGolden, ArapGoldenFrame, ArapGoldenShape, ArapGoldenShapes, Table1Golden, arap_golden,
    table1_golden,
};
pub use heldout::{heldout_knn_index, select_heldout_frames, write_heldout_set};
pub use knn::{KnnIndexSource, build_knn_index, knn_index, read_knn_index};
pub use plates::{
    PLATE_OFFSET_M, PLATE_SCENES, PLATE_TILT_DEG, PlateScene, PlateTrial, PlateTrialScene,
    evaluate_plates, perturbed_plate, plate_scenes, plate_trials, simulate_labelled,
};
pub use study::{
    ContactStudy, ContactStudyOptions, ContactStudyPhysics, ContactStudyPhysicsTables,
    ContactStudyProgress, ContactStudyReport, PlateRegion, PlateRegionStat, PlateRegions,
    PlateTable, contact_study,
};
pub use table::{
    ContactEvalOptions, ContactRow, ContactTable, Estimators, FramePrediction, ShapeRow,
    TruthLabels, evaluate_table1,
};

use moe_geom::{HandModel, Point3, Real};

use crate::error::LabError;

/// Which frames of a data set a study evaluates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameSet {
    /// The test trajectories.
    Test,
    /// Every frame.
    All,
}

impl FrameSet {
    /// The data set split of these frames (`None`: every frame).
    pub fn split(self) -> Option<moe_io::Split> {
        match self {
            Self::Test => Some(moe_io::Split::Test),
            Self::All => None,
        }
    }
}

/// Blue (0) to red (1) colour of a contact probability, for meshes a person looks at (the
/// colours of the `run` output's meshes too).
pub use moe_record::probability_colour;

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
