//! `moe-touch eval physics`: contact from physics on held-out trajectories, as tactile
//! sensors are specified (detection, location and force error by the finger's true force),
//! beside the paper's per-vertex metrics for the physics estimator, the DGCNN on its shapes and
//! the paper's chain (SR-ARAP + DGCNN) on the same markers — a thin command over
//! `moe_lab::physics_eval`.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use moe_arap::ShapeConfig;
use moe_geom::{HandEstimator as _, OwnedObservation};
use moe_geom::{HandKeypoints, HandModel, Real};
use moe_io::{DatasetReader, Split, SplitFractions};
use moe_lab::physics_eval::{
    Comparison, MarkerSource, PhysicsEvaluation, PhysicsPlateTrial, StreamFrame, evaluate_physics,
    evaluate_plates_physics, simulate_perceived,
};
use moe_physics::{CalibrationOptions, HandMaterial, PhysicsConfig, PhysicsEstimator, calibrate};
use moe_tendon_sim::randomize::{RandomSceneParams, sample_scene};

use crate::cli::eval::contact::load_estimator;
use moe_lab::datagen::{dataset_hand, dataset_params};

/// Arguments of `moe-touch eval physics`.
#[derive(Debug, Args)]
pub(crate) struct PhysicsEvalArgs {
    /// Data set directory (its frames, exact or with `--marker-noise`). Without it,
    /// `--trajectories` are simulated afresh from `--seed` (`--perceived` needs that: the
    /// frames are rendered and their markers detected).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Which frames of the data set: all (the physics estimator is not trained) or the test
    /// trajectories.
    #[arg(long, value_enum, default_value = "all")]
    frames: crate::cli::eval::contact::FrameSet,
    /// Evaluate at most this many trajectories (the first ones).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    max_trajectories: Option<u64>,
    /// Without `--data`: trajectories to simulate (ids 0..N of `--seed`).
    #[arg(long, default_value_t = 20)]
    trajectories: u64,
    /// Without `--data`: the seed of the simulated trajectories (a data set made with this seed
    /// has the same frames); with `--marker-noise`, the noise's.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Without `--data`: randomisation parameters (TOML or JSON, as `gen-data --params`).
    #[arg(long)]
    params: Option<PathBuf>,
    /// Another marker layout on the same fingers (`camera-row`, `two-rows`, `sides`,
    /// `tip-ring`): with `--data`, its markers are read off each frame's true surface.
    #[arg(long, value_name = "PRESET")]
    marker_layout: Option<moe_geom::MarkerLayoutPreset>,
    /// Gaussian noise on every marker coordinate, metres.
    #[arg(long, value_name = "M")]
    marker_noise: Option<Real>,
    /// Markers detected by the perception stage in the rendered frames (needs simulation).
    #[arg(long, conflicts_with_all = ["data", "marker_noise"])]
    perceived: bool,
    /// The hand's material (TOML, as `moe-touch calibrate` writes it); default: nominal.
    #[arg(long)]
    material: Option<PathBuf>,
    /// Calibrate first: simulate this contact-free scene (e.g. fixtures/scenes/calibration.toml)
    /// with the evaluated hand's material and mesh (the data set's, or `--params`'), fit the
    /// material to its markers from `--material` (or the nominal one), and evaluate with the
    /// fitted material.
    #[arg(long, value_name = "SCENE.toml")]
    calibrate: Option<PathBuf>,
    /// The estimator's settings (TOML or JSON `PhysicsConfig`); default: the documented ones.
    #[arg(long)]
    config: Option<PathBuf>,
    /// A contact model for the comparison rows (the DGCNN on the physics shapes and on SR-ARAP
    /// shapes from the same markers).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Also Table 2: trials per plate scene (trial 0 as committed), the physics estimator and
    /// (with `--model`) the DGCNN on its shapes; UCD predicted → true per region. 0 skips it.
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u64).range(0..=100))]
    plates: u64,
    /// Every frame on its own (the estimator reset before each frame): Table 1 without memory
    /// across frames.
    #[arg(long)]
    no_memory: bool,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    json: bool,
}

