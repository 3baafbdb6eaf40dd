//! The module's one tokio runtime, and the two ways Python waits on it: blocking (GIL released,
//! Ctrl-C honoured) and asyncio (an awaitable that drops the Rust future when cancelled).

use std::future::Future;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::OnceLock;
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
    check_fork()?;
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

/// The asyncio call of a binding: an awaitable of the running event loop. Cancelling it drops
/// `fut`, which the Rust clients make pairing-safe.
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
    awaitable_with(py, fut, move |py, result| match result {
        Ok(value) => value.to_py(py),
        Err(e) => Err(err(e)),
    })
}

/// An awaitable of a future whose output is already a Python result.
pub fn awaitable_py<'py, F>(py: Python<'py>, fut: F) -> PyResult<Bound<'py, PyAny>>
where
    F: Future<Output = PyResult<Py<PyAny>>> + Send + 'static,
{
    awaitable_with(py, fut, |_, result| result)
}

/// The asyncio bridge: `fut` runs on the runtime; its output, a plain Rust value, is handed to
/// the delivery thread, which takes the GIL, converts it with `convert` (a value, or the
/// exception of an error) and gives it to the event loop (`call_soon_threadsafe`). No tokio
/// worker ever takes the GIL (issue 32: a Python thread that holds the GIL would otherwise
/// stall the connection tasks, their stops and timers included). A cancelled asyncio future
/// aborts the task, which drops `fut`.
pub fn awaitable_with<'py, F, T, C>(
    py: Python<'py>,
    fut: F,
    convert: C,
) -> PyResult<Bound<'py, PyAny>>
where
    F: Future<Output = T> + Send + 'static,
    T: Send + 'static,
    C: FnOnce(Python<'_>, T) -> PyResult<Py<PyAny>> + Send + 'static,
{
    check_fork()?;
    let event_loop = py.import("asyncio")?.call_method0("get_running_loop")?;
    let py_fut = event_loop.call_method0("create_future")?;
    let target = (event_loop.unbind(), py_fut.clone().unbind());
    let task = runtime().spawn(async move {
        let value = fut.await;
        deliver(Box::new(move |py| {
            let (event_loop, py_fut) = target;
            // Cancelled meanwhile: nobody waits for the value.
            if py_fut.bind(py).call_method0("done")?.is_truthy()? {
                return Ok(());
            }
            let (ok, value) = match convert(py, value) {
                Ok(v) => (true, v),
                Err(e) => (false, e.into_value(py).into_any()),
            };
            let set = py.import("gripper_rs._native")?.getattr("_set_future")?;
            event_loop
                .bind(py)
                .call_method1("call_soon_threadsafe", (set, py_fut, ok, value))?;
            Ok(())
        }));
    });
    py_fut.call_method1(
        "add_done_callback",
        (AbortOnCancel {
            task: task.abort_handle(),
        },),
    )?;
    Ok(py_fut)
}

/// Sets an asyncio future's result or exception, on its event loop, unless it is already done
/// (cancelled between the delivery and this call).
#[pyfunction]
pub fn _set_future(fut: Bound<'_, PyAny>, ok: bool, value: Bound<'_, PyAny>) -> PyResult<()> {
    if fut.call_method0("done")?.is_truthy()? {
        return Ok(());
    }
    if ok {
        fut.call_method1("set_result", (value,))?;
    } else {
        fut.call_method1("set_exception", (value,))?;
    }
    Ok(())
}

/// The done callback of a bridged asyncio future: a cancelled future aborts its task.
#[pyclass(frozen)]
struct AbortOnCancel {
    task: tokio::task::AbortHandle,
}

#[pymethods]
impl AbortOnCancel {
    fn __call__(&self, fut: Bound<'_, PyAny>) -> PyResult<()> {
        if fut.call_method0("cancelled")?.is_truthy()? {
            self.task.abort();
        }
        Ok(())
    }
}

/// A value on its way to Python, for the delivery thread.
pub type Job = Box<dyn FnOnce(Python<'_>) -> PyResult<()> + Send>;

/// Jobs handed over and not yet run (so that [`_quiesce`] can wait for them).
static PENDING: AtomicUsize = AtomicUsize::new(0);
/// Set at interpreter exit: later jobs are dropped instead of taking the GIL of an interpreter
/// being finalized.
static FINALIZING: AtomicBool = AtomicBool::new(false);

/// Whether the interpreter is exiting (see [`_quiesce`]): nothing may take the GIL any more.
pub fn finalizing() -> bool {
    FINALIZING.load(Ordering::Acquire)
}

/// Hands `job` to the delivery thread (started on first use), which runs the jobs in order.
pub fn deliver(job: Job) {
    static QUEUE: OnceLock<std::sync::Mutex<std::sync::mpsc::Sender<Job>>> = OnceLock::new();
    let queue = QUEUE.get_or_init(|| {
        let (tx, rx) = std::sync::mpsc::channel::<Job>();
        let spawned = std::thread::Builder::new()
            .name("gripper-rs-deliver".into())
            .spawn(move || {
                for job in rx {
                    if !FINALIZING.load(Ordering::Acquire) {
                        Python::attach(|py| {
                            if let Err(e) = job(py) {
                                // Only a broken event loop gets here (closed, say).
                                e.write_unraisable(py, None);
                            }
                        });
                    }
                    PENDING.fetch_sub(1, Ordering::AcqRel);
                }
            });
        if let Err(e) = spawned {
            eprintln!("gripper_rs: cannot start the delivery thread: {e}");
        }
        std::sync::Mutex::new(tx)
    });
    PENDING.fetch_add(1, Ordering::AcqRel);
    let sent = queue
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .send(job)
        .is_ok();
    if !sent {
        PENDING.fetch_sub(1, Ordering::AcqRel);
    }
}

/// The process that made the runtime: after `fork` the child has a copy of the runtime whose
/// threads did not come along, and waiting on it would hang forever.
static RUNTIME_PID: OnceLock<u32> = OnceLock::new();

/// A clear error, not a hang, in a forked child (issue 32).
pub fn check_fork() -> PyResult<()> {
    let pid = *RUNTIME_PID.get_or_init(std::process::id);
    if pid == std::process::id() {
        Ok(())
    } else {
        Err(crate::errors::raise(
            "GripperError",
            format!(
                "gripper_rs cannot be used in a process forked (pid {}) from the one that \
                 used it (pid {pid}): its runtime threads and connections stay in the parent. \
                 Use the 'spawn' or 'forkserver' start method of multiprocessing, or import and \
                 connect only in the child",
                std::process::id()
            ),
            &[],
        ))
    }
}

/// How long [`quiesce`] waits at most for the runtime's tasks to end.
const QUIESCE_LIMIT: Duration = Duration::from_millis(500);

/// Called at interpreter exit (`atexit`, registered by `gripper_rs/__init__.py`, after the
/// clients were closed), while Python is still whole: waits, with the GIL released, until no
/// task is left on the runtime and the delivery thread has handed over what it holds (or
/// [`QUIESCE_LIMIT`] passed); from then on nothing takes the GIL ([`finalizing`]): a thread that
/// attaches to an interpreter being finalized crashes the process (seen before the delivery
/// thread: about one exit in four of `examples/cell.py`, which cancels a stream's pending
/// `__anext__`). A process that never used the runtime (or a forked child, whose copy of it has
/// no threads) has nothing to wait for.
#[pyfunction]
pub fn _quiesce(py: Python<'_>) {
    if RUNTIME_PID.get() != Some(&std::process::id()) {
        FINALIZING.store(true, Ordering::Release);
        return;
    }
    let metrics = runtime().metrics();
    py.detach(|| {
        let start = std::time::Instant::now();
        while (metrics.num_alive_tasks() > 0 || PENDING.load(Ordering::Acquire) > 0)
            && start.elapsed() < QUIESCE_LIMIT
        {
            std::thread::sleep(Duration::from_millis(2));
        }
    });
    FINALIZING.store(true, Ordering::Release);
}

/// Runs a synchronous constructor that spawns tasks (serial clients, simulators) inside the
/// runtime's context.
pub fn enter<T>(f: impl FnOnce() -> T) -> PyResult<T> {
    check_fork()?;
    let _guard = runtime().enter();
    Ok(f())
}

/// Seconds from Python as a `Duration`; negative, NaN or absurd values are a `ValueError`.
pub fn seconds(what: &str, s: f64) -> PyResult<Duration> {
    Duration::try_from_secs_f64(s).map_err(|_| {
        crate::errors::invalid_argument(format!(
            "{what} must be a finite, non-negative number of seconds, not {s}"
        ))
    })
}
