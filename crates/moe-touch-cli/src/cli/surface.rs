//! `moe-touch surface`: reconstruct an occluded surface from contact points with a
//! Gaussian-process implicit surface (paper §6.1), or the non-probabilistic baseline.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use moe_gpis::{
    FitConfig, GpisConfig, Hyper, HyperBounds, IcpConfig, KernelKind, Mesher, PoissonOptions,
    PosePrior, ReconstructOptions, RegistrationKind, SurfaceMethod, SurfaceOptions,
};
use moe_lab::surface_job::SurfaceFiles;

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

/// The library's method for the command line's choice.
fn method_of(args: &SurfaceArgs) -> SurfaceMethod {
    match args.method {
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
    }
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
        method: method_of(args),
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
    let options = options_of(&args)?;
    if args.prior.is_none() && options.method.needs_prior() {
        bail!("--method {:?} needs --prior PRIOR.obj", args.method);
    }
    let files = SurfaceFiles {
        contacts: args.contacts,
        prior: args.prior,
        out: args.out,
        variance_out: args.variance_out,
        query: args.query.zip(args.query_out),
    };
    let report = moe_lab::surface_job::reconstruct_files(&files, &options)?;
    for note in &report.notes {
        eprintln!("surface: {note}");
    }
    if args.json {
        // Through a JSON value, whose keys are sorted, as this report has always printed them.
        return super::print_json(&serde_json::to_value(&report)?);
    }
    super::outln!("{}", report.line());
    Ok(())
}