/// Frames of the data set, as streams.
fn dataset_streams(
    dir: &std::path::Path,
    marker_layout: Option<moe_geom::MarkerLayoutPreset>,
    split: Option<Split>,
    max_trajectories: Option<u64>,
) -> Result<Streams> {
    let reader = DatasetReader::open(dir)?;
    let data_hand = dataset_hand(&reader)?;
    let layout = reader.card().layout.clone();
    let mut params = dataset_params(reader.card())?;
    // Another marker layout on the same fingers: its markers are read off the true surface.
    let hand = match marker_layout {
        Some(preset) => {
            params.finger.marker_layout = preset.layout();
            let hand = HandModel::preset(params.preset, &params.finger)?;
            for (a, b) in hand.fingers().iter().zip(data_hand.fingers()) {
                if a.model.mesh().vertices() != b.model.mesh().vertices() {
                    bail!(
                        "--marker-layout {preset}: the fingers' meshes differ from the data set's"
                    );
                }
            }
            hand
        }
        None => data_hand,
    };
    let frame_secs = params.dt_secs * params.save_every_steps as Real;
    let mut out: Vec<StreamFrame> = Vec::new();
    let mut trajectories = 0u64;
    for f in reader.frames(split, SplitFractions::default()) {
        let f = f?;
        let new = out
            .last()
            .is_none_or(|l| l.frame.trajectory_id != f.trajectory_id);
        if new {
            if max_trajectories.is_some_and(|m| trajectories >= m) {
                break;
            }
            trajectories += 1;
        }
        let mut stream = StreamFrame::from_dataset(&f, &layout, frame_secs)?;
        if marker_layout.is_some() {
            stream.frame.markers = hand.keypoints_on(&stream.frame.shape.fingers);
        }
        out.push(stream);
    }
    if out.is_empty() {
        bail!("{}: no frames to evaluate", dir.display());
    }
    Ok(Streams {
        hand,
        frames: out,
        perceived: None,
        params,
    })
}

/// The frames to evaluate and what they were made with.
struct Streams {
    hand: HandModel,
    frames: Vec<StreamFrame>,
    /// Per frame, the markers detected in the rendered images (`--perceived`).
    perceived: Option<Vec<HandKeypoints>>,
    params: RandomSceneParams,
}

/// Trajectories simulated afresh (rendered and perceived with `--perceived`).
fn simulated_streams(args: &PhysicsEvalArgs) -> Result<Streams> {
    let mut params: RandomSceneParams = match &args.params {
        Some(p) => moe_io::read_config(p)?,
        None => RandomSceneParams::default(),
    };
    if let Some(preset) = args.marker_layout {
        params.finger.marker_layout = preset.layout();
    }
    let hand = HandModel::preset(params.preset, &params.finger)?;
    let n = args.max_trajectories.unwrap_or(args.trajectories);
    let mut frames = Vec::new();
    let mut seen = Vec::new();
    for t in 0..n {
        let sampled = sample_scene(&params, args.seed, t)?;
        if args.perceived {
            let (s, k) = simulate_perceived(&sampled.config, &hand, t, args.seed ^ t)
                .with_context(|| format!("trajectory {t}"))?;
            frames.extend(s);
            seen.extend(k);
        } else {
            frames.extend(
                moe_lab::physics_eval::simulate_stream(&sampled.config, &hand, t)
                    .with_context(|| format!("trajectory {t}"))?,
            );
        }
        eprintln!("eval physics: simulated trajectory {} of {n}", t + 1);
    }
    Ok(Streams {
        hand,
        frames,
        perceived: args.perceived.then_some(seen),
        params,
    })
}

