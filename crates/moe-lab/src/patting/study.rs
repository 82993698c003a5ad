//! The patting study (paper §5.3, §6.1, Tables 2–3): per body, several seeded truth/prior
//! pairs; every pair's pats through the DGCNN, `KNN[All]`, the physics estimator and the
//! simulator's own contacts, and the surfaces reconstructed from them with a task prior.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use moe_contact::KnnIndex;
use moe_geom::{FingerParams, HandModel, HandPreset, Real};
use moe_gpis::bench_scene::{BenchScene, SceneKind, SceneReport, Spread, evaluate_scene_with};
use moe_gpis::{HyperBounds, ReconstructOptions};
use moe_io::{IoError, PlyData};
use moe_tendon_sim::paper_scenes::{ARM_SEED, HEAD_SEED};
use moe_touch::pipeline::load_contact_model;
use serde::Serialize;

use super::{
    PatContacts, PattingEpisode, body_mesh, paper_pat_contacts, pats_of, physics_pat_contacts,
    simulate_patting, true_pat_contacts, ucd_to_truth_mm,
};
use crate::LabError;

/// Offset of the ±d points along the mean's normals at each contact (metres), as in the
/// surface benchmark.
const NORMAL_OFFSET_M: f64 = 0.005;

/// Pats per body at [`PattingSize::Small`].
pub const SMALL_PATS: usize = 3;

/// The methods of Table 3, in report order.
pub const TABLE3_METHODS: [&str; 4] = ["gp_prior", "gp_sphere", "nonprob", "prior"];

/// Default of [`PattingStudyOptions::prior_gate_m`]: 10 mm, about three times the task priors'
/// distance from their truths (2–5 mm UCD) and well inside the false contacts' (centimetres).
pub const DEFAULT_PRIOR_GATE_M: Real = 0.01;

/// Default of [`PattingStudyOptions::estimated_noise_floor_m`]: 5 mm, about the shipped model's
/// contacts' mean distance from the true surface in these scenes (4.8 mm on the arm, 6.1 mm on
/// the head). With the noise fitted freely the GP takes that error for shape: a 6–10 mm length
/// scale bends the surface through the contacts.
pub const DEFAULT_ESTIMATED_NOISE_FLOOR_M: Real = 0.005;

/// The study's size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PattingSize {
    /// One pair, [`SMALL_PATS`] pats per body, 24³ grid, level-4 priors (the golden-checked
    /// configuration).
    Small,
    /// Every pat, 64³ grid, level-5 priors.
    Full,
}

/// The progress line of a finished pair of pats (`k` of `body`, which took `secs`), as `eval
/// patting` reports it.
pub fn pair_progress(body: SceneKind, k: u64, pair: &PatPairReport, secs: f64) -> String {
    format!(
        "eval patting: {} pair {k}: {} pats in {secs:.1} s",
        body_name(body),
        pair.pats
    )
}

/// The name of a patted body (`head`, `arm`).
pub fn body_name(body: SceneKind) -> &'static str {
    match body {
        SceneKind::Head => "head",
        SceneKind::Arm => "arm",
    }
}

/// The truth seed of a body's pair 0 (the committed scene's body).
pub fn body_seed(body: SceneKind) -> u64 {
    match body {
        SceneKind::Head => HEAD_SEED,
        SceneKind::Arm => ARM_SEED,
    }
}

/// Settings of the patting study.
#[derive(Debug, Clone, PartialEq)]
pub struct PattingStudyOptions {
    /// The study's size.
    pub size: PattingSize,
    /// Truth/prior pairs per body (pair k pats the body of seed `S + 10k` with the prior of
    /// seed `S + 10k + 1`); `None`: 3 at full size, 1 at small size.
    pub pairs: Option<u64>,
    /// The bodies, in report order (empty: head and arm).
    pub bodies: Vec<SceneKind>,
    /// The contact model, with its card beside it.
    pub model: PathBuf,
    /// Seed of the wrist camera's noise.
    pub camera_seed: u64,
    /// Write the first pair of each body to `DIR/<body>/`: the truth, the prior, the contact
    /// points of each estimator, and every surface (the GP's with its posterior variance), as
    /// PLY.
    pub out: Option<PathBuf>,
    /// The GP with the prior and the non-probabilistic baseline leave out contacts farther
    /// than this from the prior (metres; 0 keeps every contact).
    pub prior_gate_m: Real,
    /// Lower bound of the GP's noise standard deviation on the estimated contacts (metres; 0
    /// leaves the fit's own bound). The true contacts keep the fit's own bound.
    pub estimated_noise_floor_m: Real,
    /// The physics estimator's settings.
    pub physics: moe_physics::PhysicsConfig,
    /// SR-ARAP's settings of the paper's pipeline (the DGCNN and KNN rows; with `[depth]`
    /// enabled, registered to each frame's depth image as well).
    pub shape: moe_arap::ShapeConfig,
}

