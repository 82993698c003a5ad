//! `moe-touch eval patting`: the paper's patting applications end to end (§5.3, §6.1). The
//! two-finger hand pats a head (30 poses) and a long arm (15 poses) in the simulator; every
//! pat's deepest press is rendered by the wrist camera with its noise and run through the
//! pipeline (detected markers, SR-ARAP, a contact estimator) to contact points in the world;
//! the contact points of all pats feed the surface reconstruction with a task prior (another
//! body of the same family).
//!
//! Reported per body, as mean ± sd over several seeded truth/prior pairs:
//! - Table 2: UCD from the estimated contact points to the true surface, for the DGCNN and for
//!   `KNN[All]` (both on the same SR-ARAP shapes; the KNN gives the contact vertices of the
//!   training frame whose markers are nearest), and for the simulator's own contact vertices;
//! - Table 3: UCD from each reconstruction to the true surface (GP with the prior, GP with a
//!   sphere, the non-probabilistic baseline, the prior alone), from the DGCNN's contacts and,
//!   as the upper bound, from the true contacts.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use moe_contact::KnnIndex;
use moe_geom::{FingerParams, HandModel, HandPreset, Real};
use moe_gpis::bench_scene::{BenchScene, SceneKind, SceneReport, Spread, evaluate_scene_with};
use moe_gpis::{HyperBounds, ReconstructOptions};
use moe_io::{DatasetReader, PlyData, SplitFractions};
use moe_lab::patting::{
    PatContacts, PattingEpisode, body_mesh, paper_pat_contacts, pats_of, physics_pat_contacts,
    simulate_patting, true_pat_contacts, ucd_to_truth_mm,
};
use moe_tendon_sim::paper_scenes::{ARM_SEED, HEAD_SEED};
use moe_touch::pipeline::load_contact_model;
use serde::Serialize;
use serde_json::{Value, json};

use crate::cli::eval::Size;
use crate::cli::eval::contact::{HELDOUT_DIR, SHIPPED_MODEL};
use crate::golden::workspace_root;

/// Offset of the ±d points along the mean's normals at each contact (metres), as in
/// `eval surface`.
const NORMAL_OFFSET_M: f64 = 0.005;

/// Pats per body at small size.
const SMALL_PATS: usize = 3;

/// A body to pat.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Body {
    /// The head of §5.3 (30 pats).
    Head,
    /// The arm under a gown of §6.1 (15 pats).
    Arm,
}

impl Body {
    fn kind(self) -> SceneKind {
        match self {
            Self::Head => SceneKind::Head,
            Self::Arm => SceneKind::Arm,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Self::Head => "head",
            Self::Arm => "arm",
        }
    }

    /// The truth seed of pair 0 (the committed scene's body).
    fn seed(self) -> u64 {
        match self {
            Self::Head => HEAD_SEED,
            Self::Arm => ARM_SEED,
        }
    }
}

/// Default of `--prior-gate`: 10 mm, about three times the task priors' distance from their
/// truths (2–5 mm UCD) and well inside the false contacts' (centimetres).
const DEFAULT_PRIOR_GATE_M: Real = 0.01;

/// Default of `--estimated-noise-floor`: 5 mm, about the shipped model's contacts' mean distance
/// from the true surface in these scenes (4.8 mm on the arm, 6.1 mm on the head). With the
/// noise fitted freely the GP takes that error for shape: a 6–10 mm length scale bends the
/// surface through the contacts.
const DEFAULT_ESTIMATED_NOISE_FLOOR_M: Real = 0.005;

