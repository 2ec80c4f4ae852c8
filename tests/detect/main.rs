//! The detectors: the robust form on turned jagged rooms, its tiles, real maps, annotated-corner recall
//! pinned, repeatability, stopping early.
//!
//! One binary a layer: linking one test binary, not one a file, is most of the build. Run one
//! file's tests with a filter: `cargo test --test detect -- annotations::`.

mod annotations;
#[path = "../common/mod.rs"]
mod common;
mod eval;
mod real_maps;
mod robust;
mod robust_tiles;
mod stop;
