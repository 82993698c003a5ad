//! An occluded surface reconstructed from contact points in files, as `moe-touch surface` runs
//! it: the contacts (and a prior mesh) read, the surface built by
//! [`moe_gpis::reconstruct_surface`] (or only the posterior conditioned, for queries), the mesh,
//! its per-vertex variance and the posterior at query points written, and a typed report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use moe_geom::{Point3, Real};
use moe_gpis::{
    ConditionReport, FitReport, IcpReport, Mesher, Observations, SphereMean, SurfaceMethod,
    SurfaceOptions, SurfacePosterior, Timings, condition_surface, reconstruct_surface,
};
use moe_io::IoError;
use serde::Serialize;

use crate::error::LabError;

/// The files of a reconstruction: what is read and what is written.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceFiles {
    /// Contact points in metres: CSV rows `x,y,z` (SDF 0) or `x,y,z,sdf`, or a PLY point cloud
    /// (an optional vertex scalar `sdf` gives the values).
    pub contacts: PathBuf,
    /// The prior mesh (closed; OBJ, PLY or STL), for the methods with a prior.
    pub prior: Option<PathBuf>,
    /// The surface mesh to write (OBJ or PLY); without it only the posterior is conditioned.
    pub out: Option<PathBuf>,
    /// A PLY of the surface with the posterior `variance` (m²) and `std` (m) per vertex.
    pub variance_out: Option<PathBuf>,
    /// Points (CSV `x,y,z`, metres) at which to query the posterior, and the CSV to write the
    /// `mean,std` (m) of each to, in order.
    pub query: Option<(PathBuf, PathBuf)>,
}

/// The `moe-touch surface --json` report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurfaceReport {
    /// The method's name on the command line: `prior`, `sphere`, `constant` or `nonprob`.
    pub method: &'static str,
    /// Contacts read.
    pub contacts: usize,
    /// Contacts left out as too far from the prior.
    pub gated_contacts: usize,
    /// The prior's registration, when one ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub registration: Option<IcpReport>,
    /// The fitted sphere (method `sphere`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sphere: Option<SphereRecord>,
    /// The posterior, for the GP methods.
    #[serde(flatten)]
    pub posterior: Option<PosteriorRecord>,
    /// Vertices of the written surface.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vertices: Option<usize>,
    /// Faces of the written surface.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub faces: Option<usize>,
    /// Grid nodes along each axis (GP methods, with a surface).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grid_dims: Option<[usize; 3]>,
    /// Wall times.
    pub timings: SurfaceTimings,
    /// Points queried.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub queries: Option<usize>,
    /// Wall time of the queries, seconds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub query_secs: Option<Real>,
    /// Wall time of everything, seconds.
    pub total_secs: Real,
    /// What the reconstruction did that a reader should know (a registration, an added
    /// interior point), one line each.
    #[serde(skip)]
    pub notes: Vec<String>,
}

/// A fitted sphere.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SphereRecord {
    /// Its centre, metres.
    pub center_m: [Real; 3],
    /// Its radius, metres.
    pub radius_m: Real,
}

/// The posterior of a GP method.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PosteriorRecord {
    /// Observations conditioned on (contacts, normal offsets, interior points).
    pub observations: usize,
    /// The hyper-parameters used.
    pub hyper: HyperRecord,
    /// Exact log marginal likelihood of all observations (exact inference only).
    pub log_marginal_likelihood: Option<Real>,
    /// Whether the sparse approximation was used.
    pub sparse: bool,
    /// Diagonal jitter added to the kernel matrix.
    pub jitter: Real,
    /// The fit, when the hyper-parameters were fitted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitReport>,
    /// The final mesher: `marching` or `poisson`.
    pub mesher: &'static str,
}

/// The hyper-parameters of a posterior (fields in alphabetical order, as the summary line
/// prints them).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HyperRecord {
    /// Whether they were fitted (rather than given).
    pub fitted: bool,
    /// Length scale, metres.
    pub lengthscale_m: Real,
    /// Observation noise variance, m².
    pub noise_variance_m2: Real,
    /// Signal variance, m².
    pub signal_variance_m2: Real,
}

/// The wall times of a reconstruction, seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(untagged)]
pub enum SurfaceTimings {
    /// Each stage of a GP method's surface.
    Stages(Timings),
    /// The whole of the non-probabilistic baseline.
    Total {
        /// Seconds.
        total_secs: Real,
    },
    /// The fit and conditioning of a posterior without a surface.
    Fit {
        /// Seconds.
        fit_secs: Real,
    },
}

/// Reads points: CSV rows `x,y,z` in metres (a fourth column is ignored), header optional.
///
/// # Errors
/// [`IoError`] for a missing, unreadable or malformed file, naming it.
pub fn read_points(path: &Path) -> Result<Vec<Point3>, LabError> {
    let rows = moe_io::read_points_csv(path)?;
    Ok(rows.iter().map(|r| Point3::new(r[0], r[1], r[2])).collect())
}

