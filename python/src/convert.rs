//! Errors to Python exceptions, numpy arrays to the workspace's types and back.

use moe_geom::{Iso3, Point3, Real, Vector3};
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion};
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::{Kind, kind_of, raise_kind};

/// Raises a Rust error as the `MoeTouchError` of its kind (`MoeTouchFileNotFoundError`,
/// `MoeTouchOSError` or `MoeTouchValueError`) with the one line the `moe-touch` tool prints.
pub(crate) fn raise(err: &(dyn std::error::Error + 'static)) -> PyErr {
    raise_kind(kind_of(err), moe_touch::error::one_line(err))
}

/// Raises `MoeTouchValueError` with `message` (bad input caught before the Rust code sees it).
pub(crate) fn invalid(message: impl Into<String>) -> PyErr {
    raise_kind(Kind::Value, message.into())
}

/// `.py()?` turns any of the workspace's errors into the `MoeTouchError` of its kind.
pub(crate) trait OrRaise<T> {
    /// The value, or the error raised as the `MoeTouchError` of its kind.
    fn py(self) -> PyResult<T>;
}

impl<T, E: std::error::Error + 'static> OrRaise<T> for Result<T, E> {
    fn py(self) -> PyResult<T> {
        self.map_err(|e| raise(&e))
    }
}

/// Points as an `(n, 3)` float64 array.
pub(crate) fn points<'py>(py: Python<'py>, points: &[Point3]) -> Bound<'py, PyArray2<f64>> {
    rows(py, points.iter().map(|p| [p.x, p.y, p.z]), points.len())
}

/// Vectors as an `(n, 3)` float64 array.
pub(crate) fn vectors<'py>(py: Python<'py>, vectors: &[Vector3]) -> Bound<'py, PyArray2<f64>> {
    rows(py, vectors.iter().map(|v| [v.x, v.y, v.z]), vectors.len())
}

/// Optional points (a marker that was not seen) as an `(n, 3)` array, NaN where missing.
pub(crate) fn optional_points<'py>(
    py: Python<'py>,
    points: &[Option<Point3>],
) -> Bound<'py, PyArray2<f64>> {
    rows(
        py,
        points
            .iter()
            .map(|p| p.map_or([Real::NAN; 3], |p| [p.x, p.y, p.z])),
        points.len(),
    )
}

/// Rows of three as an `(n, 3)` array (the one copy out of the Rust layout; the array owns it).
pub(crate) fn rows<'py, T: numpy::Element + Copy>(
    py: Python<'py>,
    rows: impl Iterator<Item = [T; 3]>,
    n: usize,
) -> Bound<'py, PyArray2<T>> {
    let mut flat = Vec::with_capacity(3 * n);
    for r in rows {
        flat.extend_from_slice(&r);
    }
    let n = flat.len() / 3;
    // `flat` holds whole rows, so the shape always fits.
    match Array2::from_shape_vec((n, 3), flat) {
        Ok(a) => a.into_pyarray(py),
        Err(_) => PyArray2::zeros(py, [0, 3], false),
    }
}

/// A vector as a 1-D array, moved into numpy without a copy.
pub(crate) fn array1<'py, T: numpy::Element>(
    py: Python<'py>,
    v: Vec<T>,
) -> Bound<'py, PyArray1<T>> {
    Array1::from_vec(v).into_pyarray(py)
}

/// The rows of an `(n, 3)` array; `what` names it in the error.
fn rows_of(array: &PyReadonlyArray2<'_, f64>, what: &str) -> PyResult<Vec<[f64; 3]>> {
    let a = array.as_array();
    if a.ncols() != 3 {
        return Err(invalid(format!(
            "{what}: expected an (n, 3) array, got shape {:?}",
            a.shape()
        )));
    }
    Ok(a.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

/// An `(n, 3)` array of finite numbers as points; `what` names it in the error.
pub(crate) fn to_points(array: &PyReadonlyArray2<'_, f64>, what: &str) -> PyResult<Vec<Point3>> {
    rows_of(array, what)?
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            if r.iter().all(|x| x.is_finite()) {
                Ok(Point3::from(r))
            } else {
                Err(invalid(format!("{what}: row {i} is not finite ({r:?})")))
            }
        })
        .collect()
}

/// Points from an `(n, 3)` array whose all-NaN rows are missing (a marker not seen, a free
/// handle); `what` names it in the error.
pub(crate) fn to_optional_points(
    array: &PyReadonlyArray2<'_, f64>,
    what: &str,
) -> PyResult<Vec<Option<Point3>>> {
    rows_of(array, what)?
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            if r.iter().all(|x| x.is_nan()) {
                Ok(None)
            } else if r.iter().all(|x| x.is_finite()) {
                Ok(Some(Point3::from(r)))
            } else {
                Err(invalid(format!(
                    "{what}: row {i} is neither finite nor all NaN (missing)"
                )))
            }
        })
        .collect()
}

