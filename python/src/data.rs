//! Reading episodes (the simulator's MCAP and ROS 2 recordings) and data sets, as numpy arrays.

use std::path::PathBuf;

use moe_io::{DatasetFrame, DatasetReader, Split, SplitFractions};
use moe_record::ros2::RosConfig;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::card::DatasetCard;
use crate::convert::{self, OrRaise, invalid};
use crate::hand::{Camera, Hand};
use crate::settings::settings;

/// One frame of an episode: the camera's images, the hand's pose, the tendon pulls and, for a
/// simulated episode, the ground truth.
#[pyclass(module = "moe_touch", frozen, get_all)]
pub struct EpisodeFrame {
    /// Time, nanoseconds.
    time_ns: u64,
    /// Time, seconds.
    time: f64,
    /// Colour, `(height, width, 3)` uint8 RGB.
    color: Py<PyArray3<u8>>,
    /// Depth aligned to colour, `(height, width)` float32 metres (0 or NaN: none).
    depth: Py<PyArray2<f32>>,
    /// Where the hand was, world-from-hand 4 × 4.
    world_from_hand: Py<PyArray2<f64>>,
    /// Tendon pulls, `(fingers, tendons)` metres.
    pulls: Py<PyArray2<f64>>,
    /// True surface, hand frame, `(n, 3)` per finger (simulated episodes), else None.
    true_vertices: Option<Vec<Py<PyArray2<f64>>>>,
    /// True contact vertices per finger (simulated episodes), else None.
    true_contact_vertices: Option<Vec<Py<PyArray1<u32>>>>,
    /// True marker centres, hand frame, `(markers, 3)` per finger (simulated), else None.
    true_markers: Option<Vec<Py<PyArray2<f64>>>>,
}

impl EpisodeFrame {
    /// Moves the frame's images into numpy (no copy) and converts the rest.
    fn new(py: Python<'_>, f: moe_record::EpisodeFrame, h: usize, w: usize) -> PyResult<Self> {
        let bad = |what: &str| {
            invalid(format!(
                "frame at {} ns: {what} does not fit {w} x {h}",
                f.time_ns
            ))
        };
        let color = Array3::from_shape_vec((h, w, 3), f.color_rgb8)
            .map_err(|_| bad("colour"))?
            .into_pyarray(py)
            .unbind();
        let depth = Array2::from_shape_vec((h, w), f.depth_m)
            .map_err(|_| bad("depth"))?
            .into_pyarray(py)
            .unbind();
        let truth = !f.finger_vertices_in_hand.is_empty();
        let per_finger = |v: &[Vec<moe_geom::Point3>]| {
            v.iter()
                .map(|p| convert::points(py, p).unbind())
                .collect::<Vec<_>>()
        };
        Ok(Self {
            time_ns: f.time_ns,
            time: 1e-9 * f.time_ns as f64,
            color,
            depth,
            world_from_hand: convert::iso(py, &f.world_from_hand).unbind(),
            pulls: convert::pulls(py, &f.tendon_pull_m)?.unbind(),
            true_vertices: truth.then(|| per_finger(&f.finger_vertices_in_hand)),
            true_contact_vertices: truth.then(|| {
                f.contact_vertices
                    .into_iter()
                    .map(|v| convert::array1(py, v).unbind())
                    .collect()
            }),
            true_markers: (!f.markers_in_hand.is_empty()).then(|| per_finger(&f.markers_in_hand)),
        })
    }
}

#[pymethods]
impl EpisodeFrame {
    fn __repr__(&self) -> String {
        format!("EpisodeFrame(time={:.3} s)", self.time)
    }
}

/// A recorded episode: the camera, the hand's layout and the frames.
#[pyclass(module = "moe_touch", frozen)]
pub struct Episode {
    /// The scene's name.
    scene: String,
    camera: Camera,
    num_fingers: usize,
    tendons_per_finger: usize,
    frames: Vec<Py<EpisodeFrame>>,
    truncated: Option<String>,
}

