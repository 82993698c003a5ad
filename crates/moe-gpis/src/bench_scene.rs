//! A reproducible benchmark of occluded-surface reconstruction (paper §6.1, Table 3): procedural
//! heads and arms, patting contacts, and the UCD of every method to the ground truth.
//!
//! **Heads.** A skull-like family: an ellipsoid (half-width `a` along x, half-length `b` along y
//! towards the face, half-height `c` along z up) modulated by a flatter forehead, an occipital
//! bulge, a jaw/neck taper below the equator and six random smooth bumps (Gaussian in the
//! direction, a few millimetres high). Every parameter is drawn from a seeded distribution around
//! adult head dimensions (breadth ≈ 152 mm, length ≈ 192 mm), so two seeds give two plausible,
//! different people: one is the ground truth, another the prior. Every member is cropped at the
//! same level below the skull ([`moe_geom::bodies::NECK_CROP_DEPTH`]), as the heads of a shape
//! data set are: the flat cut is an artefact of the crop, and a per-person crop level would put
//! a centimetre-scale error on the cut disk that no contact can correct.
//!
//! **Arms.** The paper's elongated 2:20:1 case: an ellipsoid of half-axes 30 × 300 × 15 mm whose
//! cross-section is modulated along the length (wrist, forearm bulge, elbow, upper arm) with
//! seeded amplitudes.
//!
//! **Contacts** are sampled in patches a hand can pat — top, back and sides of the head (not the
//! face); top and outer side along the arm — exactly on the ground truth, plus isotropic Gaussian
//! noise (1 mm by default).
//!
//! **Metric.** UCD from the reconstruction's vertices to the ground-truth *surface* (exact
//! point-to-triangle distance through parry, so the truth's tessellation does not bias it), in mm.

use moe_geom::{Point3, Real, TriMesh, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;
use crate::mean::{MeanFunction, MeshSdfMean};
use crate::observations::Observations;
use crate::reconstruct::SurfaceConfig;
use crate::surface::{SurfaceMethod, SurfaceOptions, reconstruct_surface};
use moe_geom::SeededRng;
use moe_geom::bodies::{ArmParams, HeadParams};

/// Which scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SceneKind {
    /// A head patted on top, back and sides.
    Head,
    /// An elongated 2:20:1 arm patted along its top and outer side.
    Arm,
}

/// How to build a scene.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SceneConfig {
    /// Head or arm.
    pub kind: SceneKind,
    /// Seed of the ground-truth shape.
    pub truth_seed: u64,
    /// Seed of the prior shape (a different member of the family).
    pub prior_seed: u64,
    /// Seed of the contact sampling and noise.
    pub contact_seed: u64,
    /// Contacts per patch.
    pub contacts_per_patch: usize,
    /// Standard deviation of the isotropic contact noise, metres (default 1 mm).
    pub noise_m: Real,
    /// Icosphere level of the ground-truth and prior meshes.
    pub mesh_level: u32,
}

impl SceneConfig {
    /// The default head scene (6 patches × 50 contacts).
    pub fn head() -> Self {
        Self {
            kind: SceneKind::Head,
            truth_seed: 1,
            prior_seed: 2,
            contact_seed: 3,
            contacts_per_patch: 50,
            noise_m: 1e-3,
            mesh_level: 5,
        }
    }

    /// The default arm scene (8 patches × 35 contacts).
    pub fn arm() -> Self {
        Self {
            kind: SceneKind::Arm,
            contacts_per_patch: 35,
            ..Self::head()
        }
    }
}

/// A ground truth, a prior and contacts.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The hidden surface.
    pub truth: TriMesh,
    /// The task prior (another member of the family).
    pub prior: TriMesh,
    /// Noisy contact points on the truth.
    pub contacts: Vec<Point3>,
}

/// Uniform direction in the cap of angular radius `alpha` around `axis`.
fn direction_in_cap(rng: &mut SeededRng, axis: &Vector3, alpha: Real) -> Vector3 {
    let cos_t = 1.0 - rng.uniform() * (1.0 - alpha.cos());
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * rng.uniform();
    let helper = if axis.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = axis.cross(&helper).normalize();
    let v = axis.cross(&u);
    (axis * cos_t + (u * phi.cos() + v * phi.sin()) * sin_t).normalize()
}

