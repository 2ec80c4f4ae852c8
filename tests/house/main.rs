//! The repository's own checks: the docs' figures, links and paths, the layering, the fuzz corpus
//! replayed.
//!
//! One binary a layer: linking one test binary, not one a file, is most of the build. Run one
//! file's tests with a filter: `cargo test --test house -- docs::`.

mod docs;
mod fuzz_regressions;
mod layering;
