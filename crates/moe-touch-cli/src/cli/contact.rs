//! `moe-touch contact`: run the contact network on a point cloud, or on a hand shape as
//! `moe-touch shape` writes it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use moe_contact::{Aggregation, DeviceKind, ForwardTimings, InputFeature};
use moe_geom::{
    ContactInput, ContactMap, HandKeypoints, HandModel, HandShape, Iso3, Point3, WorldFromHand,
};
use moe_geom::{HandEstimator as _, Observation};
use moe_lab::contact_output::{
    CONTACTS_HEADER, FingerContactRecord, PhysicsFingerRecord, contact_fingers, contact_rows,
    physics_fingers,
};
use moe_lab::point_cloud::{NetworkPrecision, PointCloudModel, PointCloudOptions};
use moe_lab::run::LoadRecord;
use moe_physics::PhysicsEstimator;
use serde::{Deserialize, Serialize};

use super::ContactMethod;

/// The float type the network computes in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
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

/// The `--points` report.
#[derive(Debug, Serialize)]
struct PointsReport {
    points: usize,
    model: String,
    card: bool,
    aggregation: Aggregation,
    dtype: Precision,
    threshold: f64,
    contact_points: usize,
    timings_ms: TimingsMs,
    out: String,
}

/// Stage timings in milliseconds.
#[derive(Debug, Serialize)]
struct TimingsMs {
    knn: f64,
    edgeconv: f64,
    head: f64,
    network: f64,
    total: f64,
}

impl TimingsMs {
    fn new(t: ForwardTimings, total_s: f64) -> Self {
        Self {
            knn: t.knn_s * 1e3,
            edgeconv: t.edgeconv_s * 1e3,
            head: t.head_s * 1e3,
            network: t.total_s() * 1e3,
            total: total_s * 1e3,
        }
    }
}

/// `contact.json`, also the `--json` report of `--shape`.
#[derive(Debug, Serialize)]
struct ShapeContactRecord {
    hand: String,
    shape: String,
    model: String,
    card: bool,
    aggregation: Aggregation,
    dtype: Precision,
    threshold: f64,
    frame: &'static str,
    fingers: Vec<FingerContactRecord>,
    contact_vertices: usize,
    timings_ms: TimingsMs,
}

fn check_threshold(t: f64) -> Result<f64> {
    if !(t > 0.0 && t <= 1.0) {
        bail!("--threshold {t} is not in (0, 1]");
    }
    Ok(t)
}

pub(crate) fn run(args: ContactArgs) -> Result<()> {
    match args.method {
        ContactMethod::Dgcnn => run_dgcnn(args),
        ContactMethod::Physics => run_physics(&args),
    }
}

fn run_dgcnn(args: ContactArgs) -> Result<()> {
    let t0 = Instant::now();
    for (given, flag) in [
        (args.keypoints.is_some(), "--keypoints"),
        (args.world_from_hand.is_some(), "--world-from-hand"),
        (args.material.is_some(), "--material"),
        (args.physics_config.is_some(), "--physics-config"),
    ] {
        if given {
            bail!(
                "{flag} is for --method physics; the DGCNN reads a point cloud (--points) or a \
                 hand shape (--hand with --shape)"
            );
        }
    }
    let Some(model_path) = &args.model else {
        bail!("--method dgcnn needs --model M.safetensors (or use --method physics)");
    };
    match (&args.points, &args.hand, &args.shape) {
        (Some(points), None, None) => {
            if args.tendon_pulls.is_some() {
                bail!("--tendon-pulls needs --hand with --shape (a point cloud has no fingers)");
            }
            run_points(&args, model_path, points, t0)
        }
        (None, Some(hand), Some(shape)) => {
            for (given, flag) in [
                (args.aggregation.is_some(), "--aggregation"),
                (args.dtype.is_some(), "--dtype"),
                (args.device.is_some(), "--device"),
            ] {
                if given {
                    bail!(
                        "{flag} is for --points; a hand shape runs the model as the runtime \
                         does (f32 on the CPU, the card's aggregation)"
                    );
                }
            }
            run_shape(&args, model_path, hand, shape, t0)
        }
        _ => bail!("give either --points, or --hand with --shape"),
    }
}

