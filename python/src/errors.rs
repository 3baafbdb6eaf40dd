//! Rust errors to the package's exception hierarchy (`gripper_rs/errors.py`): one base class,
//! `DeviceError` with the device's code, name and description, `TimeoutError` (a builtin
//! `TimeoutError`), `ConnectionLostError`, `ClosedError`, `MalformedReplyError`,
//! `InvalidArgumentError` (a `ValueError`) and `TransportError` (an `OSError`).

use pyo3::prelude::*;
use pyo3::types::PyDict;
use pyo3::IntoPyObjectExt;

const ERRORS: &str = "gripper_rs.errors";

/// The exception `class(message, **attrs)`; if the package itself is broken, that error instead.
pub fn raise(class: &str, message: String, attrs: &[(&str, Py<PyAny>)]) -> PyErr {
    Python::attach(|py| {
        let build = || -> PyResult<PyErr> {
            let cls = py.import(ERRORS)?.getattr(class)?;
            let kwargs = PyDict::new(py);
            for (k, v) in attrs {
                kwargs.set_item(k, v)?;
            }
            Ok(PyErr::from_value(cls.call((message,), Some(&kwargs))?))
        };
        build().unwrap_or_else(|e| e)
    })
}

/// A `DeviceError`: the device refused `command` with status `code`.
pub fn device<C>(
    message: String,
    code: i64,
    name: Option<&str>,
    description: Option<&str>,
    command: C,
) -> PyErr
where
    C: for<'py> IntoPyObject<'py>,
{
    Python::attach(|py| {
        let attrs = || -> PyResult<Vec<(&str, Py<PyAny>)>> {
            Ok(vec![
                ("code", code.into_py_any(py)?),
                ("name", name.into_py_any(py)?),
                ("description", description.into_py_any(py)?),
                ("command", command.into_py_any(py)?),
            ])
        };
        match attrs() {
            Ok(attrs) => raise("DeviceError", message, &attrs),
            Err(e) => e,
        }
    })
}

/// A `TimeoutError` after `timeout_s` seconds.
pub fn timeout(message: String, timeout_s: f64) -> PyErr {
    Python::attach(|py| match timeout_s.into_py_any(py) {
        Ok(t) => raise("TimeoutError", message, &[("timeout_s", t)]),
        Err(e) => e,
    })
}

/// An `InvalidArgumentError` (also a `ValueError`).
pub fn invalid_argument(message: String) -> PyErr {
    raise("InvalidArgumentError", message, &[])
}

/// A `ConnectionLostError` (also a `ConnectionError`).
pub fn connection_lost(message: String) -> PyErr {
    raise("ConnectionLostError", message, &[])
}

/// A `ClosedError`: the client was closed by this side.
pub fn closed(message: String) -> PyErr {
    raise("ClosedError", message, &[])
}

/// A `MalformedReplyError`.
pub fn malformed(message: String) -> PyErr {
    raise("MalformedReplyError", message, &[])
}

/// A `TransportError` (also an `OSError`): connecting or configuring the transport failed.
pub fn transport(message: String) -> PyErr {
    raise("TransportError", message, &[])
}
