//! The exception classes: every failure is a [`MoeTouchError`]; a missing file is also a
//! `FileNotFoundError`, another operating-system failure an `OSError`, and bad values or
//! malformed input a `ValueError`. Each carries the one line the `moe-touch` tool prints.

use pyo3::exceptions::{PyException, PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

pyo3::create_exception!(
    moe_touch,
    MoeTouchError,
    PyException,
    "A failure of MOE-Touch. It is raised as one of its subclasses: MoeTouchFileNotFoundError \
     (a missing file), MoeTouchOSError (another failure to read a file) or MoeTouchValueError \
     (bad values, malformed input, a failing stage); its message is the line the moe-touch tool \
     prints for the same error."
);

/// What kind of failure an error is, and so which exception class raises it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    /// A file (or a directory a path needs) does not exist: `FileNotFoundError`.
    NotFound(Option<i32>),
    /// The operating system refused a read: `OSError`.
    Os(Option<i32>),
    /// Bad values, malformed input or a failing stage: `ValueError`.
    Value,
}

/// The subclasses of [`MoeTouchError`] that also derive from a built-in exception, in the
/// order they are made: name, docstring.
const SUBCLASSES: [(&str, &str); 3] = [
    (
        "MoeTouchOSError",
        "The operating system refused to read a file (permissions, a directory where a file \
         was expected): a MoeTouchError and an OSError.",
    ),
    (
        "MoeTouchFileNotFoundError",
        "A file MOE-Touch was asked to read does not exist: a MoeTouchOSError and a \
         FileNotFoundError.",
    ),
    (
        "MoeTouchValueError",
        "Bad values or malformed input (a file that does not parse, a shape that does not fit, \
         an unknown setting) or a failing stage: a MoeTouchError and a ValueError.",
    ),
];

static CLASSES: PyOnceLock<[Py<PyType>; 3]> = PyOnceLock::new();

/// The three subclasses, made once: `MoeTouchOSError(MoeTouchError, OSError)`,
/// `MoeTouchFileNotFoundError(MoeTouchOSError, FileNotFoundError)` (as `FileNotFoundError` is
/// an `OSError`) and `MoeTouchValueError(MoeTouchError, ValueError)`.
pub(crate) fn classes(py: Python<'_>) -> PyResult<&[Py<PyType>; 3]> {
    CLASSES.get_or_try_init(py, || {
        let mut made: Vec<Bound<'_, PyType>> = Vec::with_capacity(3);
        for (name, doc) in SUBCLASSES {
            let bases = match name {
                "MoeTouchOSError" => [py.get_type::<MoeTouchError>(), py.get_type::<PyOSError>()],
                "MoeTouchFileNotFoundError" => {
                    [made[0].clone(), py.get_type::<PyFileNotFoundError>()]
                }
                _ => [
                    py.get_type::<MoeTouchError>(),
                    py.get_type::<PyValueError>(),
                ],
            };
            let bases = PyTuple::new(py, bases)?;
            let namespace = PyDict::new(py);
            namespace.set_item("__module__", "moe_touch")?;
            namespace.set_item("__doc__", doc)?;
            let class = py
                .get_type::<PyType>()
                .call1((name, bases, namespace))?
                .cast_into::<PyType>()?;
            made.push(class);
        }
        let [os, not_found, value] = <[_; 3]>::try_from(made)
            .map_err(|_| PyValueError::new_err("three exception classes"))?;
        Ok([not_found.unbind(), os.unbind(), value.unbind()])
    })
}

/// The exception of `kind` with `message`.
pub(crate) fn new_err(py: Python<'_>, kind: Kind, message: String) -> PyErr {
    let made = (|| -> PyResult<PyErr> {
        let [not_found, os, value] = classes(py)?;
        let (class, errno) = match kind {
            Kind::NotFound(errno) => (not_found, errno),
            Kind::Os(errno) => (os, errno),
            Kind::Value => (value, None),
        };
        let exception = class.bind(py).call1((message.as_str(),))?;
        if let Some(errno) = errno {
            // Only `errno`: with `filename` or `strerror` set, OSError would print its own text
            // in place of the tool's line.
            exception.setattr("errno", errno)?;
        }
        Ok(PyErr::from_value(exception))
    })();
    made.unwrap_or_else(|e| e)
}

/// The exception of `kind` with `message`, made with the GIL taken (callers may hold it or
/// not: errors also arise inside calls that released it).
pub(crate) fn raise_kind(kind: Kind, message: String) -> PyErr {
    Python::attach(|py| new_err(py, kind, message))
}

/// The kind of a Rust error: a `std::io::Error` anywhere in its chain of sources is an
/// operating-system failure (not found, or another), unless it reports malformed data; a
/// writer's missing directory is not found; everything else is a bad value.
pub(crate) fn kind_of(err: &(dyn std::error::Error + 'static)) -> Kind {
    let mut cause = Some(err);
    while let Some(e) = cause {
        if let Some(io) = e.downcast_ref::<std::io::Error>() {
            use std::io::ErrorKind as K;
            return match io.kind() {
                K::NotFound => Kind::NotFound(io.raw_os_error()),
                // Readers report bad bytes this way: the file was read, its content is wrong.
                K::InvalidData | K::UnexpectedEof | K::InvalidInput => Kind::Value,
                _ => Kind::Os(io.raw_os_error()),
            };
        }
        if let Some(moe_io::IoError::MissingDirectory { .. }) = e.downcast_ref::<moe_io::IoError>()
        {
            return Kind::NotFound(None);
        }
        cause = e.source();
    }
    Kind::Value
}
