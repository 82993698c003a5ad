//! Conditioning and surface reconstruction: fit (or fix) the hyper-parameters on the residuals
//! `y − m(x)`, condition exactly (or sparsely beyond [`GpisConfig::exact_limit`]), query the
//! posterior mean on a grid, mesh its zero level set and attach the posterior variance to every
//! vertex.

use std::time::Instant;

use moe_geom::{Aabb, Point3, Real, TriMesh};
use serde::{Deserialize, Serialize};

use crate::error::GpisError;
use crate::fit::{FitConfig, FitReport, fit_hyper};
use crate::gp::ExactGp;
use crate::grid::Grid3;
use crate::kernel::Hyper;
use crate::marching::{MeshingOptions, extract_surface};
use crate::mean::MeanFunction;
use crate::observations::Observations;
use crate::poisson::{PoissonOptions, poisson_surface};
use crate::posterior::{Gpis, ResidualGp};
use crate::sparse::SparseGp;

/// How to condition a GPIS.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GpisConfig {
    /// Kernel family, bounds, start point and jitter for fitting (the kernel family and jitter
    /// are used with fixed hyper-parameters too).
    pub fit: FitConfig,
    /// Fixed hyper-parameters; `None` fits them by maximum marginal likelihood.
    pub fixed: Option<Hyper>,
    /// Largest number of observations conditioned exactly (default 5000); beyond, the sparse
    /// approximation of [`crate::parts::SparseGp`] is used.
    pub exact_limit: usize,
    /// Inducing points of the sparse approximation (default 1000).
    pub inducing_points: usize,
}

/// The largest `exact_limit` and `inducing_points` of a [`GpisConfig`]: exact inference on
/// 20,000 observations holds a 3.2 GB kernel matrix.
pub const MAX_EXACT_OBSERVATIONS: usize = 20_000;

impl GpisConfig {
    /// Checks the sizes: `exact_limit` and `1 ≤ inducing_points` at most
    /// [`MAX_EXACT_OBSERVATIONS`].
    ///
    /// # Errors
    /// [`GpisError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<(), GpisError> {
        if self.exact_limit > MAX_EXACT_OBSERVATIONS {
            return Err(GpisError::InvalidParameter {
                name: "exact_limit",
                value: self.exact_limit as Real,
                reason: "at most 20,000 observations are conditioned exactly (a 3.2 GB kernel matrix)",
            });
        }
        if !(1..=MAX_EXACT_OBSERVATIONS).contains(&self.inducing_points) {
            return Err(GpisError::InvalidParameter {
                name: "inducing_points",
                value: self.inducing_points as Real,
                reason: "must be between 1 and 20,000",
            });
        }
        Ok(())
    }
}

impl Default for GpisConfig {
    fn default() -> Self {
        Self {
            fit: FitConfig::default(),
            fixed: None,
            exact_limit: 5000,
            inducing_points: 1000,
        }
    }
}

/// What conditioning produced besides the model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ConditionReport {
    /// The hyper-parameters used.
    pub hyper: Hyper,
    /// The fit, when the hyper-parameters were fitted.
    pub fit: Option<FitReport>,
    /// Exact log marginal likelihood of all observations (exact inference only).
    pub log_marginal_likelihood: Option<Real>,
    /// Whether the sparse approximation was used.
    pub sparse: bool,
    /// Absolute diagonal jitter added to the kernel matrix.
    pub jitter: Real,
    /// Seconds spent fitting and conditioning.
    pub secs: Real,
}

/// Conditions a GPIS with mean `mean` on `observations`.
///
/// # Errors
/// An invalid configuration ([`GpisConfig::validate`]), no observations, non-finite
/// observations, fitting with fewer than 3 observations, invalid hyper-parameters, or a
/// singular kernel matrix.
pub fn condition<M: MeanFunction>(
    mean: M,
    observations: &Observations,
    config: &GpisConfig,
) -> Result<(Gpis<M>, ConditionReport), GpisError> {
    let t0 = Instant::now();
    config.validate()?;
    if observations.is_empty() {
        return Err(GpisError::TooFewObservations {
            method: "gpis",
            what: "observations",
            needed: 1,
            got: 0,
        });
    }
    let points = observations.points();
    let residuals: Vec<Real> = mean
        .values(points)
        .iter()
        .zip(observations.values())
        .map(|(m, y)| y - m)
        .collect();
    let (hyper, fit) = match config.fixed {
        Some(h) => {
            h.validate()?;
            (h, None)
        }
        None => {
            let report = fit_hyper(points, &residuals, &config.fit)?;
            (report.hyper, Some(report))
        }
    };
    let kind = config.fit.kind;
    let (gp, lml, sparse) = if points.len() <= config.exact_limit {
        let gp = ExactGp::condition(points, &residuals, kind, &hyper, &config.fit.jitter)?;
        let lml = gp.log_marginal_likelihood();
        (ResidualGp::Exact(gp), Some(lml), false)
    } else {
        let gp = SparseGp::condition(
            points,
            &residuals,
            kind,
            &hyper,
            config.inducing_points,
            &config.fit.jitter,
        )?;
        (ResidualGp::Sparse(gp), None, true)
    };
    let jitter = gp.jitter();
    Ok((
        Gpis { mean, gp },
        ConditionReport {
            hyper,
            fit,
            log_marginal_likelihood: lml,
            sparse,
            jitter,
            secs: t0.elapsed().as_secs_f64(),
        },
    ))
}

