//! `moe-touch surface`: reconstruct an occluded surface from contact points with a
//! Gaussian-process implicit surface (paper §6.1), or the non-probabilistic baseline.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use moe_geom::{Point3, TriMesh};
use moe_gpis::{
    FitConfig, GpisConfig, Hyper, HyperBounds, IcpConfig, IcpReport, KernelKind, Mesher,
    Observations, PoissonOptions, PosePrior, ReconstructOptions, RegistrationKind, SphereMean,
    SurfaceMethod, SurfaceOptions, condition_surface, reconstruct_surface,
};
use serde_json::json;

/// Reconstruction method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Method {
    /// GP whose mean is the prior mesh's signed distance (the task prior).
    Prior,
    /// GP whose mean is a sphere fitted to the contacts.
    Sphere,
    /// GP with a constant mean (`--mean-value`); needs an inside (adds the contacts' centroid).
    Constant,
    /// Non-probabilistic baseline: prior vertices pulled to the contacts, Laplacian smoothing.
    Nonprob,
}

/// Kernel family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Kernel {
    /// Squared exponential (RBF).
    Rbf,
    /// Matérn 3/2.
    Matern32,
}

/// Registration transform family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Registration {
    /// Rotation and translation.
    Rigid,
    /// Rotation, translation and uniform scale.
    Similarity,
}

/// Final mesher of the GP methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum MesherArg {
    /// Marching tetrahedra on the query grid.
    Marching,
    /// Screened Poisson reconstruction from the marching-tetrahedra mesh (paper §6.1).
    Poisson,
}

/// Arguments of `moe-touch surface`.
#[derive(Debug, Args)]
pub(crate) struct SurfaceArgs {
    /// Contact points in metres: CSV rows `x,y,z` (SDF 0) or `x,y,z,sdf`, or a PLY point cloud
    /// (an optional vertex scalar `sdf` gives the values).
    #[arg(long, value_name = "FILE")]
    contacts: PathBuf,
    /// Prior mesh (closed; OBJ/PLY/STL). Required by `--method prior` and `nonprob`.
    #[arg(long, value_name = "FILE")]
    prior: Option<PathBuf>,
    /// Reconstruction method.
    #[arg(long, value_enum, default_value = "prior")]
    method: Method,
    /// Register the prior to the contacts by ICP before conditioning (rigid unless a value is
    /// given).
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "rigid", value_name = "KIND")]
    register: Option<Registration>,
    /// Registration's pose prior: standard deviation of the rotation, degrees (default 5.7).
    #[arg(
        long,
        value_name = "DEG",
        requires = "register",
        conflicts_with = "no_pose_prior"
    )]
    pose_sd_deg: Option<f64>,
    /// Registration's pose prior: standard deviation of the contacts' centroid displacement, mm
    /// (default 20).
    #[arg(
        long,
        value_name = "MM",
        requires = "register",
        conflicts_with = "no_pose_prior"
    )]
    pose_sd_mm: Option<f64>,
    /// Plain ICP without a pose prior (only when the contacts pin the pose: a patted cap does
    /// not).
    #[arg(long, requires = "register")]
    no_pose_prior: bool,
    /// Output surface mesh (OBJ or PLY). May be omitted when only querying.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Output PLY with the surface and per-vertex posterior `variance` (m²) and `std` (m).
    #[arg(long, value_name = "FILE")]
    variance_out: Option<PathBuf>,
    /// Fixed length scale (m); with --signal-variance and --noise-variance, skips fitting.
    #[arg(long, requires_all = ["signal_variance", "noise_variance"])]
    lengthscale: Option<f64>,
    /// Fixed signal variance (m²).
    #[arg(long, requires_all = ["lengthscale", "noise_variance"])]
    signal_variance: Option<f64>,
    /// Fixed noise variance (m²).
    #[arg(long, requires_all = ["lengthscale", "signal_variance"])]
    noise_variance: Option<f64>,
    /// Fitting the hyper-parameters, keep the noise standard deviation at least this (m): for
    /// contacts known to be that far off the surface (a contact estimator's error), so that the
    /// fit does not bend the surface through each of them.
    #[arg(long, value_name = "M", conflicts_with = "lengthscale")]
    noise_floor: Option<f64>,
    /// Value of the constant mean (m, positive = outside) for `--method constant`.
    #[arg(long, default_value_t = 0.02)]
    mean_value: f64,
    /// Kernel family.
    #[arg(long, value_enum, default_value = "rbf")]
    kernel: Kernel,
    /// Offset (m) of the ±d points added along the mean's normals at every contact to pin the
    /// SDF's slope (keep it well below the body's half-thickness); 0 disables them.
    #[arg(long, default_value_t = 0.005)]
    normal_offset: f64,
    /// With a prior (methods prior and nonprob): leave out contacts farther than this (m) from
    /// the (registered) prior's surface, as false contacts of a contact estimator.
    #[arg(long, value_name = "M")]
    prior_gate: Option<f64>,
    /// Grid nodes along each axis of an equivalent cube (the grid has at most N³ nodes).
    #[arg(long, default_value_t = 64)]
    grid: usize,
    /// Final mesher of the GP methods: marching tetrahedra, or screened Poisson reconstruction
    /// from its points and normals (slower: seconds on a head at depth 4).
    #[arg(long, value_enum, default_value = "marching")]
    mesher: MesherArg,
    /// Octree depth of `--mesher poisson` (finest cell = extent / 2^N; cost grows ~8x per
    /// level). Defaults to 4.
    #[arg(long, value_name = "N")]
    poisson_depth: Option<usize>,
    /// Points (CSV `x,y,z`, metres) at which to query the posterior.
    #[arg(long, value_name = "FILE", requires = "query_out")]
    query: Option<PathBuf>,
    /// Output CSV with `mean,std` (m) per query row, in the input order.
    #[arg(long, value_name = "FILE", requires = "query")]
    query_out: Option<PathBuf>,
    /// Print fitted hyper-parameters, log marginal likelihood and timings as one JSON object.
    #[arg(long)]
    json: bool,
}

