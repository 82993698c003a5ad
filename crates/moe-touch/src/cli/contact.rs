//! `moe-touch contact`: run the contact network on a point cloud, or on a hand shape as
//! `moe-touch shape` writes it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use moe_contact::candle_core::{DType, Tensor};
use moe_contact::{
    Aggregation, DeviceKind, Dgcnn, DgcnnEstimator, InputFeature, Mode, ModelCard, StageTimings,
    contact_probability, open_device,
};
use moe_geom::{ContactInput, ContactMap, HandModel, HandShape};
use serde::Serialize;

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
    /// A point cloud (CSV rows `x,y,z`, header optional): writes one row per point, in input
    /// order, `logit0,logit1,probability`, to `--out`.
    #[arg(long, value_name = "P.csv", conflicts_with_all = ["hand", "shape"], required_unless_present = "shape")]
    points: Option<PathBuf>,
    /// The hand of `--shape`: a preset (two-finger, three-finger, five-finger) or a hand config.
    #[arg(long, value_name = "PRESET|CONFIG", requires = "shape")]
    hand: Option<String>,
    /// A hand shape as `moe-touch shape` writes it: a directory with `finger_<i>.obj` (deformed,
    /// hand frame, metres). Writes to the `--out` directory, per finger, `finger_<i>.ply` with the
    /// contact probability as a vertex property and a colour ramp (blue 0 to red 1), the contact
    /// points as `contacts.csv` and a summary `contact.json`.
    #[arg(long, value_name = "DIR", requires = "hand")]
    shape: Option<PathBuf>,
    /// The tendon pulls of `--shape`, metres, for a model with the `tendon-pull` feature: the
    /// pulls of each finger comma-separated in its tendon routes' order, fingers separated by
    /// `;` (e.g. `0.002,-0.002,0,0;0,0,0.001,-0.001`).
    #[arg(long, value_name = "LIST", requires = "shape")]
    tendon_pulls: Option<String>,
    /// The model: `NAME.safetensors`, with its card `NAME.json` beside it if there is one.
    #[arg(long, value_name = "M.safetensors")]
    model: PathBuf,
    /// Edge aggregation, max or sum, overriding the card's (the weights do not depend on it).
    #[arg(long)]
    aggregation: Option<Aggregation>,
    /// Float type of the computation.
    #[arg(long, value_enum, default_value = "f32")]
    dtype: Precision,
    /// Device: cpu, or cuda in a build with the `cuda` feature.
    #[arg(long, default_value = "cpu")]
    device: DeviceKind,
    /// Contact threshold on the probability (default: the card's, else 0.5).
    #[arg(long)]
    threshold: Option<f64>,
    /// Output: a CSV file for `--points`, a directory for `--shape`.
    #[arg(long, value_name = "OUT")]
    out: PathBuf,
    /// Print the report as one JSON object.
    #[arg(long)]
    json: bool,
}

/// A loaded model: the network and its card (the defaults, widened to the weights, without one).
pub(crate) struct LoadedModel {
    pub(crate) net: Dgcnn,
    pub(crate) card: ModelCard,
    pub(crate) has_card: bool,
}

/// Reads and checks `NAME.safetensors` and its card.
pub(crate) fn load_model(
    path: &Path,
    dtype: Precision,
    device: DeviceKind,
    aggregation: Option<Aggregation>,
) -> Result<LoadedModel> {
    let device = open_device(device)?;
    let files = moe_io::read_model_files(path)?;
    let card = match &files.card {
        Some(text) => Some(
            ModelCard::from_json(text)
                .with_context(|| format!("model card {}", files.card_path.display()))?,
        ),
        None => None,
    };
    let dtype = match dtype {
        Precision::F32 => DType::F32,
        Precision::F64 => DType::F64,
    };
    let mut net = Dgcnn::from_safetensors(&files.weights, card.as_ref(), dtype, &device)
        .with_context(|| format!("model {}", path.display()))?;
    if let Some(a) = aggregation {
        net.set_aggregation(a);
    }
    let has_card = card.is_some();
    let mut card = card.unwrap_or_else(|| ModelCard::new(net.config().clone()));
    card.architecture.aggregation = net.config().aggregation;
    Ok(LoadedModel {
        net,
        card,
        has_card,
    })
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
    fn new(t: StageTimings, total_s: f64) -> Self {
        Self {
            knn: t.knn_s * 1e3,
            edgeconv: t.edgeconv_s * 1e3,
            head: t.head_s * 1e3,
            network: t.total_s() * 1e3,
            total: total_s * 1e3,
        }
    }
}

