//! `moe-touch demo`: the whole pipeline on the committed example episode with the shipped
//! model, no arguments needed — a short table, the result MCAP, the meshes of the frame with
//! the most contact, and a picture.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use crate::draw::{OrthoView, ShadedMesh, arrow, render_meshes, text};
use crate::overlay::draw_keypoints;
use anyhow::{Context, Result};
use clap::Args;
use moe_arap::ShapeConfig;
use moe_contact::DgcnnEstimator;
use moe_geom::{HandEstimator, HandModel, Point3};
use moe_lab::contact_eval::contact_ply;
use moe_lab::markers::check_hand;
use moe_lab::run::{DEFAULT_FORCE_ARROW_M_PER_N, RunDetails, RunReport, run_episode, run_info};
use moe_touch::Pipeline;
use moe_touch::perception::{DetectorConfig, MarkerDetector};
use moe_touch::pipeline::load_contact_model;

use super::ContactMethod;

/// The committed example episode, built into the binary so that an installed `moe-touch` runs
/// `demo` from any directory.
const DEMO_EPISODE: &[u8] =
    include_bytes!("../../../../fixtures/episodes/plate_tip_front_small.mcap");
/// Its name in messages.
const DEMO_EPISODE_NAME: &str = "fixtures/episodes/plate_tip_front_small.mcap (built in)";
/// The shipped contact model and its card, built in likewise.
const DEMO_MODEL: &[u8] = include_bytes!("../../../../models/contact-two-finger.safetensors");
const DEMO_MODEL_CARD: &str = include_str!("../../../../models/contact-two-finger.json");
/// Its name in messages and the result.
const DEMO_MODEL_NAME: &str = "contact-two-finger.safetensors";
/// The physics settings for the demo's episode, whose plate hides the pressed tip.
const OCCLUDING_SETTINGS: &str =
    include_str!("../../../../fixtures/physics/occluding-contact.toml");
/// Their name in messages and the result.
const OCCLUDING_SETTINGS_NAME: &str = "fixtures/physics/occluding-contact.toml (built in)";

/// Arguments of `moe-touch demo`.
#[derive(Debug, Args)]
pub(crate) struct DemoArgs {
    /// Output directory: result.mcap, report.json, the meshes of the frame with the most
    /// contact (PLY coloured by contact probability, estimate and truth) and figure.png.
    #[arg(long, value_name = "DIR", default_value = "out/demo")]
    out: PathBuf,
    /// Episode (default: the committed example, plate pressing the tip of finger 0).
    #[arg(long, value_name = "EP.mcap")]
    episode: Option<PathBuf>,
    #[command(flatten)]
    estimator: super::run::EstimatorArgs,
}

pub(crate) fn run(args: DemoArgs) -> Result<()> {
    args.estimator.check(&[], &[])?;
    let episode = match &args.episode {
        Some(path) => moe_record::read_episode(path)?,
        None => moe_record::parse_episode(Path::new(DEMO_EPISODE_NAME), DEMO_EPISODE)?,
    };
    let episode_name = args
        .episode
        .as_ref()
        .map_or_else(|| DEMO_EPISODE_NAME.to_owned(), |p| p.display().to_string());
    let hand = HandModel::preset(
        moe_geom::HandPreset::TwoFinger,
        &moe_geom::FingerParams::default(),
    )?;
    check_hand(&hand, &episode.info)
        .with_context(|| format!("the demo's two-finger hand for {episode_name}"))?;
    let detector = MarkerDetector::for_episode(&episode.info, &hand, DetectorConfig::default())?;
    match args.estimator.contact {
        ContactMethod::Dgcnn => {
            let (model, model_name) = match &args.estimator.model {
                Some(path) => (
                    load_contact_model(path, &hand)
                        .with_context(|| format!("model {}", path.display()))?,
                    path.file_name()
                        .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
                ),
                None => (
                    DgcnnEstimator::from_bytes(DEMO_MODEL, DEMO_MODEL_CARD, &hand)
                        .with_context(|| format!("model {DEMO_MODEL_NAME} (built in)"))?,
                    DEMO_MODEL_NAME.to_owned(),
                ),
            };
            let pipeline = Pipeline::paper(hand.clone(), detector, model, ShapeConfig::default())?;
            let settings = "the paper's pipeline: SR-ARAP and the contact model";
            demo(&args, &hand, &episode, pipeline, &model_name, settings)
        }
        ContactMethod::Physics => {
            // The committed episode's plate stands between the camera and the pressed tip: the
            // physics estimator runs with the settings for an occluding object unless told
            // otherwise.
            let built_in = if args.episode.is_none() && args.estimator.physics_config().is_none() {
                let config: moe_physics::PhysicsConfig = moe_io::parse_toml(
                    OCCLUDING_SETTINGS.as_bytes(),
                    Path::new(OCCLUDING_SETTINGS_NAME),
                )?;
                config
                    .validate()
                    .with_context(|| OCCLUDING_SETTINGS_NAME.to_owned())?;
                Some(config)
            } else {
                None
            };
            let settings = match (&built_in, args.estimator.physics_config()) {
                (Some(_), _) => format!(
                    "the physics estimator with {OCCLUDING_SETTINGS_NAME} (the plate hides the \
                     pressed tip's markers; --physics-config FILE for others)"
                ),
                (None, Some(p)) => format!("the physics estimator with {}", p.display()),
                (None, None) => "the physics estimator, default settings".to_owned(),
            };
            let (pipeline, name) =
                args.estimator
                    .physics_pipeline_with(hand.clone(), detector, built_in)?;
            demo(&args, &hand, &episode, pipeline, &name, &settings)
        }
    }
}

