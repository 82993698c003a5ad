//! One entry point for every surface-reconstruction method: the GP with a task prior, with a
//! sphere or a constant mean, and the non-probabilistic baseline, each with its own defaults for
//! the query region, registration and observations. `moe-touch surface`, the head and arm
//! benchmark and the patting evaluation all call
//! [`reconstruct_surface`](crate::surface::reconstruct_surface).

use std::time::Instant;

use moe_geom::{Aabb, Real, TriMesh, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;
use crate::mean::{ConstantMean, MeanFunction, MeshSdfMean, SphereMean};
use crate::nonprob::{NonProbConfig, nonprobabilistic};
use crate::observations::{ObservationKind, Observations};
use crate::posterior::Gpis;
use crate::reconstruct::{
    ConditionReport, ReconstructOptions, Timings, bounds_of, condition, reconstruct,
};
use crate::register::{IcpConfig, IcpReport, register_prior};

/// How to reconstruct a surface from contacts.
#[derive(Debug, Clone, PartialEq)]
pub enum SurfaceMethod {
    /// GP whose mean is the signed distance of a task prior mesh (another body of the same
    /// family), optionally registered to the contacts first (ICP; `None`: the prior is already in
    /// the contacts' frame). The paper's method.
    Prior {
        /// ICP registration of the prior to the contacts before it becomes the mean.
        registration: Option<IcpConfig>,
    },
    /// GP whose mean is a sphere fitted to the contacts (paper Eqs. 5–7).
    Sphere,
    /// GP with a constant mean `value` (metres; positive: "outside" away from the data). An
    /// interior observation at the contacts' centroid is added when there is none, so the level
    /// set has an inside.
    Constant {
        /// The mean's value, metres.
        value: Real,
    },
    /// The non-probabilistic baseline: the prior's vertices nearest to the contacts are moved
    /// onto them and the mesh is smoothed (no posterior, no variance).
    NonProbabilistic,
}

impl SurfaceMethod {
    /// The name used in reports: `gp_prior`, `gp_sphere`, `gp_constant`, `nonprob`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Prior { .. } => "gp_prior",
            Self::Sphere => "gp_sphere",
            Self::Constant { .. } => "gp_constant",
            Self::NonProbabilistic => "nonprob",
        }
    }

    /// Whether the method needs a prior mesh.
    pub fn needs_prior(&self) -> bool {
        matches!(self, Self::Prior { .. } | Self::NonProbabilistic)
    }
}

/// Everything [`reconstruct_surface`] needs beside the contacts and the prior.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceOptions {
    /// The method.
    pub method: SurfaceMethod,
    /// Fit, grid, meshing and variance settings of the GP methods.
    pub surface: ReconstructOptions,
    /// Distance `d` of the `±d` observations added along the mean's normals at every contact
    /// (see [`Observations::add_mean_normal_offsets`]), metres; 0 for none. Default 5 mm.
    pub normal_offset_m: Real,
    /// The region to query and mesh; `None` for the method's own (see [`query_bounds`]).
    pub bounds: Option<Aabb>,
    /// Settings of the non-probabilistic baseline.
    pub nonprob: NonProbConfig,
    /// For the methods with a prior: contacts farther than this from the (registered) prior's
    /// surface are left out before the surface is built, as false contacts (metres; `None`
    /// keeps every contact). A task prior is another body of the same family, a few millimetres
    /// from the truth, so a contact centimetres away from it is more likely a false alarm of
    /// the contact estimator than a feature of the body.
    pub prior_gate_m: Option<Real>,
}

impl Default for SurfaceOptions {
    fn default() -> Self {
        Self {
            method: SurfaceMethod::Prior { registration: None },
            surface: ReconstructOptions::default(),
            normal_offset_m: 0.005,
            bounds: None,
            nonprob: NonProbConfig::default(),
            prior_gate_m: None,
        }
    }
}

/// The posterior of a GP method, whatever its mean.
pub type SurfacePosterior = Gpis<Box<dyn MeanFunction>>;

