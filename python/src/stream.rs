//! One Python stream type for every Rust stream of the library (WSG auto-updates, GCL pushes,
//! GRIPLINK polling watches): a blocking iterator and an async iterator over the same items.
//!
//! A task on the runtime (the *pump*) owns the Rust stream and moves its items into a small
//! queue; readers take them from there. Nobody holds a lock while waiting (issue 32: `next()`
//! used to hold the stream's lock while it waited for the next item, and `close()`, which
//! needed it, froze the event loop until then): `close()` marks the queue ended, wakes every
//! reader and stops the pump, from any thread or the event loop, at once. The pump then drops
//! the Rust stream, which is what ends it on the device (WSG: updates off, if nobody else
//! streams the value).

use std::collections::VecDeque;
use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use futures_util::{FutureExt, Stream as RustStream, StreamExt};
use gripper::reconnect::{ConnectionEvent, ConnectionEvents};
use pyo3::exceptions::{PyStopAsyncIteration, PyStopIteration};
use pyo3::prelude::*;
use pyo3::types::PyType;
use pyo3::IntoPyObjectExt;
use tokio::sync::Notify;
use tokio_util::sync::CancellationToken;

use crate::convert::ToPy;
use crate::{errors, runtime};

/// The buffer a stream starts with: the Rust subscriptions' default
/// (`gripper::wsg::DEFAULT_SUBSCRIPTION_BUFFER`).
const DEFAULT_BUFFER: usize = 64;

/// An item waiting to become a Python object (converted with the GIL held, by the reader).
trait Item: Send {
    fn into_py(self: Box<Self>, py: Python<'_>) -> PyResult<Py<PyAny>>;
}

impl<T: ToPy> Item for T {
    fn into_py(self: Box<Self>, py: Python<'_>) -> PyResult<Py<PyAny>> {
        (*self).to_py(py)
    }
}

/// What a Rust stream tells besides its items.
pub trait Source: RustStream + Send + Unpin + 'static {
    /// Items the Rust stream itself dropped because its own buffer was full.
    fn missed(&self) -> u64 {
        0
    }

    /// Whether a full queue drops the newest item (a device that pushes: WSG auto-updates, GCL
    /// pushes, the same rule as the Rust streams') or makes the pump wait (a polling watch: a
    /// slow reader slows the polling, as in Rust).
    fn lossy(&self) -> bool {
        true
    }
}

/// Why a stream ended.
#[derive(Clone, Debug)]
enum End {
    /// Closed by this side (`close()`), or the client was closed: `StopIteration`.
    Finished,
    /// The connection broke for good: `ConnectionLostError` once, then `StopIteration`.
    Lost(String),
}

/// The queue between the pump and the readers.
struct Queue {
    items: VecDeque<Box<dyn Item>>,
    end: Option<End>,
    capacity: usize,
    latest_only: bool,
}

struct Shared {
    queue: Mutex<Queue>,
    /// Woken when an item or the end arrives.
    ready: Notify,
    /// Woken when a reader took an item (the pump of a polling watch waits for room).
    room: Notify,
    /// `close()`: the pump stops and drops the Rust stream.
    stop: CancellationToken,
    missed: AtomicU64,
    source_missed: AtomicU64,
}

impl Shared {
    fn queue(&self) -> MutexGuard<'_, Queue> {
        // A panic while the lock was held leaves a queue that is still consistent (every
        // change is one push or pop).
        self.queue.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn end(&self, end: End) {
        let mut q = self.queue();
        if q.end.is_none() {
            q.end = Some(end);
        }
        drop(q);
        self.ready.notify_waiters();
        self.room.notify_waiters();
    }
}

/// Tells, once the Rust stream ended, whether the connection was lost (its reason) or closed.
pub type Ending = Box<dyn FnOnce() -> Pin<Box<dyn Future<Output = Option<String>> + Send>> + Send>;

/// An [`Ending`] from a client's connection events, taken when the stream was made: the clients
/// send `Lost` (and, with a reconnect policy, `GaveUp`) before they end their streams, so the
/// events are in the buffer when the stream ends, and reading them never waits.
pub fn ending_from_events(mut events: ConnectionEvents) -> Ending {
    Box::new(move || Box::pin(std::future::ready(lost_from_events(&mut events))))
}

/// The loss the buffered events tell of, if the connection did not come back.
fn lost_from_events(events: &mut ConnectionEvents) -> Option<String> {
    {
        let mut lost = None;
        while let Some(Some(event)) = events.next().now_or_never() {
            match event {
                ConnectionEvent::Lost { reason } => lost = Some(reason),
                ConnectionEvent::GaveUp { attempts } => {
                    let reason = lost.take().unwrap_or_else(|| "connection lost".into());
                    lost = Some(format!(
                        "{reason} (gave up after {attempts} reconnect attempts)"
                    ));
                }
                ConnectionEvent::Restored { .. } => lost = None,
                _ => {}
            }
        }
        lost
    }
}