/// The contact points of one estimator on one pair.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PatContactResult {
    /// UCD to the true surface, mm (`None` when nothing was estimated).
    pub ucd_mm: Option<Real>,
    /// Contact points over all pats.
    pub points: usize,
    /// Pats with no estimated contact.
    pub pats_without_contact: usize,
}

fn contact_result(c: &PatContacts, episode: &PattingEpisode) -> Result<PatContactResult, LabError> {
    Ok(PatContactResult {
        ucd_mm: ucd_to_truth_mm(&c.points_in_world, &episode.truth)?,
        points: c.points_in_world.len(),
        pats_without_contact: c.pats_without_contact(),
    })
}

/// One truth/prior pair of one body.
#[derive(Debug, Clone, Serialize)]
pub struct PatPairReport {
    /// Seed of the patted body.
    pub truth_seed: u64,
    /// Seed of the task prior.
    pub prior_seed: u64,
    /// Pats.
    pub pats: usize,
    /// The paper's pipeline: SR-ARAP and the DGCNN at its card's threshold.
    pub dgcnn: PatContactResult,
    /// SR-ARAP and `KNN[All]`.
    pub knn_all: PatContactResult,
    /// The physics estimator (the pipeline's default), each pat from rest.
    pub physics: PatContactResult,
    /// The simulator's contact vertices.
    pub truth: PatContactResult,
    /// Table 3 from the DGCNN's contacts (`None` when it estimated none).
    pub surfaces_estimated: Option<SceneReport>,
    /// Table 3 from the physics estimator's contacts (`None` when it estimated none).
    pub surfaces_physics: Option<SceneReport>,
    /// Table 3 from the simulator's contacts.
    pub surfaces_true: SceneReport,
}

/// Table 2 over a body's pairs: the contact points' UCD to the true surface, mean ± sd over
/// the pairs where it exists.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PattingTable2 {
    /// The DGCNN's.
    pub dgcnn_ucd_mm: Option<Spread>,
    /// `KNN[All]`'s.
    pub knn_all_ucd_mm: Option<Spread>,
    /// The physics estimator's.
    pub physics_ucd_mm: Option<Spread>,
    /// Pats without a physics contact, over the pairs.
    pub physics_pats_without_contact: usize,
    /// The simulator's contacts'.
    pub true_contacts_ucd_mm: Option<Spread>,
    /// Pats without a DGCNN contact, over the pairs.
    pub dgcnn_pats_without_contact: usize,
    /// Pats without a `KNN[All]` contact, over the pairs.
    pub knn_all_pats_without_contact: usize,
    /// Pats over the pairs.
    pub pats: usize,
}

/// Table 3 from one source of contacts: each method's surface UCD to the true surface, mean ±
/// sd over the pairs where it succeeded ([`TABLE3_METHODS`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PattingTable3 {
    /// The GP with the task prior as its mean.
    pub gp_prior: Option<Spread>,
    /// The GP with a sphere as its mean.
    pub gp_sphere: Option<Spread>,
    /// The non-probabilistic baseline.
    pub nonprob: Option<Spread>,
    /// The prior alone.
    pub prior: Option<Spread>,
}

impl PattingTable3 {
    /// The figure of `method` (one of [`TABLE3_METHODS`]).
    pub fn method(&self, method: &str) -> Option<Spread> {
        match method {
            "gp_prior" => self.gp_prior,
            "gp_sphere" => self.gp_sphere,
            "nonprob" => self.nonprob,
            "prior" => self.prior,
            _ => None,
        }
    }
}

/// A body's pairs summarised.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PattingSummary {
    /// Table 2.
    pub table2: PattingTable2,
    /// Table 3 from the DGCNN's contacts.
    pub table3_estimated: PattingTable3,
    /// Table 3 from the physics estimator's contacts.
    pub table3_physics: PattingTable3,
    /// Table 3 from the simulator's contacts.
    pub table3_true_contacts: PattingTable3,
}