/// Runs the demo's pipeline over the episode and writes and prints its outputs.
fn demo<E>(
    args: &DemoArgs,
    hand: &HandModel,
    episode: &moe_record::Episode,
    mut pipeline: Pipeline<E>,
    model_name: &str,
    settings: &str,
) -> Result<()>
where
    E: HandEstimator,
    E::Details: RunDetails,
{
    let intrinsics = *pipeline.detector().intrinsics();
    let hand_from_camera = pipeline.detector().hand_from_camera();
    let threshold = pipeline.threshold();
    let (frames, report) = run_episode(&mut pipeline, &episode.info, &episode.frames, None)?;

    // The frame with the most estimated contact (the first of equals).
    let best = (0..frames.len())
        .max_by_key(|&k| (frames[k].contacts_in_world.len(), std::cmp::Reverse(k)))
        .context("the episode has no frames")?;
    let frame = &frames[best];
    let source = &episode.frames[best];
    // Everything in memory first.
    let mut plys = Vec::new();
    for f in 0..hand.num_fingers() {
        plys.push((
            format!("frame_{best}_estimate_finger_{f}.ply"),
            contact_ply(
                hand,
                f,
                &frame.vertices_in_hand[f],
                &frame.contact_probability[f],
            )?,
        ));
        if let Some(truth) = &frame.truth {
            let mut labels = vec![0.0; truth.vertices_in_hand[f].len()];
            for &v in &truth.contact_vertices[f] {
                labels[v as usize] = 1.0;
            }
            plys.push((
                format!("frame_{best}_truth_finger_{f}.ply"),
                contact_ply(hand, f, &truth.vertices_in_hand[f], &labels)?,
            ));
        }
    }
    let png = figure(
        hand,
        &intrinsics,
        hand_from_camera,
        frame,
        source,
        &report.per_frame[best],
        best,
    )?;
    let report_text = serde_json::to_string_pretty(&report)?;
    let mut info = run_info(&episode.info, model_name, threshold);
    info.force_arrow_m_per_n = report.forces.as_ref().map(|_| DEFAULT_FORCE_ARROW_M_PER_N);

    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    moe_record::write_run(&args.out.join("result.mcap"), &info, &frames)?;
    moe_io::write_atomic(&args.out.join("report.json"), report_text.as_bytes())?;
    for (name, ply) in &plys {
        moe_io::write_ply(&args.out.join(name), ply)?;
    }
    moe_io::write_atomic(&args.out.join("figure.png"), &png)?;
    print_table(&report, best, &args.out, settings);
    Ok(())
}

