//! The library's `tracing` events in Python's `logging` (issue 32), through pyo3-log: tracing's
//! `log` feature turns each event into a `log` record (no tracing subscriber is installed in a
//! Python process), and pyo3-log hands it to the `logging` logger of its module path
//! (`gripper.reconnect`, `gripper.wsg.client.task`, ...).
//!
//! pyo3-log caches each logger's effective level, so a record Python would drop costs no GIL
//! after the first one of its logger; `gripper_rs.reset_logging_cache()` makes a changed
//! `logging` configuration count. A record Python keeps is copied and handed to `logging` by the
//! package's delivery thread (the one that hands asyncio results over), in order: the runtime's
//! worker threads, which emit most records, never take the GIL for it. Once the interpreter
//! exits, records are dropped: taking the GIL of an interpreter being finalized crashes the
//! process.

use std::sync::{Arc, OnceLock};

use log::{LevelFilter, Log, Metadata, Record};
use pyo3::prelude::*;

/// pyo3-log's logger, fed from the delivery thread, silent once the interpreter is being
/// finalized.
struct Gate(Arc<pyo3_log::Logger>);

impl Log for Gate {
    fn enabled(&self, metadata: &Metadata) -> bool {
        // pyo3-log's `enabled` reads its cache only: no GIL.
        !crate::runtime::finalizing() && self.0.enabled(metadata)
    }

    fn log(&self, record: &Record) {
        if !self.enabled(record.metadata()) {
            return;
        }
        // An owned copy: the record borrows its message and names from the caller's frame.
        let level = record.level();
        let target = record.target().to_owned();
        let message = record.args().to_string();
        let module_path = record.module_path().map(str::to_owned);
        let file = record.file().map(str::to_owned);
        let line = record.line();
        let logger = Arc::clone(&self.0);
        crate::runtime::deliver(Box::new(move |_py| {
            logger.log(
                &Record::builder()
                    .level(level)
                    .target(&target)
                    .args(format_args!("{message}"))
                    .module_path(module_path.as_deref())
                    .file(file.as_deref())
                    .line(line)
                    .build(),
            );
            Ok(())
        }));
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
    if log::set_boxed_logger(Box::new(Gate(Arc::new(logger)))).is_ok() {
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
