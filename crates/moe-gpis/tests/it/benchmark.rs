//! The occluded-surface benchmark's ordering (paper Table 3) at the golden-checked small size:
//! the GP with the task prior beats the prior itself and both baselines on the head, and the
//! prior and the non-probabilistic baseline on the 2:20:1 arm.

use moe_gpis::ReconstructOptions;
use moe_gpis::bench_scene::{BenchSceneConfig, SceneReport, evaluate_family};

fn small(base: BenchSceneConfig) -> SceneReport {
    let scene = BenchSceneConfig {
        mesh_level: 4,
        contacts_per_patch: 20,
        ..base
    };
    let surface = ReconstructOptions {
        max_grid_nodes: 32 * 32 * 32,
        vertex_variance: false,
        ..ReconstructOptions::default()
    };
    let family = evaluate_family(&scene, 1, &surface, Some(0.005)).unwrap();
    assert_eq!(family.summary.len(), 4);
    family.scenes.into_iter().next().unwrap()
}

fn ucd(report: &SceneReport, method: &str) -> f64 {
    let m = report.method(method).unwrap();
    assert!(m.error.is_none(), "{method}: {:?}", m.error);
    m.ucd_mm
}

#[test]
fn gp_with_the_task_prior_is_ahead_of_the_baselines_on_the_head() {
    let r = small(BenchSceneConfig::head());
    let gp = ucd(&r, "gp_prior");
    assert!(gp < 3.6, "GP + prior UCD {gp} mm (paper 3.64 mm)");
    for other in ["prior", "gp_sphere", "nonprob"] {
        let o = ucd(&r, other);
        assert!(gp < 0.8 * o, "gp_prior {gp} mm vs {other} {o} mm");
    }
}

#[test]
fn gp_with_the_task_prior_is_ahead_on_the_arm() {
    let r = small(BenchSceneConfig::arm());
    let gp = ucd(&r, "gp_prior");
    for other in ["prior", "nonprob"] {
        let o = ucd(&r, other);
        assert!(gp < 0.8 * o, "gp_prior {gp} mm vs {other} {o} mm");
    }
}