fn run_points(args: &ContactArgs, model_path: &Path, points: &Path, t0: Instant) -> Result<()> {
    let dtype = args.dtype.unwrap_or(Precision::F32);
    let options = PointCloudOptions {
        precision: match dtype {
            Precision::F32 => NetworkPrecision::F32,
            Precision::F64 => NetworkPrecision::F64,
        },
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
    let rows = moe_io::read_points_csv(points)?;
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != 3) {
        bail!(
            "{}: row {} has {} fields; points are x,y,z",
            points.display(),
            i + 1,
            r.len()
        );
    }
    let n = rows.len();
    let cloud: Vec<[f64; 3]> = rows.iter().map(|r| [r[0], r[1], r[2]]).collect();
    let out = model
        .estimate(&cloud)
        .with_context(|| format!("points {}", points.display()))?;
    let table: Vec<Vec<f64>> = out
        .logits
        .iter()
        .zip(&out.probability)
        .map(|(l, &p)| vec![l[0], l[1], p])
        .collect();
    moe_io::write_csv(&args.out, &["logit0", "logit1", "probability"], &table)?;
    let report = PointsReport {
        points: n,
        model: model_path.display().to_string(),
        card: model.has_card(),
        aggregation: model.aggregation(),
        dtype,
        threshold,
        contact_points: out.probability.iter().filter(|&&p| p >= threshold).count(),
        timings_ms: TimingsMs::new(out.timings, t0.elapsed().as_secs_f64()),
        out: args.out.display().to_string(),
    };
    if args.json {
        super::print_json(&report)?;
    } else {
        super::outln!(
            "{} points, {} at or above {threshold}; network {:.1} ms (kNN {:.1}, EdgeConv {:.1}, \
             head {:.1}); wrote {}",
            report.points,
            report.contact_points,
            report.timings_ms.network,
            report.timings_ms.knn,
            report.timings_ms.edgeconv,
            report.timings_ms.head,
            report.out
        );
    }
    Ok(())
}

/// `--tendon-pulls`: fingers separated by `;`, each finger's pulls by `,`.
fn parse_tendon_pulls(text: &str) -> Result<Vec<Vec<f64>>> {
    text.split(';')
        .enumerate()
        .map(|(f, finger)| {
            finger
                .split(',')
                .map(str::trim)
                .enumerate()
                .map(|(t, v)| {
                    let x: f64 = v.parse().with_context(|| {
                        format!("--tendon-pulls: finger {f}, tendon {t}: '{v}' is not a number")
                    })?;
                    if !x.is_finite() {
                        bail!("--tendon-pulls: finger {f}, tendon {t}: '{v}' is not finite");
                    }
                    Ok(x)
                })
                .collect()
        })
        .collect()
}

fn read_shape(hand: &HandModel, dir: &Path) -> Result<HandShape> {
    let mut fingers = Vec::with_capacity(hand.num_fingers());
    for i in 0..hand.num_fingers() {
        let path = dir.join(format!("finger_{i}.obj"));
        let mesh = moe_io::read_mesh(&path)?;
        fingers.push(mesh.vertices().to_vec());
    }
    Ok(HandShape { fingers })
}

fn run_shape(
    args: &ContactArgs,
    model_path: &Path,
    hand_spec: &str,
    dir: &Path,
    t0: Instant,
) -> Result<()> {
    let hand = super::load_hand(hand_spec)?;
    let estimator = moe_touch::pipeline::load_contact_model(model_path, &hand)
        .with_context(|| format!("model {} on hand '{hand_spec}'", model_path.display()))?;
    let threshold = check_threshold(args.threshold.unwrap_or(estimator.threshold()))?;
    let shape = read_shape(&hand, dir)?;
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
    let mut observation = Observation::new();
    observation.tendon_pull_m = pulls.as_deref();
    let (mut maps, timings) = estimator
        .estimate_inputs(&[ContactInput::new(&shape, observation)])
        .with_context(|| format!("shape {}", dir.display()))?;
    let map: ContactMap = maps.pop().context("no contact map")?;
    // Everything in memory first, so that a failure leaves nothing half-written.
    let (plys, fingers) = contact_fingers(&hand, &shape, &map, threshold)?;
    let contacts = map.contacts_above(threshold, &shape)?;
    let rows = contact_rows(&contacts);
    let record = ShapeContactRecord {
        hand: hand_spec.to_string(),
        shape: dir.display().to_string(),
        model: model_path.display().to_string(),
        card: true,
        aggregation: estimator.network().config().aggregation,
        dtype: Precision::F32,
        threshold,
        frame: "hand",
        contact_vertices: contacts.len(),
        fingers,
        timings_ms: TimingsMs::new(timings, t0.elapsed().as_secs_f64()),
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating output directory {}", args.out.display()))?;
    for (name, ply) in &plys {
        moe_io::write_ply(&args.out.join(name), ply)?;
    }
    moe_io::write_csv(&args.out.join("contacts.csv"), &CONTACTS_HEADER, &rows)?;
    moe_io::write_json(&args.out.join("contact.json"), &record)?;
    if args.json {
        super::print_json(&record)?;
    } else {
        super::outln!(
            "hand '{}': {} contact vertices at or above {threshold}; network {:.1} ms",
            record.hand,
            record.contact_vertices,
            record.timings_ms.network
        );
        for (i, f) in record.fingers.iter().enumerate() {
            super::outln!(
                "  finger {i}: {} of {} vertices, max probability {:.3}, wrote {}",
                f.contact_vertices,
                f.vertices,
                f.max_probability,
                f.mesh
            );
        }
    }
    Ok(())
}

/// A keypoints file: the keypoints, optionally with the time of their frame (as `moe-touch
/// shape` reads it and `moe-touch markers` writes it).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct KeypointsInput {
    #[serde(default, rename = "time_ns")]
    _time_ns: Option<u64>,
    fingers: Vec<Vec<Option<Point3>>>,
}

