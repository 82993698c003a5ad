//! `moe-touch contact`: run the contact network on a point cloud, or on a hand shape as
//! `moe-touch shape` writes it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use moe_contact::{Aggregation, DeviceKind, InputFeature};
use moe_geom::{HandModel, Iso3, WorldFromHand};
use moe_lab::contact_job::{self, ContactSources, PhysicsFrame};
use moe_lab::keypoints_file::KeypointsFile;
use moe_lab::point_cloud::{NetworkPrecision, PointCloudModel, PointCloudOptions};
use moe_physics::PhysicsEstimator;

use super::ContactMethod;

/// The float type the network computes in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Precision {
    /// 32-bit (the default, as trained).
    F32,
    /// 64-bit (for validation against a reference).
    F64,
}

/// Arguments of `moe-touch contact`.
#[derive(Debug, Args)]
pub(crate) struct ContactArgs {
    /// The estimator: `dgcnn` (the graph network, on a point cloud or on a hand shape; needs
    /// `--model`) or `physics` (the finger's FEM model read backwards from one frame of markers,
    /// the tendon pulls and the hand's pose: `--hand`, `--keypoints`, `--tendon-pulls`; it
    /// estimates the dented shape, the loads and their force itself, no model).
    #[arg(long, value_enum, default_value = "dgcnn")]
    method: ContactMethod,
    /// dgcnn: a point cloud (CSV rows `x,y,z`, header optional): writes one row per point, in
    /// input order, `logit0,logit1,probability`, to `--out`.
    #[arg(long, value_name = "P.csv")]
    points: Option<PathBuf>,
    /// The hand of `--shape` or `--keypoints`: a preset (two-finger, three-finger, five-finger)
    /// or a hand config.
    #[arg(long, value_name = "PRESET|CONFIG")]
    hand: Option<String>,
    /// dgcnn: a hand shape as `moe-touch shape` writes it: a directory with `finger_<i>.obj`
    /// (deformed, hand frame, metres). Writes to the `--out` directory, per finger,
    /// `finger_<i>.ply` with the contact probability as a vertex property and a colour ramp
    /// (blue 0 to red 1), the contact points as `contacts.csv` and a summary `contact.json`.
    #[arg(long, value_name = "DIR")]
    shape: Option<PathBuf>,
    /// physics: the observed markers in the hand frame (metres), as `moe-touch shape` reads
    /// them: {"fingers": [[[x, y, z] or null, ...], ...]}, null for an unseen marker. Writes to
    /// the `--out` directory, per finger, `finger_<i>.ply` (the estimated dented surface with
    /// `contact_probability` and `force_n`, the force on each vertex in newtons, coloured by
    /// probability), `contacts.csv`, `loads.json` (every load found: finger, vertex, place at
    /// rest and on the dented surface, force vector, magnitude and their standard deviations;
    /// hand frame, metres and newtons) and a summary `contact.json` with the force on every
    /// finger.
    #[arg(long, value_name = "KP.json")]
    keypoints: Option<PathBuf>,
    /// The tendon pulls, metres: the pulls of each finger comma-separated in its tendon routes'
    /// order, fingers separated by `;` (e.g. `0.002,-0.002,0,0;0,0,0.001,-0.001`). Needed by
    /// physics, and by a dgcnn model with the `tendon-pull` feature.
    #[arg(long, value_name = "LIST", allow_hyphen_values = true)]
    tendon_pulls: Option<String>,
    /// physics: where the hand is, for the direction of gravity: `x,y,z,qx,qy,qz,qw`
    /// (`world_from_hand`, metres and a unit quaternion). Default: the identity, the hand frame
    /// is the world's and the fingers point up (gravity along the hand's −z).
    #[arg(long, value_name = "POSE", allow_hyphen_values = true)]
    world_from_hand: Option<String>,
    /// physics: the hand's material (TOML or JSON, as `moe-touch calibrate` writes it; default:
    /// the nominal silicone, E = 100 kPa).
    #[arg(long, value_name = "M.toml")]
    material: Option<PathBuf>,
    /// physics: the estimator's settings (TOML or JSON `moe_physics::PhysicsConfig`; default:
    /// the documented ones).
    #[arg(long, value_name = "C.toml")]
    physics_config: Option<PathBuf>,
    /// dgcnn: the model, `NAME.safetensors`, with its card `NAME.json` beside it if there is one.
    #[arg(long, value_name = "M.safetensors")]
    model: Option<PathBuf>,
    /// dgcnn with --points: edge aggregation, max or sum, overriding the card's (the weights do
    /// not depend on it). A hand shape runs the model as the runtime does.
    #[arg(long)]
    aggregation: Option<Aggregation>,
    /// dgcnn with --points: float type of the computation [default: f32].
    #[arg(long, value_enum)]
    dtype: Option<Precision>,
    /// dgcnn with --points: device, cpu or cuda in a build with the `cuda` feature [default:
    /// cpu].
    #[arg(long)]
    device: Option<DeviceKind>,
    /// Contact threshold on the probability (default: the model card's, else 0.5; physics:
    /// 0.5).
    #[arg(long)]
    threshold: Option<f64>,
    /// Output: a CSV file for `--points`, a directory otherwise.
    #[arg(long, value_name = "OUT")]
    out: PathBuf,
    /// Print the report as one JSON object.
    #[arg(long)]
    json: bool,
}

