//! `moe-touch run`: the whole pipeline over every frame of an episode; a result MCAP for
//! Foxglove (input image, detected markers, estimated meshes coloured by contact probability,
//! contact points in the world, with the physics estimator the loads as arrows and the force on
//! every finger, and the ground truth beside them) and a report.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use moe_arap::ShapeConfig;
use moe_geom::{HandEstimator, HandModel};
use moe_lab::markers::check_hand;
use moe_lab::run::{DEFAULT_FORCE_ARROW_M_PER_N, RunDetails, run_episode, run_info};
use moe_touch::PhysicsPipeline;
use moe_touch::Pipeline;
use moe_touch::filter::{ContactSmoother, KalmanConfig, KeypointFilter};
use moe_touch::perception::MarkerDetector;
use moe_touch::pipeline::load_contact_model;

use super::ContactMethod;

/// The shipped contact model, the default of `--model`.
pub(crate) const DEFAULT_MODEL: &str = "models/contact-two-finger.safetensors";

/// How the shape and the contact are estimated: the options `run` and `demo` share.
#[derive(Debug, Args)]
pub(crate) struct EstimatorArgs {
    /// How the shape and the contact are estimated: `physics` (the default: the finger's FEM
    /// model read backwards from the markers, the episode's tendon pulls, the hand's pose and
    /// time: the dented shape, the loads and the force on every finger, in the report and as
    /// arrows and a plottable topic in the result) or `dgcnn` (the paper's pipeline: SR-ARAP
    /// shape, then the trained network on it).
    #[arg(long, value_enum, default_value = "physics")]
    pub(crate) contact: ContactMethod,
    /// dgcnn: the trained contact model (`NAME.safetensors` with its card `NAME.json`)
    /// [default: the shipped models/contact-two-finger.safetensors].
    #[arg(long, value_name = "M.safetensors")]
    pub(crate) model: Option<PathBuf>,
    /// physics: the hand's material (TOML or JSON, as `moe-touch calibrate` writes it; default:
    /// the nominal silicone).
    #[arg(long, value_name = "M.toml")]
    material: Option<PathBuf>,
    /// physics: the estimator's settings (TOML or JSON `moe_physics::PhysicsConfig`).
    #[arg(long, value_name = "C.toml")]
    physics_config: Option<PathBuf>,
}

impl EstimatorArgs {
    /// Refuses an option of the method not chosen: the shared ones and the command's own
    /// (`dgcnn_only`, `physics_only`: whether each was given, and its flag).
    pub(crate) fn check(
        &self,
        dgcnn_only: &[(bool, &str)],
        physics_only: &[(bool, &str)],
    ) -> Result<()> {
        match self.contact {
            ContactMethod::Dgcnn => {
                let shared = [
                    (self.material.is_some(), "--material"),
                    (self.physics_config.is_some(), "--physics-config"),
                ];
                if let Some((_, flag)) = shared.iter().chain(physics_only).find(|(g, _)| *g) {
                    bail!("{flag} is for --contact physics");
                }
            }
            ContactMethod::Physics => {
                let shared = [(self.model.is_some(), "--model")];
                if let Some((_, flag)) = shared.iter().chain(dgcnn_only).find(|(g, _)| *g) {
                    bail!(
                        "{flag} is for --contact dgcnn (SR-ARAP and the network); the physics \
                         estimator makes the shape itself and has no network"
                    );
                }
            }
        }
        Ok(())
    }

    /// The settings file of the physics estimator, when one is used.
    pub(crate) fn physics_config(&self) -> Option<&Path> {
        self.physics_config.as_deref()
    }

    /// The physics pipeline for `hand` behind `detector` from `--material` and
    /// `--physics-config`, and its name for the result (with the material file's name).
    pub(crate) fn physics_pipeline(
        &self,
        hand: HandModel,
        detector: moe_touch::perception::MarkerDetector,
    ) -> Result<(PhysicsPipeline, String)> {
        self.physics_pipeline_with(hand, detector, None)
    }