fn ext(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or_default()
        .to_ascii_lowercase()
}

/// Reads observations from CSV (`x,y,z[,sdf]`) or PLY (points, optional scalar `sdf`).
fn read_observations(path: &Path) -> Result<Observations> {
    let (points, values): (Vec<Point3>, Vec<f64>) = match ext(path).as_str() {
        "ply" => {
            let ply = moe_io::read_ply(path)?;
            let values = match ply.scalar("sdf") {
                Some(s) => s.iter().map(|&v| f64::from(v)).collect(),
                None => vec![0.0; ply.points.len()],
            };
            (ply.points, values)
        }
        _ => moe_io::read_points_csv(path)?
            .into_iter()
            .map(|r| {
                (
                    Point3::new(r[0], r[1], r[2]),
                    r.get(3).copied().unwrap_or(0.0),
                )
            })
            .unzip(),
    };
    let mut obs = Observations::new();
    obs.add_valued(&points, &values)
        .with_context(|| format!("reading observations from {}", path.display()))?;
    Ok(obs)
}

fn read_prior(args: &SurfaceArgs) -> Result<Option<TriMesh>> {
    let method = method_of(args)?;
    match &args.prior {
        Some(path) => {
            Ok(Some(moe_io::read_mesh(path).with_context(|| {
                format!("reading prior {}", path.display())
            })?))
        }
        None if method.needs_prior() => {
            bail!("--method {:?} needs --prior PRIOR.obj", args.method)
        }
        None => Ok(None),
    }
}

/// The library's method for the command line's choice.
fn method_of(args: &SurfaceArgs) -> Result<SurfaceMethod> {
    Ok(match args.method {
        Method::Prior => SurfaceMethod::Prior {
            registration: args.register.map(|kind| {
                let pose_prior = (!args.no_pose_prior).then(|| {
                    let d = PosePrior::default();
                    PosePrior {
                        rotation_sd_rad: args
                            .pose_sd_deg
                            .map_or(d.rotation_sd_rad, f64::to_radians),
                        translation_sd_m: args
                            .pose_sd_mm
                            .map_or(d.translation_sd_m, |mm| 1e-3 * mm),
                        ..d
                    }
                });
                IcpConfig {
                    kind: match kind {
                        Registration::Rigid => RegistrationKind::Rigid,
                        Registration::Similarity => RegistrationKind::Similarity,
                    },
                    pose_prior,
                    ..IcpConfig::default()
                }
            }),
        },
        Method::Sphere => SurfaceMethod::Sphere,
        Method::Constant => SurfaceMethod::Constant {
            value: args.mean_value,
        },
        Method::Nonprob => SurfaceMethod::NonProbabilistic,
    })
}