/// Arguments of `moe-touch eval patting`.
#[derive(Debug, Args)]
pub(crate) struct PattingEvalArgs {
    /// Size: small = one pair, 3 pats per body, 24³ grid, level-4 priors (the golden-checked
    /// configuration); full = every pat, 64³ grid, level-5 priors.
    #[arg(long, value_enum, default_value = "full")]
    size: Size,
    /// Truth/prior pairs per body (pair k pats the body of seed `S + 10k` with the prior of
    /// seed `S + 10k + 1`); default 3 at full size, 1 at small size.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=100))]
    pairs: Option<u64>,
    /// Only these bodies (repeatable; default both).
    #[arg(long = "body", value_enum)]
    bodies: Vec<Body>,
    /// Contact model (with its card beside it).
    #[arg(long, value_name = "M.safetensors", default_value = SHIPPED_MODEL)]
    model: PathBuf,
    /// `KNN[All]` index (as `moe-touch eval contact --knn-index` writes it from a data set's
    /// training frames). Without it the index is built from the committed held-out set, a
    /// small stand-in for the comparison at small size.
    #[arg(long, value_name = "FILE")]
    knn_index: Option<PathBuf>,
    /// Seed of the camera noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Write the first pair of each body to `DIR/<body>/`: the truth, the prior, the contact
    /// points of each estimator, and every surface (the GP's with its posterior variance).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    json: bool,
    /// The GP with the prior and the non-probabilistic baseline leave out contacts farther than
    /// this from the prior (metres; 0 keeps every contact): false contacts would otherwise
    /// raise bubbles of surface where nothing is.
    #[arg(long, value_name = "M", default_value_t = DEFAULT_PRIOR_GATE_M)]
    prior_gate: Real,
    /// Lower bound of the GP's noise standard deviation on the estimated contacts (metres; 0
    /// leaves the fit's own bound): how far an estimated contact may be from the surface
    /// without the GP taking it for shape. The true contacts keep the fit's own bound.
    #[arg(long, value_name = "M", default_value_t = DEFAULT_ESTIMATED_NOISE_FLOOR_M)]
    estimated_noise_floor: Real,
}

/// The contact points of one estimator on one pair.
#[derive(Debug, Clone, Serialize)]
struct ContactResult {
    /// UCD to the true surface, mm (`None` when nothing was estimated).
    ucd_mm: Option<Real>,
    /// Contact points over all pats.
    points: usize,
    /// Pats with no estimated contact.
    pats_without_contact: usize,
}

fn contact_result(c: &PatContacts, episode: &PattingEpisode) -> Result<ContactResult> {
    Ok(ContactResult {
        ucd_mm: ucd_to_truth_mm(&c.points_in_world, &episode.truth)?,
        points: c.points_in_world.len(),
        pats_without_contact: c.pats_without_contact(),
    })
}

/// One truth/prior pair of one body.
#[derive(Debug, Clone, Serialize)]
struct PairReport {
    truth_seed: u64,
    prior_seed: u64,
    pats: usize,
    dgcnn: ContactResult,
    knn_all: ContactResult,
    /// The physics estimator (the pipeline's default), each pat from rest.
    physics: ContactResult,
    truth: ContactResult,
    /// Table 3 from the DGCNN's contacts (`None` when it estimated none).
    surfaces_estimated: Option<SceneReport>,
    /// Table 3 from the physics estimator's contacts (`None` when it estimated none).
    surfaces_physics: Option<SceneReport>,
    /// Table 3 from the simulator's contacts.
    surfaces_true: SceneReport,
}

