//! The library's errors as Python exceptions, and the two ways this module runs library code: with the
//! interpreter's lock released and a panic turned into an exception, and for long work also stopped by
//! Ctrl-C ([`interruptible`]).

use std::panic::{catch_unwind, AssertUnwindSafe};

use ogm_corners::Error;
use pyo3::exceptions::{
    PyKeyboardInterrupt, PyMemoryError, PyOSError, PyRuntimeError, PyValueError,
};
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
        Error::Interrupted => PyKeyboardInterrupt::new_err(message),
    }
}

/// Runs `f` with the interpreter's lock released (other Python threads go on meanwhile); a library error
/// becomes its exception, and a panic (a bug) a `RuntimeError` rather than an abort of the interpreter.
pub fn unlocked<T: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> ogm_corners::Result<T> + Send,
) -> PyResult<T> {
    py.detach(|| catch_unwind(AssertUnwindSafe(f)))
        .map_err(panic_error)?
        .map_err(to_py)
}

/// How often a long call looks for a signal (Ctrl-C) while it waits for the work.
const SIGNAL_POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// [`unlocked`] for long work (detection, alignment, merging): `f` runs on a worker thread under an
/// [`ogm_corners::support::stop::Stop`] while this thread looks for signals every [`SIGNAL_POLL`]. When a signal
/// handler raises (Ctrl-C: `KeyboardInterrupt`), the stop is raised, the work ends at its next check
/// (between stages, maps or pairs) and the handler's exception is raised here, instead of the call
/// running to its end with the interpreter deaf to Ctrl-C.
///
/// A signal that arrives at any moment of the call is this call's exception: one that came before the
/// polling started (while the call converted its arguments, counted memory or opened its backend, when
/// nothing looks for signals) is raised before the work starts, and one that came after the last poll
/// as the work ended is raised instead of the result.
pub fn interruptible<T: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> ogm_corners::Result<T> + Send,
) -> PyResult<T> {
    test_signal(py);
    py.check_signals()?;
    // Asked before the worker starts, and its error raised: this runs Python code, where a pending
    // signal's handler runs too (its KeyboardInterrupt, once swallowed here, lost the Ctrl-C).
    let main = is_main_thread(py)?;
    let (outcome, signal) = run_polling(py, main, f);
    if let Some(e) = signal {
        return Err(e);
    }
    if main {
        py.check_signals()?;
    }
    outcome
        .unwrap_or_else(Err)
        .map_err(panic_error)?
        .map_err(to_py)
}

/// What a worker thread gives back: the work's result, or its panic.
type Joined<T> = std::thread::Result<std::thread::Result<ogm_corners::Result<T>>>;

/// Runs `f` on a worker thread under a stop, this thread (with the interpreter's lock released) looking
/// for signals every [`SIGNAL_POLL`] when it is the `main` one: the work's outcome, and the exception a
/// signal handler raised (the stop then raised and the work waited for).
fn run_polling<T: Send>(
    py: Python<'_>,
    main: bool,
    f: impl FnOnce() -> ogm_corners::Result<T> + Send,
) -> (Joined<T>, Option<PyErr>) {
    use std::sync::mpsc::{channel, RecvTimeoutError};
    let stop = ogm_corners::support::stop::Stop::new();
    let (done, finished) = channel::<()>();
    std::thread::scope(|s| {
        let worker = {
            let stop = stop.clone();
            s.spawn(move || {
                let r = catch_unwind(AssertUnwindSafe(|| stop.run(f)));
                // The receiver may be gone already; nothing to tell then.
                let _ = done.send(());
                r
            })
        };
        let signal = py.detach(move || {
            let signal = loop {
                if !main {
                    // Signal handlers run on the main thread only: elsewhere there is nothing to look for.
                    let _ = finished.recv();
                    break None;
                }
                match finished.recv_timeout(SIGNAL_POLL) {
                    Ok(()) | Err(RecvTimeoutError::Disconnected) => break None,
                    Err(RecvTimeoutError::Timeout) => {
                        if let Err(e) = Python::attach(|py| py.check_signals()) {
                            stop.raise();
                            break Some(e);
                        }
                    }
                }
            };
            // The work ends at its next check (or, in a stage without checks, at the stage's end): waited
            // for here, with the lock released, so that other Python threads run meanwhile.
            if signal.is_some() {
                let _ = finished.recv();
            }
            signal
        });
        (worker.join(), signal)
    })
}

/// The variable that makes the tests' signal: `start` makes SIGINT arrive once in this process, at the
/// start of the first [`interruptible`] call, as if Ctrl-C came while the call was converting its
/// arguments (where a Ctrl-C was once lost). Read at each call (a few hundred nanoseconds).
const TEST_SIGNAL: &str = "OGM_CORNERS_TEST_SIGNAL";

/// Makes SIGINT arrive when [`TEST_SIGNAL`] asks for it (once): as the C signal handler does, it only
/// marks the signal pending for the next check, which then runs its Python handler.
fn test_signal(_py: Python<'_>) {
    use std::sync::atomic::{AtomicBool, Ordering};
    static FIRED: AtomicBool = AtomicBool::new(false);
    if std::env::var_os(TEST_SIGNAL).is_some_and(|v| v == "start")
        && !FIRED.swap(true, Ordering::Relaxed)
    {
        // SAFETY: called attached to the interpreter (the `Python` token), as the C API asks.
        unsafe { pyo3::ffi::PyErr_SetInterrupt() };
    }
}

/// Whether this is the interpreter's main thread (where signal handlers run).
fn is_main_thread(py: Python<'_>) -> PyResult<bool> {
    let t = py.import("threading")?;
    let current = t.call_method0("current_thread")?;
    let main = t.call_method0("main_thread")?;
    Ok(current.is(&main))
}

/// A panic's message as a `RuntimeError`.
fn panic_error(panic: Box<dyn std::any::Any + Send>) -> PyErr {
    let what = panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".to_string());
    PyRuntimeError::new_err(format!("internal error: {what}"))
}

/// Refuses, as a `MemoryError` naming the estimate and the limit, what would take more than the memory
/// budget (`OGM_MAX_MEMORY`, else 80% of the machine's memory or of this process's limits), before it is
/// allocated: the command line's check, so that a call raises instead of aborting the interpreter.
pub fn within_budget(what: impl std::fmt::Display, bytes: u64) -> PyResult<()> {
    ogm_corners::support::memory::Budget::from_option(None)
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