/// Reads observations from CSV (`x,y,z[,sdf]`) or PLY (points, optional scalar `sdf`).
///
/// # Errors
/// [`IoError`] naming the file: unreadable, malformed, or non-finite points or values.
pub fn read_observations(path: &Path) -> Result<Observations, LabError> {
    let is_ply = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    let (points, values): (Vec<Point3>, Vec<Real>) = if is_ply {
        let ply = moe_io::read_ply(path)?;
        let values = match ply.scalar("sdf") {
            Some(s) => s.iter().map(|&v| Real::from(v)).collect(),
            None => vec![0.0; ply.points.len()],
        };
        (ply.points, values)
    } else {
        moe_io::read_points_csv(path)?
            .into_iter()
            .map(|r| {
                (
                    Point3::new(r[0], r[1], r[2]),
                    r.get(3).copied().unwrap_or(0.0),
                )
            })
            .unzip()
    };
    let mut obs = Observations::new();
    obs.add_valued(&points, &values)
        .map_err(|e| IoError::invalid(path, "observations", e.to_string()))?;
    Ok(obs)
}

/// The command line's name of a method.
fn method_name(method: &SurfaceMethod) -> &'static str {
    match method {
        SurfaceMethod::Prior { .. } => "prior",
        SurfaceMethod::Sphere => "sphere",
        SurfaceMethod::Constant { .. } => "constant",
        SurfaceMethod::NonProbabilistic => "nonprob",
    }
}

impl PosteriorRecord {
    fn new(observations: usize, cond: &ConditionReport, options: &SurfaceOptions) -> Self {
        let h = cond.hyper;
        Self {
            observations,
            hyper: HyperRecord {
                fitted: cond.fit.is_some(),
                lengthscale_m: h.lengthscale,
                noise_variance_m2: h.noise_variance,
                signal_variance_m2: h.signal_variance,
            },
            log_marginal_likelihood: cond.log_marginal_likelihood,
            sparse: cond.sparse,
            jitter: cond.jitter,
            fit: cond.fit,
            mesher: match options.surface.mesher {
                Mesher::MarchingTetrahedra => "marching",
                Mesher::Poisson(_) => "poisson",
            },
        }
    }
}

/// Reconstructs the surface touched at the contacts of `files` (when `files.out` is given,
/// writing it and its variance), and queries the posterior at the query points.
///
/// # Errors
/// Unreadable or malformed inputs, a reconstruction that fails (too few contacts, a prior that
/// is not closed, a singular kernel, ...), files that cannot be written.
pub fn reconstruct_files(
    files: &SurfaceFiles,
    options: &SurfaceOptions,
) -> Result<SurfaceReport, LabError> {
    let t0 = Instant::now();
    let obs = read_observations(&files.contacts)?;
    let prior = files.prior.as_deref().map(moe_io::read_mesh).transpose()?;
    let mut report = SurfaceReport {
        method: method_name(&options.method),
        contacts: obs.contacts().len(),
        gated_contacts: 0,
        registration: None,
        sphere: None,
        posterior: None,
        vertices: None,
        faces: None,
        grid_dims: None,
        timings: SurfaceTimings::Total { total_secs: 0.0 },
        queries: None,
        query_secs: None,
        total_secs: 0.0,
        notes: Vec::new(),
    };
    if matches!(options.method, SurfaceMethod::Constant { .. }) && obs.num_interior() == 0 {
        report
            .notes
            .push("no inside observation; the contacts' centroid is added as one".into());
    }
    let gpis = match &files.out {
        Some(out) => {
            let (rec, gpis) = reconstruct_surface(&obs, prior.as_ref(), options)?;
            moe_io::write_mesh(out, &rec.mesh)?;
            if let Some(path) = &files.variance_out {
                let ply = moe_io::PlyData::with_variance(&rec.mesh, &rec.vertex_variance);
                moe_io::write_ply(path, &ply)?;
            }
            report.set_fitted(rec.registration, rec.sphere);
            report.gated_contacts = rec.gated_contacts;
            report.posterior = rec
                .condition
                .as_ref()
                .map(|cond| PosteriorRecord::new(rec.observations, cond, options));
            report.vertices = Some(rec.mesh.num_vertices());
            report.faces = Some(rec.mesh.num_faces());
            report.grid_dims = rec.grid_dims;
            report.timings = match rec.timings {
                Some(t) => SurfaceTimings::Stages(t),
                None => SurfaceTimings::Total {
                    total_secs: rec.secs,
                },
            };
            gpis
        }
        None => {
            let (gpis, cond, fitted) = condition_surface(&obs, prior.as_ref(), options)?;
            report.set_fitted(fitted.registration, fitted.sphere);
            report.gated_contacts = fitted.gated_contacts;
            report.posterior = Some(PosteriorRecord::new(fitted.observations, &cond, options));
            report.timings = SurfaceTimings::Fit {
                fit_secs: cond.secs,
            };
            Some(gpis)
        }
    };
    if let (Some(gpis), Some((points, values))) = (&gpis, &files.query) {
        let t = Instant::now();
        let n = query(gpis, points, values)?;
        report.queries = Some(n);
        report.query_secs = Some(t.elapsed().as_secs_f64());
    }
    report.total_secs = t0.elapsed().as_secs_f64();
    Ok(report)
}

