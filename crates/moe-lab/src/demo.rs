//! `moe-touch demo` as library code: the whole pipeline on the committed example episode, and
//! what the demo makes of it — the result file, the report, the meshes of the frame with the
//! most contact, a figure and a short table.
//!
//! The example episode, the shipped contact model and the physics settings for the episode's
//! occluding plate are built into the library, so that an installed `moe-touch` runs the demo
//! from any directory.

use std::fmt::Write as _;
use std::path::Path;

use image::{Rgb, RgbImage};
use moe_contact::DgcnnEstimator;
use moe_geom::nalgebra::{Matrix3, Rotation3};
use moe_geom::{
    CameraIntrinsics, HandEstimator, HandFromCamera, HandKeypoints, HandModel, Point3, Vector3,
};
use moe_io::PlyData;
use moe_record::{Episode, EpisodeFrame, RunFrame, RunInfo};
use moe_touch::Pipeline;

use crate::contact_eval::contact_ply;
use crate::draw::{OrthoView, ShadedMesh, arrow, render_meshes, text};
use crate::error::LabError;
use crate::overlay::draw_keypoints;
use crate::run::{
    DEFAULT_FORCE_ARROW_M_PER_N, FrameReport, RunDetails, RunReport, run_episode, run_info,
};

/// The committed example episode: a plate pressing the tip of finger 0 of the two-finger hand.
const EPISODE: &[u8] = include_bytes!("../../../fixtures/episodes/plate_tip_front_small.mcap");
/// The example episode's name in messages.
pub const EPISODE_NAME: &str = "fixtures/episodes/plate_tip_front_small.mcap (built in)";
/// The shipped contact model's weights.
const MODEL: &[u8] = include_bytes!("../../../models/contact-two-finger.safetensors");
/// The shipped contact model's card.
const MODEL_CARD: &str = include_str!("../../../models/contact-two-finger.json");
/// The shipped contact model's name in messages and the result.
pub const MODEL_NAME: &str = "contact-two-finger.safetensors";
/// The physics settings for the example episode, whose plate hides the pressed tip.
const OCCLUDING_SETTINGS: &str = include_str!("../../../fixtures/physics/occluding-contact.toml");
/// Their name in messages and the result.
pub const OCCLUDING_SETTINGS_NAME: &str = "fixtures/physics/occluding-contact.toml (built in)";

/// The built-in example episode, read.
///
/// # Errors
/// [`moe_io::IoError`] if the built-in recording does not read (it always does).
pub fn episode() -> Result<Episode, moe_io::IoError> {
    moe_record::parse_episode(Path::new(EPISODE_NAME), EPISODE)
}

/// The demo's hand: the two-finger preset with the default finger.
///
/// # Errors
/// [`moe_geom::GeomError`] if the preset does not build (it always does).
pub fn hand() -> Result<HandModel, moe_geom::GeomError> {
    HandModel::preset(
        moe_geom::HandPreset::TwoFinger,
        &moe_geom::FingerParams::default(),
    )
}

/// The built-in shipped contact model ([`MODEL_NAME`]) on `hand`.
///
/// # Errors
/// [`moe_contact::ContactError`] when `hand` is not the model's.
pub fn model(hand: &HandModel) -> Result<DgcnnEstimator, moe_contact::ContactError> {
    DgcnnEstimator::from_bytes(MODEL, MODEL_CARD, hand)
}

/// The built-in physics settings for the example episode ([`OCCLUDING_SETTINGS_NAME`]), read
/// but not validated.
///
/// # Errors
/// [`moe_io::IoError`] if the built-in file does not read (it always does).
pub fn occluding_settings() -> Result<moe_physics::PhysicsConfig, moe_io::IoError> {
    moe_io::parse_toml(
        OCCLUDING_SETTINGS.as_bytes(),
        Path::new(OCCLUDING_SETTINGS_NAME),
    )
}

/// What the demo makes of one run over an episode, in memory: everything it writes but the
/// figure's PNG encoding.
#[derive(Debug, Clone)]
pub struct DemoOutputs {
    /// The run's report (`report.json`).
    pub report: RunReport,
    /// The result file's description of the run.
    pub info: RunInfo,
    /// The result file's frames (`result.mcap`).
    pub frames: Vec<RunFrame>,
    /// The frame with the most estimated contact (the first of equals).
    pub best_frame: usize,
    /// That frame's finger meshes coloured by contact, by file name: the estimate of each
    /// finger and, where the episode has ground truth, the truth.
    pub meshes: Vec<(String, PlyData)>,
    /// The figure (`figure.png`): the camera frame with the markers found and the contact
    /// points, the estimated meshes coloured by contact probability with the force arrows, the
    /// true meshes coloured by the simulator's contact.
    pub figure: RgbImage,
}

