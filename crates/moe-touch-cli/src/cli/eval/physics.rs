//! `moe-touch eval physics`: contact from physics on held-out trajectories, as tactile
//! sensors are specified (detection, location and force error by the finger's true force),
//! beside the paper's per-vertex metrics for the physics estimator, the DGCNN on its shapes and
//! the paper's chain (SR-ARAP + DGCNN) on the same markers — a thin command over
//! `moe_lab::physics_eval`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::Real;
use moe_lab::physics_eval::PhysicsEvaluation;
use moe_lab::physics_study::{
    PhysicsFrames, PhysicsPlateRegions, PhysicsRegionStat, PhysicsStudyOptions, physics_golden,
    physics_study,
};
use moe_physics::PhysicsConfig;
use moe_tendon_sim::randomize::RandomSceneParams;

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

pub(crate) fn run(args: &PhysicsEvalArgs) -> Result<()> {
    let frames = match &args.data {
        Some(dir) => PhysicsFrames::Dataset {
            dir: dir.clone(),
            frames: args.frames.into(),
        },
        None => PhysicsFrames::Simulated {
            trajectories: args.trajectories,
            params: Box::new(match &args.params {
                Some(p) => moe_io::read_config(p)?,
                None => RandomSceneParams::default(),
            }),
            perceived: args.perceived,
        },
    };
    let options = PhysicsStudyOptions {
        frames,
        max_trajectories: args.max_trajectories,
        seed: args.seed,
        marker_layout: args.marker_layout,
        marker_noise_m: args.marker_noise,
        material: crate::cli::load_material(args.material.as_deref())?.0,
        calibration_scene: match &args.calibrate {
            Some(p) => Some(
                moe_io::read_config(p)
                    .with_context(|| format!("calibration scene {}", p.display()))?,
            ),
            None => None,
        },
        config: crate::cli::load_physics_config(args.config.as_deref())?.0,
        model: args.model.clone(),
        plates: args.plates,
        no_memory: args.no_memory,
    };
    let study = physics_study(&options, &mut |t, n| {
        eprintln!("eval physics: simulated trajectory {t} of {n}");
    })?;
    if let Some(report) = &study.calibration {
        eprintln!(
            "eval physics: calibrated on {} frames: E {:.0} Pa (resolution {:.1} %), damping \
             {:.4} s, RMS {:.4} -> {:.4} mm ({} evaluations)",
            report.frames,
            report.material.material.youngs_modulus_pa,
            100.0 * report.youngs_modulus_resolution,
            report.material.material.rayleigh_stiffness,
            report.rms_initial_m * 1e3,
            report.rms_fitted_m * 1e3,
            report.evaluations
        );
    }
    let report = &study.report;
    if args.json {
        println!("{}", crate::cli::eval::sorted_json(report)?);
    } else {
        print!("{}", table(&report.evaluation));
        if !report.plates.trials.is_empty() {
            print!("{}", plate_table(&report.plates.regions));
        }
    }
    Ok(())
}

/// Table 2 as Markdown.
pub(crate) fn plate_table(regions: &PhysicsPlateRegions) -> String {
    use std::fmt::Write as _;
    let mut s = String::from(
        "\n| region | physics UCD mm (missed) | DGCNN on the physics shape UCD mm (missed) |\n|---|---|---|\n",
    );
    let cell = |r: &PhysicsRegionStat| {
        format!(
            "{:.2} ± {:.2} ({:.0} %)",
            r.ucd_mean_mm,
            r.ucd_sd_mm,
            100.0 * r.missed_fraction
        )
    };
    for (name, region) in regions.in_order() {
        let _ = writeln!(
            s,
            "| {name} | {} | {} |",
            cell(&region.physics),
            cell(&region.dgcnn_on_physics)
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
    let dir = crate::golden::workspace_root().join(crate::cli::eval::contact::HELDOUT_DIR);
    crate::cli::eval::sorted_json(&physics_golden(&dir, config)?)
}
