//! Hand-model configs (TOML or JSON): a preset layout with custom finger parameters, or an
//! explicit list of fingers, each parametric or brought as the user's own mesh.
//!
//! ```toml
//! # A preset hand with longer fingers.
//! preset = "two-finger"
//! [finger]
//! length_m = 0.09
//! vertex_budget = 800
//! ```
//!
//! ```toml
//! # Explicit fingers: one parametric, one from a mesh file.
//! [[fingers]]
//! params = { length_m = 0.07 }
//! position_m = [0.025, 0.0, 0.0]
//! rotation_axis_angle_rad = [0.0, 0.0, 3.141592653589793]
//!
//! [[fingers]]
//! mesh = "finger.obj"            # relative to this file's directory; metres, finger frame
//! marker_vertices = [4, 5, 6]
//! base_vertices = [0, 1, 2, 3]
//! tendons = [{ points_in_finger = [[0.005, 0, 0], [0.005, 0, 0.05]], antagonist = 1 },
//!            { points_in_finger = [[-0.005, 0, 0], [-0.005, 0, 0.05]], antagonist = 0 }]
//! position_m = [-0.025, 0.0, 0.0]
//! ```
//!
//! A parametric finger's markers follow its `marker_layout` (see `moe_geom::MarkerLayout`): a
//! preset name or a table of rows (each at an angle around the finger, 0° = the camera side,
//! `count` defaulting to `marker_count`) and a ring near the tip.
//!
//! ```toml
//! # Two rows of seven markers at ±35° (presets: camera-row, two-rows, sides, tip-ring).
//! preset = "two-finger"
//! [finger]
//! marker_layout = "two-rows"
//! ```
//!
//! ```toml
//! # The camera row, three markers on the back and a ring of four at 85 % of the length.
//! preset = "three-finger"
//! [finger]
//! marker_layout = { rows = [{ angle_deg = 0 }, { angle_deg = 180, count = 3 }], tip_ring = 4, tip_ring_height_ratio = 0.85 }
//! ```
//!
//! The pose of an explicit finger is `hand_from_finger`: the finger frame is rotated by the
//! axis-angle vector `rotation_axis_angle_rad` (axis × angle, radians) and then translated by
//! `position_m`. Both default to zero.

use std::path::{Path, PathBuf};

use moe_geom::{
    FingerModel, FingerParams, HandFinger, HandFromFinger, HandModel, HandPreset, Iso3, Point3,
    TendonRoute, Vector3,
};
use serde::{Deserialize, Serialize};

use crate::atomic::parent_dir;
use crate::config::read_config;
use crate::error::IoError;
use crate::mesh_io::read_mesh;

/// A hand config: exactly one of `preset` or `fingers`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandConfig {
    /// A built-in layout (`"two-finger"`, `"three-finger"`, `"five-finger"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<HandPreset>,
    /// Finger parameters for every finger of the preset (omitted fields keep their defaults).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub finger: Option<FingerParams>,
    /// Explicitly placed fingers (instead of a preset).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fingers: Vec<FingerConfig>,
}

/// One explicitly placed finger: either `params` or `mesh`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerConfig {
    /// Parametric finger parameters (omitted fields keep their defaults).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub params: Option<FingerParams>,
    /// The user's own closed finger mesh (`.obj`, `.ply`, `.stl`), metres, finger frame;
    /// relative paths are resolved against the config file's directory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<PathBuf>,
    /// Marker vertex ids of `mesh`, base to tip (mesh fingers only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub marker_vertices: Vec<u32>,
    /// Vertex ids of `mesh` fixed to the palm (mesh fingers only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub base_vertices: Vec<u32>,
    /// Tendon routes in the finger frame (mesh fingers only; may be empty).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tendons: Vec<TendonConfig>,
    /// Position of the finger frame's origin in the hand frame, metres.
    #[serde(default)]
    pub position_m: [f64; 3],
    /// Rotation of the finger frame in the hand frame, as an axis-angle vector, radians.
    #[serde(default)]
    pub rotation_axis_angle_rad: [f64; 3],
}

