//! SR-ARAP on files, as `moe-touch arap` and `moe-touch shape` run it: any mesh deformed toward
//! the handle targets of a constraints file, and a hand's finger meshes estimated from one frame
//! of keypoints; each with its typed report, its summary lines and its output files.

use std::path::Path;

use moe_arap::{
    ArapConfig, ArapEnergy, ArapInfo, ArapSolver, HandleTargets, MultiShapeEstimator, Start,
};
use moe_geom::{HandKeypoints, Point3, Real, TriMesh};
use serde::{Deserialize, Serialize};

use crate::error::LabError;
use crate::output_files::OutputFiles;

/// The constraints file of `moe-touch arap`: `{"handles": [{"vertex": 12, "target": [x, y,
/// z]}, ...]}`, targets in the mesh's units.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArapConstraints {
    /// The handles.
    pub handles: Vec<ArapHandle>,
}

/// One handle of a constraints file.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArapHandle {
    /// The mesh vertex.
    pub vertex: u32,
    /// Where it goes.
    pub target: [Real; 3],
}

impl ArapConstraints {
    /// Reads a constraints file (JSON).
    ///
    /// # Errors
    /// [`moe_io::IoError`] for a missing, unreadable or malformed file, naming it.
    pub fn read(path: &Path) -> Result<Self, LabError> {
        Ok(moe_io::read_json(path)?)
    }

    /// The handles checked against a mesh of `num_vertices` vertices.
    ///
    /// # Errors
    /// [`moe_arap::ArapError`] naming the handle out of range, not finite or given two
    /// targets.
    pub fn targets(&self, num_vertices: usize) -> Result<HandleTargets, LabError> {
        let pairs: Vec<(u32, Point3)> = self
            .handles
            .iter()
            .map(|h| (h.vertex, Point3::from(h.target)))
            .collect();
        Ok(HandleTargets::from_pairs(&pairs, num_vertices)?)
    }
}

/// A mesh deformed by SR-ARAP, with what the solve reports.
#[derive(Debug, Clone)]
pub struct MeshDeformation {
    /// The rest mesh's faces with the deformed vertices.
    pub deformed: TriMesh,
    /// Distinct handle vertices.
    pub num_handles: usize,
    /// The solver's settings.
    pub config: ArapConfig,
    /// Iterations, energies and SVD fallbacks of the solve.
    pub info: ArapInfo,
    /// Largest vertex displacement from the rest mesh (mesh units).
    pub max_displacement: Real,
}

/// The `moe-touch arap` summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArapSummary {
    /// The rest mesh's file.
    pub mesh: String,
    /// The deformed mesh's file.
    pub out: String,
    /// Vertices of the mesh.
    pub num_vertices: usize,
    /// Faces of the mesh.
    pub num_faces: usize,
    /// Distinct handle vertices.
    pub num_handles: usize,
    /// The energy.
    pub energy: ArapEnergy,
    /// The smoothing weight α the solve used (0 for plain ARAP).
    pub alpha: Real,
    /// Iterations run.
    pub iterations: usize,
    /// Energy after the first iteration (squared mesh units).
    pub first_energy: Option<Real>,
    /// Energy after the last iteration (squared mesh units).
    pub final_energy: Option<Real>,
    /// Largest vertex displacement from the rest mesh (mesh units).
    pub max_displacement: Real,
    /// Rotations computed by the SVD fallback.
    pub svd_fallbacks: usize,
}

/// Deforms `rest` with SR-ARAP so that the handle vertices reach their targets, from the rest
/// shape.
///
/// # Errors
/// A mesh or configuration the solver refuses (a part without a handle, a bad α), a failing
/// solve.
pub fn deform_mesh(
    rest: &TriMesh,
    handles: &HandleTargets,
    config: &ArapConfig,
) -> Result<MeshDeformation, LabError> {
    let solver = ArapSolver::new(rest, config, &handles.vertices, &[])?;
    let solution = solver.solve(&handles.targets, &[], Start::Rest)?;
    let max_displacement = solution
        .vertices
        .iter()
        .zip(rest.vertices())
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, Real::max);
    Ok(MeshDeformation {
        deformed: rest.with_vertices(solution.vertices)?,
        num_handles: handles.vertices.len(),
        config: config.clone(),
        info: solution.info,
        max_displacement,
    })
}