/// Runs `pipeline` (on `hand`; `model_name` names its estimator in the result) over `episode`
/// and makes the demo's outputs of it. `None` when the episode has no frames.
///
/// # Errors
/// The run's errors ([`run_episode`]) and a frame whose images do not fit the camera.
pub fn run_demo<E>(
    hand: &HandModel,
    episode: &Episode,
    mut pipeline: Pipeline<E>,
    model_name: &str,
) -> Result<Option<DemoOutputs>, LabError>
where
    E: HandEstimator,
    E::Details: RunDetails,
{
    let intrinsics = *pipeline.detector().intrinsics();
    let hand_from_camera = pipeline.detector().hand_from_camera();
    let threshold = pipeline.threshold();
    let (frames, report) = run_episode(&mut pipeline, &episode.info, &episode.frames, None)?;

    let Some(best) = (0..frames.len())
        .max_by_key(|&k| (frames[k].contacts_in_world.len(), std::cmp::Reverse(k)))
    else {
        return Ok(None);
    };
    let frame = &frames[best];
    let truth_labels = frame
        .truth
        .as_ref()
        .map(|t| (t, true_labels(&t.vertices_in_hand, &t.contact_vertices)));
    let mut meshes = Vec::new();
    for f in 0..hand.num_fingers() {
        meshes.push((
            format!("frame_{best}_estimate_finger_{f}.ply"),
            contact_ply(
                hand,
                f,
                &frame.vertices_in_hand[f],
                &frame.contact_probability[f],
            )?,
        ));
        if let Some((truth, labels)) = &truth_labels {
            meshes.push((
                format!("frame_{best}_truth_finger_{f}.ply"),
                contact_ply(hand, f, &truth.vertices_in_hand[f], &labels[f])?,
            ));
        }
    }
    let figure = figure(
        hand,
        &intrinsics,
        hand_from_camera,
        frame,
        &episode.frames[best],
        &report.per_frame[best],
        best,
    )?;
    let mut info = run_info(&episode.info, model_name, threshold);
    info.force_arrow_m_per_n = report.forces.as_ref().map(|_| DEFAULT_FORCE_ARROW_M_PER_N);
    Ok(Some(DemoOutputs {
        report,
        info,
        frames,
        best_frame: best,
        meshes,
        figure,
    }))
}

impl DemoOutputs {
    /// Writes `result.mcap`, `report.json` and the meshes into the existing directory `dir`.
    ///
    /// # Errors
    /// A file that cannot be written.
    pub fn write(&self, dir: &Path) -> Result<(), LabError> {
        let report = serde_json::to_string_pretty(&self.report).map_err(|e| {
            LabError::InvalidEvaluation {
                reason: format!("a report as JSON: {e}"),
            }
        })?;
        moe_record::write_run(&dir.join("result.mcap"), &self.info, &self.frames)?;
        moe_io::write_atomic(&dir.join("report.json"), report.as_bytes())?;
        for (name, ply) in &self.meshes {
            moe_io::write_ply(&dir.join(name), ply)?;
        }
        Ok(())
    }

