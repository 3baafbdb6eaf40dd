//! `gripper_rs._native`: the compiled half of the `gripper_rs` Python package, a thin layer over
//! the `gripper` crate. The Python half (`python/gripper_rs/`) defines the exceptions, enums and
//! records these bindings build, and re-exports the classes under the Rust API's module names.
#![forbid(unsafe_code)]

// The macros first: `macro_rules!` are visible to the modules declared after them.
#[macro_use]
mod errors;
#[macro_use]
mod sim;
#[macro_use]
mod twins;
mod args;
mod convert;
mod events;
mod griplink;
mod lifecycle;
mod logging;
mod runtime;
mod smartgrasp;
mod stream;
mod wsg;
mod wsg_text;

use pyo3::prelude::*;

/// The module: one submodule per protocol.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    logging::install(py)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(logging::reset_logging_cache, m)?)?;
    m.add_class::<stream::Stream>()?;
    m.add_function(wrap_pyfunction!(runtime::_quiesce, m)?)?;
    m.add_function(wrap_pyfunction!(runtime::_set_future, m)?)?;
    m.add_submodule(&wsg::module(py)?)?;
    m.add_submodule(&wsg_text::module(py)?)?;
    m.add_submodule(&griplink::module(py)?)?;
    m.add_submodule(&smartgrasp::module(py)?)?;
    Ok(())
}
