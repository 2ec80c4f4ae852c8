//! Detection: a backend driven over a map, in memory or streamed from its file, and what comes out.
//!
//! - [`detector`] (`detector.rs`): the [`Detector`](detector::Detector) that picks a backend and runs it
//!   over a map whole or in windows of rows;
//! - [`robust`] (`robust/`): the robust form of the OGM detector for real maps, above the backends
//!   (walls' direction, tiles, suppression);
//! - [`streamed`] (`streamed.rs`): a map file streamed to keypoint files and a downsampled overlay (what
//!   `detect` and `demo` call);
//! - [`output`] (`output.rs`): keypoint files (CSV, JSON); [`overlay`] (`overlay.rs`): keypoints drawn on
//!   a map.
//!
//! A new detector: its kind in `DetectorKind` (`src/backend/mod.rs`); if it reads a few rows at a time,
//! its windowed route in `Detector::run_windows` (`detector.rs`) and its halo in `Detector::window_plan`,
//! so that it streams; if it needs the whole map, a module above the backends as `robust/` is. Any
//! per-pixel kernel gets a reference twin in `src/backend/reference/`, a fast path in
//! `src/backend/fast/`, a WGSL kernel in `shaders/` with its host code in `src/backend/gpu/`, and
//! conformance tests in `tests/backend/gpu_conformance.rs`; then come the CLI options (`src/cli/mod.rs`),
//! `bench`, `compare`, `eval`, the fuzz `detect` target and the Python options.

pub mod detector;
pub mod output;
pub mod overlay;
pub mod robust;
pub mod streamed;
