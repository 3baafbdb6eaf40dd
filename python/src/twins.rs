//! `twins!`: one list of a client's methods, expanded into the blocking class and its asyncio
//! twin. Each method is a thin layer: convert the arguments (an optional prelude that may raise),
//! call the Rust method on a clone of the client handle, convert the result or the error. The
//! prelude and body are written once, so the two APIs cannot drift apart.

/// ```text
/// twins! {
///     Blocking, Aio, error_fn;
///     blocking { extra #[pymethods] items of the blocking class }
///     aio { extra items of the asyncio class }
///     both { plain (non-async) items both classes have }   (optional)
///     /// doc
///     #[pyo3(signature = (a, b = 1.0))]
///     fn name(&self, a: f32, b: f32) [let x = prelude(a)?;] => |c| c.rust_method(x, b);
/// }
/// ```
/// Both classes have a field `inner` holding the (cheaply cloned) Rust client handle. With
/// `closing close_fn;` (an `async fn(Client) -> Result<()>`), the classes also get `with` /
/// `async with` (leaving closes the connection with `close_fn`), `is_closed` (the Rust
/// client's) and the `aio` / `blocking` views of one connection.
macro_rules! twins {
    (
        $Blocking:ident, $Aio:ident, $err:path;
        $(closing $closing:path;)?
        blocking { $($blocking_extra:item)* }
        aio { $($aio_extra:item)* }
        $(both { $($both:item)* })?
        $(
            $(#[$meta:meta])*
            fn $name:ident(&self $(, $arg:ident : $ty:ty)* $(,)?)
                $([ $($pre:stmt;)* ])?
                => |$c:ident| $body:expr;
        )*
    ) => {
        #[pymethods]
        impl $Blocking {
            $($blocking_extra)*
            $($($both)*)?
            $(
                /// The asyncio view of this connection (same connection, same pairing).
                #[getter]
                fn aio(&self) -> $Aio {
                    $Aio { inner: self.inner.clone() }
                }

                /// Whether the connection is closed for good (closed, or lost and not being
                /// restored): every call fails.
                #[getter]
                fn is_closed(&self) -> bool {
                    self.inner.is_closed()
                }

                fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
                    slf
                }

                #[pyo3(signature = (*_exc))]
                fn __exit__(
                    &self,
                    py: Python<'_>,
                    _exc: Bound<'_, pyo3::types::PyTuple>,
                ) -> PyResult<bool> {
                    $crate::runtime::block_on(py, $closing(self.inner.clone()), $err)?;
                    Ok(false)
                }
            )?
            $(
                $(#[$meta])*
                fn $name(&self, py: Python<'_> $(, $arg: $ty)*) -> PyResult<Py<PyAny>> {
                    $($($pre;)*)?
                    let $c = self.inner.clone();
                    $crate::runtime::call(py, async move { let $c = &$c; $body.await }, $err)
                }
            )*
        }

        #[pymethods]
        impl $Aio {
            $($aio_extra)*
            $($($both)*)?
            $(
                /// The blocking view of this connection (same connection, same pairing).
                #[getter]
                fn blocking(&self) -> $Blocking {
                    $Blocking { inner: self.inner.clone() }
                }

                /// Whether the connection is closed for good (closed, or lost and not being
                /// restored): every call fails.
                #[getter]
                fn is_closed(&self) -> bool {
                    self.inner.is_closed()
                }

                fn __aenter__(slf: Bound<'_, Self>) -> PyResult<Bound<'_, PyAny>> {
                    let py = slf.py();
                    let me = slf.unbind();
                    $crate::runtime::awaitable_py(py, async move { Ok(me.into_any()) })
                }

                #[pyo3(signature = (*_exc))]
                fn __aexit__<'py>(
                    &self,
                    py: Python<'py>,
                    _exc: Bound<'py, pyo3::types::PyTuple>,
                ) -> PyResult<Bound<'py, PyAny>> {
                    let close = $closing(self.inner.clone());
                    $crate::runtime::awaitable(py, async move { close.await.map(|()| false) }, $err)
                }
            )?
            $(
                $(#[$meta])*
                fn $name<'py>(&self, py: Python<'py> $(, $arg: $ty)*)
                    -> PyResult<Bound<'py, PyAny>>
                {
                    $($($pre;)*)?
                    let $c = self.inner.clone();
                    $crate::runtime::awaitable(py, async move { let $c = &$c; $body.await }, $err)
                }
            )*
        }
    };
}