/// Mean ± sd of one figure over the pairs where it exists.
fn spread(values: impl Iterator<Item = Option<Real>>) -> Option<Spread> {
    let v: Vec<Real> = values.flatten().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let n = v.len() as Real;
    let mean = v.iter().sum::<Real>() / n;
    let sd = if v.len() > 1 {
        (v.iter().map(|x| (x - mean).powi(2)).sum::<Real>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    Some(Spread { mean, sd })
}

/// The methods of Table 3, in report order.
const METHODS: [&str; 4] = ["gp_prior", "gp_sphere", "nonprob", "prior"];

/// Which contacts a surface of Table 3 was made from.
#[derive(Debug, Clone, Copy)]
enum SurfaceSource {
    Dgcnn,
    Physics,
    True,
}

fn method_spread(pairs: &[PairReport], source: SurfaceSource, method: &str) -> Option<Spread> {
    spread(pairs.iter().map(|p| {
        let report = match source {
            SurfaceSource::Dgcnn => p.surfaces_estimated.as_ref(),
            SurfaceSource::Physics => p.surfaces_physics.as_ref(),
            SurfaceSource::True => Some(&p.surfaces_true),
        };
        report
            .and_then(|r| r.method(method))
            .filter(|m| m.error.is_none())
            .map(|m| m.ucd_mm)
    }))
}

fn summary(pairs: &[PairReport]) -> Value {
    let table2 = json!({
        "dgcnn_ucd_mm": spread(pairs.iter().map(|p| p.dgcnn.ucd_mm)),
        "knn_all_ucd_mm": spread(pairs.iter().map(|p| p.knn_all.ucd_mm)),
        "physics_ucd_mm": spread(pairs.iter().map(|p| p.physics.ucd_mm)),
        "physics_pats_without_contact": pairs.iter().map(|p| p.physics.pats_without_contact).sum::<usize>(),
        "true_contacts_ucd_mm": spread(pairs.iter().map(|p| p.truth.ucd_mm)),
        "dgcnn_pats_without_contact": pairs.iter().map(|p| p.dgcnn.pats_without_contact).sum::<usize>(),
        "knn_all_pats_without_contact": pairs.iter().map(|p| p.knn_all.pats_without_contact).sum::<usize>(),
        "pats": pairs.iter().map(|p| p.pats).sum::<usize>(),
    });
    let table3 = |source: SurfaceSource| -> Value {
        METHODS
            .iter()
            .map(|m| ((*m).to_owned(), json!(method_spread(pairs, source, m))))
            .collect::<serde_json::Map<String, Value>>()
            .into()
    };
    json!({
        "table2": table2,
        "table3_estimated": table3(SurfaceSource::Dgcnn),
        "table3_physics": table3(SurfaceSource::Physics),
        "table3_true_contacts": table3(SurfaceSource::True),
    })
}

fn reconstruct_options(size: Size) -> ReconstructOptions {
    match size {
        Size::Full => ReconstructOptions::default(),
        Size::Small => ReconstructOptions {
            max_grid_nodes: 24 * 24 * 24,
            vertex_variance: false,
            ..ReconstructOptions::default()
        },
    }
}

/// The `KNN[All]` index: from a file, or built from the committed held-out set.
fn knn_index(path: Option<&Path>, hand: &HandModel) -> Result<KnnIndex> {
    let index = match path {
        Some(path) => {
            let bytes =
                std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
            KnnIndex::from_bytes(&bytes).with_context(|| format!("KNN index {}", path.display()))?
        }
        None => {
            let reader = DatasetReader::open(&workspace_root().join(HELDOUT_DIR))?;
            let frames = reader
                .labelled_frames(None, SplitFractions::default())
                .collect::<Result<Vec<_>, _>>()?;
            KnnIndex::new(&frames, false)?
        }
    };
    let counts: Vec<usize> = hand
        .fingers()
        .iter()
        .map(|f| f.model.mesh().num_vertices())
        .collect();
    anyhow::ensure!(
        index.vertices_per_finger() == counts.as_slice(),
        "the KNN index is of a hand with {:?} vertices per finger, the patting hand's has {counts:?}",
        index.vertices_per_finger()
    );
    Ok(index)
}

/// Everything about one pair; with `write`, its files go to that directory.
#[allow(clippy::too_many_arguments)]
fn evaluate_pair(
    body: Body,
    k: u64,
    pats: usize,
    size: Size,
    args: &PattingEvalArgs,
    hand: &HandModel,
    knn: &KnnIndex,
    write: Option<&Path>,
) -> Result<PairReport> {
    let truth_seed = body.seed() + 10 * k;
    let prior_seed = truth_seed + 1;
    let t = std::time::Instant::now();
    let episode = simulate_patting(body.kind(), truth_seed, pats, args.seed)?;
    let dgcnn = load_contact_model(&workspace_root().join(&args.model), hand)?;
    let threshold = dgcnn.threshold();
    let dgcnn_contacts = paper_pat_contacts(hand, &episode, dgcnn, threshold)?;
    let knn_contacts = paper_pat_contacts(hand, &episode, knn, 0.5)?;
    let physics_contacts = physics_pat_contacts(
        hand,
        &episode,
        &moe_physics::HandMaterial::default(),
        &moe_physics::PhysicsConfig::default(),
    )?;
    let true_contacts = true_pat_contacts(&episode);
    let prior_level = match size {
        Size::Full => 5,
        Size::Small => 4,
    };
    let prior = body_mesh(body.kind(), prior_seed, prior_level)?;
    let surface = reconstruct_options(size);
    let put = |name: &str, ply: &PlyData| -> Result<()> {
        if let Some(dir) = write {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
            moe_io::write_ply(&dir.join(format!("{name}.ply")), ply)?;
        }
        Ok(())
    };
    put("truth", &PlyData::from_mesh(&episode.truth))?;
    put("prior", &PlyData::from_mesh(&prior))?;
    put(
        "contacts_dgcnn",
        &PlyData::from_points(&dgcnn_contacts.points_in_world),
    )?;
    put(
        "contacts_knn_all",
        &PlyData::from_points(&knn_contacts.points_in_world),
    )?;
    put(
        "contacts_physics",
        &PlyData::from_points(&physics_contacts.points_in_world),
    )?;
    put(
        "contacts_true",
        &PlyData::from_points(&true_contacts.points_in_world),
    )?;
    // `noise_floor_m`: the GP's noise sd at least this (0 for the fit's own bound).
    let surfaces =
        |contacts: &PatContacts, tag: &str, noise_floor_m: Real| -> Result<Option<SceneReport>> {
            if contacts.points_in_world.is_empty() {
                return Ok(None);
            }
            let scene = BenchScene {
                truth: episode.truth.clone(),
                prior: prior.clone(),
                contacts: contacts.points_in_world.clone(),
            };
            let mut surface = ReconstructOptions {
                vertex_variance: write.is_some(),
                ..surface
            };
            surface.gpis.fit.bounds = surface.gpis.fit.bounds.with_noise_floor(noise_floor_m)?;
            let mut failure = None;
            let report = evaluate_scene_with(
                body.kind(),
                &scene,
                &surface,
                Some(NORMAL_OFFSET_M),
                (args.prior_gate > 0.0).then_some(args.prior_gate),
                &mut |name, mesh, variance| {
                    let ply = PlyData::with_variance(mesh, variance);
                    if let Err(e) = put(&format!("{name}_{tag}"), &ply) {
                        failure.get_or_insert(e);
                    }
                },
            )?;
            if let Some(e) = failure {
                return Err(e);
            }
            Ok(Some(report))
        };
    let surfaces_estimated = surfaces(&dgcnn_contacts, "estimated", args.estimated_noise_floor)?;
    let surfaces_physics = surfaces(&physics_contacts, "physics", args.estimated_noise_floor)?;
    let surfaces_true = surfaces(&true_contacts, "true_contacts", 0.0)?
        .context("the simulated pats touched nothing")?;
    eprintln!(
        "eval patting: {} pair {k}: {pats} pats in {:.1} s",
        body.name(),
        t.elapsed().as_secs_f64()
    );
    Ok(PairReport {
        truth_seed,
        prior_seed,
        pats,
        dgcnn: contact_result(&dgcnn_contacts, &episode)?,
        knn_all: contact_result(&knn_contacts, &episode)?,
        physics: contact_result(&physics_contacts, &episode)?,
        truth: contact_result(&true_contacts, &episode)?,
        surfaces_estimated,
        surfaces_physics,
        surfaces_true,
    })
}

/// Every body's pairs and summary.
fn evaluate(args: &PattingEvalArgs) -> Result<Value> {
    let size = args.size;
    let pairs = args.pairs.unwrap_or(match size {
        Size::Full => 3,
        Size::Small => 1,
    });
    let bodies = if args.bodies.is_empty() {
        vec![Body::Head, Body::Arm]
    } else {
        args.bodies.clone()
    };
    // Checked before any work.
    HyperBounds::default()
        .with_noise_floor(args.estimated_noise_floor)
        .context("--estimated-noise-floor")?;
    if !(args.prior_gate.is_finite() && args.prior_gate >= 0.0) {
        anyhow::bail!(
            "--prior-gate {} must be a distance in metres (0 for none)",
            args.prior_gate
        );
    }
    let hand = HandModel::preset(HandPreset::TwoFinger, &FingerParams::default())?;
    let knn = knn_index(args.knn_index.as_deref(), &hand)?;
    let mut out = Vec::new();
    for body in bodies {
        let pats = match size {
            Size::Full => pats_of(body.kind()),
            Size::Small => SMALL_PATS,
        };
        let reports = (0..pairs)
            .map(|k| {
                let dir = args
                    .out
                    .as_ref()
                    .filter(|_| k == 0)
                    .map(|d| d.join(body.name()));
                evaluate_pair(body, k, pats, size, args, &hand, &knn, dir.as_deref())
            })
            .collect::<Result<Vec<_>>>()?;
        out.push(json!({ "body": body.name(), "summary": summary(&reports), "pairs": reports }));
    }
    Ok(json!({
        "size": format!("{size:?}").to_lowercase(),
        "pairs": pairs,
        "knn_index_frames": knn.len(),
        "prior_gate_m": args.prior_gate,
        "estimated_noise_floor_m": args.estimated_noise_floor,
        "bodies": out,
    }))
}

/// The paper's figures (Tables 2 and 3; its arm rows of Table 3 are of a real gowned arm, not
/// reproduced here).
fn paper(body: &str) -> (Real, Real, Option<[Real; 4]>) {
    match body {
        "head" => (6.58, 7.76, Some([3.64, 13.83, 16.01, 5.46])),
        _ => (6.24, 6.88, None),
    }
}

fn fmt(s: &Value) -> String {
    match (s["mean"].as_f64(), s["sd"].as_f64()) {
        (Some(m), Some(sd)) => format!("{m:6.2} ± {sd:5.2}"),
        _ => "      —       ".to_owned(),
    }
}

fn print_tables(v: &Value) {
    let Some(bodies) = v["bodies"].as_array() else {
        return;
    };
    for b in bodies {
        let name = b["body"].as_str().unwrap_or_default();
        let s = &b["summary"];
        let t2 = &s["table2"];
        let (paper_dgcnn, paper_knn, paper_t3) = paper(name);
        println!(
            "{name}: {} pats over {} pair(s); KNN[All] index of {} frames",
            t2["pats"], v["pairs"], v["knn_index_frames"]
        );
        println!("  Table 2, contact points to the true surface (UCD mm):   ours            paper");
        println!(
            "    DGCNN      {}  ({} pats without contact)  {paper_dgcnn:5.2}",
            fmt(&t2["dgcnn_ucd_mm"]),
            t2["dgcnn_pats_without_contact"]
        );
        println!(
            "    KNN[All]   {}  ({} pats without contact)  {paper_knn:5.2}",
            fmt(&t2["knn_all_ucd_mm"]),
            t2["knn_all_pats_without_contact"]
        );
        println!(
            "    physics    {}  ({} pats without contact)",
            fmt(&t2["physics_ucd_mm"]),
            t2["physics_pats_without_contact"]
        );
        println!("    true contacts {}", fmt(&t2["true_contacts_ucd_mm"]));
        println!(
            "  Table 3, surface to the true surface (UCD mm): from DGCNN contacts | from physics contacts | from true contacts | paper"
        );
        for (i, m) in METHODS.iter().enumerate() {
            let p = paper_t3.map_or("—".to_owned(), |p| format!("{:.2}", p[i]));
            println!(
                "    {m:<10} {}   {}   {}   {p}",
                fmt(&s["table3_estimated"][m]),
                fmt(&s["table3_physics"][m]),
                fmt(&s["table3_true_contacts"][m])
            );
        }
    }
}

pub(crate) fn run(args: &PattingEvalArgs) -> Result<()> {
    let report = evaluate(args)?;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_tables(&report);
    }
    Ok(())
}

/// Rounds every float of `v` to 1e-3 (golden fixtures compare across machines).
pub(crate) fn round3(v: &mut Value) {
    match v {
        Value::Number(n) => {
            if let Some(f) = n.as_f64()
                && n.is_f64()
            {
                *v = json!((f * 1e3).round() / 1e3);
            }
        }
        Value::Array(a) => a.iter_mut().for_each(round3),
        Value::Object(o) => o.values_mut().for_each(round3),
        _ => {}
    }
}

/// Removes what depends on the machine (timings, vertex counts of meshes).
fn strip_timings(v: &mut Value) {
    match v {
        Value::Object(o) => {
            for key in ["secs", "variance_secs", "vertices"] {
                o.remove(key);
            }
            o.values_mut().for_each(strip_timings);
        }
        Value::Array(a) => a.iter_mut().for_each(strip_timings),
        _ => {}
    }
}

/// The golden content of `eval patting --size small`: every figure rounded to µm, timings left
/// out.
pub(crate) fn patting_fixture() -> Result<Value> {
    let args = PattingEvalArgs {
        size: Size::Small,
        pairs: None,
        bodies: Vec::new(),
        model: PathBuf::from(SHIPPED_MODEL),
        knn_index: None,
        seed: 0,
        out: None,
        json: true,
        prior_gate: DEFAULT_PRIOR_GATE_M,
        estimated_noise_floor: DEFAULT_ESTIMATED_NOISE_FLOOR_M,
    };
    let mut v = evaluate(&args)?;
    strip_timings(&mut v);
    round3(&mut v);
    Ok(v)
}
