//! What each contact-label rule labels, and whether the finger's deformation can show it.
//!
//! Every trajectory of a randomised data set is simulated twice: as generated, and as its
//! *free twin* — the same wrist motion and tendon schedule with the obstacle removed. The
//! difference between the two surfaces at the same instant (hand frame) is the deformation the
//! contact causes, the only signal a shape-based estimator has. For each rule
//! [`run_label_study`](crate::labels::run_label_study) counts, over all frames: labelled
//! vertices, frames with a label, connected patches of labelled vertices (mesh edges) and how
//! many are single vertices, labels on vertices held by the fixed base, and labelled frames
//! whose markers moved less than 0.1 mm from the twin's (the "no visible deformation" frames),
//! plus the same with every surface vertex instead of the markers.

use std::fmt::Write as _;

use moe_geom::{Real, Topology};
use moe_tendon_sim::randomize::{RandomSceneParams, sample_scene};
use moe_tendon_sim::{LabelRule, Scene, SimFrame, SurfaceContact, contact_labels, run_saving};
use serde::Serialize;

use crate::LabError;

/// Deformation below which a labelled frame counts as showing nothing, metres.
pub const VISIBLE_DEFORMATION_M: Real = 1e-4;

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

/// What one rule labelled over the study's frames.
#[derive(Debug, Default, Clone, PartialEq, Serialize)]
pub struct RuleStats {
    /// The rule.
    pub rule: &'static str,
    /// Frames (each finger's surface in one saved instant).
    pub frames: u64,
    /// Surface vertices over the frames.
    pub vertices: u64,
    /// Labelled vertices over the frames.
    pub labelled_vertices: u64,
    /// Frames with a label.
    pub labelled_frames: u64,
    /// Connected patches of labelled vertices (along mesh edges).
    pub patches: u64,
    /// Patches of one vertex.
    pub single_vertex_patches: u64,
    /// Labels on vertices held by the fixed base.
    pub labels_on_base: u64,
    /// Labelled frames whose markers all moved < 0.1 mm from the free twin's.
    pub frames_markers_still: u64,
    /// Labelled frames whose every surface vertex moved < 0.1 mm from the free twin's.
    pub frames_surface_still: u64,
    /// Sum over labelled frames of the largest marker deformation, metres (for the mean).
    pub sum_marker_deformation_m: Real,
}

/// Settings of the label study.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LabelStudyOptions {
    /// Trajectories to simulate (each twice).
    pub trajectories: u64,
    /// Seed of the randomised scenes (the data set seed).
    pub seed: u64,
}

/// The label study's report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LabelStudyReport {
    /// Seed of the randomised scenes.
    pub seed: u64,
    /// Trajectories simulated (both runs finished).
    pub trajectories: u64,
    /// Trajectories skipped because a run diverged.
    pub failed: u64,
    /// [`VISIBLE_DEFORMATION_M`].
    pub visible_deformation_m: Real,
    /// Every rule, in the study's order.
    pub rules: Vec<RuleStats>,
}

impl LabelStudyReport {
    /// The report as the table `moe-touch eval labels` prints: one row per rule (labelled
    /// vertices, frames with a label, patches, labels on the base, still frames, mean marker
    /// deformation) and a legend.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "label rules on {} trajectories of seed {} ({} diverged and skipped)",
            self.trajectories, self.seed, self.failed
        );
        let _ = writeln!(
            s,
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
        for r in &self.rules {
            let lf = r.labelled_frames.max(1) as Real;
            let _ = writeln!(
                s,
                "{:<26} {:>8.3}% {:>8.1}% {:>8.1} {:>8} {:>8} {:>8} {:>8.1}% {:>8.1}% {:>9.3}",
                r.rule,
                100.0 * r.labelled_vertices as Real / r.vertices.max(1) as Real,
                100.0 * r.labelled_frames as Real / r.frames.max(1) as Real,
                r.labelled_vertices as Real / lf,
                r.patches,
                r.single_vertex_patches,
                r.labels_on_base,
                100.0 * r.frames_markers_still as Real / lf,
                100.0 * r.frames_surface_still as Real / lf,
                1e3 * r.sum_marker_deformation_m / lf,
            );
        }
        let _ = writeln!(
            s,
            "ratio: labelled vertices; frames: frames with a label; single: one-vertex patches; \
             still: labelled frames whose markers (mk) or whole surface (sf) moved < {} mm from \
             the obstacle-free twin; mk def: mean largest marker deformation of labelled frames",
            VISIBLE_DEFORMATION_M * 1e3
        );
        s
    }
}

/// Runs the label study: each trajectory and its free twin simulated and every frame tallied
/// under each rule; `progress` is told the trajectories done (of
/// [`LabelStudyOptions::trajectories`]) after each simulated one. A trajectory either of whose
/// runs diverges is skipped and counted in [`LabelStudyReport::failed`].
///
/// # Errors
/// A scene that cannot be sampled or built.
pub fn run_label_study(
    options: &LabelStudyOptions,
    mut progress: impl FnMut(u64),
) -> Result<LabelStudyReport, LabError> {
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
    for t in 0..options.trajectories {
        let sampled = sample_scene(&params, options.seed, t)?;
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
        progress(t + 1);
    }
    Ok(LabelStudyReport {
        seed: options.seed,
        trajectories: simulated,
        failed,
        visible_deformation_m: VISIBLE_DEFORMATION_M,
        rules: stats,
    })
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
            s.frames_markers_still += u64::from(marker_def < VISIBLE_DEFORMATION_M);
            s.frames_surface_still += u64::from(surface_def < VISIBLE_DEFORMATION_M);
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

    /// Two trajectories (the first touches nothing): every rule sees the same frames and
    /// vertices, and the force rules label fewer vertices and frames the higher their threshold
    /// (each labels a subset of the one before: penetration anywhere, then ≥ 1, 10, 50 mN on
    /// the movable vertices).
    #[test]
    fn the_force_rules_nest_by_threshold() {
        let options = LabelStudyOptions {
            trajectories: 2,
            seed: 11,
        };
        let mut done = Vec::new();
        let report = run_label_study(&options, |t| done.push(t)).unwrap();
        assert_eq!(report.trajectories + report.failed, 2);
        assert_eq!(done.len() as u64, report.trajectories);
        assert_eq!(report.rules.len(), RULES.len());
        let first = &report.rules[0];
        for r in &report.rules {
            assert_eq!(
                (r.frames, r.vertices),
                (first.frames, first.vertices),
                "{}",
                r.rule
            );
            assert!(r.labelled_frames <= r.frames && r.single_vertex_patches <= r.patches);
        }
        let force = &report.rules[1..5];
        assert!(force.iter().all(|r| r.rule.contains("force")));
        assert!(
            force[0].labelled_vertices > 0,
            "the trajectories touch nothing"
        );
        for pair in force.windows(2) {
            assert!(
                pair[1].labelled_vertices <= pair[0].labelled_vertices
                    && pair[1].labelled_frames <= pair[0].labelled_frames,
                "{} vs {}",
                pair[1].rule,
                pair[0].rule
            );
        }
        // Only the rules that may label the base do.
        for (r, rule) in report.rules.iter().zip(&RULES) {
            assert!(rule.base_too || r.labels_on_base == 0, "{}", r.rule);
        }
    }
}