/// Refuses the first flag given of `flags`, saying `why`.
fn refuse(flags: &[(bool, &str)], why: &str) -> Result<()> {
    match flags.iter().find(|(given, _)| *given) {
        Some((_, flag)) => bail!("{flag} {why}"),
        None => Ok(()),
    }
}

fn check_threshold(t: f64) -> Result<f64> {
    if !(t > 0.0 && t <= 1.0) {
        bail!("--threshold {t} is not in (0, 1]");
    }
    Ok(t)
}

pub(crate) fn run(args: ContactArgs) -> Result<()> {
    match args.method {
        ContactMethod::Dgcnn => run_dgcnn(&args),
        ContactMethod::Physics => run_physics(&args),
    }
}

fn run_dgcnn(args: &ContactArgs) -> Result<()> {
    let started = Instant::now();
    refuse(
        &[
            (args.keypoints.is_some(), "--keypoints"),
            (args.world_from_hand.is_some(), "--world-from-hand"),
            (args.material.is_some(), "--material"),
            (args.physics_config.is_some(), "--physics-config"),
        ],
        "is for --method physics; the DGCNN reads a point cloud (--points) or a hand shape \
         (--hand with --shape)",
    )?;
    let Some(model_path) = &args.model else {
        bail!("--method dgcnn needs --model M.safetensors (or use --method physics)");
    };
    match (&args.points, &args.hand, &args.shape) {
        (Some(points), None, None) => {
            if args.tendon_pulls.is_some() {
                bail!("--tendon-pulls needs --hand with --shape (a point cloud has no fingers)");
            }
            run_points(args, model_path, points, started)
        }
        (None, Some(hand), Some(shape)) => {
            refuse(
                &[
                    (args.aggregation.is_some(), "--aggregation"),
                    (args.dtype.is_some(), "--dtype"),
                    (args.device.is_some(), "--device"),
                ],
                "is for --points; a hand shape runs the model as the runtime does (f32 on the \
                 CPU, the card's aggregation)",
            )?;
            run_shape(args, model_path, hand, shape, started)
        }
        _ => bail!("give either --points, or --hand with --shape"),
    }
}