/// How [`reconstruct`] turns the posterior mean's zero level set into the final mesh.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub enum Mesher {
    /// Marching tetrahedra on the query grid (the default): closed, manifold, outward.
    #[default]
    MarchingTetrahedra,
    /// The paper's final step: screened Poisson reconstruction from the vertices and normals of
    /// the marching-tetrahedra mesh, meshed crack-free on the query grid ([`crate::parts::poisson_surface`]).
    Poisson(PoissonOptions),
}

/// Grid and meshing options of [`reconstruct`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReconstructOptions {
    /// Conditioning.
    pub gpis: GpisConfig,
    /// Node budget of the query grid (default 64³).
    pub max_grid_nodes: usize,
    /// Padding around the bounds, metres (default 0.02).
    pub padding_m: Real,
    /// Marching-tetrahedra options (used by both meshers).
    pub meshing: MeshingOptions,
    /// The final mesher (default marching tetrahedra).
    pub mesher: Mesher,
    /// Compute the posterior variance at every mesh vertex (default true).
    pub vertex_variance: bool,
}

impl Default for ReconstructOptions {
    fn default() -> Self {
        Self {
            gpis: GpisConfig::default(),
            max_grid_nodes: 64 * 64 * 64,
            padding_m: 0.02,
            meshing: MeshingOptions::default(),
            mesher: Mesher::default(),
            vertex_variance: true,
        }
    }
}

/// Wall-clock seconds of each stage.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    /// Hyper-parameter fit and conditioning.
    pub fit_secs: Real,
    /// Grid query of the posterior mean.
    pub query_secs: Real,
    /// Marching tetrahedra.
    pub mesh_secs: Real,
    /// Screened Poisson reconstruction and its meshing (0 with marching tetrahedra).
    pub poisson_secs: Real,
    /// Posterior variance at the mesh vertices.
    pub variance_secs: Real,
}

/// A reconstructed surface.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    /// The zero level set of the posterior mean (or its Poisson reconstruction): closed,
    /// manifold, outward oriented.
    pub mesh: TriMesh,
    /// Posterior variance (m²) per mesh vertex; empty when not requested.
    pub vertex_variance: Vec<Real>,
    /// Conditioning outcome.
    pub report: ConditionReport,
    /// The query grid.
    pub grid: Grid3,
    /// Stage timings.
    pub timings: Timings,
}

/// Conditions a GPIS and meshes its posterior mean over a grid covering `bounds`.
///
/// # Errors
/// As [`condition`], plus [`GpisError::EmptySurface`] when the zero level set misses the grid,
/// plus those of [`poisson_surface`] with [`Mesher::Poisson`].
pub fn reconstruct<M: MeanFunction>(
    mean: M,
    observations: &Observations,
    bounds: &Aabb,
    config: &ReconstructOptions,
) -> Result<(Reconstruction, Gpis<M>), GpisError> {
    let (gpis, report) = condition(mean, observations, &config.gpis)?;
    let grid = Grid3::covering(bounds, config.padding_m, config.max_grid_nodes)?;
    let t = Instant::now();
    let values = gpis.grid_values_for_meshing(&grid);
    let query_secs = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mesh = extract_surface(&grid, &values, &config.meshing)?;
    let mesh_secs = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mesh = match &config.mesher {
        Mesher::MarchingTetrahedra => mesh,
        Mesher::Poisson(options) => {
            poisson_surface(&mesh, &grid, &values, options, &config.meshing)?
        }
    };
    let poisson_secs = match config.mesher {
        Mesher::MarchingTetrahedra => 0.0,
        Mesher::Poisson(_) => t.elapsed().as_secs_f64(),
    };
    let t = Instant::now();
    let vertex_variance = if config.vertex_variance {
        gpis.variances(mesh.vertices())
    } else {
        Vec::new()
    };
    let variance_secs = t.elapsed().as_secs_f64();
    Ok((
        Reconstruction {
            mesh,
            vertex_variance,
            timings: Timings {
                fit_secs: report.secs,
                query_secs,
                mesh_secs,
                poisson_secs,
                variance_secs,
            },
            report,
            grid,
        },
        gpis,
    ))
}

