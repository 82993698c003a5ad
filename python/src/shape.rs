//! SR-ARAP: a mesh deformed by fixed and handle vertices, and the hand's shape from its
//! markers.

use moe_arap::{ArapConfig, ShapeConfig, Start};
use moe_geom::{HandKeypoints, TriMesh};
use numpy::{AllowTypeChange, PyArray2, PyArrayLike1, PyArrayLike2, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::convert::{self, OrRaise, invalid};
use crate::hand::Hand;

/// Keypoints `[finger][marker]` from one `(markers, 3)` array per finger (NaN rows: not seen).
pub(crate) fn to_keypoints(
    fingers: &[PyReadonlyArray2<'_, f64>],
    what: &str,
) -> PyResult<HandKeypoints> {
    let fingers = fingers
        .iter()
        .enumerate()
        .map(|(f, a)| convert::to_optional_points(a, &format!("{what}[{f}]")))
        .collect::<PyResult<_>>()?;
    Ok(HandKeypoints { fingers })
}

/// Vertex ids from Python integers; `what` names them in the error.
fn vertex_ids<'a>(ids: impl Iterator<Item = &'a i64>, what: &str) -> PyResult<Vec<u32>> {
    ids.map(|&i| u32::try_from(i).map_err(|_| invalid(format!("{what}: vertex id {i}"))))
        .collect()
}

/// `MultiShapeEstimator`'s settings: `given` (the defaults without) with `iterations` per
/// frame and `warm_start` on top when set.
pub(crate) fn shape_config(
    given: ShapeConfig,
    iterations: Option<usize>,
    warm_start: bool,
) -> ShapeConfig {
    ShapeConfig {
        iterations: iterations.unwrap_or(given.iterations),
        warm_start: warm_start || given.warm_start,
        ..given
    }
}

/// SR-ARAP on any triangle mesh (one or many connected parts): factorised once for its fixed
/// and handle vertices, then solved for any targets.
#[pyclass(module = "moe_touch", frozen)]
pub struct ArapSolver {
    solver: moe_arap::ArapSolver,
}

#[pymethods]
impl ArapSolver {
    /// Builds and factorises SR-ARAP for `vertices` `(n, 3)` and `faces` `(m, 3)`, with
    /// `fixed` vertex ids held at their targets and `handles` pulled towards theirs (every part
    /// needs a fixed vertex). `alpha` is the smoothness weight, `iterations` the local-global
    /// iterations of a solve.
    #[new]
    #[pyo3(signature = (vertices, faces, fixed, handles, *, alpha=None, iterations=None))]
    fn new(
        py: Python<'_>,
        vertices: PyReadonlyArray2<'_, f64>,
        faces: PyArrayLike2<'_, i64, AllowTypeChange>,
        fixed: PyArrayLike1<'_, i64, AllowTypeChange>,
        handles: PyArrayLike1<'_, i64, AllowTypeChange>,
        alpha: Option<f64>,
        iterations: Option<usize>,
    ) -> PyResult<Self> {
        let vertices = convert::to_points(&vertices, "vertices")?;
        let f = faces.as_array();
        if f.ncols() != 3 {
            return Err(invalid(format!(
                "faces: expected an (m, 3) array, got shape {:?}",
                f.shape()
            )));
        }
        let faces: Vec<[u32; 3]> = vertex_ids(f.iter(), "faces")?
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let fixed = vertex_ids(fixed.as_array().iter(), "fixed")?;
        let handles = vertex_ids(handles.as_array().iter(), "handles")?;
        let mut config = ArapConfig::default();
        if let Some(a) = alpha {
            config.alpha = a;
        }
        if let Some(i) = iterations {
            config.iterations = i;
        }
        let solver = py.detach(|| {
            let mesh = TriMesh::new(vertices, faces).py()?;
            moe_arap::ArapSolver::new(&mesh, &config, &fixed, &handles).py()
        })?;
        Ok(Self { solver })
    }

    /// Deforms the mesh: `fixed_targets` `(len(fixed), 3)`, `handle_targets`
    /// `(len(handles), 3)` (a NaN row leaves that handle free). Starts from rest (the paper's
    /// setting) or from `start` `(n, 3)`. Returns the vertices `(n, 3)`.
    #[pyo3(signature = (fixed_targets, handle_targets, start=None))]
    fn solve<'py>(
        &self,
        py: Python<'py>,
        fixed_targets: PyReadonlyArray2<'py, f64>,
        handle_targets: PyReadonlyArray2<'py, f64>,
        start: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let fixed = convert::to_points(&fixed_targets, "fixed_targets")?;
        let handles = convert::to_optional_points(&handle_targets, "handle_targets")?;
        let start = start.map(|s| convert::to_points(&s, "start")).transpose()?;
        let solution = py.detach(|| {
            let start = start.as_deref().map_or(Start::Rest, Start::Positions);
            self.solver.solve(&fixed, &handles, start).py()
        })?;
        Ok(convert::points(py, &solution.vertices))
    }

    /// Number of vertices.
    #[getter]
    fn num_vertices(&self) -> usize {
        self.solver.num_vertices()
    }

    /// Number of connected parts (each solved on its own).
    #[getter]
    fn num_parts(&self) -> usize {
        self.solver.num_parts()
    }
}

/// The hand's shape from its markers by SR-ARAP (the paper's shape stage, Rust's
/// `moe_arap::MultiShapeEstimator`): the markers are handles, the finger bases fixed.
#[pyclass(module = "moe_touch")]
pub struct MultiShapeEstimator {
    estimator: std::sync::Mutex<moe_arap::MultiShapeEstimator>,
}

#[pymethods]
impl MultiShapeEstimator {
    /// SR-ARAP for `hand` with `iterations` per frame (default 50) and, with `warm_start`,
    /// each frame starting from the previous shape (the paper starts from rest).
    #[new]
    #[pyo3(signature = (hand, *, iterations=None, warm_start=false))]
    fn new(hand: &Hand, iterations: Option<usize>, warm_start: bool) -> PyResult<Self> {
        let estimator = moe_arap::MultiShapeEstimator::new(
            hand.model.clone(),
            shape_config(ShapeConfig::default(), iterations, warm_start),
        )
        .py()?;
        Ok(Self {
            estimator: std::sync::Mutex::new(estimator),
        })
    }

    /// The hand's surface from `keypoints`, one `(markers, 3)` array per finger, hand frame
    /// (NaN rows: markers not seen). Returns one `(n, 3)` array per finger, hand frame.
    fn estimate<'py>(
        &self,
        py: Python<'py>,
        keypoints: Vec<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Vec<Bound<'py, PyArray2<f64>>>> {
        let keypoints = to_keypoints(&keypoints, "keypoints")?;
        let shape = py.detach(|| {
            let mut estimator = convert::lock(&self.estimator, "shape estimator")?;
            estimator.estimate(&keypoints).py()
        })?;
        Ok(shape
            .shape
            .fingers
            .iter()
            .map(|f| convert::points(py, f))
            .collect())
    }
}
