//! Settings given as a TOML or JSON file, or as a dict of their fields: `material`, `config`,
//! `detector`, `ros`.

use std::path::PathBuf;

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde::de::DeserializeOwned;
use serde_json::Value;

use crate::convert::{OrRaise, invalid};

/// Settings of type `T` from `given`: a path to a TOML or JSON file, a dict of the fields
/// (read through serde as the file would be, so unknown keys are refused naming the key), or
/// None for the defaults. `what` names the argument in errors.
pub(crate) fn settings<T: DeserializeOwned + Default>(
    given: Option<&Bound<'_, PyAny>>,
    what: &str,
) -> PyResult<T> {
    let Some(given) = given.filter(|g| !g.is_none()) else {
        return Ok(T::default());
    };
    if let Ok(dict) = given.cast::<PyDict>() {
        let value = to_json(dict.as_any(), what)?;
        return serde_json::from_value(value).map_err(|e| invalid(format!("{what}: {e}")));
    }
    let path: PathBuf = given.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{what}: expected a path to a TOML or JSON file or a dict of the settings, got {}",
            type_name(given)
        ))
    })?;
    moe_io::read_config(&path).py()
}

/// The name of `value`'s type, for errors.
fn type_name(value: &Bound<'_, PyAny>) -> String {
    value
        .get_type()
        .name()
        .map_or_else(|_| "?".to_owned(), |n| n.to_string())
}

/// A Python value as JSON: None, bools, ints, finite floats, strings, dicts with string keys,
/// lists and tuples, numpy arrays and scalars (through `tolist`) and paths. `at` names the
/// value in errors (`config['solver']`).
fn to_json(value: &Bound<'_, PyAny>, at: &str) -> PyResult<Value> {
    if value.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = value.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if value.is_instance_of::<PyInt>() {
        if let Ok(i) = value.extract::<i64>() {
            return Ok(i.into());
        }
        return value
            .extract::<u64>()
            .map(Value::from)
            .map_err(|_| invalid(format!("{at}: {value} does not fit in 64 bits")));
    }
    if let Ok(f) = value.cast::<PyFloat>() {
        let x = f.value();
        return serde_json::Number::from_f64(x)
            .map(Value::Number)
            .ok_or_else(|| invalid(format!("{at}: {x} is not a finite number")));
    }
    if let Ok(s) = value.cast::<PyString>() {
        return Ok(Value::String(s.to_str()?.to_owned()));
    }
    if let Ok(dict) = value.cast::<PyDict>() {
        let mut map = serde_json::Map::with_capacity(dict.len());
        for (k, v) in dict.iter() {
            let key: String = k.extract().map_err(|_| {
                PyTypeError::new_err(format!(
                    "{at}: key {} is not a string",
                    k.repr().map_or_else(|_| "?".to_owned(), |r| r.to_string())
                ))
            })?;
            let item = to_json(&v, &format!("{at}[{key:?}]"))?;
            map.insert(key, item);
        }
        return Ok(Value::Object(map));
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        return value
            .try_iter()?
            .enumerate()
            .map(|(i, v)| to_json(&v?, &format!("{at}[{i}]")))
            .collect::<PyResult<Vec<_>>>()
            .map(Value::Array);
    }
    // numpy arrays and scalars: their Python form.
    if value.hasattr("tolist")? && value.hasattr("dtype")? {
        return to_json(&value.call_method0("tolist")?, at);
    }
    // Paths (a mesh a setting names).
    if let Ok(path) = value.extract::<PathBuf>() {
        return Ok(Value::String(path.display().to_string()));
    }
    Err(PyTypeError::new_err(format!(
        "{at}: a {} is not a setting (expected None, a bool, a number, a string, a list or a \
         dict)",
        type_name(value)
    )))
}
