//! Subcommands of the `moe-touch` tool, one module each: an `…Args` struct (clap) and a `run`
//! function. Figures go to stdout (one JSON object with `--json`), progress and logs to stderr.

pub(crate) mod arap;
pub(crate) mod calibrate;
pub(crate) mod contact;
pub(crate) mod demo;
pub(crate) mod eval;
pub(crate) mod gen_data;
pub(crate) mod hand;
pub(crate) mod markers;
pub(crate) mod plane;
pub(crate) mod run;
pub(crate) mod shape;
pub(crate) mod sim;
pub(crate) mod surface;
pub(crate) mod train;

/// A hand from `--hand`: a preset name (two-finger, three-finger, five-finger) or a hand config
/// file.
pub(crate) fn load_hand(spec: &str) -> anyhow::Result<moe_geom::HandModel> {
    use anyhow::Context;
    use moe_geom::{FingerParams, HandModel, HandPreset};
    if let Ok(preset) = spec.parse::<HandPreset>() {
        return HandModel::preset(preset, &FingerParams::default())
            .with_context(|| format!("building the {preset} preset"));
    }
    let path = std::path::PathBuf::from(spec);
    if !path.exists() {
        anyhow::bail!(
            "--hand '{spec}' is neither a preset (two-finger, three-finger, five-finger) nor an \
             existing config file"
        );
    }
    Ok(moe_io::load_hand_config(&path)?)
}

/// Which estimator finds contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub(crate) enum ContactMethod {
    /// The paper's graph network on the estimated shape (needs a trained model).
    Dgcnn,
    /// The finger's FEM model read backwards from the markers, the tendon pulls and the hand's
    /// pose: contact places, force vectors and their uncertainty, and the dented shape.
    Physics,
}

/// The hand's material from `--material` (TOML or JSON `HandMaterial`, as `moe-touch
/// calibrate` writes it), checked; the nominal material without one. Also its name for reports.
pub(crate) fn load_material(
    path: Option<&std::path::Path>,
) -> anyhow::Result<(moe_physics::HandMaterial, String)> {
    use anyhow::Context;
    let Some(path) = path else {
        return Ok((moe_physics::HandMaterial::default(), "nominal".to_owned()));
    };
    let material = moe_touch::settings::load_material(path).context("--material")?;
    Ok((material, path.display().to_string()))
}

/// The physics estimator's settings from `--physics-config` (TOML or JSON `PhysicsConfig`),
/// checked; the defaults without one. Also its name for reports.
pub(crate) fn load_physics_config(
    path: Option<&std::path::Path>,
) -> anyhow::Result<(moe_physics::PhysicsConfig, String)> {
    use anyhow::Context;
    let Some(path) = path else {
        return Ok((moe_physics::PhysicsConfig::default(), "default".to_owned()));
    };
    let config = moe_touch::settings::load_physics_config(path).context("--physics-config")?;
    Ok((config, path.display().to_string()))
}

/// A rendering camera from a file (TOML or JSON `RgbdCamera`), checked.
pub(crate) fn load_camera(
    path: &std::path::Path,
) -> anyhow::Result<moe_tendon_sim::camera::RgbdCamera> {
    use anyhow::Context;
    let camera: moe_tendon_sim::camera::RgbdCamera = moe_io::read_config(path)?;
    camera
        .validate()
        .with_context(|| path.display().to_string())?;
    Ok(camera)
}

/// The wrist camera of a study's rendered frames from `--camera`, with its noise made harsher
/// when `harsher` (the default camera's without a file); `None` (the scenes' own camera)
/// without either.
pub(crate) fn eval_camera(
    path: Option<&std::path::Path>,
    harsher: bool,
) -> anyhow::Result<Option<moe_tendon_sim::camera::RgbdCamera>> {
    use anyhow::Context;
    let camera = path
        .map(|p| load_camera(p).context("--camera"))
        .transpose()?;
    Ok(camera
        .or_else(|| harsher.then(moe_tendon_sim::camera::RgbdCamera::default))
        .map(|mut camera| {
            if harsher {
                camera.noise = camera.noise.harsher();
            }
            camera
        }))
}

/// SR-ARAP's settings from `--shape-config` (TOML or JSON `ShapeConfig`), checked; the
/// paper's without one.
pub(crate) fn load_shape_config(
    path: Option<&std::path::Path>,
) -> anyhow::Result<moe_arap::ShapeConfig> {
    use anyhow::Context;
    path.map_or_else(
        || Ok(moe_arap::ShapeConfig::default()),
        |p| moe_touch::settings::load_shape_config(p).context("--shape-config"),
    )
}

/// The marker detector's parameters from the file given to `flag` (TOML or JSON
/// `DetectorConfig`), checked; the defaults without one.
pub(crate) fn load_detector_config(
    path: Option<&std::path::Path>,
    flag: &'static str,
) -> anyhow::Result<moe_touch::perception::DetectorConfig> {
    use anyhow::Context;
    path.map_or_else(
        || Ok(moe_touch::perception::DetectorConfig::default()),
        |p| moe_touch::settings::load_detector_config(p).context(flag),
    )
}

/// Prints `value` as one JSON object on stdout.
pub(crate) fn print_json<T: serde::Serialize>(value: &T) -> anyhow::Result<()> {
    emit(format_args!("{}", serde_json::to_string(value)?));
    Ok(())
}

/// Writes one line to stdout. A reader that went away (`moe-touch … | head`) is not an error:
/// the line is dropped, where `println!` would panic; any other failure is reported on stderr.
pub(crate) fn emit(line: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = writeln!(out, "{line}")
        && e.kind() != std::io::ErrorKind::BrokenPipe
    {
        eprintln!("warning: cannot write to stdout: {e}");
    }
}

/// Writes text (lines ending in `\n`, as the library's report tables come) to stdout; see
/// [`emit`].
pub(crate) fn print_text(text: &str) {
    for line in text.lines() {
        emit(format_args!("{line}"));
    }
}

/// `println!` for command output; see [`emit`].
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::cli::emit(format_args!($($arg)*))
    };
}
pub(crate) use outln;
