//! Rust errors to the package's exception hierarchy (`gripper_rs/errors.py`): one base class,
//! `DeviceError` with the device's code, status enum, name and description, `TimeoutError` (a
//! builtin `TimeoutError`), `ConnectionLostError`, `ClosedError`, `MalformedReplyError`,
//! `InvalidArgumentError` (a `ValueError`), `TransportError` (an `OSError`) and `ProtocolError`.
//! One function, [`classify`], picks the class from the error's [`Kind`].

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

/// What kind of failure an error is: the one thing that decides its exception class
/// ([`classify`]). Each protocol's `error()` says which kind each of its variants is; once the
/// crate's `gripper::ErrorKind` (with `kind()` on every protocol's error) is in, that is the
/// only mapping left to swap (`Kind::from(e.kind())`), here.
pub enum Kind {
    /// The device refused the command.
    Device(Device),
    /// No reply within `timeout_s` seconds.
    Timeout { timeout_s: f64 },
    /// The connection broke (or the client gave up on it).
    ConnectionLost,
    /// Closed by this side.
    Closed,
    /// A reply that does not have the documented layout or does not answer the call.
    Malformed,
    /// Refused before anything was sent.
    InvalidArgument,
    /// Opening or configuring the transport failed.
    Transport,
    /// The peer broke the protocol in another way.
    Protocol,
    /// Anything else: the base class.
    Other,
}

/// A Python value made later, by the thread that holds the GIL.
pub type Deferred = Box<dyn FnOnce(Python<'_>) -> PyResult<Py<PyAny>> + Send>;

/// A device's refusal: its status as a number, the manual's symbol and text (`None` for a code
/// the manual does not list), the protocol's status enum (`module.Enum`, which keeps unknown
/// codes), and what was refused.
pub struct Device {
    pub code: i64,
    pub name: Option<String>,
    pub description: Option<String>,
    pub status_enum: Option<(&'static str, &'static str)>,
    pub command: Deferred,
}

impl Device {
    /// A refusal of `command` with status `code`.
    pub fn new<C>(code: i64, command: C) -> Self
    where
        C: for<'py> IntoPyObject<'py> + Send + 'static,
    {
        Device {
            code,
            name: None,
            description: None,
            status_enum: None,
            command: Box::new(move |py| command.into_py_any(py)),
        }
    }

    /// The manual's symbol and text of a known code.
    pub fn known(mut self, name: &str, description: &str) -> Self {
        self.name = Some(name.to_owned());
        self.description = Some(description.to_owned());
        self
    }

    /// The status also as `module.Enum(code)` (`DeviceError.status`).
    pub fn status(mut self, module: &'static str, class: &'static str) -> Self {
        self.status_enum = Some((module, class));
        self
    }
}

/// The exception for an error of `kind` with `message`: the one classifier of the package.
pub fn classify(kind: Kind, message: String) -> PyErr {
    match kind {
        Kind::Device(d) => device(message, d),
        Kind::Timeout { timeout_s } => timeout(message, timeout_s),
        Kind::ConnectionLost => raise("ConnectionLostError", message, &[]),
        Kind::Closed => raise("ClosedError", message, &[]),
        Kind::Malformed => raise("MalformedReplyError", message, &[]),
        Kind::InvalidArgument => raise("InvalidArgumentError", message, &[]),
        Kind::Transport => raise("TransportError", message, &[]),
        Kind::Protocol => raise("ProtocolError", message, &[]),
        Kind::Other => raise("GripperError", message, &[]),
    }
}

/// A `DeviceError`.
fn device(message: String, d: Device) -> PyErr {
    Python::attach(|py| {
        let attrs = || -> PyResult<Vec<(&str, Py<PyAny>)>> {
            let status = match d.status_enum {
                Some((module, class)) => crate::convert::enum_value(py, module, class, d.code)?,
                None => py.None(),
            };
            Ok(vec![
                ("code", d.code.into_py_any(py)?),
                ("name", d.name.into_py_any(py)?),
                ("description", d.description.into_py_any(py)?),
                ("command", (d.command)(py)?),
                ("status", status),
            ])
        };
        match attrs() {
            Ok(attrs) => raise("DeviceError", message, &attrs),
            Err(e) => e,
        }
    })
}

/// A `TimeoutError` after `timeout_s` seconds.
fn timeout(message: String, timeout_s: f64) -> PyErr {
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

/// A `TransportError` (also an `OSError`): connecting or configuring the transport failed.
pub fn transport(message: String) -> PyErr {
    raise("TransportError", message, &[])
}
