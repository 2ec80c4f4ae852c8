//! The command line: every subcommand, folders and reruns, batch detection, and one test per defect of
//! the hostile-input review.
//!
//! One binary a layer: linking one test binary, not one a file, is most of the build. Run one
//! file's tests with a filter: `cargo test --test cli -- batch::`.

mod batch;
mod bench;
mod commands;
#[path = "../common/mod.rs"]
mod common;
mod folders_and_reruns;
mod reliability;
