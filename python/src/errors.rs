//! The library's errors as Python exceptions, and the one way this module runs library code: with the
//! interpreter's lock released and a panic turned into an exception.

use std::panic::{catch_unwind, AssertUnwindSafe};

use ogm_corners::Error;
use pyo3::exceptions::{PyMemoryError, PyOSError, PyRuntimeError, PyValueError};
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

/// Refuses, as a `MemoryError` naming the estimate and the limit, what would take more than the memory
/// budget (`OGM_MAX_MEMORY`, else 80% of the machine's memory or of this process's limits), before it is
/// allocated: the command line's check, so that a call raises instead of aborting the interpreter.
pub fn within_budget(what: impl std::fmt::Display, bytes: u64) -> PyResult<()> {
    ogm_corners::memory::Budget::from_option(None)
        .map_err(to_py)?
        .check(what, bytes)
        .map_err(|e| PyMemoryError::new_err(e.to_string()))
}

/// A transform's numbers, refused unless finite (NaN would compose map A with B silently dropped).
pub fn finite_transform(t: (f64, f64, f64)) -> PyResult<(f64, f64, f64)> {
    if [t.0, t.1, t.2].iter().all(|v| v.is_finite()) {
        Ok(t)
    } else {
        Err(PyValueError::new_err(format!(
            "the transform (theta_deg {}, tx {}, ty {}) is not finite",
            t.0, t.1, t.2
        )))
    }
}
