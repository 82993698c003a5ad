//! Every method on one scene, scored by UCD and Chamfer distance to the ground truth.

use moe_geom::{Point3, Real, TriMesh};
use serde::{Deserialize, Serialize};

use super::scene::{BenchScene, SceneKind};
use crate::error::GpisError;
use crate::mean::{MeanFunction, MeshSdfMean};
use crate::observations::Observations;
use crate::reconstruct::ReconstructOptions;
use crate::surface::{SurfaceMethod, SurfaceOptions, reconstruct_surface};

/// UCD (mm) from `points` to the surface of `truth`.
///
/// # Errors
/// A non-watertight truth.
pub fn ucd_to_surface_mm(points: &[Point3], truth: &MeshSdfMean) -> Result<Real, GpisError> {
    if points.is_empty() {
        return Err(GpisError::TooFewObservations {
            method: "ucd",
            what: "points",
            needed: 1,
            got: 0,
        });
    }
    Ok(1e3 * truth.values(points).iter().map(|v| v.abs()).sum::<Real>() / points.len() as Real)
}

/// UCD (mm) from the truth's vertices to the surface of `recon`.
fn reverse_ucd_mm(truth: &TriMesh, recon: &TriMesh) -> Result<Real, GpisError> {
    ucd_to_surface_mm(truth.vertices(), &MeshSdfMean::new(recon)?)
}

/// One method's result on a scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodResult {
    /// `prior`, `gp_prior`, `gp_sphere` or `nonprob`.
    pub method: String,
    /// UCD from the reconstruction to the ground truth (the paper's metric), mm.
    pub ucd_mm: Real,
    /// UCD from the ground truth to the reconstruction (completeness: large when parts of the
    /// body are missing or misplaced), mm.
    pub ucd_truth_to_recon_mm: Real,
    /// Bidirectional Chamfer distance, the mean of the two, mm.
    pub bcd_mm: Real,
    /// Fit + grid query + meshing, seconds (0 for the prior itself).
    pub secs: Real,
    /// Posterior variance at the vertices, seconds (GP methods).
    pub variance_secs: Real,
    /// Vertices of the reconstruction.
    pub vertices: usize,
    /// Fitted length scale, mm (GP methods).
    pub lengthscale_mm: Option<Real>,
    /// Fitted signal standard deviation, mm (GP methods).
    pub signal_sd_mm: Option<Real>,
    /// Fitted noise standard deviation, mm (GP methods).
    pub noise_sd_mm: Option<Real>,
    /// Contacts left out as false by the prior gate (see [`SurfaceOptions::prior_gate_m`]).
    #[serde(default)]
    pub gated_contacts: usize,
    /// Why the method failed on this scene (its figures are then NaN, `null` in JSON).
    pub error: Option<String>,
}

impl MethodResult {
    fn failed(method: &str, err: &GpisError) -> Self {
        Self {
            method: method.to_owned(),
            ucd_mm: Real::NAN,
            ucd_truth_to_recon_mm: Real::NAN,
            bcd_mm: Real::NAN,
            secs: Real::NAN,
            variance_secs: Real::NAN,
            vertices: 0,
            lengthscale_mm: None,
            signal_sd_mm: None,
            noise_sd_mm: None,
            gated_contacts: 0,
            error: Some(err.to_string()),
        }
    }
}

/// All methods on one scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneReport {
    /// Which scene.
    pub scene: SceneKind,
    /// Number of contacts.
    pub contacts: usize,
    /// Grid nodes of the GP queries.
    pub grid_nodes: usize,
    /// One entry per method.
    pub methods: Vec<MethodResult>,
}

impl SceneReport {
    /// The result of a method by name.
    pub fn method(&self, name: &str) -> Option<&MethodResult> {
        self.methods.iter().find(|m| m.method == name)
    }
}

/// Runs one method through [`reconstruct_surface`] and scores it against the truth.
fn method_result(
    options: &SurfaceOptions,
    scene: &BenchScene,
    contacts: &Observations,
    truth: &MeshSdfMean,
    sink: &mut MeshSink<'_>,
) -> Result<(MethodResult, usize), GpisError> {
    let (rec, _) = reconstruct_surface(contacts, Some(&scene.prior), options)?;
    sink(rec.method, &rec.mesh, &rec.vertex_variance);
    let ucd_mm = ucd_to_surface_mm(rec.mesh.vertices(), truth)?;
    let back = reverse_ucd_mm(truth.mesh(), &rec.mesh)?;
    let hyper = rec.condition.map(|c| c.hyper);
    Ok((
        MethodResult {
            method: rec.method.to_owned(),
            ucd_mm,
            ucd_truth_to_recon_mm: back,
            bcd_mm: 0.5 * (ucd_mm + back),
            secs: rec.secs,
            variance_secs: rec.timings.map_or(0.0, |t| t.variance_secs),
            vertices: rec.mesh.num_vertices(),
            lengthscale_mm: hyper.map(|h| 1e3 * h.lengthscale),
            signal_sd_mm: hyper.map(|h| 1e3 * h.signal_variance.sqrt()),
            noise_sd_mm: hyper.map(|h| 1e3 * h.noise_variance.sqrt()),
            gated_contacts: rec.gated_contacts,
            error: None,
        },
        rec.grid_dims.map_or(0, |d| d.iter().product()),
    ))
}