/// One finger of `contact.json`.
#[derive(Debug, Serialize)]
struct FingerContactRecord {
    mesh: String,
    vertices: usize,
    contact_vertices: usize,
    max_probability: f64,
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
    let t0 = Instant::now();
    let model = load_model(&args.model, args.dtype, args.device, args.aggregation)?;
    let threshold = check_threshold(args.threshold.unwrap_or(model.card.threshold))?;
    match (&args.points, &args.hand, &args.shape) {
        (Some(points), None, None) => run_points(&args, points, &model, threshold, t0),
        (None, Some(hand), Some(shape)) => run_shape(&args, hand, shape, model, threshold, t0),
        _ => bail!("give either --points, or --hand with --shape"),
    }
}

fn run_points(
    args: &ContactArgs,
    points: &Path,
    model: &LoadedModel,
    threshold: f64,
    t0: Instant,
) -> Result<()> {
    let spec = &model.card.architecture.input;
    if spec.features != [InputFeature::Xyz] {
        bail!(
            "model {}: its input features ({}) cannot be made from a point cloud; use --hand \
             with --shape",
            args.model.display(),
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
    let mut values: Vec<f64> = rows.into_iter().flatten().collect();
    spec.normalise(&mut values);
    let x = Tensor::from_vec(values, (1, n, 3), &moe_contact::candle_core::Device::Cpu)?;
    let out = model
        .net
        .forward_with(&x, Mode::Eval)
        .with_context(|| format!("points {}", points.display()))?;
    let logits = out
        .logits
        .to_dtype(DType::F64)?
        .flatten_all()?
        .to_vec1::<f64>()?;
    let prob = contact_probability(&out.logits)?
        .to_dtype(DType::F64)?
        .flatten_all()?
        .to_vec1::<f64>()?;
    let table: Vec<Vec<f64>> = logits
        .chunks_exact(2)
        .zip(&prob)
        .map(|(l, &p)| vec![l[0], l[1], p])
        .collect();
    moe_io::write_csv(&args.out, &["logit0", "logit1", "probability"], &table)?;
    let report = PointsReport {
        points: n,
        model: args.model.display().to_string(),
        card: model.has_card,
        aggregation: model.net.config().aggregation,
        dtype: args.dtype,
        threshold,
        contact_points: prob.iter().filter(|&&p| p >= threshold).count(),
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
    hand_spec: &str,
    dir: &Path,
    model: LoadedModel,
    threshold: f64,
    t0: Instant,
) -> Result<()> {
    let hand = super::load_hand(hand_spec)?;
    let shape = read_shape(&hand, dir)?;
    let has_card = model.has_card;
    let aggregation = model.net.config().aggregation;
    let estimator = DgcnnEstimator::new(model.net, model.card, &hand)
        .with_context(|| format!("model {} on hand '{hand_spec}'", args.model.display()))?;
    let pulls = args
        .tendon_pulls
        .as_deref()
        .map(parse_tendon_pulls)
        .transpose()?;
    if pulls.is_some() && !estimator.features().needs_tendon_pulls() {
        bail!(
            "--tendon-pulls: model {} does not take them (its features: {})",
            args.model.display(),
            estimator.features().spec().describe()
        );
    }
    let (mut maps, timings) = estimator
        .estimate_inputs(&[ContactInput {
            tendon_pull_m: pulls.as_deref(),
            ..ContactInput::shape(&shape)
        }])
        .with_context(|| format!("shape {}", dir.display()))?;
    let map: ContactMap = maps.pop().context("no contact map")?;
    // Everything in memory first, so that a failure leaves nothing half-written.
    let mut plys = Vec::with_capacity(hand.num_fingers());
    let mut fingers = Vec::with_capacity(hand.num_fingers());
    for (i, probs) in map.fingers.iter().enumerate() {
        let ply = moe_touch::contact_eval::contact_ply(&hand, i, &shape.fingers[i], probs)?;
        let name = format!("finger_{i}.ply");
        fingers.push(FingerContactRecord {
            mesh: name.clone(),
            vertices: probs.len(),
            contact_vertices: probs.iter().filter(|&&p| p >= threshold).count(),
            max_probability: probs.iter().copied().fold(0.0, f64::max),
        });
        plys.push((name, ply));
    }
    let contacts = map.contacts_above(threshold, &shape)?;
    let rows: Vec<Vec<f64>> = contacts
        .iter()
        .map(|c| {
            vec![
                c.finger as f64,
                f64::from(c.vertex),
                c.point.x,
                c.point.y,
                c.point.z,
                c.probability,
            ]
        })
        .collect();
    let record = ShapeContactRecord {
        hand: hand_spec.to_string(),
        shape: dir.display().to_string(),
        model: args.model.display().to_string(),
        card: has_card,
        aggregation,
        dtype: args.dtype,
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
    moe_io::write_csv(
        &args.out.join("contacts.csv"),
        &["finger", "vertex", "x", "y", "z", "probability"],
        &rows,
    )?;
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
