//! The library's `tracing` events in Python's `logging` (issue 32), through pyo3-log: tracing's
//! `log` feature turns each event into a `log` record (no tracing subscriber is installed in a
//! Python process), and pyo3-log hands it to the `logging` logger of its module path
//! (`gripper.reconnect`, `gripper.wsg.client.task`, ...).
//!
//! pyo3-log caches each logger's effective level, so a record Python would drop costs no GIL
//! after the first one of its logger; `gripper_rs.reset_logging_cache()` makes a changed
//! `logging` configuration count. A record Python keeps is handed over on the thread that
//! emitted it (a runtime thread: warnings such as a lost connection are rare). Once the
//! interpreter exits, records are dropped: taking the GIL of an interpreter being finalized
//! crashes the process.

use std::sync::OnceLock;

use log::{LevelFilter, Log, Metadata, Record};
use pyo3::prelude::*;

/// pyo3-log's logger, silent once the interpreter is being finalized.
struct Gate(pyo3_log::Logger);

impl Log for Gate {
    fn enabled(&self, metadata: &Metadata) -> bool {
        !crate::runtime::finalizing() && self.0.enabled(metadata)
    }

    fn log(&self, record: &Record) {
        if !crate::runtime::finalizing() {
            self.0.log(record);
        }
    }

    fn flush(&self) {}
}

static RESET: OnceLock<pyo3_log::ResetHandle> = OnceLock::new();

/// Installs the bridge (once per process; another extension's logger, if one was installed
/// first, is left in place).
pub fn install(py: Python<'_>) -> PyResult<()> {
    let logger =
        pyo3_log::Logger::new(py, pyo3_log::Caching::LoggersAndLevels)?.filter(LevelFilter::Debug);
    let reset = logger.reset_handle();
    if log::set_boxed_logger(Box::new(Gate(logger))).is_ok() {
        log::set_max_level(LevelFilter::Debug);
        let _ = RESET.set(reset);
    }
    Ok(())
}

/// Forgets the cached `logging` levels: call after changing the `logging` configuration (levels,
/// handlers) of the `gripper` loggers once the package has logged.
#[pyfunction]
pub fn reset_logging_cache() {
    if let Some(reset) = RESET.get() {
        reset.reset();
    }
}
