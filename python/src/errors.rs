//! The library's errors as Python exceptions, and the one way this module runs library code: with the
//! interpreter's lock released and a panic turned into an exception.

use std::panic::{catch_unwind, AssertUnwindSafe};

use ogm_corners::Error;
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    _core,
    BackendUnavailableError,
    PyRuntimeError,
    "The backend asked for cannot be had (no GPU adapter for backend=\"gpu\")."
);

/// The exception for a library error, with the command line's one-line message: bad input is a
/// `ValueError`, an output that cannot be written an `OSError`, a missing GPU a `BackendUnavailableError`.
pub fn to_py(e: Error) -> PyErr {
    let message = e.to_string();
    match e {
        Error::Input { .. } => PyValueError::new_err(message),
        Error::Output { .. } => PyOSError::new_err(message),
        Error::Unavailable(_) => BackendUnavailableError::new_err(message),
        Error::Internal(_) | Error::Declined(_) => PyRuntimeError::new_err(message),
    }
}

/// Runs `f` with the interpreter's lock released (other Python threads go on meanwhile); a library error
/// becomes its exception, and a panic (a bug) a `RuntimeError` rather than an abort of the interpreter.
pub fn unlocked<T: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> ogm_corners::Result<T> + Send,
) -> PyResult<T> {
    py.detach(|| catch_unwind(AssertUnwindSafe(f)))
        .map_err(|panic| {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            PyRuntimeError::new_err(format!("internal error: {what}"))
        })?
        .map_err(to_py)
}
