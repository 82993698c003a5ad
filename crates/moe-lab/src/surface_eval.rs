//! The occluded-surface reconstruction benchmark of `moe_gpis::bench_scene` (paper §6.1, Table
//! 3) on the procedural head and the 2:20:1 arm: UCD from each reconstruction to the ground
//! truth for GP + prior, GP + sphere, the non-probabilistic baseline and the prior itself, plus
//! runtimes, each scene family on several truth/prior/contact seed triples.

use std::fmt::Write as _;
use std::path::PathBuf;

use moe_gpis::ReconstructOptions;
use moe_gpis::bench_scene::{
    BenchSceneConfig, FamilyReport, SceneKind, SceneReport, build_scene, evaluate_family,
    evaluate_scene_with,
};
use moe_io::PlyData;
use serde::Serialize;

use crate::error::LabError;

/// Offset of the ±d points along the mean's normals at each contact (metres).
pub const NORMAL_OFFSET_M: f64 = 0.005;

/// Size of the benchmark.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SurfaceBenchSize {
    /// Level-4 meshes, 20 contacts per patch, a 32³ grid: the golden-checked configuration.
    Small,
    /// Level-5 meshes, 50 (head) / 35 (arm) contacts per patch, a 64³ grid: the reported one.
    Full,
}

/// Options of [`evaluate_surfaces`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceEvalOptions {
    /// The benchmark's size.
    pub size: SurfaceBenchSize,
    /// Scenes per family (default 8 at full size, 1 at small size).
    pub pairs: Option<usize>,
    /// Standard deviation of the contact noise, metres (default: the scene's, 1 mm).
    pub noise_m: Option<f64>,
}

/// The benchmark's report (`moe-touch eval surface --json`).
#[derive(Debug, Clone, Serialize)]
pub struct SurfaceEvalReport {
    /// The benchmark's size.
    pub size: SurfaceBenchSize,
    /// Each family: its scenes' reports (the first scene's is the table) and the summary.
    pub families: Vec<FamilyReport>,
}

impl SurfaceEvalReport {
    /// The report as the tables `moe-touch eval surface` prints: per family, its first scene
    /// (every method's Chamfer distances, times and vertices) and, over several scenes, every
    /// method's mean ± sd and how often it was the best; a blank line after each family.
    pub fn table(&self) -> String {
        let mut s = String::new();
        for f in &self.families {
            scene_table(&mut s, &f.scenes[0]);
            if f.scenes.len() > 1 {
                family_table(&mut s, f);
            }
            s.push('\n');
        }
        s
    }
}

/// One scene's table.
fn scene_table(s: &mut String, r: &SceneReport) {
    let _ = writeln!(
        s,
        "scene {:?}: {} contacts, {} grid nodes (UCD = reconstruction -> truth, the paper's metric; back = truth -> reconstruction)",
        r.scene, r.contacts, r.grid_nodes
    );
    let _ = writeln!(
        s,
        "  {:<10} {:>9} {:>9} {:>9} {:>10} {:>10} {:>9}",
        "method", "UCD mm", "back mm", "BCD mm", "time ms", "var ms", "vertices"
    );
    for m in &r.methods {
        if let Some(e) = &m.error {
            let _ = writeln!(s, "  {:<10} failed: {e}", m.method);
            continue;
        }
        let _ = writeln!(
            s,
            "  {:<10} {:>9.3} {:>9.3} {:>9.3} {:>10.1} {:>10.1} {:>9}",
            m.method,
            m.ucd_mm,
            m.ucd_truth_to_recon_mm,
            m.bcd_mm,
            1e3 * m.secs,
            1e3 * m.variance_secs,
            m.vertices
        );
    }
}

/// A family's summary over its scenes.
fn family_table(s: &mut String, f: &FamilyReport) {
    let _ = writeln!(
        s,
        "family {:?}: {} scenes (seeds +0, +10, ...), mean ± sd",
        f.scene,
        f.scenes.len()
    );
    let _ = writeln!(
        s,
        "  {:<10} {:>15} {:>15} {:>9} {:>8}",
        "method", "UCD mm", "BCD mm", "best UCD", "failed"
    );
    for m in &f.summary {
        let _ = writeln!(
            s,
            "  {:<10} {:>7.2} ± {:<5.2} {:>7.2} ± {:<5.2} {:>9} {:>8}",
            m.method,
            m.ucd_mm.mean,
            m.ucd_mm.sd,
            m.bcd_mm.mean,
            m.bcd_mm.sd,
            m.best_ucd,
            m.failures
        );
    }
}

/// The scene and surface configurations of a benchmark size, with the contact noise (metres)
/// overridden when given.
fn configs(
    size: SurfaceBenchSize,
    noise_m: Option<f64>,
) -> Vec<(BenchSceneConfig, ReconstructOptions)> {
    [BenchSceneConfig::head(), BenchSceneConfig::arm()]
        .into_iter()
        .map(|base| BenchSceneConfig {
            noise_m: noise_m.unwrap_or(base.noise_m),
            ..base
        })
        .map(|base| match size {
            SurfaceBenchSize::Full => (base, ReconstructOptions::default()),
            SurfaceBenchSize::Small => (
                BenchSceneConfig {
                    mesh_level: 4,
                    contacts_per_patch: 20,
                    ..base
                },
                ReconstructOptions {
                    max_grid_nodes: 32 * 32 * 32,
                    vertex_variance: false,
                    ..ReconstructOptions::default()
                },
            ),
        })
        .collect()
}

