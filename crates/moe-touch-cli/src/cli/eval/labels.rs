//! `moe-touch eval labels`: what each contact-label rule labels, and whether the finger's
//! deformation can show it.
//!
//! Every trajectory of a randomised data set is simulated twice: as generated, and as its
//! *free twin* — the same wrist motion and tendon schedule with the obstacle removed. The
//! difference between the two surfaces at the same instant (hand frame) is the deformation the
//! contact causes, the only signal a shape-based estimator has. For each rule the study counts,
//! over all frames: labelled vertices, frames with a label, connected patches of labelled
//! vertices (mesh edges) and how many are single vertices, labels on vertices held by the fixed
//! base, and labelled frames whose markers moved less than 0.1 mm from the twin's (the
//! "no visible deformation" frames), plus the same with every surface vertex instead of the
//! markers.

use anyhow::Result;
use clap::Args;
use moe_geom::{Real, Topology};
use moe_tendon_sim::randomize::{RandomSceneParams, sample_scene};
use moe_tendon_sim::{LabelRule, Scene, SimFrame, SurfaceContact, contact_labels, run_saving};
use serde::Serialize;
use serde_json::json;

/// Arguments of `moe-touch eval labels`.
#[derive(Debug, Args)]
pub(crate) struct LabelsEvalArgs {
    /// Trajectories to simulate (each twice).
    #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub(crate) trajectories: u64,
    /// Seed of the randomised scenes (the data set seed).
    #[arg(long, default_value_t = 11)]
    pub(crate) seed: u64,
    /// Print one JSON object on stdout instead of a table.
    #[arg(long)]
    pub(crate) json: bool,
}

/// Deformation below which a labelled frame counts as showing nothing, metres.
const VISIBLE_M: Real = 1e-4;

/// One labelling rule of the study.
#[derive(Debug, Clone, Copy)]
struct Rule {
    name: &'static str,
    rule: LabelRule,
    distance_m: Real,
    force_n: Real,
    /// Whether vertices held by the base may be labelled (the force rule's `movable` mask off).
    base_too: bool,
}

const RULES: [Rule; 9] = [
    Rule {
        name: "proximity < 1 mm",
        rule: LabelRule::Proximity,
        distance_m: 1e-3,
        force_n: 0.0,
        base_too: true,
    },
    Rule {
        name: "penetration (force > 0)",
        rule: LabelRule::Force,
        distance_m: 0.0,
        force_n: 0.0,
        base_too: true,
    },
    Rule {
        name: "force ≥ 1 mN, movable",
        rule: LabelRule::Force,
        distance_m: 0.0,
        force_n: 1e-3,
        base_too: false,
    },
    Rule {
        name: "force ≥ 10 mN, movable",
        rule: LabelRule::Force,
        distance_m: 0.0,
        force_n: 1e-2,
        base_too: false,
    },
    Rule {
        name: "force ≥ 50 mN, movable",
        rule: LabelRule::Force,
        distance_m: 0.0,
        force_n: 5e-2,
        base_too: false,
    },
    Rule {
        name: "press 0.5 mm, ≥ 10 mN",
        rule: LabelRule::Press,
        distance_m: 5e-4,
        force_n: 1e-2,
        base_too: false,
    },
    Rule {
        name: "press 0.5 mm, ≥ 50 mN",
        rule: LabelRule::Press,
        distance_m: 5e-4,
        force_n: 5e-2,
        base_too: false,
    },
    Rule {
        name: "press 1 mm, ≥ 10 mN",
        rule: LabelRule::Press,
        distance_m: 1e-3,
        force_n: 1e-2,
        base_too: false,
    },
    Rule {
        name: "press 1 mm, ≥ 50 mN",
        rule: LabelRule::Press,
        distance_m: 1e-3,
        force_n: 5e-2,
        base_too: false,
    },
];

#[derive(Debug, Default, Clone, Serialize)]
struct RuleStats {
    rule: &'static str,
    frames: u64,
    vertices: u64,
    labelled_vertices: u64,
    labelled_frames: u64,
    patches: u64,
    single_vertex_patches: u64,
    labels_on_base: u64,
    /// Labelled frames whose markers all moved < 0.1 mm from the free twin's.
    frames_markers_still: u64,
    /// Labelled frames whose every surface vertex moved < 0.1 mm from the free twin's.
    frames_surface_still: u64,
    /// Sum over labelled frames of the largest marker deformation, metres (for the mean).
    sum_marker_deformation_m: Real,
}