/// A GP method's mean, ready to condition: the mean function, the observations it conditions
/// on (the contacts plus normal offsets and, for a constant mean, an interior point), the query
/// region, and what was fitted on the way.
pub struct PreparedMean {
    /// The mean function.
    pub mean: Box<dyn MeanFunction>,
    /// The observations to condition on.
    pub observations: Observations,
    /// The query and meshing region.
    pub bounds: Aabb,
    /// The registration of the prior, when one ran.
    pub registration: Option<IcpReport>,
    /// The fitted sphere ([`SurfaceMethod::Sphere`]).
    pub sphere: Option<SphereMean>,
    /// Contacts left out by [`SurfaceOptions::prior_gate_m`].
    pub gated_contacts: usize,
}

impl std::fmt::Debug for PreparedMean {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PreparedMean")
            .field("observations", &self.observations.len())
            .field("bounds", &self.bounds)
            .field("registration", &self.registration)
            .field("sphere", &self.sphere)
            .field("gated_contacts", &self.gated_contacts)
            .finish_non_exhaustive()
    }
}

/// A reconstructed surface and how it was obtained.
#[derive(Debug, Clone)]
pub struct SurfaceResult {
    /// The method's report name ([`SurfaceMethod::name`]).
    pub method: &'static str,
    /// The surface (closed for the GP methods; the deformed prior for the baseline).
    pub mesh: TriMesh,
    /// Observations conditioned on (contacts, normal offsets, interior points); the contacts for
    /// the baseline.
    pub observations: usize,
    /// Posterior variance at every vertex (m²); empty for the baseline or when
    /// [`ReconstructOptions::vertex_variance`] is off.
    pub vertex_variance: Vec<Real>,
    /// Hyper-parameters and conditioning (GP methods).
    pub condition: Option<ConditionReport>,
    /// The prior's registration, when one ran.
    pub registration: Option<IcpReport>,
    /// The fitted sphere ([`SurfaceMethod::Sphere`]).
    pub sphere: Option<SphereMean>,
    /// Contacts left out by [`SurfaceOptions::prior_gate_m`].
    pub gated_contacts: usize,
    /// Grid nodes along each axis (GP methods).
    pub grid_dims: Option<[usize; 3]>,
    /// Per-stage wall times (GP methods).
    pub timings: Option<Timings>,
    /// Wall time of the whole reconstruction without the per-vertex variance, seconds.
    pub secs: Real,
}

fn too_few(what: &'static str, needed: usize, got: usize) -> GpisError {
    GpisError::TooFewObservations {
        method: "surface",
        what,
        needed,
        got,
    }
}

fn require_prior<'a>(
    method: &SurfaceMethod,
    prior: Option<&'a TriMesh>,
) -> Result<&'a TriMesh, GpisError> {
    prior.ok_or(GpisError::MissingPrior {
        method: method.name(),
    })
}

/// The region a method queries by default: for a prior, the box around the observations and
/// the prior; for a sphere, the sphere's box clipped to the observations' box grown by half its
/// size on every side (a sphere fitted to a few patches can be far larger than the body); for a
/// constant mean, the observations' box grown by half its size (plus 1 mm).
pub fn query_bounds(
    observations: &Observations,
    prior: Option<&TriMesh>,
    sphere: Option<&SphereMean>,
) -> Option<Aabb> {
    let points = observations.points();
    if let Some(prior) = prior {
        return bounds_of(points, Some(prior));
    }
    let b = bounds_of(points, None)?;
    let g = b.extents() * 0.5;
    Some(match sphere {
        Some(s) => {
            let r = Vector3::repeat(s.radius);
            Aabb {
                min: (s.center - r).sup(&(b.min - g)).inf(&b.min),
                max: (s.center + r).inf(&(b.max + g)).sup(&b.max),
            }
        }
        None => {
            let g = g + Vector3::repeat(1e-3);
            Aabb {
                min: b.min - g,
                max: b.max + g,
            }
        }
    })
}

