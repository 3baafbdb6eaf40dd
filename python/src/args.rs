//! Arguments from Python that pyo3 would refuse with a plain `OverflowError` or `ValueError`
//! (an integer out of its range, a sequence of the wrong length): refused as the package's
//! `InvalidArgumentError` instead (issue 32: every error is a `GripperError`).

use std::ops::Deref;

use pyo3::exceptions::{PyOverflowError, PyValueError};
use pyo3::prelude::*;

/// An argument of type `T` whose out-of-range values raise `InvalidArgumentError`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Checked<T>(pub T);

impl<T> Deref for Checked<T> {
    type Target = T;

    fn deref(&self) -> &T {
        &self.0
    }
}

/// The error pyo3 gave for `obj`, as `InvalidArgumentError` when it is a range or length error
/// (a wrong type stays a `TypeError`, as everywhere in Python).
fn refine<T>(obj: &Bound<'_, PyAny>, e: PyErr, what: &str) -> PyErr {
    let py = obj.py();
    if e.is_instance_of::<PyOverflowError>(py) || e.is_instance_of::<PyValueError>(py) {
        let shown = obj
            .repr()
            .map(|r| r.to_string())
            .unwrap_or_else(|_| "the value".into());
        let ty = std::any::type_name::<T>();
        crate::errors::invalid_argument(format!("{what}{shown} does not fit {ty}: {e}"))
    } else {
        e
    }
}

/// `obj` as `T`; a range or length error is an `InvalidArgumentError` naming `name`.
pub fn extract<'py, T>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<T>
where
    T: FromPyObjectOwned<'py>,
{
    obj.extract::<T>()
        .map_err(|e| refine::<T>(obj, e.into(), &format!("{name}: ")))
}

impl<'a, 'py, T> FromPyObject<'a, 'py> for Checked<T>
where
    T: FromPyObjectOwned<'py>,
{
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let obj = obj.to_owned();
        obj.extract::<T>()
            .map(Checked)
            .map_err(|e| refine::<T>(&obj, e.into(), ""))
    }
}