pub(crate) fn run(args: &LabelsEvalArgs) -> Result<()> {
    let params = RandomSceneParams::default();
    let mut stats: Vec<RuleStats> = RULES
        .iter()
        .map(|r| RuleStats {
            rule: r.name,
            ..RuleStats::default()
        })
        .collect();
    let mut simulated = 0u64;
    let mut failed = 0u64;
    for t in 0..args.trajectories {
        let sampled = sample_scene(&params, args.seed, t)?;
        let mut scene = Scene::new(sampled.config.clone())?;
        let mut free_config = sampled.config.clone();
        free_config.obstacles.clear();
        let mut free = Scene::new(free_config)?;
        let steps = scene.num_steps();
        let (Ok(frames), Ok(free_frames)) =
            (run_saving(&mut scene, steps), run_saving(&mut free, steps))
        else {
            failed += 1;
            continue;
        };
        simulated += 1;
        let topologies: Vec<Topology> = scene
            .hand()
            .fingers()
            .iter()
            .map(|f| Topology::new(f.model.mesh()))
            .collect();
        let movable: Vec<Vec<bool>> = scene
            .bodies()
            .iter()
            .map(|b| b.movable_surface_vertices().to_vec())
            .collect();
        for (f, g) in frames.iter().zip(&free_frames) {
            tally(&scene, f, g, &topologies, &movable, &mut stats);
        }
        eprint!("\r{}/{} trajectories", t + 1, args.trajectories);
    }
    eprintln!();
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({
                "seed": args.seed,
                "trajectories": simulated,
                "failed": failed,
                "visible_deformation_m": VISIBLE_M,
                "rules": stats,
            }))?
        );
        return Ok(());
    }
    println!(
        "label rules on {simulated} trajectories of seed {} ({failed} diverged and skipped)",
        args.seed
    );
    println!(
        "{:<26} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>9}",
        "rule",
        "ratio",
        "frames",
        "v/frame",
        "patches",
        "single",
        "on base",
        "mk still",
        "sf still",
        "mk def mm"
    );
    for s in &stats {
        let lf = s.labelled_frames.max(1) as Real;
        println!(
            "{:<26} {:>8.3}% {:>8.1}% {:>8.1} {:>8} {:>8} {:>8} {:>8.1}% {:>8.1}% {:>9.3}",
            s.rule,
            100.0 * s.labelled_vertices as Real / s.vertices.max(1) as Real,
            100.0 * s.labelled_frames as Real / s.frames.max(1) as Real,
            s.labelled_vertices as Real / lf,
            s.patches,
            s.single_vertex_patches,
            s.labels_on_base,
            100.0 * s.frames_markers_still as Real / lf,
            100.0 * s.frames_surface_still as Real / lf,
            1e3 * s.sum_marker_deformation_m / lf,
        );
    }
    println!(
        "ratio: labelled vertices; frames: frames with a label; single: one-vertex patches; \
         still: labelled frames whose markers (mk) or whole surface (sf) moved < {} mm from \
         the obstacle-free twin; mk def: mean largest marker deformation of labelled frames",
        VISIBLE_M * 1e3
    );
    Ok(())
}

fn tally(
    scene: &Scene,
    f: &SimFrame,
    free: &SimFrame,
    topologies: &[Topology],
    movable: &[Vec<bool>],
    stats: &mut [RuleStats],
) {
    let mut marker_def: Real = 0.0;
    let mut surface_def: Real = 0.0;
    for (i, (a, b)) in f.fingers.iter().zip(&free.fingers).enumerate() {
        let d = |v: usize| (a.vertices_in_hand[v] - b.vertices_in_hand[v]).norm();
        for &m in scene.hand().fingers()[i].model.marker_vertices() {
            marker_def = marker_def.max(d(m as usize));
        }
        for v in 0..a.vertices_in_hand.len() {
            surface_def = surface_def.max(d(v));
        }
    }
    for (rule, s) in RULES.iter().zip(stats.iter_mut()) {
        let params = moe_tendon_sim::ContactParams {
            label_rule: rule.rule,
            contact_distance_m: rule.distance_m,
            press_distance_m: rule.distance_m,
            label_force_n: rule.force_n,
            ..scene.contact_params().clone()
        };
        let mut any = false;
        s.frames += 1;
        for (i, finger) in f.fingers.iter().enumerate() {
            let contact = SurfaceContact {
                distances_m: finger.distances_m.clone(),
                forces_n: finger.contact_force_n.clone(),
                force_vectors_n: Vec::new(),
            };
            let all = vec![true; movable[i].len()];
            let mask = if rule.base_too { &all } else { &movable[i] };
            let labels = contact_labels(&contact, mask, &params);
            let n = labels.iter().filter(|&&l| l).count() as u64;
            s.vertices += labels.len() as u64;
            s.labelled_vertices += n;
            s.labels_on_base += labels
                .iter()
                .zip(&movable[i])
                .filter(|&(&l, &m)| l && !m)
                .count() as u64;
            any |= n > 0;
            for size in patch_sizes(&labels, &topologies[i]) {
                s.patches += 1;
                s.single_vertex_patches += u64::from(size == 1);
            }
        }
        if any {
            s.labelled_frames += 1;
            s.frames_markers_still += u64::from(marker_def < VISIBLE_M);
            s.frames_surface_still += u64::from(surface_def < VISIBLE_M);
            s.sum_marker_deformation_m += marker_def;
        }
    }
}

/// Sizes of the connected components of the labelled vertices along mesh edges.
fn patch_sizes(labels: &[bool], topology: &Topology) -> Vec<usize> {
    let mut seen = vec![false; labels.len()];
    let mut sizes = Vec::new();
    for start in 0..labels.len() {
        if !labels[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        let (mut stack, mut size) = (vec![start], 0);
        while let Some(v) = stack.pop() {
            size += 1;
            for &n in topology.neighbors(v) {
                let n = n as usize;
                if labels[n] && !seen[n] {
                    seen[n] = true;
                    stack.push(n);
                }
            }
        }
        sizes.push(size);
    }
    sizes
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::TriMesh;

    #[test]
    fn patches_are_edge_connected_components() {
        // A strip of four triangles: vertices 0..6, edges along and across.
        let mesh = TriMesh::new(
            (0..6)
                .map(|i| moe_geom::Point3::new(Real::from(i / 2), Real::from(i % 2), 0.0))
                .collect(),
            vec![[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4]],
        )
        .unwrap();
        let topo = Topology::new(&mesh);
        let labels = [true, false, false, false, true, true];
        let mut sizes = patch_sizes(&labels, &topo);
        sizes.sort_unstable();
        assert_eq!(sizes, vec![1, 2]);
        assert!(patch_sizes(&[false; 6], &topo).is_empty());
    }
}
