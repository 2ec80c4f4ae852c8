//! Stopping long work early. A caller that can be interrupted (the Python package, on Ctrl-C) runs the
//! work under a [`Stop`] ([`Stop::run`]); the work calls [`check`] between its stages, maps and pairs,
//! and returns [`Error::Interrupted`] once the stop is raised. Work run under no stop (the command line,
//! which a signal simply ends) never stops early, and a check costs one thread-local read.
//!
//! The stop lives in a thread-local so that the library's signatures stay as they are; parallel work
//! carries it into its worker threads with [`current`] and [`with`].

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::support::error::{Error, Result};

thread_local! {
    static CURRENT: RefCell<Option<Stop>> = const { RefCell::new(None) };
}

/// A request to stop, shared by the caller (who raises it) and the work (which checks it).
#[derive(Clone, Debug, Default)]
pub struct Stop(Arc<AtomicBool>);

impl Stop {
    /// A stop not raised yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks the work to stop at its next check (from any thread).
    pub fn raise(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether [`raise`](Self::raise) was called.
    pub fn is_raised(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// Runs `f` on this thread under this stop: its [`check`]s see it.
    pub fn run<R>(&self, f: impl FnOnce() -> R) -> R {
        with(Some(self.clone()), f)
    }
}

/// The stop this thread's work runs under, if any: what parallel work hands to its worker threads.
pub fn current() -> Option<Stop> {
    CURRENT.with(|c| c.borrow().clone())
}

/// Runs `f` on this thread under `stop` (none: under no stop), then puts back what was there, even if
/// `f` panics.
pub fn with<R>(stop: Option<Stop>, f: impl FnOnce() -> R) -> R {
    struct Restore(Option<Stop>);
    impl Drop for Restore {
        fn drop(&mut self) {
            let previous = self.0.take();
            CURRENT.with(|c| *c.borrow_mut() = previous);
        }
    }
    let _restore = Restore(CURRENT.with(|c| c.replace(stop)));
    f()
}

/// [`Error::Interrupted`] when the stop this thread's work runs under has been raised.
pub fn check() -> Result<()> {
    let raised = CURRENT.with(|c| c.borrow().as_ref().is_some_and(Stop::is_raised));
    if raised {
        Err(Error::Interrupted)
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_check_fails_only_under_a_raised_stop_and_the_stop_is_put_back() {
        assert!(check().is_ok());
        let stop = Stop::new();
        stop.run(|| {
            assert!(check().is_ok());
            stop.raise();
            assert!(matches!(check(), Err(Error::Interrupted)));
            // Inner work under no stop is not stopped; the outer stop is back after it.
            with(None, || assert!(check().is_ok()));
            assert!(check().is_err());
            // Another thread sees it only when handed over.
            let carried = current();
            std::thread::scope(|s| {
                s.spawn(|| assert!(check().is_ok()));
                s.spawn(|| with(carried, || assert!(check().is_err())));
            });
        });
        assert!(check().is_ok());
        let r = std::panic::catch_unwind(|| stop.run(|| panic!("in the work")));
        assert!(r.is_err() && check().is_ok());
    }
}