impl Episode {
    fn new(
        py: Python<'_>,
        episode: moe_record::Episode,
        truncated: Option<String>,
    ) -> PyResult<Self> {
        let info = episode.info;
        let (h, w) = (info.camera.height as usize, info.camera.width as usize);
        let frames = episode
            .frames
            .into_iter()
            .map(|f| Py::new(py, EpisodeFrame::new(py, f, h, w)?))
            .collect::<PyResult<_>>()?;
        Ok(Self {
            camera: Camera::of_episode(&info),
            num_fingers: info.hand_from_finger.len(),
            tendons_per_finger: info.tendons_per_finger,
            scene: info.scene,
            frames,
            truncated,
        })
    }
}

#[pymethods]
impl Episode {
    /// The scene's name.
    #[getter]
    fn scene(&self) -> &str {
        &self.scene
    }

    /// The wrist camera (intrinsics and mounting on the hand).
    #[getter]
    fn camera(&self) -> Camera {
        self.camera
    }

    /// Number of fingers of the recorded hand.
    #[getter]
    fn num_fingers(&self) -> usize {
        self.num_fingers
    }

    /// Tendons per finger.
    #[getter]
    fn tendons_per_finger(&self) -> usize {
        self.tendons_per_finger
    }

    /// Why the episode ends early (a file cut short is read up to its last whole frame), else
    /// None.
    #[getter]
    fn truncated(&self) -> Option<&str> {
        self.truncated.as_deref()
    }

    /// The frames, in time order.
    #[getter]
    fn frames(&self, py: Python<'_>) -> Vec<Py<EpisodeFrame>> {
        self.frames.iter().map(|f| f.clone_ref(py)).collect()
    }

    fn __len__(&self) -> usize {
        self.frames.len()
    }

    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyIterator>> {
        pyo3::types::PyList::new(py, self.frames.iter().map(|f| f.clone_ref(py)))?.try_iter()
    }

    fn __getitem__(&self, py: Python<'_>, index: isize) -> PyResult<Py<EpisodeFrame>> {
        let n = self.frames.len() as isize;
        let i = if index < 0 { index + n } else { index };
        usize::try_from(i)
            .ok()
            .and_then(|i| self.frames.get(i))
            .map(|f| f.clone_ref(py))
            .ok_or_else(|| {
                pyo3::exceptions::PyIndexError::new_err(format!(
                    "frame {index} of an episode of {n} frames"
                ))
            })
    }

    fn __repr__(&self) -> String {
        format!(
            "Episode({:?}, {} frames, {} fingers, {} x {})",
            self.scene,
            self.frames.len(),
            self.num_fingers,
            self.camera.intrinsics.width,
            self.camera.intrinsics.height
        )
    }
}

/// Reads an episode: the simulator's MCAP (`moe-touch sim --out`), or a ROS 2 recording (a
/// rosbag2 directory with MCAP storage, or an MCAP file of CDR messages) of `hand` (default:
/// the two-finger preset) with the topics, frames and joint names of `ros` (a TOML or JSON
/// file, or a dict; default: `realsense2_camera`'s topics). A simulated episode cut short is
/// read up to its last whole frame, and `Episode.truncated` says why; it carries its hand's
/// layout, which a given `hand` must fit.
#[pyfunction]
#[pyo3(signature = (path, hand=None, ros=None))]
pub(crate) fn read_episode(
    py: Python<'_>,
    path: PathBuf,
    hand: Option<&Hand>,
    ros: Option<&Bound<'_, PyAny>>,
) -> PyResult<Episode> {
    if ros.is_some() || moe_record::ros2::is_ros2_recording(&path) {
        return read_ros2_bag(py, path, hand, ros);
    }
    let (episode, cut) = py.detach(|| moe_record::read_episode_prefix(&path).py())?;
    if let Some(hand) = hand
        && let Some(reason) = episode.info.hand_mismatch(&hand.model)
    {
        return Err(invalid(format!("hand '{}': {reason}", hand.label())));
    }
    Episode::new(py, episode, cut.map(|e| moe_touch::error::one_line(&e)))
}