/// The posterior's `mean,std` at the points of `points`, written to `values`; the number of
/// points.
fn query(gpis: &SurfacePosterior, points: &Path, values: &Path) -> Result<usize, LabError> {
    let pts = read_points(points)?;
    let rows: Vec<Vec<Real>> = gpis
        .query(&pts)
        .map_err(|e| IoError::invalid(points, "query points", e.to_string()))?
        .iter()
        .map(|(m, s)| vec![*m, *s])
        .collect();
    moe_io::write_csv(values, &["mean", "std"], &rows)?;
    Ok(pts.len())
}

impl SurfaceReport {
    /// Records the registration and the fitted sphere, when the method produced them.
    fn set_fitted(&mut self, registration: Option<IcpReport>, sphere: Option<SphereMean>) {
        if let Some(icp) = &registration {
            self.notes.push(format!(
                "registered the prior ({} iterations, RMS {:.2} mm -> {:.2} mm)",
                icp.iterations,
                1e3 * icp.rms_before_m,
                1e3 * icp.rms_after_m
            ));
        }
        self.registration = registration;
        self.sphere = sphere.map(|s| SphereRecord {
            center_m: s.center.into(),
            radius_m: s.radius,
        });
    }

    /// The one line `moe-touch surface` prints; `-` for what the method does not report.
    pub fn line(&self) -> String {
        /// A value as compact JSON, as the line has always shown it.
        fn json<T: Serialize>(value: &T) -> String {
            serde_json::to_string(value).unwrap_or_else(|e| e.to_string())
        }
        let posterior = self.posterior.as_ref();
        format!(
            "surface: method {}, {} contacts, {} vertices, hyper {}, log marginal likelihood {}",
            self.method,
            self.contacts,
            self.vertices.map_or_else(|| "-".into(), |v| v.to_string()),
            posterior.map_or_else(|| "-".into(), |p| json(&p.hyper)),
            posterior.map_or_else(|| "-".into(), |p| json(&p.log_marginal_likelihood)),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("moe-lab-surface-{}-{name}", std::process::id()))
    }

    /// Points on a sphere of radius 5 cm about the origin.
    fn sphere_csv(path: &Path) {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let rows: Vec<Vec<Real>> = (0..60)
            .map(|i| {
                let z = 1.0 - 2.0 * (f64::from(i) + 0.5) / 60.0;
                let (r, t) = ((1.0 - z * z).sqrt(), golden * f64::from(i));
                vec![0.05 * r * t.cos(), 0.05 * r * t.sin(), 0.05 * z]
            })
            .collect();
        moe_io::write_csv(path, &["x", "y", "z"], &rows).unwrap();
    }

    #[test]
    fn a_posterior_is_queried_in_order_and_reported_without_a_surface() {
        let contacts = scratch("contacts.csv");
        let (points, values) = (scratch("query.csv"), scratch("values.csv"));
        sphere_csv(&contacts);
        moe_io::write_csv(
            &points,
            &["x", "y", "z"],
            &[vec![0.0; 3], vec![0.2, 0.0, 0.0]],
        )
        .unwrap();
        let files = SurfaceFiles {
            contacts: contacts.clone(),
            query: Some((points.clone(), values.clone())),
            ..SurfaceFiles::default()
        };
        let options = SurfaceOptions {
            method: SurfaceMethod::Constant { value: 0.02 },
            ..SurfaceOptions::default()
        };
        let report = reconstruct_files(&files, &options).unwrap();
        assert_eq!((report.method, report.contacts), ("constant", 60));
        assert_eq!(report.queries, Some(2));
        assert_eq!(report.vertices, None);
        assert!(matches!(report.timings, SurfaceTimings::Fit { .. }));
        assert_eq!(report.notes.len(), 1, "{:?}", report.notes);
        let posterior = report.posterior.as_ref().unwrap();
        assert_eq!(posterior.mesher, "marching");
        let line = report.line();
        let start = "surface: method constant, 60 contacts, - vertices, hyper {\"fitted\":true,";
        assert!(line.starts_with(start), "{line}");
        let table = moe_io::read_csv(&values).unwrap();
        assert_eq!(table.rows.len(), 2);
        assert!(
            table.rows[0][0] < 0.0 && table.rows[1][0] > 0.0,
            "{:?}",
            table.rows
        );
        for p in [contacts, points, values] {
            std::fs::remove_file(p).unwrap();
        }
    }

    #[test]
    fn non_finite_contacts_are_refused_naming_the_file() {
        let contacts = scratch("nan.csv");
        std::fs::write(&contacts, "x,y,z\n0,0,0\n0,0,1\n0,1,0\n1,0,inf\n").unwrap();
        let err = read_observations(&contacts).unwrap_err().to_string();
        assert!(err.contains("nan.csv"), "{err}");
        std::fs::remove_file(contacts).unwrap();
    }
}
