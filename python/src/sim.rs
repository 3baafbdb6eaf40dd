//! What the three `SimServer` classes share: the running Rust simulator, taken out on shutdown.

use std::sync::Mutex;

use pyo3::prelude::*;

use crate::errors;
use crate::runtime;

/// A running simulator until `shutdown()` (or the end of a `with` block) takes it out and drops
/// it, which stops it.
pub struct Slot<T>(Mutex<Option<T>>);

impl<T> Slot<T> {
    /// Holds a running simulator.
    pub fn new(server: T) -> Self {
        Slot(Mutex::new(Some(server)))
    }

    /// `f` on the running simulator, or `ClosedError` after shutdown.
    pub fn with<R>(&self, f: impl FnOnce(&T) -> R) -> PyResult<R> {
        let guard = self
            .0
            .lock()
            .map_err(|_| errors::closed("the simulator's lock is poisoned".into()))?;
        match guard.as_ref() {
            Some(s) => Ok(f(s)),
            None => Err(errors::closed("the simulator was shut down".into())),
        }
    }

    /// Stops the simulator (idempotent). Dropped inside the runtime: stopping signals its tasks.
    pub fn shutdown(&self) -> PyResult<()> {
        let taken = self
            .0
            .lock()
            .map_err(|_| errors::closed("the simulator's lock is poisoned".into()))?
            .take();
        runtime::enter(|| drop(taken))?;
        Ok(())
    }
}

/// The `#[pymethods]` of a `SimServer` class (a struct with a `server: Slot<_>` and an `addr`):
/// the given methods, and what every simulator has: `address`, `port`, `shutdown()`, `with`
/// support and `repr`.
/// (pyo3 takes one `#[pymethods]` block per class, so the shared methods are added here.)
macro_rules! sim_pymethods {
    ($ty:ident, $path:literal; $($methods:tt)*) => {
        #[pymethods]
        impl $ty {
            $($methods)*

            /// "host:port" to connect to.
            #[getter]
            fn address(&self) -> String {
                self.addr.to_string()
            }

            /// The port it listens on.
            #[getter]
            fn port(&self) -> u16 {
                self.addr.port()
            }

            /// Stops serving and closes every connection (idempotent).
            fn shutdown(&self) -> PyResult<()> {
                self.server.shutdown()
            }

            fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
                slf
            }

            #[pyo3(signature = (*_exc))]
            fn __exit__(&self, _exc: Bound<'_, pyo3::types::PyTuple>) -> PyResult<bool> {
                self.shutdown()?;
                Ok(false)
            }

            fn __repr__(&self) -> String {
                format!(concat!("<", $path, " at {}>"), self.addr)
            }
        }
    };
}
