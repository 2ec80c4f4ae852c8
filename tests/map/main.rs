//! Maps: decoding (against the `image` crate), loading and bad input, the synthetic office, streamed
//! detection against the reference on every backend and under a memory cap.
//!
//! One binary a layer: linking one test binary, not one a file, is most of the build. Run one
//! file's tests with a filter: `cargo test --test map -- decode::`.

#[path = "../common/mod.rs"]
mod common;
mod decode;
mod decode_refusals;
mod loading;
mod streaming;
mod synthetic;