/// A Rust stream with its [`Ending`], on its way to becoming a [`Stream`].
pub struct Ended<S>(pub S, pub Ending);

impl<S> ToPy for Ended<S>
where
    S: Source,
    S::Item: ToPy,
{
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        Stream::with_ending(self.0, self.1).into_py_any(py)
    }
}

/// A stream of values: `for v in stream` blocks for each (Ctrl-C ends the wait),
/// `async for v in stream` awaits each. A lost connection ends it with `ConnectionLostError`;
/// `close()` (or leaving `with` / `async with`) ends it at once, from any thread or task: the
/// readers waiting on it get `StopIteration` / `StopAsyncIteration`.
#[pyclass(module = "gripper_rs", name = "Stream", frozen)]
pub struct Stream {
    shared: Arc<Shared>,
}

impl Stream {
    /// Wraps a Rust stream whose items convert to Python; it ends as a closed stream.
    pub fn new<S>(stream: S) -> Self
    where
        S: Source,
        S::Item: ToPy,
    {
        Self::with_ending(stream, Box::new(|| Box::pin(std::future::ready(None))))
    }

    /// Wraps a Rust stream; when it ends, `ending` tells whether the connection was lost.
    pub fn with_ending<S>(stream: S, ending: Ending) -> Self
    where
        S: Source,
        S::Item: ToPy,
    {
        let shared = Arc::new(Shared {
            queue: Mutex::new(Queue {
                items: VecDeque::new(),
                end: None,
                capacity: DEFAULT_BUFFER,
                latest_only: false,
            }),
            ready: Notify::new(),
            room: Notify::new(),
            stop: CancellationToken::new(),
            missed: AtomicU64::new(0),
            source_missed: AtomicU64::new(0),
        });
        runtime::runtime().spawn(pump(stream, ending, shared.clone()));
        Stream { shared }
    }
}

impl Drop for Stream {
    /// A stream Python forgot ends like a closed one: the pump stops and drops the Rust stream,
    /// which ends it on the device (as dropping the Rust stream itself would).
    fn drop(&mut self) {
        self.shared.stop.cancel();
    }
}

/// Moves the Rust stream's items into the queue until it ends or `close()` stops it.
async fn pump<S>(mut stream: S, ending: Ending, shared: Arc<Shared>)
where
    S: Source,
    S::Item: ToPy,
{
    loop {
        let next = tokio::select! {
            biased;
            () = shared.stop.cancelled() => return,
            next = stream.next() => next,
        };
        shared
            .source_missed
            .store(stream.missed(), Ordering::Relaxed);
        let Some(item) = next else {
            let end = match ending().await {
                Some(reason) => End::Lost(reason),
                None => End::Finished,
            };
            shared.end(end);
            return;
        };
        let item: Box<dyn Item> = Box::new(item);
        loop {
            let room = shared.room.notified();
            tokio::pin!(room);
            room.as_mut().enable();
            {
                let mut q = shared.queue();
                if q.end.is_some() {
                    return;
                }
                if q.latest_only {
                    // Only the newest value counts: an unread older one is replaced.
                    let replaced = q.items.len() as u64;
                    q.items.clear();
                    q.items.push_back(item);
                    shared.missed.fetch_add(replaced, Ordering::Relaxed);
                    break;
                }
                if q.items.len() < q.capacity {
                    q.items.push_back(item);
                    break;
                }
                if stream.lossy() {
                    shared.missed.fetch_add(1, Ordering::Relaxed);
                    break;
                }
            }
            // A polling watch with a full queue: wait for a reader (or the end).
            tokio::select! {
                biased;
                () = shared.stop.cancelled() => return,
                () = room => {}
            }
        }
        shared.ready.notify_waiters();
    }
}

/// What a reader gets.
enum Next {
    Item(Box<dyn Item>),
    End(End),
}

/// The next item, or the end; waits without holding any lock.
async fn next(shared: Arc<Shared>) -> Next {
    loop {
        let ready = shared.ready.notified();
        tokio::pin!(ready);
        // Registered before the queue is looked at: an item pushed in between still wakes us.
        ready.as_mut().enable();
        {
            let mut q = shared.queue();
            if let Some(item) = q.items.pop_front() {
                drop(q);
                shared.room.notify_waiters();
                return Next::Item(item);
            }
            if let Some(end) = &mut q.end {
                // A loss is raised once; the stream is then exhausted like any iterator.
                return Next::End(std::mem::replace(end, End::Finished));
            }
        }
        ready.await;
    }
}

/// A reader's result as Python sees it: the item, or the end as `stop` (`StopIteration` /
/// `StopAsyncIteration`) or a `ConnectionLostError`.
fn deliver(py: Python<'_>, next: Next, stop: fn() -> PyErr) -> PyResult<Py<PyAny>> {
    match next {
        Next::Item(item) => item.into_py(py),
        Next::End(End::Finished) => Err(stop()),
        Next::End(End::Lost(reason)) => Err(errors::connection_lost(format!(
            "the stream ended: connection lost: {reason}"
        ))),
    }
}