/// Builds a GP method's mean from the contacts in `observations` (and any other observations
/// they carry) and `prior`: registration and signed distance of the prior, sphere fit or
/// constant; adds the normal offsets; chooses the query region.
///
/// # Errors
/// [`SurfaceMethod::NonProbabilistic`] (it has no mean: use [`reconstruct_surface`]), a missing
/// or non-watertight prior, a failed sphere fit, an invalid normal offset, no observations.
pub fn prepare_mean(
    observations: &Observations,
    prior: Option<&TriMesh>,
    options: &SurfaceOptions,
) -> Result<PreparedMean, GpisError> {
    let d = options.normal_offset_m;
    if !(d.is_finite() && d >= 0.0) {
        return Err(GpisError::InvalidParameter {
            name: "normal_offset_m",
            value: d,
            reason: "must be finite and at least 0",
        });
    }
    let gate = prior_gate(options)?;
    if observations.is_empty() {
        return Err(too_few("observations", 1, 0));
    }
    let contacts = observations.contacts();
    let mut obs = observations.clone();
    let mut registration = None;
    let mut sphere = None;
    let mut gated_contacts = 0;
    let (mean, bounds): (Box<dyn MeanFunction>, Option<Aabb>) = match &options.method {
        SurfaceMethod::Prior { registration: icp } => {
            let given = require_prior(&options.method, prior)?;
            let registered = match icp {
                Some(cfg) => {
                    let (moved, report) = register_prior(given, &contacts, cfg)?;
                    registration = Some(report);
                    Some(moved)
                }
                None => None,
            };
            let prior = registered.as_ref().unwrap_or(given);
            let sdf = MeshSdfMean::new(prior)?;
            if let Some(gate) = gate {
                gated_contacts = gate_contacts(&mut obs, &sdf, gate)?;
            }
            let bounds = query_bounds(&obs, Some(prior), None);
            (Box::new(sdf), bounds)
        }
        SurfaceMethod::Sphere => {
            let s = SphereMean::fit(&contacts)?;
            sphere = Some(s);
            (Box::new(s), query_bounds(&obs, None, Some(&s)))
        }
        SurfaceMethod::Constant { value } => {
            if !value.is_finite() {
                return Err(GpisError::InvalidParameter {
                    name: "constant mean (m)",
                    value: *value,
                    reason: "must be finite",
                });
            }
            if obs.num_interior() == 0 {
                obs.add_centroid_interior()?;
            }
            let bounds = query_bounds(&obs, None, None);
            (Box::new(ConstantMean { value: *value }), bounds)
        }
        SurfaceMethod::NonProbabilistic => {
            return Err(GpisError::InvalidParameter {
                name: "method",
                value: Real::NAN,
                reason: "the non-probabilistic baseline has no mean function",
            });
        }
    };
    if d > 0.0 {
        obs.add_mean_normal_offsets(&mean, d)?;
    }
    let bounds = options
        .bounds
        .or(bounds)
        .ok_or_else(|| too_few("observations", 1, 0))?;
    Ok(PreparedMean {
        mean,
        observations: obs,
        bounds,
        registration,
        sphere,
        gated_contacts,
    })
}

/// [`SurfaceOptions::prior_gate_m`], checked (finite and positive), before any work is done.
fn prior_gate(options: &SurfaceOptions) -> Result<Option<Real>, GpisError> {
    match options.prior_gate_m {
        Some(gate) if !(gate.is_finite() && gate > 0.0) => Err(GpisError::InvalidParameter {
            name: "prior_gate_m",
            value: gate,
            reason: "must be finite and positive",
        }),
        gate => Ok(gate),
    }
}

/// Leaves out the contacts of `obs` farther than `gate` (checked by [`prior_gate`]) from the
/// prior's surface; returns how many.
fn gate_contacts(
    obs: &mut Observations,
    prior: &MeshSdfMean,
    gate: Real,
) -> Result<usize, GpisError> {
    let dropped =
        obs.retain_contacts(|p| prior.value_within(p, gate).is_some_and(|v| v.abs() <= gate));
    if !obs.kinds().contains(&ObservationKind::Contact) {
        return Err(too_few("contacts within the prior gate", 1, 0));
    }
    Ok(dropped)
}