    /// [`EstimatorArgs::physics_pipeline`] with `settings` in place of the defaults when
    /// `--physics-config` is not given.
    pub(crate) fn physics_pipeline_with(
        &self,
        hand: HandModel,
        detector: moe_touch::perception::MarkerDetector,
        settings: Option<moe_physics::PhysicsConfig>,
    ) -> Result<(PhysicsPipeline, String)> {
        let (material, material_name) = super::load_material(self.material.as_deref())?;
        let config = match (self.physics_config.as_deref(), settings) {
            (None, Some(settings)) => settings,
            (path, _) => super::load_physics_config(path)?.0,
        };
        let pipeline = PhysicsPipeline::physics(hand, detector, &material, &config)
            .context("the physics estimator")?;
        let name = match material_name.as_str() {
            "nominal" => "physics (nominal material)".to_owned(),
            _ => format!(
                "physics (material {})",
                Path::new(&material_name)
                    .file_name()
                    .map_or(material_name.clone(), |n| n.to_string_lossy().into_owned())
            ),
        };
        Ok((pipeline, name))
    }
}

/// Arguments of `moe-touch run`.
#[derive(Debug, Args)]
pub(crate) struct RunArgs {
    /// Episode to read: MCAP as `moe-touch sim --out EP.mcap` records it (an episode cut short
    /// runs up to its last complete frame, and the cut is reported), or a ROS 2 recording (a
    /// rosbag2 directory with MCAP storage, or an MCAP file of CDR messages).
    #[arg(long, value_name = "EP.mcap|BAG")]
    episode: PathBuf,
    /// The ROS 2 recording's topics, frame names, pairing tolerance and tendon joint names
    /// (TOML `RosConfig`; defaults: `realsense2_camera`'s topics, frames `world` and `hand`).
    /// Implies that `--episode` is a ROS 2 recording.
    #[arg(long, value_name = "CONFIG.toml")]
    ros: Option<PathBuf>,
    #[command(flatten)]
    estimator: EstimatorArgs,
    /// physics: length of a force arrow in the result file per newton, metres [default: 0.2,
    /// a 50 mN press draws a 10 mm arrow].
    #[arg(long, value_name = "M_PER_N")]
    force_scale: Option<f64>,
    /// Result file (MCAP; open it in Foxglove with fixtures/foxglove/run_layout.json).
    #[arg(long, value_name = "RESULT.mcap")]
    out: PathBuf,
    /// Also write the report (per-frame and overall figures) as JSON here.
    #[arg(long, value_name = "R.json")]
    report: Option<PathBuf>,
    /// Also write the results as a ROS 2 recording into this new directory, to replay beside
    /// the robot's own topics: `visualization_msgs/MarkerArray` on /moe_touch/markers (the
    /// surface coloured by contact, the markers found, the contact points, the loads as
    /// arrows) and each finger's force as `geometry_msgs/WrenchStamped` on
    /// /moe_touch/finger{i}/wrench, in the frames of `--ros` (default `world`, `hand`); the
    /// arrows' length per newton is `--force-scale`'s.
    #[arg(long, value_name = "DIR")]
    ros_out: Option<PathBuf>,
    /// The hand: a preset (two-finger, three-finger, five-finger) or a hand config file; it
    /// must be the episode's hand and the model's.
    #[arg(long, value_name = "PRESET|CONFIG", default_value = "two-finger")]
    hand: String,
    /// Marker-detector parameters (TOML or JSON `DetectorConfig`).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// dgcnn: SR-ARAP's settings (TOML or JSON `ShapeConfig`; its `[depth]` part registers the
    /// shape to the frames' depth image as well). `--iterations` and `--warm-start` override it.
    #[arg(long, value_name = "FILE")]
    shape_config: Option<PathBuf>,
    /// dgcnn: SR-ARAP iterations per frame [default: 50].
    #[arg(long)]
    iterations: Option<usize>,
    /// dgcnn: start each frame's shape from the previous one (tracking; the paper starts from
    /// rest).
    #[arg(long)]
    warm_start: bool,
    /// Filter the keypoints over time with a constant-velocity Kalman filter per marker
    /// (default noise levels of `KalmanConfig`).
    #[arg(long)]
    kalman: bool,
    /// Smooth the contact map over time with this weight on the new frame, in (0, 1].
    #[arg(long, value_name = "ALPHA")]
    smooth_contact: Option<f64>,
    /// Print the report (without the per-frame list) as one JSON object.
    #[arg(long)]
    json: bool,
    /// Fail (exit status non-zero, after writing the result and the report) when any frame
    /// could not be estimated. Without it, failed frames are marked in the report and the
    /// result, and only a run of which no frame was estimated fails.
    #[arg(long)]
    strict: bool,
}

