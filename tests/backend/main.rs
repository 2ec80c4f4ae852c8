//! The backends: the rule table; shader validation with naga, no GPU needed; GPU conformance of every
//! kernel on lavapipe; the fast path against the reference, property tests; shapes with known corners;
//! OpenCV agreement.
//!
//! One binary a layer: linking one test binary, not one a file, is most of the build. Run one
//! file's tests with a filter: `cargo test --test backend -- fast_baselines::`.

#[path = "../common/mod.rs"]
mod common;
mod fast_baselines;
mod fast_ogm;
mod gpu_classify;
mod gpu_conformance;
mod gpu_device_map;
mod opencv;
mod rules;
mod shaders;
mod shapes;