/// Reads a ROS 2 recording (see `read_episode`) of `hand` (default: two-finger).
#[pyfunction]
#[pyo3(signature = (path, hand=None, ros=None))]
pub(crate) fn read_ros2_bag(
    py: Python<'_>,
    path: PathBuf,
    hand: Option<&Hand>,
    ros: Option<&Bound<'_, PyAny>>,
) -> PyResult<Episode> {
    let config: RosConfig = settings(ros, "ros")?;
    let hand = match hand {
        Some(h) => h.clone(),
        None => Hand::from_spec("two-finger")?,
    };
    let episode =
        py.detach(|| moe_record::ros2::read_ros2_bag(&path, &config, &hand.model).py())?;
    Episode::new(py, episode, None)
}

/// Whether `path` is a ROS 2 recording (a directory with `metadata.yaml`, or an MCAP file of
/// CDR messages).
#[pyfunction]
pub(crate) fn is_ros2_recording(path: PathBuf) -> bool {
    moe_record::ros2::is_ros2_recording(&path)
}

/// A data set written by `moe-touch gen-data`: its card, and its frames shard by shard as
/// arrays.
#[pyclass(module = "moe_touch", frozen)]
pub struct Dataset {
    reader: DatasetReader,
    /// The card (made once).
    card: Py<DatasetCard>,
}

/// The split named `split` ("train", "validation", "test"), or every frame for None.
fn parse_split(split: Option<&str>) -> PyResult<Option<Split>> {
    match split {
        None => Ok(None),
        Some("train") => Ok(Some(Split::Train)),
        Some("validation") => Ok(Some(Split::Validation)),
        Some("test") => Ok(Some(Split::Test)),
        Some(other) => Err(invalid(format!(
            "split '{other}': expected train, validation or test"
        ))),
    }
}

/// Rows of three of every frame (`items`, `rows` per frame) as an `(F, rows, 3)` array.
fn stack3<'py>(
    py: Python<'py>,
    frames: &[DatasetFrame],
    rows: usize,
    name: &str,
    items: fn(&DatasetFrame) -> &[[f32; 3]],
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let flat: Vec<f32> = frames
        .iter()
        .flat_map(|f| items(f).iter().flatten().copied())
        .collect();
    Array3::from_shape_vec((frames.len(), rows, 3), flat)
        .map(|a| a.into_pyarray(py))
        .map_err(|_| invalid(format!("shard frames: {name} differ in length")))
}

/// Frames stacked along a first axis: the shard's arrays.
fn stacked<'py>(py: Python<'py>, frames: &[DatasetFrame]) -> PyResult<Bound<'py, PyDict>> {
    let n = frames.len();
    let d = PyDict::new(py);
    let ragged = |what: &str| invalid(format!("shard frames: {what} differ in length"));
    macro_rules! stack {
        ($name:literal, $field:ident, $cols:expr) => {{
            let cols = $cols;
            let flat: Vec<_> = frames
                .iter()
                .flat_map(|f| f.$field.iter().copied())
                .collect();
            Array2::from_shape_vec((n, cols), flat)
                .map_err(|_| ragged($name))?
                .into_pyarray(py)
        }};
    }
    let first = frames.first();
    let nv = first.map_or(0, |f| f.vertices.len());
    let nm = first.map_or(0, |f| f.markers.len());
    d.set_item(
        "trajectory_id",
        Array1::from_iter(frames.iter().map(|f| f.trajectory_id)).into_pyarray(py),
    )?;
    d.set_item(
        "frame_index",
        Array1::from_iter(frames.iter().map(|f| f.frame_index)).into_pyarray(py),
    )?;
    d.set_item(
        "vertices",
        stack3(py, frames, nv, "vertices", |f| &f.vertices)?,
    )?;
    d.set_item("contact", stack!("contact", contact, nv))?;
    d.set_item(
        "contact_force_n",
        stack!("contact_force_n", contact_force_n, nv),
    )?;
    d.set_item(
        "obstacle_distance_m",
        stack!("obstacle_distance_m", obstacle_distance_m, nv),
    )?;
    d.set_item(
        "markers",
        stack3(py, frames, nm, "markers", |f| &f.markers)?,
    )?;
    let nf = first
        .and_then(|f| f.finger_force_n.as_ref())
        .map_or(0, Vec::len);
    if n > 0 && frames.iter().all(|f| f.finger_force_n.is_some()) {
        d.set_item(
            "finger_force_n",
            stack3(py, frames, nf, "finger_force_n", |f| {
                f.finger_force_n.as_deref().unwrap_or_default()
            })?,
        )?;
    } else {
        d.set_item("finger_force_n", py.None())?;
    }
    d.set_item(
        "world_from_hand",
        stack!("world_from_hand", world_from_hand, 7),
    )?;
    d.set_item(
        "tendon_pull_m",
        stack!(
            "tendon_pull_m",
            tendon_pull_m,
            first.map_or(0, |f| f.tendon_pull_m.len())
        ),
    )?;
    d.set_item(
        "object_family",
        Array1::from_iter(frames.iter().map(|f| f.object_family)).into_pyarray(py),
    )?;
    d.set_item(
        "object_params",
        stack!(
            "object_params",
            object_params,
            first.map_or(0, |f| f.object_params.len())
        ),
    )?;
    Ok(d)
}