impl MeshDeformation {
    /// The summary, naming the rest mesh's file and the deformed mesh's.
    pub fn summary(&self, mesh: &Path, out: &Path) -> ArapSummary {
        let info = &self.info;
        ArapSummary {
            mesh: mesh.display().to_string(),
            out: out.display().to_string(),
            num_vertices: self.deformed.num_vertices(),
            num_faces: self.deformed.num_faces(),
            num_handles: self.num_handles,
            energy: self.config.energy,
            alpha: self.config.effective_alpha(),
            iterations: info.iterations,
            first_energy: info.energy.first().copied(),
            final_energy: info.energy.last().copied(),
            max_displacement: self.max_displacement,
            svd_fallbacks: info.svd_fallbacks,
        }
    }

    /// Writes the deformed mesh to `out` (OBJ or PLY) and, when asked, the energy after every
    /// iteration to `energy_log` (CSV `iteration,energy`).
    ///
    /// # Errors
    /// [`moe_io::IoError`] naming the file that could not be written.
    pub fn write(&self, out: &Path, energy_log: Option<&Path>) -> Result<(), LabError> {
        moe_io::write_mesh(out, &self.deformed)?;
        if let Some(path) = energy_log {
            let mut csv = String::from("iteration,energy\n");
            for (t, e) in self.info.energy.iter().enumerate() {
                csv.push_str(&format!("{t},{e:e}\n"));
            }
            moe_io::write_atomic(path, csv.as_bytes())?;
        }
        Ok(())
    }
}

impl ArapSummary {
    /// The one line `moe-touch arap` prints.
    pub fn line(&self) -> String {
        let energy = |e: Option<Real>| e.map_or_else(|| "-".to_owned(), |e| format!("{e:.4e}"));
        format!(
            "{}: {} vertices, {} handles, {} iterations of {} ARAP (α = {}); energy {} → {}; \
             max displacement {:.4e}; wrote {}",
            self.mesh,
            self.num_vertices,
            self.num_handles,
            self.iterations,
            self.energy,
            self.alpha,
            energy(self.first_energy),
            energy(self.final_energy),
            self.max_displacement,
            self.out
        )
    }
}

/// One finger of `shape.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FingerShapeRecord {
    /// The finger's mesh file.
    pub mesh: String,
    /// The frame of its vertices.
    pub frame: &'static str,
    /// Iterations run (0 when every marker was missing).
    pub iterations: usize,
    /// Markers used as handles.
    pub markers_used: Vec<usize>,
    /// Markers missing from the keypoints.
    pub missing_markers: Vec<usize>,
    /// Mesh vertex of every marker's handle.
    pub handle_vertices: Vec<Option<u32>>,
    /// Whether every marker was missing (the finger is left at its rest shape).
    pub all_markers_missing: bool,
    /// Energy after the last iteration.
    pub final_energy: Option<Real>,
    /// Energy after every iteration.
    pub energy: Vec<Real>,
    /// Largest vertex displacement from the rest shape, metres.
    pub max_displacement_m: Real,
}

/// `shape.json`, also the `moe-touch shape --json` report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShapeRecord {
    /// The hand, as given.
    pub hand: String,
    /// The keypoints file.
    pub keypoints: String,
    /// The energy.
    pub energy: ArapEnergy,
    /// The smoothing weight α.
    pub alpha: Real,
    /// Iterations per finger.
    pub iterations: usize,
    /// Every finger.
    pub fingers: Vec<FingerShapeRecord>,
}

/// A hand's estimated shape: the record and the files (`finger_<i>.obj`, deformed, hand
/// frame, metres; `shape.json`).
#[derive(Debug)]
pub struct HandShapeOutput {
    /// The record.
    pub record: ShapeRecord,
    /// The files to write.
    pub files: OutputFiles,
}