/// The box around a set of points and (optionally) a mesh.
pub fn bounds_of(points: &[Point3], mesh: Option<&TriMesh>) -> Option<Aabb> {
    let mut all: Vec<Point3> = points.to_vec();
    if let Some(m) = mesh {
        let b = m.aabb();
        all.extend([b.min, b.max]);
    }
    Aabb::from_points(&all)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::KernelKind;
    use crate::mean::{ConstantMean, SphereMean};
    use moe_geom::SeededRng;
    use moe_geom::{Topology, Vector3};

    fn sphere_points(r: Real, n: usize, seed: u64) -> Vec<Point3> {
        let mut rng = SeededRng::new(seed);
        (0..n)
            .map(|_| {
                let d = Vector3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
                Point3::from(d * r)
            })
            .collect()
    }

    /// The largest distance of a vertex of `mesh` from the origin-centred sphere of radius `r`.
    fn max_radial_deviation(mesh: &TriMesh, r: Real) -> Real {
        mesh.vertices()
            .iter()
            .map(|p| (p.coords.norm() - r).abs())
            .fold(0.0, Real::max)
    }

    /// 400 contacts on a sphere of radius `r` = 80 mm, and a deliberately wrong sphere mean
    /// (offset centre, 10 mm too large), with the contacts' bounds.
    fn points_on_a_sphere_and_a_wrong_sphere_mean() -> (Real, Observations, SphereMean, Aabb) {
        let r = 0.08;
        let pts = sphere_points(r, 400, 3);
        let obs = Observations::from_contacts(&pts).unwrap();
        let mean = SphereMean {
            center: Point3::new(0.005, 0.0, -0.004),
            radius: 0.09,
        };
        (r, obs, mean, bounds_of(&pts, None).unwrap())
    }

    #[test]
    fn reconstruction_from_sphere_points_lies_within_half_a_millimetre() {
        let (r, obs, mean, b) = points_on_a_sphere_and_a_wrong_sphere_mean();
        let (rec, gpis) = reconstruct(mean, &obs, &b, &ReconstructOptions::default()).unwrap();
        rec.mesh.require_closed().unwrap();
        assert_eq!(Topology::new(&rec.mesh).euler_characteristic(), 2);
        let worst = max_radial_deviation(&rec.mesh, r);
        assert!(worst < 5e-4, "max deviation {worst} m, {:?}", rec.report);
        // Narrow-band values give exactly the dense-grid mesh.
        assert_dense_grid_gives_the_same_mesh(&gpis, &rec);
        // Variance is small on the data-covered surface.
        let max_sd = rec
            .vertex_variance
            .iter()
            .fold(0.0 as Real, |m, v| m.max(v.sqrt()));
        assert!(max_sd < 2e-3, "{max_sd}");
    }

    /// Narrow-band values give exactly the mesh of dense-grid values: same faces, vertices within
    /// 1e-9 m.
    fn assert_dense_grid_gives_the_same_mesh<M: MeanFunction>(
        gpis: &Gpis<M>,
        rec: &Reconstruction,
    ) {
        let dense = gpis.grid_values(&rec.grid);
        let dense_mesh = extract_surface(&rec.grid, &dense, &MeshingOptions::default()).unwrap();
        assert_eq!(dense_mesh.faces(), rec.mesh.faces());
        let max_diff = dense_mesh
            .vertices()
            .iter()
            .zip(rec.mesh.vertices())
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, Real::max);
        assert!(max_diff < 1e-9, "{max_diff}");
    }

    #[test]
    fn narrow_band_with_a_mesh_prior_gives_the_dense_mesh() {
        let prior_mesh =
            moe_geom::shapes::star_shaped(3, Point3::origin(), |d| 0.07 + 0.01 * d.x * d.y)
                .unwrap();
        let prior = crate::mean::MeshSdfMean::new(&prior_mesh).unwrap();
        let pts: Vec<Point3> = sphere_points(0.075, 300, 7)
            .into_iter()
            .filter(|p| p.z > 0.0)
            .collect();
        let mut obs = Observations::from_contacts(&pts).unwrap();
        obs.add_mean_normal_offsets(&prior, 0.01).unwrap();
        let b = bounds_of(&pts, Some(&prior_mesh)).unwrap();
        let cfg = ReconstructOptions {
            max_grid_nodes: 40 * 40 * 40,
            vertex_variance: false,
            ..ReconstructOptions::default()
        };
        let (rec, gpis) = reconstruct(&prior, &obs, &b, &cfg).unwrap();
        assert_dense_grid_gives_the_same_mesh(&gpis, &rec);
    }

    #[test]
    fn poisson_mesher_gives_a_closed_sphere_with_variance_on_its_vertices() {
        let (r, obs, mean, b) = points_on_a_sphere_and_a_wrong_sphere_mean();
        let cfg = ReconstructOptions {
            max_grid_nodes: 40 * 40 * 40,
            mesher: Mesher::Poisson(PoissonOptions::default()),
            ..ReconstructOptions::default()
        };
        let (rec, _) = reconstruct(mean, &obs, &b, &cfg).unwrap();
        rec.mesh.require_closed().unwrap();
        assert_eq!(Topology::new(&rec.mesh).euler_characteristic(), 2);
        assert_eq!(rec.vertex_variance.len(), rec.mesh.num_vertices());
        assert!(rec.timings.poisson_secs > 0.0);
        let worst = max_radial_deviation(&rec.mesh, r);
        assert!(worst < 1e-3, "max deviation {worst} m");
    }

    #[test]
    fn beyond_the_exact_limit_the_sparse_approximation_is_used_and_agrees() {
        let r = 0.08;
        let pts = sphere_points(r, 600, 5);
        let obs = Observations::from_contacts(&pts).unwrap();
        let mean = SphereMean {
            center: Point3::new(0.004, 0.0, 0.0),
            radius: 0.085,
        };
        let hyper = Hyper {
            signal_variance: 1e-4,
            lengthscale: 0.05,
            noise_variance: 1e-8,
        };
        let exact_cfg = GpisConfig {
            fixed: Some(hyper),
            ..GpisConfig::default()
        };
        let sparse_cfg = GpisConfig {
            exact_limit: 500,
            inducing_points: 250,
            ..exact_cfg
        };
        let (exact, re) = condition(mean, &obs, &exact_cfg).unwrap();
        let (sparse, rs) = condition(mean, &obs, &sparse_cfg).unwrap();
        assert!(!re.sparse && rs.sparse);
        assert!(rs.log_marginal_likelihood.is_none());
        let probes = sphere_points(r, 200, 6);
        let worst = probes
            .iter()
            .map(|p| (exact.mean_at(p) - sparse.mean_at(p)).abs())
            .fold(0.0, Real::max);
        // 250 inducing points for 600 observations: the SDF differs by well under a millimetre.
        assert!(worst < 3e-4, "max |exact - sparse| = {worst} m");
        // The sizes are bounded before anything is allocated.
        for (bad, name) in [
            (
                GpisConfig {
                    exact_limit: MAX_EXACT_OBSERVATIONS + 1,
                    ..exact_cfg
                },
                "exact_limit",
            ),
            (
                GpisConfig {
                    inducing_points: 0,
                    ..exact_cfg
                },
                "inducing_points",
            ),
            (
                GpisConfig {
                    inducing_points: MAX_EXACT_OBSERVATIONS + 1,
                    ..exact_cfg
                },
                "inducing_points",
            ),
        ] {
            match condition(mean, &obs, &bad) {
                Err(GpisError::InvalidParameter { name: got, .. }) => assert_eq!(got, name),
                other => panic!("{name}: {:?}", other.map(|_| ())),
            }
        }
    }

    #[test]
    fn constant_mean_needs_an_inside_and_fixed_hyper_parameters_are_used() {
        let pts = sphere_points(0.05, 200, 4);
        let mut obs = Observations::from_contacts(&pts).unwrap();
        obs.add_centroid_interior().unwrap();
        let config = ReconstructOptions {
            gpis: GpisConfig {
                fixed: Some(Hyper {
                    signal_variance: 1e-3,
                    lengthscale: 0.05,
                    noise_variance: 1e-8,
                }),
                fit: FitConfig {
                    kind: KernelKind::Matern32,
                    ..FitConfig::default()
                },
                ..GpisConfig::default()
            },
            ..ReconstructOptions::default()
        };
        let b = bounds_of(&pts, None).unwrap();
        let (rec, _) = reconstruct(ConstantMean { value: 0.02 }, &obs, &b, &config).unwrap();
        assert_eq!(rec.report.hyper.lengthscale, 0.05);
        assert!(rec.report.fit.is_none());
        let mean_dev = rec
            .mesh
            .vertices()
            .iter()
            .map(|p| (p.coords.norm() - 0.05).abs())
            .sum::<Real>()
            / rec.mesh.num_vertices() as Real;
        assert!(mean_dev < 2e-3, "{mean_dev}");
    }
}