/// The camera frame at twice its size, pixel for pixel, with the markers found and the contact
/// points drawn on at that size so that the labels stay legible.
fn camera_panel(
    intrinsics: &moe_geom::CameraIntrinsics,
    hand_from_camera: moe_geom::HandFromCamera,
    frame: &moe_record::RunFrame,
    source: &moe_record::EpisodeFrame,
) -> Result<image::RgbImage> {
    let small = image::RgbImage::from_raw(
        intrinsics.width,
        intrinsics.height,
        frame.color_rgb8.clone(),
    )
    .context("the frame's colour image does not have the camera's size")?;
    let big = image::imageops::resize(
        &small,
        2 * small.width(),
        2 * small.height(),
        image::imageops::FilterType::Nearest,
    );
    let scaled = moe_geom::CameraIntrinsics {
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
    let keypoints = moe_geom::HandKeypoints {
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

/// The demo's figure: the camera frame with the markers found (labels that do not overlap) and
/// the contact points; the estimated finger meshes coloured by contact probability with the
/// estimated force arrows; the true meshes coloured by the simulator's contact.
fn figure(
    hand: &HandModel,
    intrinsics: &moe_geom::CameraIntrinsics,
    hand_from_camera: moe_geom::HandFromCamera,
    frame: &moe_record::RunFrame,
    source: &moe_record::EpisodeFrame,
    record: &moe_lab::run::FrameReport,
    index: usize,
) -> Result<Vec<u8>> {
    const PANEL_W: u32 = 320;
    const HEADER: u32 = 28;
    let white = image::Rgb([255, 255, 255]);
    let ink = image::Rgb([20, 20, 20]);
    let camera = camera_panel(intrinsics, hand_from_camera, frame, source)?;

    // The meshes, seen from the side the fingers bend to (hand x right, z up), turned 25°.
    let view_from_hand = moe_geom::nalgebra::Rotation3::from_matrix_unchecked(
        moe_geom::nalgebra::Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0),
    ) * moe_geom::nalgebra::Rotation3::from_axis_angle(
        &moe_geom::Vector3::z_axis(),
        25f64.to_radians(),
    );
    let height = camera.height();
    let truth_labels: Option<Vec<Vec<f64>>> = frame.truth.as_ref().map(|t| {
        t.vertices_in_hand
            .iter()
            .zip(&t.contact_vertices)
            .map(|(v, c)| {
                let mut l = vec![0.0; v.len()];
                for &i in c {
                    l[i as usize] = 1.0;
                }
                l
            })
            .collect()
    });
    let all = frame.vertices_in_hand.iter().flatten().chain(
        frame
            .truth
            .iter()
            .flat_map(|t| t.vertices_in_hand.iter().flatten()),
    );
    let view = OrthoView::fitting(view_from_hand, all, PANEL_W, height - 2 * HEADER, 12.0);
    let background = image::Rgb([250, 250, 250]);
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
            image::Rgb([10, 10, 10]),
        );
    }
    let truth = match (&frame.truth, &truth_labels) {
        (Some(t), Some(labels)) => render_meshes(
            &view,
            &meshes(hand, &t.vertices_in_hand, labels),
            background,
        ),
        _ => image::RgbImage::from_pixel(view.width, view.height, background),
    };

    let width = camera.width() + 2 * PANEL_W;
    let mut canvas = image::RgbImage::from_pixel(width, height + HEADER, white);
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
    let mut png = Vec::new();
    canvas
        .write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)
        .context("encoding the figure")?;
    Ok(png)
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

/// The demo's table: `settings` says how contact was estimated.
fn print_table(r: &RunReport, best: usize, out: &Path, settings: &str) {
    let opt = |v: Option<f64>, unit: &str| v.map_or("—".to_owned(), |v| format!("{v:.2} {unit}"));
    super::outln!("MOE-Touch demo: plate pressing the tip of finger 0, seen by the wrist camera");
    super::outln!("  contact estimation          {settings}");
    super::outln!("  frames                      {}", r.frames);
    if let Some(m) = &r.markers {
        super::outln!(
            "  markers found               {:.1} % of the visible ones ({} of {}), {:.2} mm off",
            100.0 * m.detection_rate,
            m.detected,
            m.visible,
            m.mean_error_mm
        );
    }
    super::outln!(
        "  shape BCD                   {}",
        opt(r.shape_bcd_mm, "mm")
    );
    if let Some(c) = &r.contact {
        super::outln!(
            "  contact BCD / UCD           {} / {} ({} of {} contact frames found, {} false alarms)",
            opt(Some(c.bcd_mm).filter(|v| v.is_finite()), "mm"),
            opt(Some(c.ucd_mm).filter(|v| v.is_finite()), "mm"),
            c.contact_frames - c.misses,
            c.contact_frames,
            c.false_alarms
        );
    }
    super::outln!(
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
        super::outln!("  estimated force             {}", cells.join(", "));
    }
    super::outln!(
        "wrote {}: result.mcap (open in Foxglove with fixtures/foxglove/run_layout.json), report.json, figure.png, frame_{best}_*.ply",
        out.display()
    );
}
