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