fn options_of(args: &SurfaceArgs) -> Result<SurfaceOptions> {
    if args.prior_gate.is_some() && matches!(args.method, Method::Sphere | Method::Constant) {
        bail!("--prior-gate needs a method with a prior (prior or nonprob)");
    }
    if args.noise_floor.is_some() && args.method == Method::Nonprob {
        bail!("--noise-floor bounds the GP's fit: the GP methods only (prior, sphere, constant)");
    }
    let fixed = match (args.lengthscale, args.signal_variance, args.noise_variance) {
        (Some(lengthscale), Some(signal_variance), Some(noise_variance)) => Some(Hyper {
            signal_variance,
            lengthscale,
            noise_variance,
        }),
        _ => None,
    };
    let gpis = GpisConfig {
        fit: FitConfig {
            kind: match args.kernel {
                Kernel::Rbf => KernelKind::Rbf,
                Kernel::Matern32 => KernelKind::Matern32,
            },
            bounds: HyperBounds::default()
                .with_noise_floor(args.noise_floor.unwrap_or(0.0))
                .context("--noise-floor")?,
            ..FitConfig::default()
        },
        fixed,
        ..GpisConfig::default()
    };
    let mesher = match args.mesher {
        MesherArg::Marching => Mesher::MarchingTetrahedra,
        MesherArg::Poisson => {
            let depth = args
                .poisson_depth
                .unwrap_or(PoissonOptions::default().depth);
            let options = PoissonOptions {
                depth,
                density_depth: PoissonOptions::default().density_depth.min(depth),
                ..PoissonOptions::default()
            };
            options.validate().context("--poisson-depth")?;
            Mesher::Poisson(options)
        }
    };
    Ok(SurfaceOptions {
        method: method_of(args)?,
        surface: ReconstructOptions {
            gpis,
            max_grid_nodes: args.grid.saturating_pow(3),
            vertex_variance: args.variance_out.is_some(),
            mesher,
            ..ReconstructOptions::default()
        },
        normal_offset_m: args.normal_offset,
        prior_gate_m: args.prior_gate,
        ..SurfaceOptions::default()
    })
}

pub(crate) fn run(args: SurfaceArgs) -> Result<()> {
    if args.out.is_none() && args.query.is_none() {
        bail!(
            "nothing to do: give --out SURFACE.obj and/or --query POINTS.csv --query-out VALUES.csv"
        );
    }
    if args.variance_out.is_some() && args.out.is_none() {
        bail!("--variance-out needs --out (the variance is attached to the output surface)");
    }
    if args.poisson_depth.is_some() && args.mesher != MesherArg::Poisson {
        bail!("--poisson-depth needs --mesher poisson");
    }
    if args.grid < 2 || args.grid > 256 {
        bail!(
            "--grid must be between 2 and 256 nodes per axis, got {}",
            args.grid
        );
    }
    if args.method == Method::Nonprob {
        if args.query.is_some() || args.variance_out.is_some() {
            bail!("--method nonprob has no posterior: --query and --variance-out need a GP method");
        }
        if args.mesher != MesherArg::Marching {
            bail!("--mesher applies to the GP methods, not to --method nonprob");
        }
        if args.out.is_none() {
            bail!("--method nonprob needs --out SURFACE.obj");
        }
    }
    let t0 = Instant::now();
    let obs = read_observations(&args.contacts)?;
    let prior = read_prior(&args)?;
    let options = options_of(&args)?;
    let mut report = serde_json::Map::new();
    report.insert(
        "method".into(),
        json!(format!("{:?}", args.method).to_lowercase()),
    );
    report.insert("contacts".into(), json!(obs.contacts().len()));
    if args.method == Method::Constant && obs.num_interior() == 0 {
        eprintln!("surface: no inside observation; the contacts' centroid is added as one");
    }

    let gpis = if let Some(out) = &args.out {
        let (rec, gpis) = reconstruct_surface(&obs, prior.as_ref(), &options)?;
        moe_io::write_mesh(out, &rec.mesh)?;
        if let Some(vpath) = &args.variance_out {
            let ply = moe_io::PlyData::with_variance(&rec.mesh, &rec.vertex_variance);
            moe_io::write_ply(vpath, &ply)?;
        }
        insert_fitted(&mut report, rec.registration.as_ref(), rec.sphere.as_ref())?;
        report.insert("gated_contacts".into(), json!(rec.gated_contacts));
        if let Some(cond) = &rec.condition {
            report.insert("observations".into(), json!(rec.observations));
            insert_condition(&mut report, cond)?;
            report.insert("mesher".into(), json!(mesher_name(&args)));
        }
        report.insert("vertices".into(), json!(rec.mesh.num_vertices()));
        report.insert("faces".into(), json!(rec.mesh.num_faces()));
        if let Some(dims) = rec.grid_dims {
            report.insert("grid_dims".into(), json!(dims));
        }
        match rec.timings {
            Some(t) => report.insert("timings".into(), serde_json::to_value(t)?),
            None => report.insert("timings".into(), json!({ "total_secs": rec.secs })),
        };
        gpis
    } else {
        let (gpis, cond, fitted) = condition_surface(&obs, prior.as_ref(), &options)?;
        insert_fitted(
            &mut report,
            fitted.registration.as_ref(),
            fitted.sphere.as_ref(),
        )?;
        report.insert("observations".into(), json!(fitted.observations));
        report.insert("gated_contacts".into(), json!(fitted.gated_contacts));
        report.insert("mesher".into(), json!(mesher_name(&args)));
        insert_condition(&mut report, &cond)?;
        report.insert("timings".into(), json!({ "fit_secs": cond.secs }));
        Some(gpis)
    };

    if let (Some(gpis), Some(q), Some(qout)) = (&gpis, &args.query, &args.query_out) {
        let rows = moe_io::read_points_csv(q)?;
        let pts: Vec<Point3> = rows.iter().map(|r| Point3::new(r[0], r[1], r[2])).collect();
        let t = Instant::now();
        let values = gpis
            .query(&pts)
            .with_context(|| format!("querying {}", q.display()))?;
        let rows: Vec<Vec<f64>> = values.iter().map(|(m, s)| vec![*m, *s]).collect();
        moe_io::write_csv(qout, &["mean", "std"], &rows)?;
        report.insert("queries".into(), json!(pts.len()));
        report.insert("query_secs".into(), json!(t.elapsed().as_secs_f64()));
    }
    report.insert("total_secs".into(), json!(t0.elapsed().as_secs_f64()));
    finish(&args, report)
}