/// The material fitted to the calibration scene simulated with the hand's own material and
/// mesh (`params`), from `initial`.
fn calibrated(
    scene: &std::path::Path,
    hand: &HandModel,
    params: &RandomSceneParams,
    initial: &HandMaterial,
    config: &PhysicsConfig,
) -> Result<HandMaterial> {
    let mut scene_config: moe_tendon_sim::SceneConfig = moe_io::read_config(scene)?;
    scene_config.material = params.material.clone();
    scene_config.voxel = params.voxel.clone();
    let stream = moe_lab::physics_eval::simulate_stream(&scene_config, hand, 0)
        .with_context(|| format!("calibration scene {}", scene.display()))?;
    let frames: Vec<OwnedObservation> = stream
        .iter()
        .map(|s| {
            s.frame
                .observation()
                .with_time(s.time_secs)
                .to_owned_observation()
        })
        .collect();
    let report = calibrate(
        hand,
        &[frames],
        initial,
        config,
        &CalibrationOptions::default(),
    )?;
    eprintln!(
        "eval physics: calibrated on {} frames: E {:.0} Pa (resolution {:.1} %), damping {:.4} s, \
         RMS {:.4} -> {:.4} mm ({} evaluations)",
        report.frames,
        report.material.material.youngs_modulus_pa,
        100.0 * report.youngs_modulus_resolution,
        report.material.material.rayleigh_stiffness,
        report.rms_initial_m * 1e3,
        report.rms_fitted_m * 1e3,
        report.evaluations
    );
    Ok(report.material)
}

pub(crate) fn run(args: &PhysicsEvalArgs) -> Result<()> {
    let Streams {
        hand,
        frames,
        perceived,
        params,
    } = match &args.data {
        Some(dir) => {
            let split = match args.frames {
                crate::cli::eval::contact::FrameSet::Test => Some(Split::Test),
                crate::cli::eval::contact::FrameSet::All => None,
            };
            dataset_streams(dir, args.marker_layout, split, args.max_trajectories)?
        }
        None => simulated_streams(args)?,
    };
    let mut material: HandMaterial = match &args.material {
        Some(p) => moe_io::read_config(p)?,
        None => HandMaterial::default(),
    };
    let config: PhysicsConfig = match &args.config {
        Some(p) => moe_io::read_config(p)?,
        None => PhysicsConfig::default(),
    };
    if let Some(scene) = &args.calibrate {
        material = calibrated(scene, &hand, &params, &material, &config)?;
    }
    let mut estimator = PhysicsEstimator::new(&hand, &material, &config)?;
    let dgcnn = args
        .model
        .as_ref()
        .map(|m| load_estimator(m, &hand))
        .transpose()?;
    let source = match (&perceived, args.marker_noise) {
        (Some(seen), _) => MarkerSource::Given(seen),
        (None, Some(sigma_m)) => MarkerSource::Noisy {
            sigma_m,
            seed: args.seed,
        },
        (None, None) => MarkerSource::Exact,
    };
    let shape = ShapeConfig::default();
    let eval = evaluate_physics(
        &hand,
        &frames,
        source,
        &mut estimator,
        Comparison {
            dgcnn: dgcnn.as_ref(),
            shape: &shape,
            forget_between_frames: args.no_memory,
        },
    )?;
    let plates = if args.plates > 0 {
        evaluate_plates_physics(
            &hand,
            &moe_lab::contact_eval::plate_scenes()?,
            args.plates,
            args.seed,
            &mut estimator,
            dgcnn.as_ref(),
        )?
    } else {
        Vec::new()
    };
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "evaluation": eval,
                "plates": { "trials": plates, "regions": plate_regions(&plates) },
            })
        );
    } else {
        print!("{}", table(&eval));
        if !plates.is_empty() {
            print!("{}", plate_table(&plates));
        }
    }
    Ok(())
}

/// Per region: mean ± sd over the trials of the UCD (mm) of the physics estimator and of the
/// DGCNN on its shapes, with the share of contact frames missed.
pub(crate) fn plate_regions(plates: &[PhysicsPlateTrial]) -> serde_json::Value {
    let mut out = serde_json::Map::new();
    for region in ["tip", "middle", "base"] {
        let trials: Vec<&PhysicsPlateTrial> =
            plates.iter().filter(|t| t.region == region).collect();
        let stat = |f: &dyn Fn(&PhysicsPlateTrial) -> Option<&moe_contact::ContactReport>| {
            let reports: Vec<&moe_contact::ContactReport> =
                trials.iter().filter_map(|t| f(t)).collect();
            let v: Vec<Real> = reports
                .iter()
                .map(|r| r.ucd_mm)
                .filter(|x| x.is_finite())
                .collect();
            let n = v.len() as Real;
            let mean = v.iter().sum::<Real>() / n.max(1.0);
            let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<Real>() / n.max(1.0)).sqrt();
            let frames: u64 = reports.iter().map(|r| r.contact_frames).sum();
            let misses: u64 = reports.iter().map(|r| r.misses).sum();
            serde_json::json!({
                "ucd_mean_mm": mean, "ucd_sd_mm": sd, "trials": v.len(),
                "missed_fraction": misses as Real / frames.max(1) as Real,
            })
        };
        out.insert(
            region.to_owned(),
            serde_json::json!({
                "physics": stat(&|t| Some(&t.physics)),
                "dgcnn_on_physics": stat(&|t| t.dgcnn_on_physics.as_ref()),
            }),
        );
    }
    serde_json::Value::Object(out)
}

