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
        runtime::enter(|| drop(taken));
        Ok(())
    }
}