/// Conditions a GP method without meshing: the posterior, for queries at points.
///
/// # Errors
/// As [`prepare_mean`] and [`condition`].
pub fn condition_surface(
    observations: &Observations,
    prior: Option<&TriMesh>,
    options: &SurfaceOptions,
) -> Result<(SurfacePosterior, ConditionReport, PreparedMeanReport), GpisError> {
    let prepared = prepare_mean(observations, prior, options)?;
    let report = PreparedMeanReport {
        registration: prepared.registration,
        sphere: prepared.sphere,
        observations: prepared.observations.len(),
        gated_contacts: prepared.gated_contacts,
    };
    let (gpis, cond) = condition(prepared.mean, &prepared.observations, &options.surface.gpis)?;
    Ok((gpis, cond, report))
}

/// What [`condition_surface`] fitted beside the posterior.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PreparedMeanReport {
    /// The prior's registration, when one ran.
    pub registration: Option<IcpReport>,
    /// The fitted sphere ([`SurfaceMethod::Sphere`]).
    pub sphere: Option<SphereMean>,
    /// Observations conditioned on (contacts, offsets, interior points).
    pub observations: usize,
    /// Contacts left out by [`SurfaceOptions::prior_gate_m`].
    #[serde(default)]
    pub gated_contacts: usize,
}