    /// The demo's table, lines ending in `\n`: `settings` says how contact was estimated, `dir`
    /// where the outputs were written.
    pub fn summary(&self, dir: &Path, settings: &str) -> String {
        let r = &self.report;
        let opt =
            |v: Option<f64>, unit: &str| v.map_or("—".to_owned(), |v| format!("{v:.2} {unit}"));
        let mut s = String::new();
        let _ = writeln!(
            s,
            "MOE-Touch demo: plate pressing the tip of finger 0, seen by the wrist camera"
        );
        let _ = writeln!(s, "  contact estimation          {settings}");
        let _ = writeln!(s, "  frames                      {}", r.frames);
        if let Some(m) = &r.markers {
            let _ = writeln!(
                s,
                "  markers found               {:.1} % of the visible ones ({} of {}), {:.2} mm off",
                100.0 * m.detection_rate,
                m.detected,
                m.visible,
                m.mean_error_mm
            );
        }
        let _ = writeln!(
            s,
            "  shape BCD                   {}",
            opt(r.shape_bcd_mm, "mm")
        );
        if let Some(c) = &r.contact {
            let _ = writeln!(
                s,
                "  contact BCD / UCD           {} / {} ({} of {} contact frames found, {} false alarms)",
                opt(Some(c.bcd_mm).filter(|v| v.is_finite()), "mm"),
                opt(Some(c.ucd_mm).filter(|v| v.is_finite()), "mm"),
                c.contact_frames - c.misses,
                c.contact_frames,
                c.false_alarms
            );
        }
        let _ = writeln!(
            s,
            "  frames per second           {:.1} (median frame {:.1} ms: markers {:.2}, estimate {:.2}, contact points {:.2})",
            r.frames_per_second,
            r.total_ms.median_ms,
            r.markers_ms.median_ms,
            r.estimate_ms.median_ms,
            r.points_ms.median_ms
        );
        if let Some(forces) = &r.forces {
            let cells: Vec<String> = forces
                .fingers
                .iter()
                .enumerate()
                .map(|(f, s)| {
                    format!(
                        "finger {f} up to {:.3} N in {} frames",
                        s.max_magnitude_n, s.frames_with_force
                    )
                })
                .collect();
            let _ = writeln!(s, "  estimated force             {}", cells.join(", "));
        }
        let _ = writeln!(
            s,
            "wrote {}: result.mcap (open in Foxglove with fixtures/foxglove/run_layout.json), report.json, figure.png, frame_{}_*.ply",
            dir.display(),
            self.best_frame
        );
        s
    }
}

/// Per finger, 1 at the vertices in contact and 0 elsewhere.
fn true_labels(vertices: &[Vec<Point3>], contact_vertices: &[Vec<u32>]) -> Vec<Vec<f64>> {
    vertices
        .iter()
        .zip(contact_vertices)
        .map(|(v, c)| {
            let mut l = vec![0.0; v.len()];
            for &i in c {
                l[i as usize] = 1.0;
            }
            l
        })
        .collect()
}

/// The camera frame at twice its size, pixel for pixel, with the markers found and the contact
/// points drawn on at that size so that the labels stay legible.
fn camera_panel(
    intrinsics: &CameraIntrinsics,
    hand_from_camera: HandFromCamera,
    frame: &RunFrame,
    source: &EpisodeFrame,
) -> Result<RgbImage, LabError> {
    let small = RgbImage::from_raw(
        intrinsics.width,
        intrinsics.height,
        frame.color_rgb8.clone(),
    )
    .ok_or(moe_touch::TouchError::ImageSize {
        what: "the frame's colour image bytes",
        expected: 3 * intrinsics.width as usize * intrinsics.height as usize,
        got: frame.color_rgb8.len(),
    })?;
    let big = image::imageops::resize(
        &small,
        2 * small.width(),
        2 * small.height(),
        image::imageops::FilterType::Nearest,
    );
    let scaled = CameraIntrinsics {
        width: big.width(),
        height: big.height(),
        fx: 2.0 * intrinsics.fx,
        fy: 2.0 * intrinsics.fy,
        cx: 2.0 * intrinsics.cx + 0.5,
        cy: 2.0 * intrinsics.cy + 0.5,
    };
    let hand_from_world = source.world_from_hand.inverse();
    let contacts_in_hand: Vec<Point3> = frame
        .contacts_in_world
        .iter()
        .map(|p| hand_from_world * p)
        .collect();
    let keypoints = HandKeypoints {
        fingers: frame.markers_in_hand.clone(),
    };
    Ok(draw_keypoints(
        &scaled,
        hand_from_camera,
        big.as_raw(),
        &keypoints,
        &contacts_in_hand,
    )?)
}