/// Receives each method's surface as [`evaluate_scene_with`] computes it: the method's name,
/// the mesh and the posterior variance per vertex (empty for the prior and the
/// non-probabilistic baseline, or when [`ReconstructOptions::vertex_variance`] is off).
pub type MeshSink<'a> = dyn FnMut(&str, &TriMesh, &[Real]) + 'a;

/// Runs the prior, GP + prior, GP + sphere and the non-probabilistic baseline on a scene.
///
/// The GP methods condition on the contacts plus `±normal_offset_m` points along the mean's
/// normals at each contact (see [`Observations::add_mean_normal_offsets`]; `None` for contacts
/// only).
///
/// # Errors
/// Any reconstruction error.
pub fn evaluate_scene(
    kind: SceneKind,
    scene: &BenchScene,
    surface: &ReconstructOptions,
    normal_offset_m: Option<Real>,
) -> Result<SceneReport, GpisError> {
    evaluate_scene_with(
        kind,
        scene,
        surface,
        normal_offset_m,
        None,
        &mut |_, _, _| {},
    )
}

/// [`evaluate_scene`], handing every method's surface to `sink` (to write or display it), with
/// the contacts of the methods with a prior gated by `prior_gate_m` if given (see
/// [`SurfaceOptions::prior_gate_m`]).
///
/// # Errors
/// As [`evaluate_scene`].
pub fn evaluate_scene_with(
    kind: SceneKind,
    scene: &BenchScene,
    surface: &ReconstructOptions,
    normal_offset_m: Option<Real>,
    prior_gate_m: Option<Real>,
    sink: &mut MeshSink<'_>,
) -> Result<SceneReport, GpisError> {
    let truth = MeshSdfMean::new(&scene.truth)?;
    let obs = Observations::from_contacts(&scene.contacts)?;
    let mut methods = Vec::new();
    let ucd_mm = ucd_to_surface_mm(scene.prior.vertices(), &truth)?;
    let back = reverse_ucd_mm(&scene.truth, &scene.prior)?;
    sink("prior", &scene.prior, &[]);
    methods.push(MethodResult {
        method: "prior".to_owned(),
        ucd_mm,
        ucd_truth_to_recon_mm: back,
        bcd_mm: 0.5 * (ucd_mm + back),
        secs: 0.0,
        variance_secs: 0.0,
        vertices: scene.prior.num_vertices(),
        lengthscale_mm: None,
        signal_sd_mm: None,
        noise_sd_mm: None,
        gated_contacts: 0,
        error: None,
    });
    let bounds = crate::reconstruct::bounds_of(&scene.contacts, Some(&scene.prior)).ok_or(
        GpisError::TooFewObservations {
            method: "benchmark",
            what: "contacts",
            needed: 1,
            got: 0,
        },
    )?;
    // Both GP methods query the same grid, the task prior's: a narrower box around a sphere
    // would clip it where it strays from the body and hide that error from the one-way
    // distance. Building the prior's BVH and fitting the sphere are part of the timed work. A
    // method that fails on a scene (e.g. a sphere fit to a flat patch set) is reported as
    // failed; the others still run.
    let options = |method: SurfaceMethod| SurfaceOptions {
        method,
        surface: *surface,
        normal_offset_m: normal_offset_m.unwrap_or(0.0),
        bounds: Some(bounds),
        prior_gate_m,
        ..SurfaceOptions::default()
    };
    let mut grid_nodes = 0;
    for method in [
        SurfaceMethod::Prior { registration: None },
        SurfaceMethod::Sphere,
        SurfaceMethod::NonProbabilistic,
    ] {
        let name = method.name();
        let is_prior = matches!(method, SurfaceMethod::Prior { .. });
        match method_result(&options(method), scene, &obs, &truth, sink) {
            Ok((result, nodes)) => {
                if is_prior {
                    grid_nodes = nodes;
                }
                methods.push(result);
            }
            // The baseline fails only on its input, or when the gate leaves no contact: the
            // latter is the method's failure on this scene, like a degenerate sphere fit.
            Err(e @ GpisError::TooFewObservations { .. }) => {
                methods.push(MethodResult::failed(name, &e));
            }
            Err(e) if name != "nonprob" => methods.push(MethodResult::failed(name, &e)),
            Err(e) => return Err(e),
        }
    }
    Ok(SceneReport {
        scene: kind,
        contacts: scene.contacts.len(),
        grid_nodes,
        methods,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::shapes::icosphere;

    /// A gate that leaves no contact is a failure of the methods with a prior on this scene,
    /// reported as such; the sphere and the report itself go on.
    #[test]
    fn a_gate_that_leaves_no_contact_fails_the_prior_methods_not_the_scene() {
        let scene = BenchScene {
            truth: icosphere(2, 0.08),
            prior: icosphere(2, 0.08),
            // Every contact 20 mm outside the prior.
            contacts: icosphere(1, 0.1).vertices().to_vec(),
        };
        let surface = ReconstructOptions {
            max_grid_nodes: 16 * 16 * 16,
            vertex_variance: false,
            ..ReconstructOptions::default()
        };
        let report = evaluate_scene_with(
            SceneKind::Head,
            &scene,
            &surface,
            None,
            Some(0.01),
            &mut |_, _, _| {},
        )
        .unwrap();
        for name in ["gp_prior", "nonprob"] {
            let m = report.method(name).unwrap();
            assert!(
                m.error.as_deref().is_some_and(|e| e.contains("gate")),
                "{name}: {m:?}"
            );
        }
        assert!(report.method("gp_sphere").unwrap().error.is_none());
    }
}