/// A 4 × 4 rigid transform (rotation orthonormal to 1e-6, last row `0 0 0 1`, finite); `what`
/// names it in the error.
pub(crate) fn to_iso(array: &PyReadonlyArray2<'_, f64>, what: &str) -> PyResult<Iso3> {
    let a = array.as_array();
    if a.shape() != [4, 4] {
        return Err(invalid(format!(
            "{what}: expected a 4 x 4 transform, got shape {:?}",
            a.shape()
        )));
    }
    if a.iter().any(|x| !x.is_finite()) {
        return Err(invalid(format!("{what}: the transform is not finite")));
    }
    let last_row = [a[[3, 0]], a[[3, 1]], a[[3, 2]], a[[3, 3]]];
    if last_row != [0.0, 0.0, 0.0, 1.0] {
        return Err(invalid(format!(
            "{what}: the last row must be 0 0 0 1, got {last_row:?}"
        )));
    }
    let r = Matrix3::from_fn(|i, j| a[[i, j]]);
    let off = (r.transpose() * r - Matrix3::identity()).abs().max();
    if off > 1e-6 || r.determinant() < 0.0 {
        return Err(invalid(format!(
            "{what}: the upper-left 3 x 3 block is not a rotation (|RᵀR − I| = {off:.1e}, det = \
             {:.6})",
            r.determinant()
        )));
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(Iso3::from_parts(
        Translation3::new(a[[0, 3]], a[[1, 3]], a[[2, 3]]),
        rotation,
    ))
}

/// A rigid transform as a 4 × 4 array.
pub(crate) fn iso<'py>(py: Python<'py>, iso: &Iso3) -> Bound<'py, PyArray2<f64>> {
    let m = iso.to_homogeneous();
    Array2::from_shape_fn((4, 4), |(i, j)| m[(i, j)]).into_pyarray(py)
}

/// Locks a pipeline's or estimator's state (`what` names it if a panic in another thread left
/// it poisoned). Called with the GIL released, so that waiting for another thread's call does
/// not hold the interpreter.
pub(crate) fn lock<'a, T>(
    state: &'a std::sync::Mutex<T>,
    what: &str,
) -> PyResult<std::sync::MutexGuard<'a, T>> {
    state.lock().map_err(|_| {
        invalid(format!(
            "the {what} failed in another thread; make a new one"
        ))
    })
}

/// The tendon pulls of a hand of `fingers` fingers with `tendons` tendons each (`None`: its
/// fingers differ, which an array cannot hold) from an `(fingers, tendons)` array.
pub(crate) fn to_hand_pulls(
    array: &PyReadonlyArray2<'_, f64>,
    fingers: usize,
    tendons: Option<usize>,
) -> PyResult<Vec<Vec<f64>>> {
    let Some(tendons) = tendons else {
        return Err(invalid(
            "pulls: the hand's fingers have different numbers of tendons, which an array of \
             pulls cannot hold",
        ));
    };
    let shape = [fingers, tendons];
    if array.shape() != shape {
        return Err(invalid(format!(
            "pulls: expected shape {shape:?} (fingers, tendons), got {:?}",
            array.shape()
        )));
    }
    to_pulls(array)
}

/// Tendon pulls `[finger][tendon]` from an `(fingers, tendons)` array.
pub(crate) fn to_pulls(array: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<Vec<f64>>> {
    let a = array.as_array();
    if let Some(((f, t), x)) = a.indexed_iter().find(|(_, x)| !x.is_finite()) {
        return Err(invalid(format!(
            "pulls: finger {f}, tendon {t} is not finite ({x})"
        )));
    }
    Ok(a.rows().into_iter().map(|r| r.to_vec()).collect())
}

/// Tendon pulls `[finger][tendon]` as an `(fingers, tendons)` array.
pub(crate) fn pulls<'py>(
    py: Python<'py>,
    pulls: &[Vec<f64>],
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let cols = pulls.first().map_or(0, Vec::len);
    if pulls.iter().any(|p| p.len() != cols) {
        return Err(invalid(
            "tendon pulls: fingers have different numbers of tendons",
        ));
    }
    let flat: Vec<f64> = pulls.iter().flatten().copied().collect();
    Array2::from_shape_vec((pulls.len(), cols), flat)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| invalid(format!("tendon pulls: {e}")))
}
