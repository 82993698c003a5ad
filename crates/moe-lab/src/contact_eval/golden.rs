//! The golden content of the contact study's stages on a few held-out frames (what the
//! workspace's golden fixtures hold): SR-ARAP's shapes and Table 1 without timings.

use moe_arap::MultiShapeEstimator;
use moe_contact::DgcnnEstimator;
use moe_geom::{ContactInput, HandModel, HandShape, LabelledFrame, Point3, Real, SeededRng, bcd};
use serde::Serialize;

use super::augmentation::marker_subset;
use super::table::{ContactEvalOptions, Estimators, evaluate_table1};
use crate::error::LabError;

/// One SR-ARAP shape of [`ArapGolden`], against the true surface (mm).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArapGoldenShape {
    /// BCD to the true surface.
    pub bcd_mm: Real,
    /// Mean distance from vertex i to the true vertex i.
    pub vertex_mean_mm: Real,
    /// Largest such distance.
    pub vertex_max_mm: Real,
    /// Five estimated vertices of each finger, evenly spaced by index.
    pub sample_vertices_mm: Vec<[Real; 3]>,
}

/// The SR-ARAP shapes of one frame of [`ArapGolden`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArapGoldenShapes {
    /// From every marker.
    pub all_markers: ArapGoldenShape,
    /// From the seeded subset of markers.
    pub four_markers: ArapGoldenShape,
}

/// One frame of [`ArapGolden`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArapGoldenFrame {
    /// Its trajectory.
    pub trajectory: u64,
    /// Its index in the trajectory.
    pub frame: u32,
    /// Its shapes.
    pub shapes: ArapGoldenShapes,
}

/// The golden ARAP stage: SR-ARAP shapes of the frames' keypoints (all markers and the seeded
/// subset of [`ContactEvalOptions::default`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArapGolden {
    /// Every frame.
    pub frames: Vec<ArapGoldenFrame>,
}

/// One shape's figures against the truth.
fn arap_shape(shape: &HandShape, truth: &HandShape) -> Result<ArapGoldenShape, LabError> {
    let est: Vec<Point3> = shape.fingers.iter().flatten().copied().collect();
    let truth: Vec<Point3> = truth.fingers.iter().flatten().copied().collect();
    let errors: Vec<Real> = est
        .iter()
        .zip(&truth)
        .map(|(a, b)| (a - b).norm())
        .collect();
    let sample_vertices_mm = shape
        .fingers
        .iter()
        .flat_map(|v| {
            (0..5).map(move |j| {
                let p = v[j * (v.len() - 1) / 4];
                [1e3 * p.x, 1e3 * p.y, 1e3 * p.z]
            })
        })
        .collect();
    Ok(ArapGoldenShape {
        bcd_mm: 1e3 * bcd(&est, &truth)?,
        vertex_mean_mm: 1e3 * errors.iter().sum::<Real>() / errors.len() as Real,
        vertex_max_mm: 1e3 * errors.iter().copied().fold(0.0, Real::max),
        sample_vertices_mm,
    })
}

/// [`ArapGolden`] of `frames` of `hand`.
///
/// # Errors
/// A failing SR-ARAP solve or frames that do not fit the hand.
pub fn arap_golden(hand: &HandModel, frames: &[LabelledFrame]) -> Result<ArapGolden, LabError> {
    let options = ContactEvalOptions::default();
    let mut arap = MultiShapeEstimator::new(hand.clone(), options.shape.clone())?;
    let rng = SeededRng::new(options.seed);
    let mut out = Vec::with_capacity(frames.len());
    for (k, f) in frames.iter().enumerate() {
        let subset = marker_subset(&f.markers, options.subset_markers, &mut rng.split(k as u64));
        let all = arap.estimate(&f.markers)?.shape;
        let all_markers = arap_shape(&all, &f.shape)?;
        let four = arap.estimate(&subset)?.shape;
        let four_markers = arap_shape(&four, &f.shape)?;
        out.push(ArapGoldenFrame {
            trajectory: f.trajectory_id,
            frame: f.frame_index,
            shapes: ArapGoldenShapes {
                all_markers,
                four_markers,
            },
        });
    }
    Ok(ArapGolden { frames: out })
}

/// The golden contact stage: Table 1 of a model on the frames (no KNN rows) without its wall
/// times (`ms_per_frame` of every row), and the network's summed contact probability per frame
/// on the true shape.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table1Golden {
    /// The table's fields but its rows' wall times.
    #[serde(flatten)]
    pub table: serde_json::Map<String, serde_json::Value>,
    /// The network's summed contact probability on each frame's true shape.
    pub probability_sum_per_frame: Vec<Real>,
}

/// [`Table1Golden`] of `dgcnn` on `frames` of `hand`, labelled by `rule`.
///
/// # Errors
/// As [`evaluate_table1`] and the network.
pub fn table1_golden(
    hand: &HandModel,
    frames: &[LabelledFrame],
    rule: &str,
    dgcnn: &DgcnnEstimator,
) -> Result<Table1Golden, LabError> {
    let estimators = Estimators {
        dgcnn,
        knn_all: None,
        knn_sub: None,
    };
    let (table, _) = evaluate_table1(
        hand,
        frames,
        rule,
        None,
        estimators,
        &ContactEvalOptions::default(),
        &|_| false,
    )?;
    let probability_sum_per_frame = frames
        .iter()
        .map(|f| {
            let map = dgcnn.estimate_map(&ContactInput::of_frame(f, &f.shape))?;
            Ok(map.fingers.iter().flatten().sum::<Real>())
        })
        .collect::<Result<_, LabError>>()?;
    let serde_json::Value::Object(table) = crate::without_keys(&table, &["ms_per_frame"])? else {
        return Err(LabError::InvalidEvaluation {
            reason: "Table 1 is not a JSON object".into(),
        });
    };
    Ok(Table1Golden {
        table,
        probability_sum_per_frame,
    })
}