fn run_points(
    args: &ContactArgs,
    model_path: &Path,
    points: &Path,
    started: Instant,
) -> Result<()> {
    let precision = match args.dtype.unwrap_or(Precision::F32) {
        Precision::F32 => NetworkPrecision::F32,
        Precision::F64 => NetworkPrecision::F64,
    };
    let options = PointCloudOptions {
        precision,
        device: args.device.unwrap_or(DeviceKind::Cpu),
        aggregation: args.aggregation,
    };
    let model = PointCloudModel::load(model_path, &options)
        .with_context(|| format!("model {}", model_path.display()))?;
    let threshold = check_threshold(args.threshold.unwrap_or(model.card().threshold))?;
    let spec = &model.card().architecture.input;
    if spec.features != [InputFeature::Xyz] {
        bail!(
            "model {}: its input features ({}) cannot be made from a point cloud; use --hand \
             with --shape",
            model_path.display(),
            spec.describe()
        );
    }
    let cloud = contact_job::read_point_cloud(points)?;
    let contact = model
        .estimate(&cloud)
        .with_context(|| format!("points {}", points.display()))?;
    let report = contact_job::write_points_contact(
        &model, model_path, precision, &contact, threshold, &args.out, started,
    )?;
    if args.json {
        return super::print_json(&report);
    }
    super::outln!("{}", report.line());
    Ok(())
}

/// Comma-separated finite numbers; `name(i)` names the `i`-th in errors.
fn numbers(text: &str, name: impl Fn(usize) -> String) -> Result<Vec<f64>> {
    text.split(',')
        .map(str::trim)
        .enumerate()
        .map(|(i, v)| {
            let x: f64 = v
                .parse()
                .with_context(|| format!("{}: '{v}' is not a number", name(i)))?;
            if !x.is_finite() {
                bail!("{}: '{v}' is not finite", name(i));
            }
            Ok(x)
        })
        .collect()
}

/// `--tendon-pulls`: fingers separated by `;`, each finger's pulls by `,`.
fn parse_tendon_pulls(text: &str) -> Result<Vec<Vec<f64>>> {
    text.split(';')
        .enumerate()
        .map(|(f, finger)| {
            numbers(finger, |t| {
                format!("--tendon-pulls: finger {f}, tendon {t}")
            })
        })
        .collect()
}

fn run_shape(
    args: &ContactArgs,
    model_path: &Path,
    hand_spec: &str,
    dir: &Path,
    started: Instant,
) -> Result<()> {
    let hand = super::load_hand(hand_spec)?;
    let estimator = moe_touch::pipeline::load_contact_model(model_path, &hand)
        .with_context(|| format!("model {} on hand '{hand_spec}'", model_path.display()))?;
    let threshold = check_threshold(args.threshold.unwrap_or(estimator.threshold()))?;
    let shape = contact_job::read_hand_shape(&hand, dir)?;
    let pulls = args
        .tendon_pulls
        .as_deref()
        .map(parse_tendon_pulls)
        .transpose()?;
    if pulls.is_some() && !estimator.features().needs_tendon_pulls() {
        bail!(
            "--tendon-pulls: model {} does not take them (its features: {})",
            model_path.display(),
            estimator.features().spec().describe()
        );
    }
    let sources = ContactSources {
        hand: hand_spec.to_owned(),
        input: dir.display().to_string(),
        model: model_path.display().to_string(),
    };
    let output = contact_job::shape_contact(
        &estimator,
        &hand,
        &shape,
        pulls.as_deref(),
        threshold,
        sources,
        started,
    )
    .with_context(|| format!("shape {}", dir.display()))?;
    output.files.write(&args.out)?;
    if args.json {
        return super::print_json(&output.record);
    }
    super::outln!("{}", output.record.summary());
    Ok(())
}

/// `--tendon-pulls` checked against the hand's tendon routes.
fn hand_tendon_pulls(text: &str, hand: &HandModel) -> Result<Vec<Vec<f64>>> {
    let pulls = parse_tendon_pulls(text)?;
    if pulls.len() != hand.num_fingers() {
        bail!(
            "--tendon-pulls: {} fingers of tendon pulls, the hand has {} (fingers are separated \
             by ';')",
            pulls.len(),
            hand.num_fingers()
        );
    }
    for (f, (p, hf)) in pulls.iter().zip(hand.fingers()).enumerate() {
        let expected = hf.model.tendon_routes().len();
        if p.len() != expected {
            bail!(
                "--tendon-pulls: finger {f} has {} tendon pulls, its tendon routes are {expected}",
                p.len()
            );
        }
    }
    Ok(pulls)
}

