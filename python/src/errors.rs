//! Rust errors to the package's exception hierarchy (`gripper_rs/errors.py`): one base class,
//! `DeviceError` with the device's code, status enum, name and description, `TimeoutError` (a
//! builtin `TimeoutError`), `ConnectionLostError`, `ClosedError`, `MalformedReplyError`,
//! `InvalidArgumentError` (a `ValueError`), `TransportError` (an `OSError`) and `ProtocolError`.
//! One function, [`error`], picks the class from the error's [`gripper::ErrorKind`] (`kind()` of
//! every protocol's error); each protocol adds only its extras ([`Classified`]).

use std::future::Future;
use std::time::Duration;

use gripper::ErrorKind;
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

/// What the package needs of a protocol's error beyond its [`ErrorKind`]: the extras only that
/// protocol's error carries. Each protocol module implements it for its `Error`; [`error`] is
/// the one classifier.
pub trait Classified: std::fmt::Display {
    /// The crate's classification (`Error::kind`).
    fn kind(&self) -> ErrorKind;
    /// The device's refusal for a `DeviceError` (code, status enum, manual symbol and text,
    /// what was refused); `None` for an error of kind [`ErrorKind::Device`] that carries no
    /// status of the protocol's table (SmartGrasp: a server that is not OPERATIONAL), which is
    /// a `ProtocolError`.
    fn refusal(self) -> Option<Device>;
    /// The call's timeout that ran out, for a `TimeoutError`; `None` for a connect timeout (an
    /// I/O error of kind `TimedOut`, which carries no duration).
    fn timeout(&self) -> Option<Duration>;
}

/// `classified!(Error, refusal)` in a protocol's module: its `error` (the `Error` as the
/// package's exception, [`error`]) and its [`Classified`]: the crate's `kind()`, the duration of
/// the `Timeout { timeout, .. }` variant (all four protocols have it), and `refusal`, the
/// protocol's own `fn(Error) -> Option<Device>`.
macro_rules! classified {
    ($Error:ident, $refusal:path) => {
        /// The protocol's error as the package's exception ([`crate::errors::error`]).
        pub fn error(e: $Error) -> pyo3::PyErr {
            $crate::errors::error(e)
        }

        impl $crate::errors::Classified for $Error {
            fn kind(&self) -> gripper::ErrorKind {
                $Error::kind(self)
            }

            fn refusal(self) -> Option<$crate::errors::Device> {
                $refusal(self)
            }

            fn timeout(&self) -> Option<std::time::Duration> {
                match self {
                    $Error::Timeout { timeout, .. } => Some(*timeout),
                    _ => None,
                }
            }
        }
    };
}

/// A protocol's error as the package's exception: the class from its [`ErrorKind`], the
/// attributes from the protocol's extras ([`Classified`]). The one classifier of the package.
pub fn error<E: Classified>(e: E) -> PyErr {
    let message = e.to_string();
    match e.kind() {
        ErrorKind::Device => match e.refusal() {
            Some(d) => device(message, d),
            None => raise("ProtocolError", message, &[]),
        },
        // `timeout_s` is None for a connect timeout: the I/O error has no duration, and the
        // connect timeout is the caller's own `connect_timeout_s`.
        ErrorKind::Timeout => timeout(message, e.timeout().map(|t| t.as_secs_f64())),
        // The peer cannot serve this client (SmartGrasp older than V3), or a reply was lost on
        // the wire (WSG after E_CMD_PENDING, SmartGrasp's counter): neither is a refusal nor a
        // malformed reply, both the peer breaking the exchange.
        ErrorKind::Incompatible | ErrorKind::ReplyLost => raise("ProtocolError", message, &[]),
        ErrorKind::MalformedReply => raise("MalformedReplyError", message, &[]),
        ErrorKind::InvalidArgument => raise("InvalidArgumentError", message, &[]),
        ErrorKind::ConnectionLost => raise("ConnectionLostError", message, &[]),
        ErrorKind::Closed => raise("ClosedError", message, &[]),
        // `ErrorKind` is non-exhaustive: an unknown kind is a failure of the link, as its docs
        // ask.
        _ => raise("TransportError", message, &[]),
    }
}

/// `close()` (and leaving a `with` block) of every client, idempotent (issue 32): a client that
/// is already closed, or whose connection is already lost (the error was raised by the call that
/// saw it), is fine to leave. After a successful close it waits until `is_closed` says so
/// ([`crate::lifecycle::closed`]).
pub async fn close_for_exit<E: Classified>(
    closing: impl Future<Output = Result<(), E>>,
    is_closed: impl Fn() -> bool,
) -> Result<(), E> {
    match closing.await {
        Err(e) if e.kind().is_disconnected() => Ok(()),
        Ok(()) => {
            crate::lifecycle::closed(is_closed).await;
            Ok(())
        }
        Err(e) => Err(e),
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

/// A `TimeoutError` after `timeout_s` seconds (None: the connect timeout).
fn timeout(message: String, timeout_s: Option<f64>) -> PyErr {
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