/// Table 2 as Markdown.
pub(crate) fn plate_table(plates: &[PhysicsPlateTrial]) -> String {
    use std::fmt::Write as _;
    let regions = plate_regions(plates);
    let mut s = String::from(
        "\n| region | physics UCD mm (missed) | DGCNN on the physics shape UCD mm (missed) |\n|---|---|---|\n",
    );
    for region in ["tip", "middle", "base"] {
        let cell = |k: &str| {
            let r = &regions[region][k];
            format!(
                "{:.2} ± {:.2} ({:.0} %)",
                r["ucd_mean_mm"].as_f64().unwrap_or(Real::NAN),
                r["ucd_sd_mm"].as_f64().unwrap_or(Real::NAN),
                100.0 * r["missed_fraction"].as_f64().unwrap_or(Real::NAN)
            )
        };
        let _ = writeln!(
            s,
            "| {region} | {} | {} |",
            cell("physics"),
            cell("dgcnn_on_physics")
        );
    }
    s
}

/// The report as Markdown tables.
pub(crate) fn table(e: &PhysicsEvaluation) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} frames of {} trajectories, markers: {}; physics estimator {:.1} ms per frame \
         (median; p90 {:.1}); {} finger-frames failed",
        e.frames,
        e.trajectories,
        e.markers,
        e.physics_ms_median,
        e.physics_ms_p90,
        e.failed_fingers
    );
    let _ = writeln!(
        s,
        "\n| contact estimation | BCD mm | UCD mm | missed frames | false-alarm frames | P | R | F1 | IoU |\n|---|---|---|---|---|---|---|---|---|"
    );
    let mut row = |name: &str, r: &moe_contact::ContactReport| {
        let _ = writeln!(
            s,
            "| {name} | {:.2} | {:.2} | {:.1} % | {:.1} % | {:.3} | {:.3} | {:.3} | {:.3} |",
            r.bcd_mm,
            r.ucd_mm,
            100.0 * r.miss_rate,
            100.0 * r.false_alarm_rate,
            r.precision,
            r.recall,
            r.f1,
            r.iou
        );
    };
    row("physics estimator", &e.physics);
    if let Some(r) = &e.dgcnn_on_physics {
        row("DGCNN on the physics shape", r);
    }
    if let Some(r) = &e.dgcnn_on_sr_arap {
        row("DGCNN on the SR-ARAP shape", r);
    }
    if let Some(r) = &e.physics_placed_by_dgcnn {
        row("physics, placed by the DGCNN on its shape", r);
    }
    let _ = writeln!(
        s,
        "\nshape BCD: physics {:.3} mm{}",
        e.physics_shape_bcd_mm,
        if e.sr_arap_shape_bcd_mm.is_finite() {
            format!(", SR-ARAP {:.3} mm", e.sr_arap_shape_bcd_mm)
        } else {
            String::new()
        }
    );
    let f = &e.forces;
    let _ = writeln!(
        s,
        "\n| true force (N) | fingers | detected | location median mm (along) | force error median N (%) |\n|---|---|---|---|---|"
    );
    for b in &f.bins {
        let _ = writeln!(
            s,
            "| {:.2}–{} | {} | {:.1} % | {:.2} ({:.2}) | {:.3} ({:.0} %) |",
            b.lo_n,
            if b.hi_n.is_finite() {
                format!("{:.2}", b.hi_n)
            } else {
                "∞".into()
            },
            b.fingers,
            100.0 * b.detection_rate,
            b.location_median_mm,
            b.along_median_mm,
            b.force_error_median_n,
            b.force_error_median_pct
        );
    }
    let _ = writeln!(
        s,
        "\nfalse alarms: {} of {} unpressed finger-frames ({:.1} %); smallest force detected 90 % of the time: {:.3} N; truth: {}",
        f.false_alarm_fingers,
        f.unpressed_fingers,
        100.0 * f.false_alarm_fingers as Real / f.unpressed_fingers.max(1) as Real,
        f.force_detected_90pct_n,
        if f.net_force_truth {
            "net force vectors"
        } else {
            "summed magnitudes (an old data set)"
        }
    );
    let t = &e.stream;
    let _ = writeln!(
        s,
        "presses (runs of contact frames of a finger): {}; detected in their first frame: {} \
         ({:.1} %), after {:.2} frames on average; held frames after detection dropped: {} of {} \
         ({:.1} %, {} presses flicker); releases still reported: {} of {} ({:.1} %)",
        t.presses,
        t.onset_detected,
        100.0 * t.onset_detected as Real / t.presses.max(1) as Real,
        t.onset_delay_frames_mean,
        t.held_frames_dropped,
        t.held_frames,
        100.0 * t.held_frames_dropped as Real / t.held_frames.max(1) as Real,
        t.presses_with_flicker,
        t.release_false_alarms,
        t.releases,
        100.0 * t.release_false_alarms as Real / t.releases.max(1) as Real,
    );
    s
}