/// Builds a scene.
///
/// # Errors
/// Mesh validation (never for the built-in families).
pub fn build_scene(config: &SceneConfig) -> Result<Scene, GpisError> {
    let mut rng = SeededRng::new(config.contact_seed);
    let noise = |rng: &mut SeededRng| {
        Vector3::new(rng.normal(), rng.normal(), rng.normal()) * config.noise_m
    };
    match config.kind {
        SceneKind::Head => {
            let truth = HeadParams::sample(config.truth_seed);
            let prior = HeadParams::sample(config.prior_seed);
            // Top, crown, back, two sides, front of the scalp above the forehead.
            let patches = [
                Vector3::new(0.0, 0.0, 1.0),
                Vector3::new(0.0, -0.7, 0.7),
                Vector3::new(0.0, -1.0, 0.15),
                Vector3::new(1.0, -0.1, 0.35),
                Vector3::new(-1.0, -0.1, 0.35),
                Vector3::new(0.0, 0.55, 0.85),
            ];
            let mut contacts = Vec::new();
            for axis in patches {
                let axis = axis.normalize();
                for _ in 0..config.contacts_per_patch {
                    let d = direction_in_cap(&mut rng, &axis, 0.38);
                    let p = Point3::from(d * truth.radius(&d));
                    contacts.push(p + noise(&mut rng));
                }
            }
            Ok(Scene {
                truth: truth.mesh(config.mesh_level)?,
                prior: prior.mesh(config.mesh_level)?,
                contacts,
            })
        }
        SceneKind::Arm => {
            let truth = ArmParams::sample(config.truth_seed);
            let prior = ArmParams::sample(config.prior_seed);
            let mut contacts = Vec::new();
            // Four stations along the arm, top (z) and outer side (x).
            for s0 in [-0.6, -0.2, 0.2, 0.6] {
                for phi0 in [std::f64::consts::FRAC_PI_2, 0.0] {
                    for _ in 0..config.contacts_per_patch {
                        let s: Real = s0 + rng.uniform_range(-0.12, 0.12);
                        let phi: Real = phi0 + rng.uniform_range(-0.6, 0.6);
                        let q = (1.0 - s * s).sqrt();
                        let d = Vector3::new(q * phi.cos(), s, q * phi.sin());
                        contacts.push(truth.point(&d) + noise(&mut rng));
                    }
                }
            }
            Ok(Scene {
                truth: truth.mesh(config.mesh_level)?,
                prior: prior.mesh(config.mesh_level)?,
                contacts,
            })
        }
    }
}

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
    scene: &Scene,
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
            error: None,
        },
        rec.grid_dims.map_or(0, |d| d.iter().product()),
    ))
}

/// Receives each method's surface as [`evaluate_scene_with`] computes it: the method's name,
/// the mesh and the posterior variance per vertex (empty for the prior and the
/// non-probabilistic baseline, or when [`SurfaceConfig::vertex_variance`] is off).
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
    scene: &Scene,
    surface: &SurfaceConfig,
    normal_offset_m: Option<Real>,
) -> Result<SceneReport, GpisError> {
    evaluate_scene_with(kind, scene, surface, normal_offset_m, &mut |_, _, _| {})
}

/// [`evaluate_scene`], handing every method's surface to `sink` (to write or display it).
///
/// # Errors
/// As [`evaluate_scene`].
pub fn evaluate_scene_with(
    kind: SceneKind,
    scene: &Scene,
    surface: &SurfaceConfig,
    normal_offset_m: Option<Real>,
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

/// Mean and sample standard deviation of one figure over the scenes of a family.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// Mean.
    pub mean: Real,
    /// Sample standard deviation (0 for one scene).
    pub sd: Real,
}

impl Spread {
    fn of(values: &[Real]) -> Self {
        let n = values.len() as Real;
        let mean = values.iter().sum::<Real>() / n;
        let sd = if values.len() > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<Real>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Self { mean, sd }
    }
}

/// One method over a family of scenes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodSummary {
    /// Method name (as in [`MethodResult::method`]).
    pub method: String,
    /// Scenes where the method ran.
    pub runs: usize,
    /// Scenes where it failed (left out of the figures).
    pub failures: usize,
    /// UCD reconstruction → truth, mm.
    pub ucd_mm: Spread,
    /// Bidirectional Chamfer distance, mm.
    pub bcd_mm: Spread,
    /// Scenes where this method had the lowest UCD of all methods.
    pub best_ucd: usize,
}