fn mesher_name(args: &SurfaceArgs) -> String {
    format!("{:?}", args.mesher).to_lowercase()
}

/// The registration and the fitted sphere, when the method produced them.
fn insert_fitted(
    report: &mut serde_json::Map<String, serde_json::Value>,
    registration: Option<&IcpReport>,
    sphere: Option<&SphereMean>,
) -> Result<()> {
    if let Some(icp) = registration {
        eprintln!(
            "surface: registered the prior ({} iterations, RMS {:.2} mm -> {:.2} mm)",
            icp.iterations,
            1e3 * icp.rms_before_m,
            1e3 * icp.rms_after_m
        );
        report.insert("registration".into(), serde_json::to_value(icp)?);
    }
    if let Some(s) = sphere {
        report.insert(
            "sphere".into(),
            json!({ "center_m": [s.center.x, s.center.y, s.center.z], "radius_m": s.radius }),
        );
    }
    Ok(())
}

fn insert_condition(
    report: &mut serde_json::Map<String, serde_json::Value>,
    cond: &moe_gpis::ConditionReport,
) -> Result<()> {
    let h = cond.hyper;
    report.insert(
        "hyper".into(),
        json!({
            "lengthscale_m": h.lengthscale,
            "signal_variance_m2": h.signal_variance,
            "noise_variance_m2": h.noise_variance,
            "fitted": cond.fit.is_some(),
        }),
    );
    report.insert(
        "log_marginal_likelihood".into(),
        json!(cond.log_marginal_likelihood),
    );
    report.insert("sparse".into(), json!(cond.sparse));
    report.insert("jitter".into(), json!(cond.jitter));
    if let Some(fit) = &cond.fit {
        report.insert("fit".into(), serde_json::to_value(fit)?);
    }
    Ok(())
}

fn finish(args: &SurfaceArgs, report: serde_json::Map<String, serde_json::Value>) -> Result<()> {
    if args.json {
        return super::print_json(&serde_json::Value::Object(report));
    }
    let get = |k: &str| {
        report
            .get(k)
            .map(|v| v.to_string())
            .unwrap_or_else(|| "-".into())
    };
    super::outln!(
        "surface: method {}, {} contacts, {} vertices, hyper {}, log marginal likelihood {}",
        get("method").trim_matches('"'),
        get("contacts"),
        get("vertices"),
        get("hyper"),
        get("log_marginal_likelihood")
    );
    Ok(())
}
