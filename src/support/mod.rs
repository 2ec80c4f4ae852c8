//! Services every layer uses, knowing nothing of maps: errors, files written whole, the memory budget,
//! stopping on a signal, the worker pool, small statistics, drawing and HTML pages, and the marks the
//! tool leaves in its own outputs.

pub mod error;
pub mod files;
pub mod marks;
pub mod memory;
pub mod plot;
pub mod report;
pub(crate) mod stats;
pub mod stop;
pub mod threads;