/// Every method on several scenes of one family: different people, different contacts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FamilyReport {
    /// Which family.
    pub scene: SceneKind,
    /// The per-scene reports, the base configuration's scene first.
    pub scenes: Vec<SceneReport>,
    /// One summary per method, in the order of [`SceneReport::methods`].
    pub summary: Vec<MethodSummary>,
}

/// Runs [`evaluate_scene`] on `pairs` scenes of `base`'s family: scene `k` adds `10 k` to each
/// of the base's seeds (truth, prior, contacts), so scene 0 is the base scene itself.
///
/// # Errors
/// `pairs == 0`, or any error of [`build_scene`] / [`evaluate_scene`] (a method failing on one
/// scene is counted in [`MethodSummary::failures`] instead).
pub fn evaluate_family(
    base: &SceneConfig,
    pairs: usize,
    surface: &SurfaceConfig,
    normal_offset_m: Option<Real>,
) -> Result<FamilyReport, GpisError> {
    if pairs == 0 {
        return Err(GpisError::TooFewObservations {
            method: "benchmark",
            what: "scene pairs",
            needed: 1,
            got: 0,
        });
    }
    let mut scenes = Vec::with_capacity(pairs);
    for k in 0..pairs as u64 {
        let config = SceneConfig {
            truth_seed: base.truth_seed + 10 * k,
            prior_seed: base.prior_seed + 10 * k,
            contact_seed: base.contact_seed + 10 * k,
            ..*base
        };
        let scene = build_scene(&config)?;
        scenes.push(evaluate_scene(base.kind, &scene, surface, normal_offset_m)?);
    }
    let names: Vec<String> = scenes[0].methods.iter().map(|m| m.method.clone()).collect();
    let summary = names
        .iter()
        .map(|name| {
            let ok: Vec<&MethodResult> = scenes
                .iter()
                .filter_map(|s| s.method(name))
                .filter(|m| m.error.is_none())
                .collect();
            let ucd: Vec<Real> = ok.iter().map(|m| m.ucd_mm).collect();
            let bcd: Vec<Real> = ok.iter().map(|m| m.bcd_mm).collect();
            let best_ucd = scenes
                .iter()
                .filter(|s| {
                    let best = s
                        .methods
                        .iter()
                        .filter(|m| m.error.is_none())
                        .min_by(|a, b| a.ucd_mm.total_cmp(&b.ucd_mm));
                    best.is_some_and(|m| &m.method == name)
                })
                .count();
            let nan = Spread {
                mean: Real::NAN,
                sd: Real::NAN,
            };
            MethodSummary {
                method: name.clone(),
                runs: ok.len(),
                failures: scenes.len() - ok.len(),
                ucd_mm: if ok.is_empty() { nan } else { Spread::of(&ucd) },
                bcd_mm: if ok.is_empty() { nan } else { Spread::of(&bcd) },
                best_ucd,
            }
        })
        .collect();
    Ok(FamilyReport {
        scene: base.kind,
        scenes,
        summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_is_the_sample_mean_and_deviation() {
        let s = Spread::of(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(s.mean, 2.5);
        assert!((s.sd - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(Spread::of(&[7.0]), Spread { mean: 7.0, sd: 0.0 });
    }

    #[test]
    fn scenes_are_reproducible_closed_and_plausible() {
        let cfg = SceneConfig {
            mesh_level: 3,
            ..SceneConfig::head()
        };
        let a = build_scene(&cfg).unwrap();
        let b = build_scene(&cfg).unwrap();
        assert_eq!(a.contacts, b.contacts);
        assert_eq!(a.truth, b.truth);
        a.truth.require_closed().unwrap();
        a.prior.require_closed().unwrap();
        assert_ne!(a.truth, a.prior);
        assert_eq!(a.contacts.len(), 300);
        let ext = a.truth.aabb().extents();
        assert!(
            ext.x > 0.12 && ext.x < 0.2 && ext.y > 0.16 && ext.y < 0.25,
            "{ext}"
        );
        assert!(ext.z > 0.22 && ext.z < 0.32, "{ext}");
        let arm = build_scene(&SceneConfig {
            mesh_level: 3,
            ..SceneConfig::arm()
        })
        .unwrap();
        let e = arm.truth.aabb().extents();
        assert!(e.y > 8.0 * e.x && e.x > 1.5 * e.z, "2:20:1 ({e})");
        arm.truth.require_closed().unwrap();
    }
}