/// One body's pairs and their summary.
#[derive(Debug, Clone, Serialize)]
pub struct PattingBodyReport {
    /// The body.
    pub body: SceneKind,
    /// Over the pairs.
    pub summary: PattingSummary,
    /// Every pair.
    pub pairs: Vec<PatPairReport>,
}

/// The patting study's report.
#[derive(Debug, Clone, Serialize)]
pub struct PattingStudyReport {
    /// The study's size.
    pub size: PattingSize,
    /// Pairs per body.
    pub pairs: u64,
    /// Frames of the `KNN[All]` index.
    pub knn_index_frames: usize,
    /// [`PattingStudyOptions::prior_gate_m`].
    pub prior_gate_m: Real,
    /// [`PattingStudyOptions::estimated_noise_floor_m`].
    pub estimated_noise_floor_m: Real,
    /// Every body.
    pub bodies: Vec<PattingBodyReport>,
}

/// The paper's figures (Tables 2 and 3; its arm rows of Table 3 are of a real gowned arm, not
/// reproduced here).
fn paper(body: &str) -> (Real, Real, Option<[Real; 4]>) {
    match body {
        "head" => (6.58, 7.76, Some([3.64, 13.83, 16.01, 5.46])),
        _ => (6.24, 6.88, None),
    }
}

/// A figure as `mean ± sd`, a dash when there is none.
fn fmt(s: Option<Spread>) -> String {
    match s {
        Some(Spread { mean, sd }) => format!("{mean:6.2} ± {sd:5.2}"),
        None => "      —       ".to_owned(),
    }
}