/// `--world-from-hand x,y,z,qx,qy,qz,qw`: a translation in metres and a unit quaternion.
fn parse_world_from_hand(text: &str) -> Result<WorldFromHand> {
    let values = numbers(text, |i| format!("--world-from-hand: value {i}"))?;
    let [x, y, z, qx, qy, qz, qw] = values[..] else {
        bail!(
            "--world-from-hand: {} values, expected 7 (x,y,z,qx,qy,qz,qw)",
            values.len()
        );
    };
    let q = moe_geom::nalgebra::Quaternion::new(qw, qx, qy, qz);
    if (q.norm() - 1.0).abs() > 1e-3 {
        bail!(
            "--world-from-hand: the quaternion (qx,qy,qz,qw) has norm {:.6}, not 1",
            q.norm()
        );
    }
    Ok(WorldFromHand::new(Iso3::from_parts(
        moe_geom::nalgebra::Translation3::new(x, y, z),
        moe_geom::math::UnitQuat::new_normalize(q),
    )))
}

fn run_physics(args: &ContactArgs) -> Result<()> {
    let started = Instant::now();
    refuse(
        &[
            (args.points.is_some(), "--points"),
            (args.shape.is_some(), "--shape"),
            (args.model.is_some(), "--model"),
            (args.aggregation.is_some(), "--aggregation"),
            (args.dtype.is_some(), "--dtype"),
            (args.device.is_some(), "--device"),
        ],
        "is for --method dgcnn; the physics estimator reads markers (--keypoints), estimates \
         the shape itself and has no network",
    )?;
    let (Some(hand_spec), Some(kp_path), Some(pulls_text)) =
        (&args.hand, &args.keypoints, &args.tendon_pulls)
    else {
        bail!(
            "--method physics needs --hand, --keypoints and --tendon-pulls (the commanded pulls, \
             metres; 0,0,0,0;0,0,0,0 for a two-finger hand at rest)"
        );
    };
    let threshold = check_threshold(args.threshold.unwrap_or(moe_physics::CONTACT_THRESHOLD))?;
    let hand = super::load_hand(hand_spec)?;
    let keypoints = KeypointsFile::read_for_hand(kp_path, &hand).context("--keypoints")?;
    let pulls = hand_tendon_pulls(pulls_text, &hand)?;
    let world_from_hand = match &args.world_from_hand {
        Some(text) => parse_world_from_hand(text)?,
        None => WorldFromHand::identity(),
    };
    let (material, material_name) = super::load_material(args.material.as_deref())?;
    let (config, config_name) = super::load_physics_config(args.physics_config.as_deref())?;
    let mut estimator = PhysicsEstimator::new(&hand, &material, &config)
        .with_context(|| format!("the physics estimator of hand '{hand_spec}'"))?;
    let frame = PhysicsFrame {
        keypoints: &keypoints,
        tendon_pull_m: &pulls,
        world_from_hand,
    };
    let sources = ContactSources {
        hand: hand_spec.clone(),
        input: kp_path.display().to_string(),
        model: material_name,
    };
    let physics = contact_job::physics_contact(
        &mut estimator,
        frame,
        threshold,
        sources,
        config_name,
        started,
    )
    .with_context(|| format!("keypoints {}", kp_path.display()))?;
    physics.output.files.write(&args.out)?;
    if args.json {
        return super::print_json(&physics.output.record);
    }
    for warning in physics.warnings() {
        eprintln!("warning: {warning}");
    }
    super::outln!("{}", physics.summary());
    Ok(())
}