/// Estimates the shape of `estimator`'s hand from one frame of keypoints; `hand` and
/// `keypoints_file` name the hand and the keypoints in the record.
///
/// # Errors
/// Keypoints that do not fit the hand, a failing solve.
pub fn estimate_hand_shape(
    estimator: &mut MultiShapeEstimator,
    keypoints: &HandKeypoints,
    hand: &str,
    keypoints_file: &Path,
) -> Result<HandShapeOutput, LabError> {
    let estimate = estimator.estimate(keypoints)?;
    let model = estimator.hand();
    let mut files = OutputFiles::new();
    let mut fingers = Vec::with_capacity(model.num_fingers());
    for (i, (vertices, report)) in estimate
        .shape
        .fingers
        .iter()
        .zip(&estimate.reports)
        .enumerate()
    {
        let rest = model.rest_vertices_in_hand(i);
        let max_displacement_m = vertices
            .iter()
            .zip(&rest)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        let mesh = format!("finger_{i}.obj");
        let finger_mesh = model.fingers()[i].model.mesh();
        files.add_mesh(mesh.clone(), finger_mesh.with_vertices(vertices.clone())?);
        fingers.push(FingerShapeRecord {
            mesh,
            frame: "hand",
            iterations: report.iterations,
            missing_markers: (0..report.handle_vertices.len())
                .filter(|m| !report.markers_used.contains(m))
                .collect(),
            markers_used: report.markers_used.clone(),
            handle_vertices: report.handle_vertices.clone(),
            all_markers_missing: report.all_markers_missing,
            final_energy: report.energy.last().copied(),
            energy: report.energy.clone(),
            max_displacement_m,
        });
    }
    let options = estimator.options();
    let record = ShapeRecord {
        hand: hand.to_owned(),
        keypoints: keypoints_file.display().to_string(),
        energy: options.energy,
        alpha: options.alpha,
        iterations: options.iterations,
        fingers,
    };
    files.add_json("shape.json", record.clone());
    Ok(HandShapeOutput { record, files })
}

impl ShapeRecord {
    /// A warning for every finger whose markers were all missing.
    pub fn warnings(&self) -> Vec<String> {
        self.fingers
            .iter()
            .enumerate()
            .filter(|(_, f)| f.all_markers_missing)
            .map(|(i, _)| format!("finger {i}: every marker missing, left at the rest shape"))
            .collect()
    }

    /// The lines `moe-touch shape` prints: the hand, then a line per finger.
    pub fn summary(&self) -> String {
        let mut text = format!("hand '{}': {} fingers", self.hand, self.fingers.len());
        for (i, f) in self.fingers.iter().enumerate() {
            text.push_str(&format!(
                "\n  finger {i}: {} of {} markers, {} iterations, max displacement {:.2} mm, \
                 wrote {}",
                f.markers_used.len(),
                f.handle_vertices.len(),
                f.iterations,
                f.max_displacement_m * 1e3,
                f.mesh
            ));
        }
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_arap::ShapeConfig;
    use moe_geom::{FingerParams, HandModel, HandPreset};

    #[test]
    fn a_mesh_whose_handles_all_move_together_is_translated() {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let rest = hand.fingers()[0].model.mesh().clone();
        let shift = moe_geom::Vector3::new(0.0, 0.0, 0.01);
        let constraints = ArapConstraints {
            handles: [0u32, 10, 20, 30]
                .iter()
                .map(|&v| ArapHandle {
                    vertex: v,
                    target: (rest.vertices()[v as usize] + shift).into(),
                })
                .collect(),
        };
        let handles = constraints.targets(rest.num_vertices()).unwrap();
        let config = ArapConfig {
            iterations: 5,
            ..ArapConfig::default()
        };
        let done = deform_mesh(&rest, &handles, &config).unwrap();
        let summary = done.summary(Path::new("rest.obj"), Path::new("out.obj"));
        assert_eq!(summary.num_handles, 4);
        assert!(
            (summary.max_displacement - 0.01).abs() < 1e-6,
            "{summary:?}"
        );
        assert!(
            summary.line().starts_with("rest.obj: "),
            "{}",
            summary.line()
        );
        let far = ArapConstraints {
            handles: vec![ArapHandle {
                vertex: 1_000_000,
                target: [0.0; 3],
            }],
        };
        assert!(far.targets(rest.num_vertices()).is_err());
    }

    #[test]
    fn a_finger_without_markers_stays_at_rest_and_is_warned_of() {
        let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default()).unwrap();
        let keypoints = HandKeypoints {
            fingers: hand
                .fingers()
                .iter()
                .map(|f| vec![None; f.model.marker_vertices().len()])
                .collect(),
        };
        let mut estimator = MultiShapeEstimator::new(hand, ShapeConfig::default()).unwrap();
        let out = estimate_hand_shape(
            &mut estimator,
            &keypoints,
            "two-finger",
            Path::new("kp.json"),
        )
        .unwrap();
        assert_eq!(out.record.warnings().len(), 2);
        assert_eq!(out.record.fingers[0].max_displacement_m, 0.0);
        assert_eq!(
            out.files.names().collect::<Vec<_>>(),
            ["finger_0.obj", "finger_1.obj", "shape.json"]
        );
        assert!(
            out.record
                .summary()
                .starts_with("hand 'two-finger': 2 fingers\n")
        );
    }
}