/// A tendon route of a mesh finger.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TendonConfig {
    /// Polyline from the base to the anchor, finger frame, metres.
    pub points_in_finger: Vec<[f64; 3]>,
    /// Index of the antagonistic tendon of the same finger.
    pub antagonist: usize,
}

/// Loads a hand config (`.toml` or `.json`) and builds the hand.
///
/// # Errors
/// Parse errors of the config (with line and column), [`IoError::Config`] for inconsistent
/// entries (naming the finger), [`IoError::Referenced`] when a finger mesh cannot be read, and
/// [`IoError::Geometry`] when the fingers are invalid (open mesh, bad vertex ids...).
pub fn load_hand_config(path: &Path) -> Result<HandModel, IoError> {
    let config: HandConfig = read_config(path)?;
    config.build(path)
}

impl HandConfig {
    /// Builds the hand; `path` is the config's own path, used to resolve relative mesh paths and
    /// to name errors.
    ///
    /// # Errors
    /// As [`load_hand_config`].
    pub fn build(&self, path: &Path) -> Result<HandModel, IoError> {
        let config_error = |message: String| IoError::Config {
            path: path.to_path_buf(),
            message,
        };
        let geometry = |e| IoError::geometry(path, e);
        match (self.preset, self.fingers.is_empty()) {
            (Some(_), false) => Err(config_error(
                "give either 'preset' or '[[fingers]]', not both".into(),
            )),
            (None, true) => Err(config_error(
                "give a 'preset' or at least one '[[fingers]]' entry".into(),
            )),
            (Some(preset), true) => {
                let params = self.finger.clone().unwrap_or_default();
                HandModel::preset(preset, &params).map_err(geometry)
            }
            (None, false) => {
                if self.finger.is_some() {
                    return Err(config_error(
                        "'[finger]' applies to presets only; give each finger its own 'params'"
                            .into(),
                    ));
                }
                let fingers = self
                    .fingers
                    .iter()
                    .enumerate()
                    .map(|(i, f)| f.build(i, path))
                    .collect::<Result<Vec<_>, _>>()?;
                HandModel::new(fingers).map_err(geometry)
            }
        }
    }
}

