//! The MOE-Touch laboratory: what reproduces the paper and makes data, as library code.
//!
//! - [`datagen`]: sharded, resumable, deterministic data set generation with the tendon FEM
//!   simulator; [`episode`]: recording simulated episodes (rendered wrist-camera frames with
//!   their ground truth).
//! - The studies, each a function with typed options and a typed `Serialize` report that the
//!   `moe-touch eval` commands print: [`contact_eval`] (paper Tables 1–2, the plate experiments
//!   and the one registry of the paper's plate scenes), [`physics_eval`] and [`physics_study`]
//!   (contact from physics scored as tactile sensors are specified), [`markers`] (marker
//!   perception against the ground truth), [`labels`] (contact-label rules),
//!   [`observability`] (the Cramér–Rao bound per marker layout), [`surface_eval`] (occluded
//!   surfaces), [`patting`] and [`grasp`] (the applications; [`grasp::fit_grasp_plane`] is the
//!   grasp's plane rule, a pure function a robot calls with its own frame estimates).
//! - [`run`] (the pipeline over a recorded episode, scored where the episode has ground truth),
//!   [`training`] (a contact model from data sets: [`training::TrainingRun`]),
//!   [`calibration_streams`] (contact-free streams for calibration), [`contact_output`] and
//!   [`point_cloud`] (what `moe-touch contact` writes and runs).
//! - What the file commands do, each with a typed report, its summary lines and its output
//!   files: [`contact_job`] (`contact`), [`surface_job`] (`surface`), [`hand_job`] (`hand`),
//!   [`shape_job`] (`arap`, `shape`), [`marker_job`] (`markers`), [`plane_job`] (`plane`); the
//!   keypoints file they share ([`keypoints_file`]) and the output files written together
//!   ([`output_files::OutputFiles`]).
//!
//! Architecture invariant: the runtime (`moe-touch`) never depends on this crate; this crate
//! may use the simulator. Nothing here parses command lines or prints.

/// The contact-free streams a material calibration fits, from an episode or a data set.
pub mod calibration_streams;
/// The simulation study of contact estimation (paper Tables 1–2).
pub mod contact_eval;
/// Contact from files as `moe-touch contact` runs it: the network on a point cloud or a hand
/// shape, or physics on one frame; typed records, summaries and output files.
pub mod contact_job;
/// What `moe-touch contact` writes of one estimate: coloured meshes, records, `contacts.csv`.
pub mod contact_output;
/// Sharded, resumable, deterministic data set generation.
pub mod datagen;
/// `moe-touch demo`: the pipeline on the built-in example episode and what the demo writes.
pub mod demo;
/// Drawing on images: pixels, lines, a bitmap font, labels that do not overlap, meshes coloured
/// by contact probability.
pub mod draw;
/// Recording simulated episodes (rendered camera frames with ground truth).
pub mod episode;
/// The crate's error type.
pub mod error;
/// Small SVG figures written by hand (the plate errors per region).
pub mod figure;
/// Golden fixtures: committed reference results of the numerical stages, how each is
/// recomputed, compared and rewritten.
pub mod golden;
/// Grasping paper on an unknown incline: press, fit the plane, reorient, press again.
pub mod grasp;
/// A hand model's files (`moe-touch hand`): rest meshes, vertex ids, measures and the bound of a
/// press's place on finger 0.
pub mod hand_job;
/// The keypoints file: one frame's markers in the hand frame, read, checked and written.
pub mod keypoints_file;
/// What each contact-label rule labels, and whether the finger's deformation can show it.
pub mod labels;
/// Marker tracking over a recorded episode (`moe-touch markers`): keypoints lines and a report.
pub mod marker_job;
/// Marker perception scored against an episode's ground truth.
pub mod markers;
/// The Cramér–Rao bound of a press's place and force for each marker layout of the study.
pub mod observability;
/// A command's output files, made in memory and written together.
pub mod output_files;
/// Marker detections and contact points drawn over camera frames.
pub mod overlay;
/// Patting a hidden body: simulated pats, contacts from the pipeline, and their error.
pub mod patting;
/// Contact from physics evaluated as tactile sensors are specified (detection, location and
/// force by the finger's true force), beside the paper's metrics.
pub mod physics_eval;
/// `eval physics` as one call: frames, calibration, the physics study and its typed report.
pub mod physics_study;
/// A plane fitted to points by RANSAC (`moe-touch plane`) with its report.
pub mod plane_job;
/// The contact network on a bare point cloud (no hand), to check a model file.
pub mod point_cloud;
/// Running the pipeline over a recorded episode, scored against its ground truth.
pub mod run;
/// SR-ARAP on files: any mesh toward a constraints file's targets (`moe-touch arap`), a hand
/// from one frame of keypoints (`moe-touch shape`).
pub mod shape_job;
/// A scripted scene's run written out: meshes per saved frame with a summary, or an episode.
pub mod sim_output;
/// Long runs: an episode looped for thousands of frames with gaps, resets and refused frames;
/// memory and frame times window by window.
pub mod soak;
/// The occluded-surface reconstruction benchmark (paper Table 3) with its typed report.
pub mod surface_eval;
/// An occluded surface from contact points in files (`moe-touch surface`) with its report.
pub mod surface_job;
/// Training a contact model on generated data sets.
pub mod training;

