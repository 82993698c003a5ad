//! The hand (presets and config files) and the wrist camera.

use std::path::PathBuf;

use moe_geom::{CameraIntrinsics, FingerParams, HandFromCamera, HandModel, HandPreset, Transform};
use numpy::{PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::convert::{self, OrRaise, invalid};

/// A soft multi-finger hand: its fingers' rest surfaces, markers and tendons, and where each
/// finger sits on the palm. `Hand.preset("two-finger")` or `Hand.from_file("hand.toml")`.
#[pyclass(module = "moe_touch", frozen)]
#[derive(Debug, Clone)]
pub struct Hand {
    pub(crate) model: HandModel,
    name: String,
}

impl Hand {
    /// The hand of `spec` as `moe-touch --hand` takes it: a preset name or a config file.
    pub(crate) fn from_spec(spec: &str) -> PyResult<Self> {
        if let Ok(preset) = spec.parse::<HandPreset>() {
            return Self::preset(preset.name());
        }
        let path = PathBuf::from(spec);
        if !path.exists() {
            return Err(invalid(format!(
                "hand '{spec}' is neither a preset (two-finger, three-finger, five-finger) nor \
                 an existing config file"
            )));
        }
        Self::from_file(path)
    }

    /// The preset's name or the config file's path.
    pub(crate) fn label(&self) -> &str {
        &self.name
    }

    fn finger(&self, finger: usize) -> PyResult<&moe_geom::HandFinger> {
        self.model.fingers().get(finger).ok_or_else(|| {
            pyo3::exceptions::PyIndexError::new_err(format!(
                "finger {finger} of a hand with {} fingers",
                self.model.num_fingers()
            ))
        })
    }
}

#[pymethods]
impl Hand {
    /// A built-in hand: "two-finger", "three-finger" or "five-finger" (the paper's finger).
    #[staticmethod]
    fn preset(name: &str) -> PyResult<Self> {
        let preset: HandPreset = name.parse().map_err(invalid)?;
        let model = HandModel::preset(preset, &FingerParams::default()).py()?;
        Ok(Self {
            model,
            name: preset.name().to_owned(),
        })
    }

    /// A hand from a config file (TOML or JSON, as `moe-touch hand --write-config` writes
    /// it): your own finger meshes and marker layout.
    #[staticmethod]
    fn from_file(path: PathBuf) -> PyResult<Self> {
        let model = moe_io::load_hand_config(&path).py()?;
        Ok(Self {
            model,
            name: path.display().to_string(),
        })
    }

    /// A preset name or a config file, as the tool's `--hand` takes it.
    #[staticmethod]
    fn load(spec: &str) -> PyResult<Self> {
        Self::from_spec(spec)
    }

    /// The preset's name or the config file's path.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// Number of fingers.
    #[getter]
    fn num_fingers(&self) -> usize {
        self.model.num_fingers()
    }

    /// Tendons of every finger.
    #[getter]
    fn tendons_per_finger(&self) -> PyResult<usize> {
        self.model.tendons_per_finger().py()
    }

    /// Surface vertices of the whole hand.
    #[getter]
    fn num_vertices(&self) -> usize {
        self.model.num_vertices()
    }

    /// Finger `finger`'s rest surface in the hand frame, `(n, 3)` metres.
    fn rest_vertices<'py>(
        &self,
        py: Python<'py>,
        finger: usize,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.finger(finger)?;
        Ok(convert::points(
            py,
            &self.model.rest_vertices_in_hand(finger),
        ))
    }

    /// Finger `finger`'s triangles, `(m, 3)` vertex indices.
    fn faces<'py>(&self, py: Python<'py>, finger: usize) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let f = self.finger(finger)?;
        let faces = f.model.mesh().faces();
        Ok(convert::rows(py, faces.iter().copied(), faces.len()))
    }

    /// The vertices finger `finger`'s markers sit on, in marker order.
    fn marker_vertices<'py>(
        &self,
        py: Python<'py>,
        finger: usize,
    ) -> PyResult<Bound<'py, PyArray1<u32>>> {
        let f = self.finger(finger)?;
        Ok(convert::array1(py, f.model.marker_vertices().to_vec()))
    }

    /// Where finger `finger`'s base sits on the palm: hand-from-finger, 4 × 4.
    fn hand_from_finger<'py>(
        &self,
        py: Python<'py>,
        finger: usize,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let f = self.finger(finger)?;
        Ok(convert::iso(py, f.hand_from_finger.iso()))
    }

    /// Every marker at rest, hand frame: one `(markers, 3)` array per finger.
    fn rest_keypoints<'py>(&self, py: Python<'py>) -> Vec<Bound<'py, PyArray2<f64>>> {
        self.model
            .rest_keypoints()
            .fingers
            .iter()
            .map(|m| convert::optional_points(py, m))
            .collect()
    }

    fn __repr__(&self) -> String {
        format!(
            "Hand({:?}, {} fingers, {} vertices)",
            self.name,
            self.model.num_fingers(),
            self.model.num_vertices()
        )
    }
}

/// The wrist camera: pinhole intrinsics of the colour image (depth is aligned to it) and where
/// the camera sits on the hand.
#[pyclass(module = "moe_touch", frozen)]
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    pub(crate) intrinsics: CameraIntrinsics,
    pub(crate) hand_from_camera: HandFromCamera,
}

impl Camera {
    pub(crate) fn of_episode(info: &moe_record::EpisodeInfo) -> Self {
        Self {
            intrinsics: info.camera.into(),
            hand_from_camera: Transform::new(info.hand_from_camera),
        }
    }
}

#[pymethods]
impl Camera {
    /// A `width` × `height` pinhole camera (focal lengths and principal point in pixels)
    /// mounted at `hand_from_camera` (4 × 4; the camera looks along its +z, x right, y down).
    #[new]
    #[pyo3(signature = (width, height, fx, fy, cx, cy, hand_from_camera))]
    fn new(
        width: u32,
        height: u32,
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        hand_from_camera: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<Self> {
        let intrinsics = CameraIntrinsics {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        };
        intrinsics.validate().py()?;
        Ok(Self {
            intrinsics,
            hand_from_camera: Transform::new(convert::to_iso(
                &hand_from_camera,
                "hand_from_camera",
            )?),
        })
    }

    /// Image width, pixels.
    #[getter]
    fn width(&self) -> u32 {
        self.intrinsics.width
    }

    /// Image height, pixels.
    #[getter]
    fn height(&self) -> u32 {
        self.intrinsics.height
    }

    /// `(fx, fy, cx, cy)`, pixels.
    #[getter]
    fn intrinsics(&self) -> (f64, f64, f64, f64) {
        let c = self.intrinsics;
        (c.fx, c.fy, c.cx, c.cy)
    }

    /// Where the camera sits on the hand, 4 × 4.
    #[getter]
    fn hand_from_camera<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        convert::iso(py, self.hand_from_camera.iso())
    }

    fn __repr__(&self) -> String {
        let c = self.intrinsics;
        format!(
            "Camera({} x {}, fx={}, fy={}, cx={}, cy={})",
            c.width, c.height, c.fx, c.fy, c.cx, c.cy
        )
    }
}
