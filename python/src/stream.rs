//! One Python stream type for every Rust stream of the library (WSG auto-updates, GRIPLINK
//! polling watches): a blocking iterator and an async iterator over the same items.

use std::pin::Pin;
use std::sync::Arc;

use futures_util::{Stream as RustStream, StreamExt};
use pyo3::exceptions::PyStopAsyncIteration;
use pyo3::prelude::*;

use crate::convert::ToPy;
use crate::runtime;

/// An item waiting to become a Python object (converted with the GIL held, after the wait).
trait Item: Send {
    fn into_py(self: Box<Self>, py: Python<'_>) -> PyResult<Py<PyAny>>;
}

impl<T: ToPy> Item for T {
    fn into_py(self: Box<Self>, py: Python<'_>) -> PyResult<Py<PyAny>> {
        (*self).to_py(py)
    }
}

type Boxed = Pin<Box<dyn RustStream<Item = Box<dyn Item>> + Send>>;

/// The stream, shared between a Python iterator and the awaitables it handed out. `None` once
/// closed: dropping the Rust stream is what ends it on the device (e.g. WSG turns updates off).
type Shared = Arc<tokio::sync::Mutex<Option<Boxed>>>;

/// A stream of values: `for v in stream` blocks for each (Ctrl-C ends the wait),
/// `async for v in stream` awaits each. Ends when the connection does; `close()` ends it early.
#[pyclass(module = "gripper_rs", name = "Stream")]
pub struct Stream {
    inner: Shared,
}

impl Stream {
    /// Wraps a Rust stream whose items convert to Python.
    pub fn new<S, T>(stream: S) -> Self
    where
        S: RustStream<Item = T> + Send + 'static,
        T: ToPy,
    {
        let boxed: Boxed = Box::pin(stream.map(|v| Box::new(v) as Box<dyn Item>));
        Stream {
            inner: Arc::new(tokio::sync::Mutex::new(Some(boxed))),
        }
    }
}

async fn next(inner: Shared) -> Option<Box<dyn Item>> {
    let mut guard = inner.lock().await;
    match guard.as_mut() {
        Some(s) => s.next().await,
        None => None,
    }
}

#[pymethods]
impl Stream {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&self, py: Python<'_>) -> PyResult<Option<Py<PyAny>>> {
        let item = runtime::block_on(
            py,
            async { Ok::<_, PyErr>(next(self.inner.clone()).await) },
            |e| e,
        )?;
        item.map(|i| i.into_py(py)).transpose()
    }

    fn __aiter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __anext__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let inner = self.inner.clone();
        pyo3_async_runtimes::tokio::future_into_py(py, async move {
            match next(inner).await {
                Some(item) => Python::attach(|py| item.into_py(py)),
                None => Err(PyStopAsyncIteration::new_err(())),
            }
        })
    }

    /// Ends the stream now (the device stops sending, if nobody else streams the value).
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        let inner = self.inner.clone();
        runtime::block_on(
            py,
            async move {
                inner.lock().await.take();
                Ok::<_, PyErr>(())
            },
            |e| e,
        )
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __exit__(
        &self,
        py: Python<'_>,
        _ty: Option<Bound<'_, PyAny>>,
        _value: Option<Bound<'_, PyAny>>,
        _tb: Option<Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        self.close(py)?;
        Ok(false)
    }
}