pub use error::LabError;

/// The `q` quantile of `sorted` (ascending) by nearest rank, rounded up: the `⌈q·n⌉`-th value,
/// so the 99th percentile of fewer than 100 values is the largest. `None` for no values.
pub(crate) fn nearest_rank<T: Copy>(sorted: &[T], q: f64) -> Option<T> {
    let n = sorted.len();
    (n > 0).then(|| sorted[((q * n as f64).ceil() as usize).clamp(1, n) - 1])
}

/// What running each item of a study gave: the results of the items that ran, in order, the
/// items that failed (id and error message), and the first error itself.
pub(crate) struct EachRun<T> {
    pub(crate) ran: Vec<T>,
    pub(crate) failed: Vec<(u64, String)>,
    pub(crate) first_error: Option<LabError>,
}

/// Runs `run` on every id, going on past the ones that fail: a study's trajectories or trials,
/// of which one failing must not lose the others.
pub(crate) fn run_each<T>(
    ids: impl IntoIterator<Item = u64>,
    mut run: impl FnMut(u64) -> Result<T, LabError>,
) -> EachRun<T> {
    let mut each = EachRun {
        ran: Vec::new(),
        failed: Vec::new(),
        first_error: None,
    };
    for id in ids {
        match run(id) {
            Ok(t) => each.ran.push(t),
            Err(e) => {
                each.failed.push((id, e.to_string()));
                each.first_error.get_or_insert(e);
            }
        }
    }
    each
}

/// `n` and `noun`, plural unless `n` is 1 ("1 load", "2 loads"), as the report tables say it.
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// `value` as JSON without the fields named `keys`, at any depth: a report as a golden fixture
/// holds it, without what depends on the machine (wall times, counts of machine-made meshes).
///
/// # Errors
/// [`LabError::InvalidEvaluation`] for a value that does not serialise to JSON (a non-finite
/// float serialises as `null` and is kept).
pub fn without_keys<T: serde::Serialize>(
    value: &T,
    keys: &[&str],
) -> Result<serde_json::Value, LabError> {
    fn strip(v: &mut serde_json::Value, keys: &[&str]) {
        match v {
            serde_json::Value::Object(o) => {
                o.retain(|k, _| !keys.contains(&k.as_str()));
                o.values_mut().for_each(|v| strip(v, keys));
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(|v| strip(v, keys)),
            _ => {}
        }
    }
    let mut v = serde_json::to_value(value).map_err(|e| LabError::InvalidEvaluation {
        reason: format!("a report as JSON: {e}"),
    })?;
    strip(&mut v, keys);
    Ok(v)
}

#[cfg(test)]
mod tests {
    #[test]
    fn without_keys_drops_the_named_fields_at_every_depth_and_keeps_the_rest() {
        let report = serde_json::json!({
            "secs": 1.5,
            "rows": [{"method": "a", "secs": 2.0, "bcd_mm": 0.5}],
            "nested": {"inner": {"secs": 3.0, "frames": 7}},
        });
        let v = crate::without_keys(&report, &["secs"]).unwrap();
        assert_eq!(
            v,
            serde_json::json!({
                "rows": [{"method": "a", "bcd_mm": 0.5}],
                "nested": {"inner": {"frames": 7}},
            })
        );
        assert_eq!(crate::without_keys(&report, &[]).unwrap(), report);
    }
}