/// Reconstructs the surface touched at `observations` (contacts, optionally with other
/// observations) with `options.method`, and the GP posterior with it when the method is a GP.
///
/// # Errors
/// No contacts, a method needing a prior without one ([`GpisError::MissingPrior`]), and the
/// errors of the stages (registration, sphere fit, conditioning, meshing).
pub fn reconstruct_surface(
    observations: &Observations,
    prior: Option<&TriMesh>,
    options: &SurfaceOptions,
) -> Result<(SurfaceResult, Option<SurfacePosterior>), GpisError> {
    let t = Instant::now();
    if let SurfaceMethod::NonProbabilistic = options.method {
        let prior = require_prior(&options.method, prior)?;
        let gate = prior_gate(options)?;
        if !observations.kinds().contains(&ObservationKind::Contact) {
            return Err(too_few("contacts", 1, 0));
        }
        let (contacts, gated_contacts) = match gate {
            Some(gate) => {
                let mut obs = observations.clone();
                let gated = gate_contacts(&mut obs, &MeshSdfMean::new(prior)?, gate)?;
                (obs.contacts(), gated)
            }
            None => (observations.contacts(), 0),
        };
        let mesh = nonprobabilistic(prior, &contacts, &options.nonprob)?;
        return Ok((
            SurfaceResult {
                method: options.method.name(),
                mesh,
                observations: contacts.len(),
                vertex_variance: Vec::new(),
                condition: None,
                registration: None,
                sphere: None,
                gated_contacts,
                grid_dims: None,
                timings: None,
                secs: t.elapsed().as_secs_f64(),
            },
            None,
        ));
    }
    let prepared = prepare_mean(observations, prior, options)?;
    let (rec, gpis) = reconstruct(
        prepared.mean,
        &prepared.observations,
        &prepared.bounds,
        &options.surface,
    )?;
    let secs = t.elapsed().as_secs_f64() - rec.timings.variance_secs;
    Ok((
        SurfaceResult {
            method: options.method.name(),
            mesh: rec.mesh,
            observations: prepared.observations.len(),
            vertex_variance: rec.vertex_variance,
            condition: Some(rec.report),
            registration: prepared.registration,
            sphere: prepared.sphere,
            gated_contacts: prepared.gated_contacts,
            grid_dims: Some(rec.grid.dims),
            timings: Some(rec.timings),
            secs,
        },
        Some(gpis),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::shapes::icosphere;
    use moe_geom::{Point3, SeededRng};

    /// `n` contacts on the upper half of the sphere of radius `r` at the origin.
    fn cap_contacts(r: Real, n: usize) -> Observations {
        let mut rng = SeededRng::new(5);
        let points: Vec<Point3> = (0..n)
            .map(|_| {
                let mut d = Vector3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
                d.z = d.z.abs();
                Point3::from(d * r)
            })
            .collect();
        Observations::from_contacts(&points).unwrap()
    }

    fn small(method: SurfaceMethod) -> SurfaceOptions {
        SurfaceOptions {
            method,
            surface: ReconstructOptions {
                max_grid_nodes: 24 * 24 * 24,
                vertex_variance: false,
                ..ReconstructOptions::default()
            },
            ..SurfaceOptions::default()
        }
    }

    /// Mean distance of the mesh's vertices from the sphere of radius `r` at the origin.
    fn mean_radial_error(mesh: &TriMesh, r: Real) -> Real {
        mesh.vertices()
            .iter()
            .map(|p| (p.coords.norm() - r).abs())
            .sum::<Real>()
            / mesh.num_vertices() as Real
    }

    #[test]
    fn every_method_recovers_a_touched_sphere() {
        let r = 0.08;
        let contacts = cap_contacts(r, 150);
        // A prior 10 % too large: the contacts must pull the surface in.
        let prior = icosphere(3, 1.1 * r);
        let prior_error = mean_radial_error(&prior, r);
        for method in [
            SurfaceMethod::Prior { registration: None },
            SurfaceMethod::Sphere,
            SurfaceMethod::NonProbabilistic,
        ] {
            let name = method.name();
            let (rec, gpis) = reconstruct_surface(&contacts, Some(&prior), &small(method)).unwrap();
            assert_eq!(rec.method, name);
            assert_eq!(gpis.is_some(), name != "nonprob");
            assert_eq!(rec.condition.is_some(), name != "nonprob");
            let err = mean_radial_error(&rec.mesh, r);
            assert!(
                err < 0.6 * prior_error,
                "{name}: {err} vs prior {prior_error}"
            );
            if name == "gp_sphere" {
                let s = rec.sphere.unwrap();
                assert!((s.radius - r).abs() < 1e-6 && s.center.coords.norm() < 1e-6);
            }
        }
        // The prior's SDF is exact on the contacts' side; the constant mean only needs the
        // contacts (and gains the centroid as its interior point).
        let (rec, _) = reconstruct_surface(
            &contacts,
            None,
            &small(SurfaceMethod::Constant { value: 0.02 }),
        )
        .unwrap();
        // A constant has no normals to offset along: the contacts and one interior point.
        assert_eq!(rec.observations, 150 + 1);
        rec.mesh.require_closed().unwrap();
    }

    /// False contacts far from the prior: the gate leaves exactly those out, for the GP and the
    /// baseline, and the surface then stays near the body; a bad gate and a gate that leaves
    /// nothing are errors.
    #[test]
    fn the_prior_gate_leaves_out_far_contacts() {
        let r = 0.08;
        let mut contacts = cap_contacts(r, 120);
        let outliers = [
            Point3::new(0.0, 0.0, 1.5 * r),
            Point3::new(1.4 * r, 0.2 * r, 0.3 * r),
            Point3::new(-0.2 * r, 1.45 * r, 0.1 * r),
        ];
        contacts.add_contacts(&outliers).unwrap();
        let prior = icosphere(3, 1.05 * r);
        let gated = |method| SurfaceOptions {
            prior_gate_m: Some(0.01),
            ..small(method)
        };
        for method in [
            SurfaceMethod::Prior { registration: None },
            SurfaceMethod::NonProbabilistic,
        ] {
            let name = method.name();
            let (all, _) =
                reconstruct_surface(&contacts, Some(&prior), &small(method.clone())).unwrap();
            let (kept, _) = reconstruct_surface(&contacts, Some(&prior), &gated(method)).unwrap();
            assert_eq!(all.gated_contacts, 0, "{name}");
            assert_eq!(kept.gated_contacts, outliers.len(), "{name}");
            // An outlier pulls the GP's surface to itself (0.4–0.5 r off); without them every
            // vertex is within 0.2 r.
            let worst = |mesh: &TriMesh| {
                mesh.vertices()
                    .iter()
                    .map(|p| (p.coords.norm() - r).abs())
                    .fold(0.0, Real::max)
            };
            let (e_all, e_kept) = (worst(&all.mesh), worst(&kept.mesh));
            assert!(e_kept < 0.2 * r, "{name}: gated {e_kept}");
            // The baseline's smoothing pulls a lone moved vertex back, so only the GP shows
            // the outliers.
            if name == "gp_prior" {
                assert!(e_all > 0.3 * r, "{name}: all {e_all}");
            }
        }
        // The sphere has no prior: the gate does not apply.
        let (sphere, _) =
            reconstruct_surface(&contacts, Some(&prior), &gated(SurfaceMethod::Sphere)).unwrap();
        assert_eq!(sphere.gated_contacts, 0);
        for bad in [0.0, -0.01, Real::NAN] {
            let options = SurfaceOptions {
                prior_gate_m: Some(bad),
                ..small(SurfaceMethod::Prior { registration: None })
            };
            assert!(matches!(
                prepare_mean(&contacts, Some(&prior), &options),
                Err(GpisError::InvalidParameter {
                    name: "prior_gate_m",
                    ..
                })
            ));
        }
        let far = Observations::from_contacts(&outliers).unwrap();
        assert!(matches!(
            reconstruct_surface(&far, Some(&prior), &gated(SurfaceMethod::NonProbabilistic)),
            Err(GpisError::TooFewObservations { .. })
        ));
    }

    #[test]
    fn given_bounds_replace_the_methods_own() {
        let contacts = cap_contacts(0.08, 60);
        let wide = Aabb {
            min: Point3::new(-0.2, -0.2, -0.2),
            max: Point3::new(0.2, 0.2, 0.2),
        };
        let own = prepare_mean(&contacts, None, &small(SurfaceMethod::Sphere)).unwrap();
        assert!(own.bounds.extents().x < 0.3);
        let options = SurfaceOptions {
            bounds: Some(wide),
            ..small(SurfaceMethod::Sphere)
        };
        let given = prepare_mean(&contacts, None, &options).unwrap();
        assert_eq!(given.bounds, wide);
        // The sphere's own box is clipped to the contacts' box grown by half its size.
        let cb = bounds_of(contacts.points(), None).unwrap();
        assert!(own.bounds.min.z >= cb.min.z - 0.5 * cb.extents().z - 1e-12);
    }

    #[test]
    fn missing_priors_and_bad_options_are_typed_errors() {
        let contacts = cap_contacts(0.08, 30);
        for method in [
            SurfaceMethod::Prior { registration: None },
            SurfaceMethod::NonProbabilistic,
        ] {
            let name = method.name();
            assert!(matches!(
                reconstruct_surface(&contacts, None, &small(method)),
                Err(GpisError::MissingPrior { method }) if method == name
            ));
        }
        let bad_offset = SurfaceOptions {
            normal_offset_m: -1.0,
            ..small(SurfaceMethod::Sphere)
        };
        assert!(matches!(
            reconstruct_surface(&contacts, None, &bad_offset),
            Err(GpisError::InvalidParameter {
                name: "normal_offset_m",
                ..
            })
        ));
        assert!(matches!(
            reconstruct_surface(
                &contacts,
                None,
                &small(SurfaceMethod::Constant { value: Real::NAN })
            ),
            Err(GpisError::InvalidParameter { .. })
        ));
        assert!(matches!(
            reconstruct_surface(&Observations::new(), None, &small(SurfaceMethod::Sphere)),
            Err(GpisError::TooFewObservations { .. })
        ));
    }
}