/// Reads `--keypoints` and checks it against the hand, naming the file and the item.
fn read_keypoints(path: &Path, hand: &HandModel) -> Result<HandKeypoints> {
    let input: KeypointsInput = moe_io::read_json(path)?;
    let name = path.display();
    if input.fingers.len() != hand.num_fingers() {
        bail!(
            "--keypoints {name}: {} fingers, the hand has {}",
            input.fingers.len(),
            hand.num_fingers()
        );
    }
    for (f, (markers, hf)) in input.fingers.iter().zip(hand.fingers()).enumerate() {
        let expected = hf.model.marker_vertices().len();
        if markers.len() != expected {
            bail!(
                "--keypoints {name}: finger {f} has {} markers, the hand's finger has {expected}",
                markers.len()
            );
        }
        if let Some(m) = markers
            .iter()
            .position(|p| p.is_some_and(|p| !p.iter().all(|c| c.is_finite())))
        {
            bail!("--keypoints {name}: finger {f}, marker {m} is not finite");
        }
    }
    Ok(HandKeypoints {
        fingers: input.fingers,
    })
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
pub(crate) fn parse_world_from_hand(text: &str) -> Result<WorldFromHand> {
    let values: Vec<f64> = text
        .split(',')
        .map(str::trim)
        .enumerate()
        .map(|(i, v)| {
            let x: f64 = v
                .parse()
                .with_context(|| format!("--world-from-hand: value {i}: '{v}' is not a number"))?;
            if !x.is_finite() {
                bail!("--world-from-hand: value {i}: '{v}' is not finite");
            }
            Ok(x)
        })
        .collect::<Result<_>>()?;
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

/// The physics `contact.json`, also its `--json` report.
#[derive(Debug, Serialize)]
struct PhysicsContactRecord {
    method: ContactMethod,
    hand: String,
    keypoints: String,
    tendon_pull_m: Vec<Vec<f64>>,
    /// `x,y,z,qx,qy,qz,qw`.
    world_from_hand: [f64; 7],
    material: String,
    physics_config: String,
    threshold: f64,
    frame: &'static str,
    units: &'static str,
    fingers: Vec<PhysicsFingerRecord>,
    contact_vertices: usize,
    loads: usize,
    loads_file: &'static str,
    timings_ms: PhysicsTimingsMs,
}

/// Wall time of the physics path, milliseconds.
#[derive(Debug, Serialize)]
struct PhysicsTimingsMs {
    /// Building the finger models.
    setup_ms: f64,
    /// The estimate.
    estimate_ms: f64,
    total_ms: f64,
}

/// `loads.json`.
#[derive(Debug, Serialize)]
struct LoadsFile<'a> {
    frame: &'static str,
    units: &'static str,
    loads: &'a [LoadRecord],
}

fn run_physics(args: &ContactArgs) -> Result<()> {
    let t0 = Instant::now();
    let dgcnn_only = "is for --method dgcnn; the physics estimator reads markers (--keypoints), \
                      estimates the shape itself and has no network";
    for (given, flag) in [
        (args.points.is_some(), "--points"),
        (args.shape.is_some(), "--shape"),
        (args.model.is_some(), "--model"),
        (args.aggregation.is_some(), "--aggregation"),
        (args.dtype.is_some(), "--dtype"),
        (args.device.is_some(), "--device"),
    ] {
        if given {
            bail!("{flag} {dgcnn_only}");
        }
    }
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
    let keypoints = read_keypoints(kp_path, &hand)?;
    let pulls = hand_tendon_pulls(pulls_text, &hand)?;
    let world_from_hand = match &args.world_from_hand {
        Some(text) => parse_world_from_hand(text)?,
        None => WorldFromHand::identity(),
    };
    let (material, material_name) = super::load_material(args.material.as_deref())?;
    let (config, config_name) = super::load_physics_config(args.physics_config.as_deref())?;
    let mut estimator = PhysicsEstimator::new(&hand, &material, &config)
        .with_context(|| format!("the physics estimator of hand '{hand_spec}'"))?;
    let t_setup = Instant::now();
    let estimate = estimator
        .estimate(
            &Observation::from_keypoints(&keypoints)
                .with_tendon_pulls(&pulls)
                .with_world_from_hand(world_from_hand),
        )
        .with_context(|| format!("keypoints {}", kp_path.display()))?;
    let t_estimate = Instant::now();
    // Everything in memory first, so that a failure leaves nothing half-written.
    let (plys, fingers) = physics_fingers(&hand, &estimate, threshold)?;
    let contacts = estimate
        .contact
        .contacts_above(threshold, &estimate.shape)?;
    let rows = contact_rows(&contacts);
    let loads: Vec<LoadRecord> = estimate
        .details
        .loads
        .iter()
        .map(LoadRecord::from)
        .collect();
    let loads_text = serde_json::to_string_pretty(&LoadsFile {
        frame: "hand",
        units: "metres, newtons",
        loads: &loads,
    })?;
    let iso = world_from_hand.iso();
    let (t, q) = (iso.translation.vector, iso.rotation.quaternion());
    let end = Instant::now();
    let ms = |a: Instant, b: Instant| 1e3 * (b - a).as_secs_f64();
    let record = PhysicsContactRecord {
        method: ContactMethod::Physics,
        hand: hand_spec.clone(),
        keypoints: kp_path.display().to_string(),
        tendon_pull_m: pulls,
        world_from_hand: [t.x, t.y, t.z, q.i, q.j, q.k, q.w],
        material: material_name,
        physics_config: config_name,
        threshold,
        frame: "hand",
        units: "metres, newtons",
        contact_vertices: contacts.len(),
        loads: loads.len(),
        loads_file: "loads.json",
        fingers,
        timings_ms: PhysicsTimingsMs {
            setup_ms: ms(t0, t_setup),
            estimate_ms: ms(t_setup, t_estimate),
            total_ms: ms(t0, end),
        },
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating output directory {}", args.out.display()))?;
    for (name, ply) in &plys {
        moe_io::write_ply(&args.out.join(name), ply)?;
    }
    moe_io::write_csv(&args.out.join("contacts.csv"), &CONTACTS_HEADER, &rows)?;
    moe_io::write_atomic(&args.out.join("loads.json"), loads_text.as_bytes())?;
    moe_io::write_json(&args.out.join("contact.json"), &record)?;
    if args.json {
        return super::print_json(&record);
    }
    print_physics(&record, &loads);
    Ok(())
}

/// The physics estimate's lines on stdout: the hand, each finger, each load.
fn print_physics(record: &PhysicsContactRecord, loads: &[LoadRecord]) {
    let threshold = record.threshold;
    super::outln!(
        "hand '{}' (physics, material {}): {}, {} contact vertices at or above {threshold}; \
         estimate {:.1} ms",
        record.hand,
        record.material,
        super::count(record.loads, "load"),
        record.contact_vertices,
        record.timings_ms.estimate_ms
    );
    for (i, f) in record.fingers.iter().enumerate() {
        if let Some(e) = &f.error {
            eprintln!("warning: finger {i}: no estimate ({e}); left at its rest shape");
        }
        super::outln!(
            "  finger {i}: force {:.3} N ({:+.3}, {:+.3}, {:+.3}) from {}, pressed with \
             probability {:.3}, {} contact vertices, wrote {}",
            f.force_magnitude_n,
            f.force_n.x,
            f.force_n.y,
            f.force_n.z,
            super::count(f.loads, "load"),
            f.pressed_probability,
            f.contact_vertices,
            f.mesh
        );
    }
    for l in loads {
        super::outln!(
            "  load on finger {} at vertex {} ({:.1}, {:.1}, {:.1}) mm: {:.3} ± {:.3} N",
            l.finger,
            l.vertex,
            1e3 * l.location_m.x,
            1e3 * l.location_m.y,
            1e3 * l.location_m.z,
            l.magnitude_n,
            l.magnitude_sd_n
        );
    }
}