impl PattingStudyReport {
    /// The report as the tables `moe-touch eval patting` prints: per body, Table 2 (the
    /// contact points' UCD to the true surface per estimator) and Table 3 (each surface's UCD
    /// from the DGCNN's, the physics estimator's and the true contacts), beside the paper's
    /// figures.
    pub fn table(&self) -> String {
        let mut out = String::new();
        for b in &self.bodies {
            let name = body_name(b.body);
            let s = &b.summary;
            let t2 = &s.table2;
            let (paper_dgcnn, paper_knn, paper_t3) = paper(name);
            let _ = writeln!(
                out,
                "{name}: {} pats over {} pair(s); KNN[All] index of {} frames",
                t2.pats, self.pairs, self.knn_index_frames
            );
            let _ = writeln!(
                out,
                "  Table 2, contact points to the true surface (UCD mm):   ours            paper"
            );
            let _ = writeln!(
                out,
                "    DGCNN      {}  ({} pats without contact)  {paper_dgcnn:5.2}",
                fmt(t2.dgcnn_ucd_mm),
                t2.dgcnn_pats_without_contact
            );
            let _ = writeln!(
                out,
                "    KNN[All]   {}  ({} pats without contact)  {paper_knn:5.2}",
                fmt(t2.knn_all_ucd_mm),
                t2.knn_all_pats_without_contact
            );
            let _ = writeln!(
                out,
                "    physics    {}  ({} pats without contact)",
                fmt(t2.physics_ucd_mm),
                t2.physics_pats_without_contact
            );
            let _ = writeln!(out, "    true contacts {}", fmt(t2.true_contacts_ucd_mm));
            let _ = writeln!(
                out,
                "  Table 3, surface to the true surface (UCD mm): from DGCNN contacts | from physics contacts | from true contacts | paper"
            );
            for (i, m) in TABLE3_METHODS.iter().enumerate() {
                let p = paper_t3.map_or("—".to_owned(), |p| format!("{:.2}", p[i]));
                let _ = writeln!(
                    out,
                    "    {m:<10} {}   {}   {}   {p}",
                    fmt(s.table3_estimated.method(m)),
                    fmt(s.table3_physics.method(m)),
                    fmt(s.table3_true_contacts.method(m))
                );
            }
        }
        out
    }
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

/// Table 3 from the surfaces of each pair (`None` where a pair has none from that source).
fn table3(reports: &[Option<&SceneReport>]) -> PattingTable3 {
    let method = |name: &str| {
        spread(reports.iter().map(|report| {
            report
                .and_then(|r| r.method(name))
                .filter(|m| m.error.is_none())
                .map(|m| m.ucd_mm)
        }))
    };
    PattingTable3 {
        gp_prior: method("gp_prior"),
        gp_sphere: method("gp_sphere"),
        nonprob: method("nonprob"),
        prior: method("prior"),
    }
}

fn summary(pairs: &[PatPairReport]) -> PattingSummary {
    let surfaces = |f: fn(&PatPairReport) -> Option<&SceneReport>| -> Vec<Option<&SceneReport>> {
        pairs.iter().map(f).collect()
    };
    let pats_without = |f: fn(&PatPairReport) -> &PatContactResult| {
        pairs
            .iter()
            .map(|p| f(p).pats_without_contact)
            .sum::<usize>()
    };
    PattingSummary {
        table2: PattingTable2 {
            dgcnn_ucd_mm: spread(pairs.iter().map(|p| p.dgcnn.ucd_mm)),
            knn_all_ucd_mm: spread(pairs.iter().map(|p| p.knn_all.ucd_mm)),
            physics_ucd_mm: spread(pairs.iter().map(|p| p.physics.ucd_mm)),
            physics_pats_without_contact: pats_without(|p| &p.physics),
            true_contacts_ucd_mm: spread(pairs.iter().map(|p| p.truth.ucd_mm)),
            dgcnn_pats_without_contact: pats_without(|p| &p.dgcnn),
            knn_all_pats_without_contact: pats_without(|p| &p.knn_all),
            pats: pairs.iter().map(|p| p.pats).sum::<usize>(),
        },
        table3_estimated: table3(&surfaces(|p| p.surfaces_estimated.as_ref())),
        table3_physics: table3(&surfaces(|p| p.surfaces_physics.as_ref())),
        table3_true_contacts: table3(&surfaces(|p| Some(&p.surfaces_true))),
    }
}

fn reconstruct_options(size: PattingSize) -> ReconstructOptions {
    match size {
        PattingSize::Full => ReconstructOptions::default(),
        PattingSize::Small => ReconstructOptions {
            max_grid_nodes: 24 * 24 * 24,
            vertex_variance: false,
            ..ReconstructOptions::default()
        },
    }
}

/// The hand of the patting study: the two-finger hand with the default finger.
///
/// # Errors
/// Never for the preset (its meshes are valid).
pub fn patting_hand() -> Result<HandModel, LabError> {
    Ok(HandModel::preset(
        HandPreset::TwoFinger,
        &FingerParams::default(),
    )?)
}

/// Checks that `knn` was built for `hand`: as many vertices per finger.
fn check_knn(knn: &KnnIndex, hand: &HandModel) -> Result<(), LabError> {
    let counts: Vec<usize> = hand
        .fingers()
        .iter()
        .map(|f| f.model.mesh().num_vertices())
        .collect();
    if knn.vertices_per_finger() == counts.as_slice() {
        Ok(())
    } else {
        Err(LabError::InvalidEvaluation {
            reason: format!(
                "the KNN index is of a hand with {:?} vertices per finger, the patting hand's has {counts:?}",
                knn.vertices_per_finger()
            ),
        })
    }
}

/// Writes `ply` as `dir/name.ply`, creating `dir`.
fn write_ply_in(dir: &Path, name: &str, ply: &PlyData) -> Result<(), LabError> {
    std::fs::create_dir_all(dir).map_err(|source| IoError::Io {
        path: dir.to_owned(),
        source,
    })?;
    Ok(moe_io::write_ply(&dir.join(format!("{name}.ply")), ply)?)
}

/// Everything about pair `k` of `body`; with `write`, its files go to that directory.
fn evaluate_pair(
    body: SceneKind,
    k: u64,
    pats: usize,
    options: &PattingStudyOptions,
    hand: &HandModel,
    knn: &KnnIndex,
    write: Option<&Path>,
) -> Result<PatPairReport, LabError> {
    let truth_seed = body_seed(body) + 10 * k;
    let prior_seed = truth_seed + 1;
    let episode = simulate_patting(body, truth_seed, pats, options.camera_seed)?;
    let dgcnn = load_contact_model(&options.model, hand)?;
    let threshold = dgcnn.threshold();
    let dgcnn_contacts = paper_pat_contacts(hand, &episode, &options.shape, dgcnn, threshold)?;
    let knn_contacts = paper_pat_contacts(hand, &episode, &options.shape, knn, 0.5)?;
    let physics_contacts = physics_pat_contacts(
        hand,
        &episode,
        &moe_physics::HandMaterial::default(),
        &options.physics,
    )?;
    let true_contacts = true_pat_contacts(&episode);
    let prior_level = match options.size {
        PattingSize::Full => 5,
        PattingSize::Small => 4,
    };
    let prior = body_mesh(body, prior_seed, prior_level)?;
    let surface = reconstruct_options(options.size);
    let put = |name: &str, ply: &PlyData| -> Result<(), LabError> {
        match write {
            Some(dir) => write_ply_in(dir, name, ply),
            None => Ok(()),
        }
    };
    put("truth", &PlyData::from_mesh(&episode.truth))?;
    put("prior", &PlyData::from_mesh(&prior))?;
    for (name, contacts) in [
        ("contacts_dgcnn", &dgcnn_contacts),
        ("contacts_knn_all", &knn_contacts),
        ("contacts_physics", &physics_contacts),
        ("contacts_true", &true_contacts),
    ] {
        put(name, &PlyData::from_points(&contacts.points_in_world))?;
    }
    // `noise_floor_m`: the GP's noise sd at least this (0 for the fit's own bound).
    let surfaces = |contacts: &PatContacts,
                    tag: &str,
                    noise_floor_m: Real|
     -> Result<Option<SceneReport>, LabError> {
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
            body,
            &scene,
            &surface,
            Some(NORMAL_OFFSET_M),
            (options.prior_gate_m > 0.0).then_some(options.prior_gate_m),
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
    let floor = options.estimated_noise_floor_m;
    let surfaces_estimated = surfaces(&dgcnn_contacts, "estimated", floor)?;
    let surfaces_physics = surfaces(&physics_contacts, "physics", floor)?;
    let surfaces_true = surfaces(&true_contacts, "true_contacts", 0.0)?.ok_or_else(|| {
        LabError::InvalidEvaluation {
            reason: "the simulated pats touched nothing".into(),
        }
    })?;
    Ok(PatPairReport {
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

/// Runs the patting study with the two-finger hand ([`patting_hand`]) and the `KNN[All]`
/// index `knn` (built for that hand), calling `after_pair` with each body, pair number and
/// pair report as it is done (to report progress; its error ends the study).
///
/// # Errors
/// An estimated noise floor or prior gate that is not a distance, an index of another hand,
/// a model that cannot be loaded, a failing simulation, pipeline or reconstruction, a file
/// that cannot be written, or `after_pair`'s error.
pub fn run_patting_study<E: From<LabError>>(
    options: &PattingStudyOptions,
    knn: &KnnIndex,
    mut after_pair: impl FnMut(SceneKind, u64, &PatPairReport) -> Result<(), E>,
) -> Result<PattingStudyReport, E> {
    let size = options.size;
    let pairs = options.pairs.unwrap_or(match size {
        PattingSize::Full => 3,
        PattingSize::Small => 1,
    });
    let bodies = if options.bodies.is_empty() {
        vec![SceneKind::Head, SceneKind::Arm]
    } else {
        options.bodies.clone()
    };
    check_distances(options)?;
    let hand = patting_hand()?;
    check_knn(knn, &hand)?;
    let mut out = Vec::new();
    for body in bodies {
        let pats = match size {
            PattingSize::Full => pats_of(body),
            PattingSize::Small => SMALL_PATS,
        };
        let mut reports = Vec::new();
        for k in 0..pairs {
            let dir = options
                .out
                .as_ref()
                .filter(|_| k == 0)
                .map(|d| d.join(body_name(body)));
            let report = evaluate_pair(body, k, pats, options, &hand, knn, dir.as_deref())?;
            after_pair(body, k, &report)?;
            reports.push(report);
        }
        out.push(PattingBodyReport {
            body,
            summary: summary(&reports),
            pairs: reports,
        });
    }
    Ok(PattingStudyReport {
        size,
        pairs,
        knn_index_frames: knn.len(),
        prior_gate_m: options.prior_gate_m,
        estimated_noise_floor_m: options.estimated_noise_floor_m,
        bodies: out,
    })
}

/// Checks the noise floor and the prior gate before any work.
///
/// # Errors
/// [`LabError::Surface`] for a noise floor the GP's bounds refuse,
/// [`LabError::InvalidEvaluation`] for a prior gate that is not a distance.
pub fn check_distances(options: &PattingStudyOptions) -> Result<(), LabError> {
    HyperBounds::default().with_noise_floor(options.estimated_noise_floor_m)?;
    let gate = options.prior_gate_m;
    if !(gate.is_finite() && gate >= 0.0) {
        return Err(LabError::InvalidEvaluation {
            reason: format!("prior gate {gate} must be a distance in metres (0 for none)"),
        });
    }
    Ok(())
}