#[pymethods]
impl Dataset {
    /// Opens the data set directory `path` (reads its card; shards are read when asked for).
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let reader = py.detach(|| DatasetReader::open(&path).py())?;
        let card = Py::new(py, DatasetCard::new(py, reader.card())?)?;
        Ok(Self { reader, card })
    }

    /// The card (layout, seed, generator, shards, totals, families; `to_dict()` for the raw
    /// form).
    #[getter]
    fn card(&self, py: Python<'_>) -> Py<DatasetCard> {
        self.card.clone_ref(py)
    }

    /// Number of shards.
    #[getter]
    fn num_shards(&self) -> usize {
        self.reader.num_shards()
    }

    /// Number of frames (the card's total).
    fn __len__(&self) -> usize {
        self.reader.card().totals.frames as usize
    }

    /// Shard `index` as a dict of arrays stacked over its frames: `trajectory_id` (F,),
    /// `frame_index` (F,), `vertices` (F, N, 3), `contact` (F, N) uint8, `contact_force_n` (F,
    /// N), `obstacle_distance_m` (F, N), `markers` (F, M, 3), `finger_force_n` (F, fingers,
    /// 3) or None, `world_from_hand` (F, 7: xyz then quaternion xyzw), `tendon_pull_m` (F, T),
    /// `object_family` (F,), `object_params` (F, P). float32 but `trajectory_id` (uint64),
    /// `frame_index` (uint32), `contact` and `object_family` (uint8) and `world_from_hand`
    /// (float64). An index past the last shard is an `IndexError`.
    fn shard<'py>(&self, py: Python<'py>, index: usize) -> PyResult<Bound<'py, PyDict>> {
        let n = self.reader.num_shards();
        if index >= n {
            return Err(pyo3::exceptions::PyIndexError::new_err(format!(
                "shard {index} of a data set of {n} shards"
            )));
        }
        let frames = py.detach(|| self.reader.shard(index).py())?;
        stacked(py, &frames).map_err(|e| invalid(format!("shard {index}: {e}")))
    }

    /// The frames of `split` ("train", "validation", "test"; None: all), one dict per frame (as
    /// `shard`, without the first axis: scalars for the per-frame numbers), read a shard at a
    /// time. A shard that fails to read raises its error and ends the iteration.
    #[pyo3(signature = (split=None))]
    fn frames(&self, split: Option<&str>) -> PyResult<DatasetFrames> {
        Ok(DatasetFrames {
            frames: self
                .reader
                .clone()
                .into_frames(parse_split(split)?, SplitFractions::default()),
        })
    }
}

/// Iterator over a data set's frames (see `Dataset.frames`): `moe_io`'s, reading a shard at a
/// time with the GIL released.
#[pyclass(module = "moe_touch")]
pub struct DatasetFrames {
    frames: moe_io::dataset::DatasetFrames<DatasetReader>,
}

#[pymethods]
impl DatasetFrames {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let frames = &mut self.frames;
        let Some(frame) = py.detach(|| frames.next()).transpose().py()? else {
            return Ok(None);
        };
        let d = stacked(py, std::slice::from_ref(&frame))?;
        for (k, v) in d.iter() {
            if !v.is_none() {
                d.set_item(k, v.get_item(0)?)?;
            }
        }
        Ok(Some(d))
    }
}