/// The benchmark: every family (head, arm), `pairs` scenes each.
///
/// # Errors
/// A scene that cannot be built or a reconstruction that fails outright.
pub fn evaluate_surfaces(options: &SurfaceEvalOptions) -> Result<SurfaceEvalReport, LabError> {
    let pairs = options.pairs.unwrap_or(match options.size {
        SurfaceBenchSize::Full => 8,
        SurfaceBenchSize::Small => 1,
    });
    let families = configs(options.size, options.noise_m)
        .iter()
        .map(|(scene, surface)| {
            Ok(evaluate_family(
                scene,
                pairs,
                surface,
                Some(NORMAL_OFFSET_M),
            )?)
        })
        .collect::<Result<_, LabError>>()?;
    Ok(SurfaceEvalReport {
        size: options.size,
        families,
    })
}

/// Each family's first scene to look at: the truth, the contacts and every method's surface
/// (PLY, with the posterior `variance` and `std` for the GP methods whatever the size), each
/// named `<scene>/<name>.ply`, in memory.
///
/// # Errors
/// A scene or reconstruction that fails.
pub fn surface_meshes(
    size: SurfaceBenchSize,
    noise_m: Option<f64>,
) -> Result<Vec<(PathBuf, PlyData)>, LabError> {
    let mut meshes = Vec::new();
    for (config, surface) in configs(size, noise_m) {
        let scene = build_scene(&config)?;
        let sub = PathBuf::from(format!("{:?}", config.kind).to_lowercase());
        let name = |n: &str| sub.join(format!("{n}.ply"));
        meshes.push((name("truth"), PlyData::from_mesh(&scene.truth)));
        meshes.push((name("contacts"), PlyData::from_points(&scene.contacts)));
        let surface = ReconstructOptions {
            vertex_variance: true,
            ..surface
        };
        evaluate_scene_with(
            config.kind,
            &scene,
            &surface,
            Some(NORMAL_OFFSET_M),
            None,
            &mut |n, mesh, variance| {
                meshes.push((name(n), PlyData::with_variance(mesh, variance)));
            },
        )?;
    }
    Ok(meshes)
}

/// One method of a scene of [`SurfaceFixture`], Chamfer figures rounded to µm.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurfaceFixtureMethod {
    /// The method.
    pub method: String,
    /// UCD, reconstruction to truth, mm.
    pub ucd_mm: f64,
    /// UCD, truth to reconstruction, mm.
    pub ucd_truth_to_recon_mm: f64,
    /// BCD, mm.
    pub bcd_mm: f64,
}

/// One scene of [`SurfaceFixture`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurfaceFixtureScene {
    /// Which scene.
    pub scene: SceneKind,
    /// Number of contacts.
    pub contacts: usize,
    /// Grid nodes of the reconstruction.
    pub grid_nodes: usize,
    /// Every method.
    pub methods: Vec<SurfaceFixtureMethod>,
}

/// The golden content of the small benchmark with one pair: Chamfer figures rounded to µm
/// (timings and vertex counts are left out: they depend on the machine).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurfaceFixture {
    /// The first scene of each family.
    pub scenes: Vec<SurfaceFixtureScene>,
}

/// [`SurfaceFixture`] of the small benchmark with one pair.
///
/// # Errors
/// As [`evaluate_surfaces`].
pub fn surface_fixture() -> Result<SurfaceFixture, LabError> {
    let report = evaluate_surfaces(&SurfaceEvalOptions {
        size: SurfaceBenchSize::Small,
        pairs: Some(1),
        noise_m: None,
    })?;
    let round3 = |v: f64| (v * 1e3).round() / 1e3;
    let scenes = report
        .families
        .iter()
        .map(|f| {
            let r = &f.scenes[0];
            SurfaceFixtureScene {
                scene: r.scene,
                contacts: r.contacts,
                grid_nodes: r.grid_nodes,
                methods: r
                    .methods
                    .iter()
                    .map(|m| SurfaceFixtureMethod {
                        method: m.method.to_string(),
                        ucd_mm: round3(m.ucd_mm),
                        ucd_truth_to_recon_mm: round3(m.ucd_truth_to_recon_mm),
                        bcd_mm: round3(m.bcd_mm),
                    })
                    .collect(),
            }
        })
        .collect();
    Ok(SurfaceFixture { scenes })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each family's first scene gives the truth, the contacts and every method's closed
    /// surface, the GP with the prior's with its posterior variance.
    #[test]
    fn surface_meshes_are_closed_with_their_variance() {
        let meshes = surface_meshes(SurfaceBenchSize::Small, None).unwrap();
        let find = |path: &PathBuf| meshes.iter().find(|(p, _)| p == path).map(|(_, ply)| ply);
        for scene in ["head", "arm"] {
            for name in ["truth", "prior", "gp_prior", "nonprob"] {
                let path = PathBuf::from(scene).join(format!("{name}.ply"));
                let ply = find(&path).unwrap_or_else(|| panic!("{}", path.display()));
                let has_variance = ply.scalar("variance").is_some();
                assert_eq!(has_variance, name == "gp_prior", "{}", path.display());
                ply.clone().into_mesh().unwrap().require_closed().unwrap();
            }
            let contacts = find(&PathBuf::from(scene).join("contacts.ply")).unwrap();
            assert!(contacts.faces.is_empty() && contacts.points.len() >= 120);
        }
    }
}