impl FingerConfig {
    fn build(&self, index: usize, config_path: &Path) -> Result<HandFinger, IoError> {
        let config_error = |message: String| IoError::Config {
            path: config_path.to_path_buf(),
            message: format!("fingers[{index}]: {message}"),
        };
        let geometry = |e| IoError::InvalidData {
            path: config_path.to_path_buf(),
            item: format!("fingers[{index}]"),
            message: format!("{e}"),
        };
        let model = match (&self.params, &self.mesh) {
            (Some(_), Some(_)) => {
                return Err(config_error(
                    "give either 'params' or 'mesh', not both".into(),
                ));
            }
            (None, None) => return Err(config_error("give 'params' or 'mesh'".into())),
            (Some(params), None) => {
                if !(self.marker_vertices.is_empty()
                    && self.base_vertices.is_empty()
                    && self.tendons.is_empty())
                {
                    return Err(config_error(
                        "'marker_vertices', 'base_vertices' and 'tendons' belong to mesh fingers; \
                         a parametric finger places its own"
                            .into(),
                    ));
                }
                FingerModel::from_params(params).map_err(geometry)?
            }
            (None, Some(mesh_path)) => {
                let resolved = parent_dir(config_path).join(mesh_path);
                let mesh = read_mesh(&resolved).map_err(|e| IoError::Referenced {
                    path: config_path.to_path_buf(),
                    what: format!("fingers[{index}].mesh"),
                    source: Box::new(e),
                })?;
                let tendons = self
                    .tendons
                    .iter()
                    .map(|t| TendonRoute {
                        points_in_finger: t
                            .points_in_finger
                            .iter()
                            .map(|p| Point3::new(p[0], p[1], p[2]))
                            .collect(),
                        antagonist: t.antagonist,
                    })
                    .collect();
                FingerModel::from_parts(
                    mesh,
                    self.marker_vertices.clone(),
                    self.base_vertices.clone(),
                    tendons,
                )
                .map_err(geometry)?
            }
        };
        let finite = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
        if !finite(&self.position_m) || !finite(&self.rotation_axis_angle_rad) {
            return Err(config_error("pose has a non-finite value".into()));
        }
        let iso = Iso3::new(
            Vector3::from(self.position_m),
            Vector3::from(self.rotation_axis_angle_rad),
        );
        Ok(HandFinger {
            model,
            hand_from_finger: HandFromFinger::new(iso),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::parse_toml;

    fn build(toml_text: &str) -> Result<HandModel, IoError> {
        let path = Path::new("hand.toml");
        let c: HandConfig = parse_toml(toml_text.as_bytes(), path)?;
        c.build(path)
    }

    #[test]
    fn preset_with_overrides_uses_them() {
        let h =
            build("preset = \"three-finger\"\n[finger]\nlength_m = 0.06\nvertex_budget = 300\n")
                .unwrap();
        assert_eq!(h.num_fingers(), 3);
        let zmax = h.fingers()[0]
            .model
            .mesh()
            .vertices()
            .iter()
            .map(|p| p.z)
            .fold(f64::MIN, f64::max);
        assert!((zmax - 0.06).abs() < 1e-9, "{zmax}");
    }

    #[test]
    fn explicit_parametric_fingers_get_their_pose() {
        let h = build(
            "[[fingers]]\nparams = { vertex_budget = 200 }\nposition_m = [0.01, 0.02, 0.03]\n\
             rotation_axis_angle_rad = [0.0, 0.0, 1.5707963267948966]\n",
        )
        .unwrap();
        let iso = h.fingers()[0].hand_from_finger.iso();
        let p = iso * Point3::new(1.0, 0.0, 0.0);
        assert!((p - Point3::new(0.01, 1.02, 0.03)).norm() < 1e-12, "{p}");
    }

    #[test]
    fn inconsistent_configs_are_rejected_with_reasons() {
        let both = build("preset = \"two-finger\"\n[[fingers]]\nparams = {}\n").unwrap_err();
        assert!(matches!(both, IoError::Config { .. }), "{both}");
        assert!(matches!(build("").unwrap_err(), IoError::Config { .. }));
        let unknown = build("preset = \"two-finger\"\nextra = 1\n").unwrap_err();
        assert!(
            matches!(unknown, IoError::Parse { line: Some(2), .. }),
            "{unknown}"
        );
        let bad_param = build("preset = \"two-finger\"\n[finger]\nlength_m = -1.0\n").unwrap_err();
        assert!(matches!(bad_param, IoError::Geometry { .. }), "{bad_param}");
        let ids_on_param = build("[[fingers]]\nparams = {}\nmarker_vertices = [1]\n").unwrap_err();
        assert!(
            ids_on_param.to_string().contains("fingers[0]"),
            "{ids_on_param}"
        );
        let missing = build("[[fingers]]\nmesh = \"does-not-exist.obj\"\nmarker_vertices = [0]\nbase_vertices = [1]\n")
            .unwrap_err();
        assert!(matches!(missing, IoError::Referenced { .. }), "{missing}");
        assert!(
            missing.to_string().contains("does-not-exist.obj"),
            "{missing}"
        );
    }

    fn marker_counts(h: &HandModel) -> Vec<usize> {
        h.fingers()
            .iter()
            .map(|f| f.model.marker_vertices().len())
            .collect()
    }

    #[test]
    fn marker_layouts_by_name_or_table() {
        for (name, count) in [
            ("camera-row", 7),
            ("two-rows", 14),
            ("sides", 21),
            ("tip-ring", 13),
        ] {
            let h = build(&format!(
                "preset = \"two-finger\"\n[finger]\nmarker_layout = \"{name}\"\n"
            ))
            .unwrap();
            assert_eq!(marker_counts(&h), [count, count], "{name}");
        }
        // The default layout spelled out is the default finger: same marker ids.
        let default = build("preset = \"two-finger\"\n").unwrap();
        let spelled = build(
            "preset = \"two-finger\"\n[finger]\nmarker_layout = { rows = [{ angle_deg = 0 }] }\n",
        )
        .unwrap();
        assert_eq!(spelled, default);
        // A table: rows with and without a count, a ring; per explicit finger too.
        let h = build(
            "preset = \"three-finger\"\n[finger]\nmarker_count = 5\nmarker_layout = { rows = \
             [{ angle_deg = 0 }, { angle_deg = 180, count = 3 }], tip_ring = 4, \
             tip_ring_height_ratio = 0.85 }\n",
        )
        .unwrap();
        assert_eq!(marker_counts(&h), [12, 12, 12]);
        let h = build(
            "[[fingers]]\nparams = { marker_layout = \"sides\" }\n\
             [[fingers]]\nparams = { marker_layout = { tip_ring = 6 } }\nposition_m = [0.05, 0, 0]\n",
        )
        .unwrap();
        assert_eq!(marker_counts(&h), [21, 13]);
        // JSON takes the same forms.
        let path = Path::new("hand.json");
        let c: HandConfig = crate::config::parse_json(
            br#"{"preset": "two-finger", "finger": {"marker_layout": {"rows": [{"angle_deg": 35}, {"angle_deg": -35}]}}}"#,
            path,
        )
        .unwrap();
        assert_eq!(
            c.finger.as_ref().unwrap().marker_layout,
            moe_geom::MarkerLayoutPreset::TwoRows.layout()
        );
    }

    #[test]
    fn marker_layouts_round_trip_and_the_default_is_not_written() {
        let text = toml::to_string(&FingerParams::default()).unwrap();
        assert!(!text.contains("marker_layout"), "{text}");
        for preset in moe_geom::MarkerLayoutPreset::ALL {
            let params = FingerParams {
                marker_layout: preset.layout(),
                ..FingerParams::default()
            };
            let text = toml::to_string(&params).unwrap();
            let back: FingerParams = toml::from_str(&text).unwrap();
            assert_eq!(back, params, "{text}");
            let json = serde_json::to_string(&params).unwrap();
            let back: FingerParams = serde_json::from_str(&json).unwrap();
            assert_eq!(back, params, "{json}");
        }
    }

    #[test]
    fn bad_marker_layouts_are_refused_naming_them() {
        let unknown = build("preset = \"two-finger\"\n[finger]\nmarker_layout = \"three-rows\"\n")
            .unwrap_err();
        let msg = unknown.to_string();
        assert!(
            matches!(unknown, IoError::Parse { line: Some(3), .. }),
            "{msg}"
        );
        assert!(
            msg.contains("three-rows") && msg.contains("two-rows"),
            "{msg}"
        );
        let field = build(
            "preset = \"two-finger\"\n[finger]\nmarker_layout = { rows = [{ angle = 35 }] }\n",
        )
        .unwrap_err();
        assert!(field.to_string().contains("angle"), "{field}");
        for (text, name) in [
            (
                "marker_layout = { rows = [{ angle_deg = 270 }] }",
                "marker_layout.rows.angle_deg",
            ),
            (
                "marker_layout = { rows = [{ count = 0 }] }",
                "marker_layout.rows.count",
            ),
            (
                "marker_layout = { rows = [{ angle_deg = 0 }, { angle_deg = 1 }] }",
                "marker_layout.rows",
            ),
            (
                "marker_layout = { tip_ring = 6, tip_ring_height_ratio = 0.05 }",
                "marker_layout.tip_ring_height_ratio",
            ),
        ] {
            let err = build(&format!("preset = \"two-finger\"\n[finger]\n{text}\n")).unwrap_err();
            assert!(matches!(err, IoError::Geometry { .. }), "{err}");
            assert!(err.to_string().contains(name), "{text}: {err}");
        }
    }
}