fn stop_iteration() -> PyErr {
    PyStopIteration::new_err(())
}

fn stop_async_iteration() -> PyErr {
    PyStopAsyncIteration::new_err(())
}

/// An awaitable that is already done with `value` (for `__aenter__`, `aclose`).
fn ready<'py>(py: Python<'py>, value: Py<PyAny>) -> PyResult<Bound<'py, PyAny>> {
    runtime::awaitable_py(py, std::future::ready(Ok(value)))
}

#[pymethods]
impl Stream {
    /// `Stream[float]` in annotations that are evaluated at run time.
    #[classmethod]
    fn __class_getitem__<'py>(
        cls: &Bound<'py, PyType>,
        item: Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let py = cls.py();
        py.import("types")?
            .getattr("GenericAlias")?
            .call1((cls.clone(), item))
    }

    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let shared = self.shared.clone();
        let next = runtime::block_on(py, async { Ok::<_, PyErr>(next(shared).await) }, |e| e)?;
        deliver(py, next, stop_iteration)
    }

    fn __aiter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __anext__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let shared = self.shared.clone();
        runtime::awaitable_with(py, next(shared), |py, next| {
            deliver(py, next, stop_async_iteration)
        })
    }

    /// Ends the stream now: readers waiting on it get `StopIteration` / `StopAsyncIteration`,
    /// unread items are dropped, and the device is told to stop sending (in the background, if
    /// nobody else streams the value). Never waits; calling it again does nothing.
    fn close(&self) {
        self.shared.stop.cancel();
        self.shared.queue().items.clear();
        self.shared.end(End::Finished);
    }

    /// `close()` as an awaitable (the async generator protocol's name).
    fn aclose<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.close();
        ready(py, py.None())
    }

    /// Whether the stream has ended (closed, or its connection ended) and its queue is empty.
    #[getter]
    fn is_closed(&self) -> bool {
        let q = self.shared.queue();
        q.end.is_some() && q.items.is_empty()
    }

    /// Items dropped so far because the reader fell behind: the buffer was full (the newest
    /// item was dropped), or with `latest_only` an unread item was replaced by a newer one.
    #[getter]
    fn missed(&self) -> u64 {
        self.shared.missed.load(Ordering::Relaxed)
            + self.shared.source_missed.load(Ordering::Relaxed)
    }

    /// How many unread items the stream keeps (default 64). While it is full, pushed values
    /// (WSG auto-updates, GCL pushes) are dropped and counted in `missed`; a polling watch
    /// (GRIPLINK) instead polls no faster than it is read.
    #[getter]
    fn buffer_size(&self) -> usize {
        self.shared.queue().capacity
    }

    #[setter]
    fn set_buffer_size(&self, size: Bound<'_, PyAny>) -> PyResult<()> {
        let size: usize = crate::args::extract(&size, "buffer_size")?;
        if size == 0 {
            return Err(errors::invalid_argument(
                "buffer_size must be at least 1".into(),
            ));
        }
        self.shared.queue().capacity = size;
        self.shared.room.notify_waiters();
        Ok(())
    }

    /// Keep only the newest unread value: a reader always gets the latest state, and each
    /// value it never saw counts in `missed`.
    #[getter]
    fn latest_only(&self) -> bool {
        self.shared.queue().latest_only
    }

    #[setter]
    fn set_latest_only(&self, on: bool) {
        let mut q = self.shared.queue();
        q.latest_only = on;
        if on && q.items.len() > 1 {
            let dropped = q.items.len() - 1;
            q.items.drain(..dropped);
            self.shared
                .missed
                .fetch_add(dropped as u64, Ordering::Relaxed);
        }
        drop(q);
        self.shared.room.notify_waiters();
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    #[pyo3(signature = (*_exc))]
    fn __exit__(&self, _exc: Bound<'_, pyo3::types::PyTuple>) -> bool {
        self.close();
        false
    }

    fn __aenter__<'py>(slf: Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let py = slf.py();
        ready(py, slf.into_any().unbind())
    }

    #[pyo3(signature = (*_exc))]
    fn __aexit__<'py>(
        &self,
        py: Python<'py>,
        _exc: Bound<'py, pyo3::types::PyTuple>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.close();
        ready(py, false.into_pyobject(py)?.to_owned().into_any().unbind())
    }

    fn __repr__(&self) -> String {
        let q = self.shared.queue();
        let state = if q.end.is_some() { "ended" } else { "open" };
        format!(
            "<gripper_rs.Stream {state}, {} unread, {} missed>",
            q.items.len(),
            self.missed()
        )
    }
}

impl<T: Send + 'static> Source for gripper::wsg::Subscription<T> {
    fn missed(&self) -> u64 {
        gripper::wsg::Subscription::missed(self)
    }
}

impl Source for gripper::wsg::text::Pushes {
    fn missed(&self) -> u64 {
        gripper::wsg::text::Pushes::missed(self)
    }
}

impl<T: Send + 'static> Source for gripper::griplink::Watch<T> {
    fn lossy(&self) -> bool {
        false
    }
}
