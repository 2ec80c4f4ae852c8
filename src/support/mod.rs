//! Services every layer uses, knowing nothing of maps:
//!
//! - `error.rs`: the library's one error type, with the exit status the command-line tool maps it to;
//! - `files.rs`: files written whole (atomic outputs), input/output identity checks, regular-file reads;
//! - `memory.rs`: the memory budget;
//! - `stop.rs`: stopping long work early (Ctrl-C in Python);
//! - `threads.rs`: the worker pool;
//! - `stats.rs`: small statistics: the median shared by `bench` and the many-map merger's level of
//!   conflict;
//! - `marks.rs`: the marks the tool leaves in its own outputs;
//! - `plot.rs`: drawing: a 5x7 font, line plots and pictures fitted to a box;
//! - `report/`: self-contained HTML pages.

pub mod error;
pub mod files;
pub mod marks;
pub mod memory;
pub mod plot;
pub mod report;
pub(crate) mod stats;
pub mod stop;
pub mod threads;
