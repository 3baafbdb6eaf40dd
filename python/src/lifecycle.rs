//! Clients closed at interpreter exit (issue 32): each client a constructor hands to Python is
//! tracked, weakly, by `gripper_rs/_lifecycle.py`, whose `atexit` handler closes those still
//! alive, announcing the disconnect where the protocol has one (WSG 0x07, GCL `BYE()`,
//! GRIPLINK `BYE`): a gripper that loses its connection unannounced goes into FAST STOP, and
//! the next program's motions are refused until it is acknowledged.

use pyo3::prelude::*;
use pyo3::PyClass;

/// `value` as a Python object, tracked for the close at exit.
pub fn track<T>(py: Python<'_>, value: T) -> PyResult<Py<T>>
where
    T: PyClass + Into<PyClassInitializer<T>>,
{
    let obj = Py::new(py, value)?;
    py.import("gripper_rs._lifecycle")?
        .call_method1("track", (obj.clone_ref(py),))?;
    Ok(obj)
}

/// After a successful `close()`: waits, briefly, until the client's task has ended and
/// `is_closed()` says so. GRIPLINK's and GCL's `close()` return on the `ACK` of `BYE`, and the
/// task ends a moment later; Python's `is_closed` right after `close()` must not say False.
pub async fn closed(is_closed: impl Fn() -> bool) {
    let deadline = tokio::time::Instant::now() + std::time::Duration::from_secs(2);
    while !is_closed() && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(std::time::Duration::from_millis(1)).await;
    }
}
