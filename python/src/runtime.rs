//! The module's one tokio runtime, and the two ways Python waits on it: blocking (GIL released,
//! Ctrl-C honoured) and asyncio (an awaitable that drops the Rust future when cancelled).

use std::future::Future;
use std::time::Duration;

use pyo3::prelude::*;

use crate::convert::ToPy;

/// How often a blocking wait wakes to let Python run its signal handlers: a Ctrl-C ends the
/// wait within this (the issue asks for 0.2 s; a slice is cheap, a timer wheel entry).
const SIGNAL_SLICE: Duration = Duration::from_millis(50);

/// The shared runtime: the clients' and simulators' background tasks run on its workers.
/// pyo3-async-runtimes owns it so that the asyncio bridge and the blocking API use the same one.
pub fn runtime() -> &'static tokio::runtime::Runtime {
    pyo3_async_runtimes::tokio::get_runtime()
}

/// Runs `fut` to completion on the calling thread with the GIL released, in slices of
/// [`SIGNAL_SLICE`]; between slices Python's signal handlers run, and an exception they raise
/// (KeyboardInterrupt) drops `fut`. The Rust clients guarantee that a dropped call never shifts
/// the pairing of replies, so the client stays usable.
pub fn block_on<F, T, E>(py: Python<'_>, fut: F, err: fn(E) -> PyErr) -> PyResult<T>
where
    F: Future<Output = Result<T, E>> + Send,
    T: Send,
    E: Send,
{
    let rt = runtime();
    let mut fut = std::pin::pin!(fut);
    loop {
        // The timer is made inside `block_on`: it needs the runtime's context.
        let slice = py.detach(|| {
            rt.block_on(async { tokio::time::timeout(SIGNAL_SLICE, fut.as_mut()).await })
        });
        match slice {
            Ok(result) => return result.map_err(err),
            Err(_elapsed) => py.check_signals()?,
        }
    }
}

/// The blocking call of a binding: waits for `fut` and converts its value.
pub fn call<F, T, E>(py: Python<'_>, fut: F, err: fn(E) -> PyErr) -> PyResult<Py<PyAny>>
where
    F: Future<Output = Result<T, E>> + Send,
    T: ToPy,
    E: Send,
{
    block_on(py, fut, err)?.to_py(py)
}

/// The asyncio call of a binding: an awaitable of the current event loop. Cancelling it drops
/// `fut` (pyo3-async-runtimes' `Cancellable`), which the Rust clients make pairing-safe.
pub fn awaitable<'py, F, T, E>(
    py: Python<'py>,
    fut: F,
    err: fn(E) -> PyErr,
) -> PyResult<Bound<'py, PyAny>>
where
    F: Future<Output = Result<T, E>> + Send + 'static,
    T: ToPy,
    E: Send + 'static,
{
    pyo3_async_runtimes::tokio::future_into_py(py, async move {
        let value = fut.await.map_err(err)?;
        Python::attach(|py| value.to_py(py))
    })
}

/// How long [`quiesce`] waits at most for the runtime's tasks to end.
const QUIESCE_LIMIT: Duration = Duration::from_millis(500);

/// Called at interpreter exit (`atexit`, registered by `gripper_rs/__init__.py`), while Python is
/// still whole: waits, with the GIL released, until no task is left on the runtime (or
/// [`QUIESCE_LIMIT`] passed), then a moment more for the completions those tasks handed to
/// the blocking pool. An asyncio call's completion attaches to Python from a runtime thread
/// (pyo3-async-runtimes sets the future's result there, even for a cancelled one); one that
/// attaches while the interpreter is being finalized crashes the process (seen: about one exit
/// in four of `examples/cell.py`, which cancels a stream's pending `__anext__`).
#[pyfunction]
pub fn _quiesce(py: Python<'_>) {
    let metrics = runtime().metrics();
    py.detach(|| {
        let start = std::time::Instant::now();
        while metrics.num_alive_tasks() > 0 && start.elapsed() < QUIESCE_LIMIT {
            std::thread::sleep(Duration::from_millis(2));
        }
        std::thread::sleep(Duration::from_millis(20));
    });
}

/// Runs a synchronous constructor that spawns tasks (serial clients, simulators) inside the
/// runtime's context.
pub fn enter<T>(f: impl FnOnce() -> T) -> T {
    let _guard = runtime().enter();
    f()
}

/// Seconds from Python as a `Duration`; negative, NaN or absurd values are a `ValueError`.
pub fn seconds(what: &str, s: f64) -> PyResult<Duration> {
    Duration::try_from_secs_f64(s).map_err(|_| {
        crate::errors::invalid_argument(format!(
            "{what} must be a finite, non-negative number of seconds, not {s}"
        ))
    })
}