/// The demo's figure (see [`DemoOutputs::figure`]) of frame `index`.
fn figure(
    hand: &HandModel,
    intrinsics: &CameraIntrinsics,
    hand_from_camera: HandFromCamera,
    frame: &RunFrame,
    source: &EpisodeFrame,
    record: &FrameReport,
    index: usize,
) -> Result<RgbImage, LabError> {
    const PANEL_W: u32 = 320;
    const HEADER: u32 = 28;
    let white = Rgb([255, 255, 255]);
    let ink = Rgb([20, 20, 20]);
    let camera = camera_panel(intrinsics, hand_from_camera, frame, source)?;

    // The meshes, seen from the side the fingers bend to (hand x right, z up), turned 25°.
    let view_from_hand = Rotation3::from_matrix_unchecked(Matrix3::new(
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0,
    )) * Rotation3::from_axis_angle(&Vector3::z_axis(), 25f64.to_radians());
    let height = camera.height();
    let truth_labels: Option<Vec<Vec<f64>>> = frame
        .truth
        .as_ref()
        .map(|t| true_labels(&t.vertices_in_hand, &t.contact_vertices));
    let all = frame.vertices_in_hand.iter().flatten().chain(
        frame
            .truth
            .iter()
            .flat_map(|t| t.vertices_in_hand.iter().flatten()),
    );
    let view = OrthoView::fitting(view_from_hand, all, PANEL_W, height - 2 * HEADER, 12.0);
    let background = Rgb([250, 250, 250]);
    let mut estimate = render_meshes(
        &view,
        &meshes(hand, &frame.vertices_in_hand, &frame.contact_probability),
        background,
    );
    for load in record.loads.iter().flatten() {
        // The force the world exerts, drawn as an arrow ending where it acts.
        let tip = view.project(&load.location_m);
        let tail = view.project(&(load.location_m - load.force_n * DEFAULT_FORCE_ARROW_M_PER_N));
        arrow(
            &mut estimate,
            (tail.0, tail.1),
            (tip.0, tip.1),
            8.0,
            Rgb([10, 10, 10]),
        );
    }
    let truth = match (&frame.truth, &truth_labels) {
        (Some(t), Some(labels)) => render_meshes(
            &view,
            &meshes(hand, &t.vertices_in_hand, labels),
            background,
        ),
        _ => RgbImage::from_pixel(view.width, view.height, background),
    };

    let width = camera.width() + 2 * PANEL_W;
    let mut canvas = RgbImage::from_pixel(width, height + HEADER, white);
    image::imageops::replace(&mut canvas, &camera, 0, i64::from(HEADER));
    let x_est = i64::from(camera.width());
    let x_truth = x_est + i64::from(PANEL_W);
    image::imageops::replace(&mut canvas, &estimate, x_est, i64::from(2 * HEADER));
    image::imageops::replace(&mut canvas, &truth, x_truth, i64::from(2 * HEADER));
    let t = 1e-9 * frame.time_ns as f64;
    text(
        &mut canvas,
        8.0,
        9.0,
        &format!("camera, frame {index} ({t:.2} s)"),
        ink,
    );
    text(
        &mut canvas,
        x_est as f64 + 8.0,
        9.0,
        "estimate: p(contact), force",
        ink,
    );
    text(
        &mut canvas,
        x_truth as f64 + 8.0,
        9.0,
        "truth: simulator contact",
        ink,
    );
    for (f, force) in record.finger_forces.iter().flatten().enumerate() {
        text(
            &mut canvas,
            x_est as f64 + 8.0,
            f64::from(HEADER) + 4.0 + 14.0 * f as f64,
            &format!("finger {f}: {:.3} n", force.magnitude_n),
            ink,
        );
    }
    Ok(canvas)
}

/// The fingers of `hand` in `shapes`, coloured by `values`.
fn meshes<'a>(
    hand: &'a HandModel,
    shapes: &'a [Vec<Point3>],
    values: &'a [Vec<f64>],
) -> Vec<ShadedMesh<'a>> {
    (0..hand.num_fingers())
        .map(|f| ShadedMesh {
            vertices: &shapes[f],
            faces: hand.fingers()[f].model.mesh().faces(),
            probability: &values[f],
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The built-in episode, model and settings read, and fit the demo's hand.
    #[test]
    fn the_built_in_inputs_read_and_fit_the_hand() {
        let hand = hand().unwrap();
        let episode = episode().unwrap();
        assert!(!episode.frames.is_empty());
        crate::markers::check_hand(&hand, &episode.info).unwrap();
        model(&hand).unwrap();
        occluding_settings().unwrap().validate().unwrap();
    }

    #[test]
    fn true_labels_mark_the_contact_vertices_of_each_finger() {
        let v = vec![vec![Point3::origin(); 3], vec![Point3::origin(); 2]];
        let labels = true_labels(&v, &[vec![2], vec![]]);
        assert_eq!(labels, vec![vec![0.0, 0.0, 1.0], vec![0.0, 0.0]]);
    }
}