/// Checks a force arrow scale.
pub(crate) fn check_force_scale(scale: f64) -> Result<f64> {
    if !(scale.is_finite() && scale > 0.0) {
        bail!("--force-scale {scale} must be a positive number of metres per newton");
    }
    Ok(scale)
}

pub(crate) fn run(args: RunArgs) -> Result<()> {
    args.estimator.check(
        &[
            (args.shape_config.is_some(), "--shape-config"),
            (args.iterations.is_some(), "--iterations"),
            (args.warm_start, "--warm-start"),
        ],
        &[(args.force_scale.is_some(), "--force-scale")],
    )?;
    let force_scale = check_force_scale(args.force_scale.unwrap_or(DEFAULT_FORCE_ARROW_M_PER_N))?;
    if let Some(dir) = args.ros_out.as_ref().filter(|d| d.exists()) {
        bail!(
            "--ros-out {}: already exists; give a new directory",
            dir.display()
        );
    }
    let config = super::load_detector_config(args.config.as_deref(), "--config")?;
    let hand = super::load_hand(&args.hand)?;
    // The recording's topics and frames, read once: they name the input's and the results'.
    let ros = ros_config(&args)?;
    let given = args.ros.as_ref().map(|_| &ros);
    let (episode, cut) = moe_record::ros2::read_recording(&args.episode, given, &hand)?;
    check_hand(&hand, &episode.info)
        .with_context(|| format!("--hand {} for {}", args.hand, args.episode.display()))?;
    let detector = MarkerDetector::for_episode(&episode.info, &hand, config)
        .with_context(|| format!("the camera of {}", args.episode.display()))?;
    match args.estimator.contact {
        ContactMethod::Dgcnn => {
            let model_path = args
                .estimator
                .model
                .clone()
                .unwrap_or_else(|| PathBuf::from(DEFAULT_MODEL));
            let model = load_contact_model(&model_path, &hand).with_context(|| {
                format!("model {} on hand '{}'", model_path.display(), args.hand)
            })?;
            let given = super::load_shape_config(args.shape_config.as_deref())?;
            let options = ShapeConfig {
                iterations: args.iterations.unwrap_or(given.iterations),
                warm_start: args.warm_start || given.warm_start,
                ..given
            };
            let pipeline = Pipeline::paper(hand, detector, model, options)?;
            let model_name = model_path
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
            finish(&args, &ros, pipeline, &episode, cut, &model_name, None)
        }
        ContactMethod::Physics => {
            let (pipeline, name) = args.estimator.physics_pipeline(hand, detector)?;
            finish(
                &args,
                &ros,
                pipeline,
                &episode,
                cut,
                &name,
                Some(force_scale),
            )
        }
    }
}

/// The ROS 2 topics and frames of `--ros`, or the defaults.
fn ros_config(args: &RunArgs) -> Result<moe_record::ros2::RosConfig> {
    Ok(match &args.ros {
        Some(path) => moe_io::read_config(path)?,
        None => moe_record::ros2::RosConfig::default(),
    })
}

