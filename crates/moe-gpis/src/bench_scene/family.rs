//! Every method over a family of scenes: per-scene reports and per-method spreads.

use moe_geom::Real;
use serde::{Deserialize, Serialize};

use super::evaluate::{MethodResult, SceneReport, evaluate_scene};
use super::scene::{BenchSceneConfig, SceneKind, build_scene};
use crate::error::GpisError;
use crate::reconstruct::ReconstructOptions;

/// Mean and sample standard deviation of one figure over the scenes of a family.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// Mean.
    pub mean: Real,
    /// Sample standard deviation (0 for one scene).
    pub sd: Real,
}

impl Spread {
    fn of(values: &[Real]) -> Self {
        let n = values.len() as Real;
        let mean = values.iter().sum::<Real>() / n;
        let sd = if values.len() > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<Real>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Self { mean, sd }
    }
}

/// One method over a family of scenes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodSummary {
    /// Method name (as in [`MethodResult::method`]).
    pub method: String,
    /// Scenes where the method ran.
    pub runs: usize,
    /// Scenes where it failed (left out of the figures).
    pub failures: usize,
    /// UCD reconstruction → truth, mm.
    pub ucd_mm: Spread,
    /// Bidirectional Chamfer distance, mm.
    pub bcd_mm: Spread,
    /// Scenes where this method had the lowest UCD of all methods.
    pub best_ucd: usize,
}

/// Every method on several scenes of one family: different people, different contacts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FamilyReport {
    /// Which family.
    pub scene: SceneKind,
    /// The per-scene reports, the base configuration's scene first.
    pub scenes: Vec<SceneReport>,
    /// One summary per method, in the order of [`SceneReport::methods`].
    pub summary: Vec<MethodSummary>,
}

/// Runs [`evaluate_scene`] on `pairs` scenes of `base`'s family: scene `k` adds `10 k` to each
/// of the base's seeds (truth, prior, contacts), so scene 0 is the base scene itself.
///
/// # Errors
/// `pairs == 0`, or any error of [`build_scene`] / [`evaluate_scene`] (a method failing on one
/// scene is counted in [`MethodSummary::failures`] instead).
pub fn evaluate_family(
    base: &BenchSceneConfig,
    pairs: usize,
    surface: &ReconstructOptions,
    normal_offset_m: Option<Real>,
) -> Result<FamilyReport, GpisError> {
    if pairs == 0 {
        return Err(GpisError::TooFewObservations {
            method: "benchmark",
            what: "scene pairs",
            needed: 1,
            got: 0,
        });
    }
    let mut scenes = Vec::with_capacity(pairs);
    for k in 0..pairs as u64 {
        let config = BenchSceneConfig {
            truth_seed: base.truth_seed + 10 * k,
            prior_seed: base.prior_seed + 10 * k,
            contact_seed: base.contact_seed + 10 * k,
            ..*base
        };
        let scene = build_scene(&config)?;
        scenes.push(evaluate_scene(base.kind, &scene, surface, normal_offset_m)?);
    }
    let names: Vec<String> = scenes[0].methods.iter().map(|m| m.method.clone()).collect();
    let summary = names
        .iter()
        .map(|name| {
            let ok: Vec<&MethodResult> = scenes
                .iter()
                .filter_map(|s| s.method(name))
                .filter(|m| m.error.is_none())
                .collect();
            let ucd: Vec<Real> = ok.iter().map(|m| m.ucd_mm).collect();
            let bcd: Vec<Real> = ok.iter().map(|m| m.bcd_mm).collect();
            let best_ucd = scenes
                .iter()
                .filter(|s| {
                    let best = s
                        .methods
                        .iter()
                        .filter(|m| m.error.is_none())
                        .min_by(|a, b| a.ucd_mm.total_cmp(&b.ucd_mm));
                    best.is_some_and(|m| &m.method == name)
                })
                .count();
            let nan = Spread {
                mean: Real::NAN,
                sd: Real::NAN,
            };
            MethodSummary {
                method: name.clone(),
                runs: ok.len(),
                failures: scenes.len() - ok.len(),
                ucd_mm: if ok.is_empty() { nan } else { Spread::of(&ucd) },
                bcd_mm: if ok.is_empty() { nan } else { Spread::of(&bcd) },
                best_ucd,
            }
        })
        .collect();
    Ok(FamilyReport {
        scene: base.kind,
        scenes,
        summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_is_the_sample_mean_and_deviation() {
        let s = Spread::of(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(s.mean, 2.5);
        assert!((s.sd - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(Spread::of(&[7.0]), Spread { mean: 7.0, sd: 0.0 });
    }
}
