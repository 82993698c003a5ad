//! The one loader of each settings file a pipeline takes: read (TOML or JSON, by extension,
//! through `moe-io`) and validated, so that a bad value is refused naming the file, before any
//! pipeline is built.

use std::path::Path;

use crate::TouchError;
use crate::perception::DetectorConfig;

/// A settings value that can say whether it is valid.
trait Validated {
    /// Checks every field.
    fn check(&self) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;
}

impl Validated for DetectorConfig {
    fn check(&self) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(self.validate()?)
    }
}

#[cfg(feature = "physics")]
impl Validated for moe_physics::HandMaterial {
    fn check(&self) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(self.validate()?)
    }
}

#[cfg(feature = "physics")]
impl Validated for moe_physics::PhysicsConfig {
    fn check(&self) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(self.validate()?)
    }
}

#[cfg(feature = "physics")]
impl Validated for moe_physics::DepthBoundModel {
    fn check(&self) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(self.validate()?)
    }
}

impl Validated for moe_arap::ShapeConfig {
    fn check(&self) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(self.validate()?)
    }
}

/// Reads and checks the settings file at `path`.
fn load<T: serde::de::DeserializeOwned + Validated>(path: &Path) -> Result<T, TouchError> {
    let value: T = moe_io::read_config(path)?;
    value
        .check()
        .map_err(|source| TouchError::InvalidSettings {
            path: path.to_path_buf(),
            source,
        })?;
    Ok(value)
}

/// The marker detector's parameters (`DetectorConfig`) from a TOML or JSON file, checked.
///
/// # Errors
/// [`TouchError::Io`] for a missing, unreadable or malformed file (naming it, with the line),
/// [`TouchError::InvalidSettings`] for a value out of range (naming the file and the field).
pub fn load_detector_config(path: &Path) -> Result<DetectorConfig, TouchError> {
    load(path)
}

/// SR-ARAP's settings (`ShapeConfig`: iterations, smoothing, warm start, registration to the
/// depth image) from a TOML or JSON file, checked.
///
/// # Errors
/// As [`load_detector_config`].
pub fn load_shape_config(path: &Path) -> Result<moe_arap::ShapeConfig, TouchError> {
    load(path)
}

/// The hand's material (`HandMaterial`, as `moe-touch calibrate` writes it) from a TOML or JSON
/// file, checked.
///
/// # Errors
/// As [`load_detector_config`].
#[cfg(feature = "physics")]
pub fn load_material(path: &Path) -> Result<moe_physics::HandMaterial, TouchError> {
    load(path)
}

/// The physics estimator's settings (`PhysicsConfig`) from a TOML or JSON file, checked.
///
/// # Errors
/// As [`load_detector_config`].
#[cfg(feature = "physics")]
pub fn load_physics_config(path: &Path) -> Result<moe_physics::PhysicsConfig, TouchError> {
    load(path)
}

/// A depth camera for the Cramér–Rao bound (`DepthBoundModel`: intrinsics, mount, noise, range)
/// from a TOML or JSON file, checked; fields not given keep the virtual camera's values.
///
/// # Errors
/// As [`load_detector_config`].
#[cfg(feature = "physics")]
pub fn load_depth_bound_model(path: &Path) -> Result<moe_physics::DepthBoundModel, TouchError> {
    load(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scratch file with `text`, named `name`.
    fn file(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("moe-touch-settings-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn settings_files_are_read_and_checked_naming_the_file() {
        let empty = file("empty.toml", "");
        assert_eq!(
            load_detector_config(&empty).unwrap(),
            DetectorConfig::default()
        );
        let missing = empty.with_file_name("missing.toml");
        assert!(matches!(
            load_detector_config(&missing),
            Err(TouchError::Io(_))
        ));
        let unknown = file("unknown.toml", "no_such_field = 1\n");
        let err = load_detector_config(&unknown).unwrap_err();
        assert!(matches!(err, TouchError::Io(_)), "{err}");
        assert!(err.to_string().contains("no_such_field"), "{err}");
        #[cfg(feature = "physics")]
        {
            let material = moe_physics::HandMaterial::default();
            let text = toml_of(&material);
            assert_eq!(load_material(&file("m.toml", &text)).unwrap(), material);
            // A negative Young's modulus parses and is refused, naming the file.
            let bad = text.replace(
                &format!(
                    "youngs_modulus_pa = {:?}",
                    material.material.youngs_modulus_pa
                ),
                "youngs_modulus_pa = -1.0",
            );
            assert_ne!(bad, text, "the test edits the modulus");
            let path = file("bad.toml", &bad);
            let err = load_material(&path).unwrap_err();
            assert!(
                matches!(&err, TouchError::InvalidSettings { path: p, .. } if *p == path),
                "{err}"
            );
            assert!(err.to_string().contains("youngs_modulus_pa"), "{err}");
            assert_eq!(
                load_physics_config(&empty).unwrap(),
                moe_physics::PhysicsConfig::default()
            );
        }
    }

    #[cfg(feature = "physics")]
    fn toml_of(material: &moe_physics::HandMaterial) -> String {
        let dir = std::env::temp_dir().join(format!("moe-touch-settings-w-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.toml");
        moe_io::write_toml(&path, material).unwrap();
        std::fs::read_to_string(path).unwrap()
    }
}
