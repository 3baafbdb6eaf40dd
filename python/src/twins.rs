//! `twins!`: one list of a client's methods, expanded into the blocking class and its asyncio
//! twin. Each method is a thin layer: convert the arguments (an optional prelude that may raise),
//! call the Rust method on a clone of the client handle, convert the result or the error. The
//! prelude and body are written once, so the two APIs cannot drift apart.

/// ```text
/// twins! {
///     Blocking, Aio, error_fn;
///     blocking { extra #[pymethods] items of the blocking class }
///     aio { extra items of the asyncio class }
///     /// doc
///     #[pyo3(signature = (a, b = 1.0))]
///     fn name(&self, a: f32, b: f32) [let x = prelude(a)?;] => |c| c.rust_method(x, b);
/// }
/// ```
/// Both classes have a field `inner` holding the (cheaply cloned) Rust client handle.
macro_rules! twins {
    (
        $Blocking:ident, $Aio:ident, $err:path;
        blocking { $($blocking_extra:item)* }
        aio { $($aio_extra:item)* }
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