/// Golden physics stage: the physics estimator (nominal material, the settings for exact
/// markers in `fixtures/physics/exact-markers.toml`) on the committed held-out trajectories as
/// streams, from their exact markers: the contact figures, the force table and, per frame, the
/// loads (finger, vertex, force) and every finger's statistic.
pub(crate) fn golden_physics() -> Result<serde_json::Value> {
    let root = crate::golden::workspace_root();
    let config: PhysicsConfig =
        moe_io::read_config(&root.join("fixtures/physics/exact-markers.toml"))?;
    golden_physics_with(&config)
}

/// Golden physics stage with the default settings (those of the pipeline, for detected
/// markers) on the same frames.
pub(crate) fn golden_physics_default() -> Result<serde_json::Value> {
    golden_physics_with(&PhysicsConfig::default())
}

/// The golden content of the physics estimator with `config` on the held-out frames.
fn golden_physics_with(config: &PhysicsConfig) -> Result<serde_json::Value> {
    let root = crate::golden::workspace_root();
    let Streams { hand, frames, .. } = dataset_streams(
        &root.join(crate::cli::eval::contact::HELDOUT_DIR),
        None,
        None,
        None,
    )?;
    let mut estimator = PhysicsEstimator::new(&hand, &HandMaterial::default(), config)?;
    let shape = ShapeConfig::default();
    let eval = evaluate_physics(
        &hand,
        &frames,
        MarkerSource::Exact,
        &mut estimator,
        Comparison {
            dgcnn: None,
            shape: &shape,
            forget_between_frames: false,
        },
    )?;
    let mut value = serde_json::to_value(&eval)?;
    if let Some(o) = value.as_object_mut() {
        o.remove("physics_ms_median");
        o.remove("physics_ms_p90");
    }
    // The loads frame by frame, the estimator reset at each trajectory as above.
    let mut per_frame = Vec::with_capacity(frames.len());
    let mut previous = None;
    for sf in &frames {
        if previous != Some(sf.frame.trajectory_id) {
            estimator.reset();
            previous = Some(sf.frame.trajectory_id);
        }
        let est = estimator.estimate(&sf.frame.observation().with_time(sf.time_secs))?;
        per_frame.push(serde_json::json!({
            "loads": est.details.loads.iter().map(|l| serde_json::json!({
                "finger": l.finger,
                "vertex": l.vertex,
                "force_n": [l.force_n.x, l.force_n.y, l.force_n.z],
            })).collect::<Vec<_>>(),
            "statistic": est.details.fingers.iter().map(|f| f.statistic).collect::<Vec<_>>(),
        }));
    }
    value["per_frame"] = serde_json::Value::Array(per_frame);
    Ok(value)
}
