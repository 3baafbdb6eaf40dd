//! Rust values to Python objects: plain values directly, the protocols' enums and records as the
//! Python classes of the package (`gripper_rs.wsg.GripState`, ...), so that they are `IntEnum`s and
//! dataclasses a type checker knows.

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use pyo3::IntoPyObjectExt;

/// A value a binding hands back to Python.
pub trait ToPy: Send + 'static {
    /// The Python object for `self`.
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>>;
}

macro_rules! plain {
    ($($t:ty),*) => {$(
        impl ToPy for $t {
            fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
                self.into_py_any(py)
            }
        }
    )*};
}
plain!(
    (),
    bool,
    f64,
    u8,
    u16,
    u32,
    u64,
    i32,
    i64,
    String,
    Option<String>,
    Option<u32>,
    Py<PyAny>
);

/// The decimal an `f32` was written as (0.1, not 0.10000000149011612): the devices send
/// single-precision values, and Python users compare them with what they typed.
pub fn f32_to_f64(v: f32) -> f64 {
    format!("{v}").parse().unwrap_or(f64::from(v))
}

impl ToPy for f32 {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        f32_to_f64(self).into_py_any(py)
    }
}

impl ToPy for bytes::Bytes {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        Ok(PyBytes::new(py, &self).into_any().unbind())
    }
}

impl<T: ToPy> ToPy for Vec<T> {
    fn to_py(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let items = self
            .into_iter()
            .map(|v| v.to_py(py))
            .collect::<PyResult<Vec<_>>>()?;
        items.into_py_any(py)
    }
}

/// `module.name` of the package (already imported: the Python half imports `_native`).
pub fn class<'py>(py: Python<'py>, module: &str, name: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import(module)?.getattr(name)
}

/// `module.Enum(code)`: the package's open `IntEnum`s keep unknown codes.
pub fn enum_value(py: Python<'_>, module: &str, name: &str, code: i64) -> PyResult<Py<PyAny>> {
    Ok(class(py, module, name)?.call1((code,))?.unbind())
}

/// `module.Enum.MEMBER`: the package's plain enums (outcomes), by member name.
pub fn enum_member(py: Python<'_>, module: &str, name: &str, member: &str) -> PyResult<Py<PyAny>> {
    Ok(class(py, module, name)?.getattr(member)?.unbind())
}

/// `module.Record(**fields)`: one of the package's frozen dataclasses.
pub fn record<'py>(
    py: Python<'py>,
    module: &str,
    name: &str,
    fields: &[(&str, Bound<'py, PyAny>)],
) -> PyResult<Py<PyAny>> {
    let kwargs = PyDict::new(py);
    for (key, value) in fields {
        kwargs.set_item(key, value)?;
    }
    Ok(class(py, module, name)?.call((), Some(&kwargs))?.unbind())
}

/// Shorthand for a record field: any convertible value as a Python object.
pub fn field<'py, T: IntoPyObjectExt<'py>>(py: Python<'py>, v: T) -> PyResult<Bound<'py, PyAny>> {
    v.into_bound_py_any(py)
}