/// Runs the pipeline over the episode, writes the result and the report, prints the summary.
fn finish<E>(
    args: &RunArgs,
    ros: &moe_record::ros2::RosConfig,
    mut pipeline: Pipeline<E>,
    episode: &moe_record::Episode,
    cut: Option<moe_io::IoError>,
    model_name: &str,
    force_scale: Option<f64>,
) -> Result<()>
where
    E: HandEstimator,
    E::Details: RunDetails,
{
    if args.kalman {
        pipeline = pipeline.with_keypoint_filter(KeypointFilter::new(KalmanConfig::default())?);
    }
    if let Some(alpha) = args.smooth_contact {
        pipeline = pipeline.with_contact_smoothing(ContactSmoother::new(alpha)?);
    }
    let truncated = cut.map(|err| {
        eprintln!(
            "warning: {err}; running the {} complete frames before the cut",
            episode.frames.len()
        );
        err.to_string()
    });
    let (frames, report) = run_episode(&mut pipeline, &episode.info, &episode.frames, truncated)
        .with_context(|| format!("episode {}", args.episode.display()))?;
    let mut info = run_info(&episode.info, model_name, pipeline.threshold());
    info.force_arrow_m_per_n = force_scale;
    // The report is built before anything is written; the result file is written whole.
    let report_text = serde_json::to_string_pretty(&report)?;
    // The ROS 2 results first: their writer removes what it wrote on a failure, so a failing
    // command leaves neither output behind.
    if let Some(dir) = &args.ros_out {
        let arrow = force_scale.unwrap_or(DEFAULT_FORCE_ARROW_M_PER_N);
        moe_record::ros2::write_ros2_results(dir, &frames, ros, arrow)?;
    }
    if let Err(e) = moe_record::write_run(&args.out, &info, &frames) {
        if let Some(dir) = &args.ros_out {
            let _ = std::fs::remove_dir_all(dir);
        }
        return Err(e.into());
    }
    if let Some(path) = &args.report {
        moe_io::write_atomic(path, report_text.as_bytes())?;
    }
    if args.json {
        let mut value = serde_json::to_value(&report)?;
        if let Some(obj) = value.as_object_mut() {
            obj.remove("per_frame");
            obj.insert("out".into(), args.out.display().to_string().into());
        }
        super::print_json(&value)?;
    } else {
        super::print_text(&report.summary(&args.out));
    }
    failed_frames_status(&report, args.strict)
}

/// The run's status from its failed frames: an error when no frame was estimated, or with
/// `strict` when any frame was not (naming the first failure).
fn failed_frames_status(report: &moe_lab::run::RunReport, strict: bool) -> Result<()> {
    let first = report.per_frame.iter().find_map(|f| {
        f.failure
            .as_ref()
            .map(|e| format!("frame at {} ns: {}", f.time_ns, e.error))
    });
    status_of(report.frames, report.failed_frames, first, strict)
}

fn status_of(frames: usize, failed: usize, first: Option<String>, strict: bool) -> Result<()> {
    match first {
        Some(first) if failed == frames => {
            bail!("no frame of {failed} was estimated; the first: {first}")
        }
        Some(first) if strict => {
            bail!("--strict: {failed} of {frames} frames were not estimated; the first: {first}")
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::status_of;

    #[test]
    fn a_run_fails_when_no_frame_was_estimated_or_strictly_when_any_was_not() {
        let first = || Some("frame at 5 ns: estimate stage: x".to_owned());
        assert!(status_of(7, 0, None, true).is_ok());
        assert!(status_of(7, 1, first(), false).is_ok());
        let strict = status_of(7, 1, first(), true).unwrap_err().to_string();
        assert_eq!(
            strict,
            "--strict: 1 of 7 frames were not estimated; the first: frame at 5 ns: estimate stage: x"
        );
        let none = status_of(7, 7, first(), false).unwrap_err().to_string();
        assert!(none.starts_with("no frame of 7 was estimated"), "{none}");
    }
}
