//! # ogm-corners
//!
//! Corner detection in robot occupancy grid maps with the method of "A New Corner Detector Approach for
//! Occupancy Grid Map Merging": a free cell is a corner when its 8 neighbours match one of three rules,
//! compiled into a 256-entry table indexed by the neighbour bit pattern.
//!
//! ```
//! use ogm_corners::{DetectOptions, Detector, MapImage, OccupancyMap};
//!
//! // A free room (254) with a wall (0) around it: its four inner corners are keypoints.
//! let mut img = MapImage::filled(8, 8, 254).unwrap();
//! for i in 0..8 {
//!     for (x, y) in [(i, 0), (i, 7), (0, i), (7, i)] {
//!         img.pixels_mut()[y * 8 + x] = 0;
//!     }
//! }
//! let mut detector = Detector::new(DetectOptions::default());
//! let found = detector.detect(&OccupancyMap::from_image(img)).unwrap();
//! let corners: Vec<(u32, u32)> = found.keypoints.iter().map(|k| (k.x, k.y)).collect();
//! assert_eq!(corners, vec![(1, 1), (6, 1), (1, 6), (6, 6)]);
//! ```
//!
//! ## Using the library
//!
//! ```no_run
//! use ogm_corners::backend::gpu::{GpuBackend, GpuOptions};
//! use ogm_corners::detect::robust::RobustParams;
//! use ogm_corners::{DetectOptions, Detector, DetectorKind, OccupancyMap, RuleSet};
//!
//! // The paper's detector on a ROS map (its yaml, the image beside it).
//! let map = OccupancyMap::load("map.yaml")?;
//! let mut detector = Detector::new(DetectOptions { rules: RuleSet::Paper, ..DetectOptions::default() });
//! for k in detector.detect(&map)?.keypoints {
//!     println!("{} {} rule {}", k.x, k.y, k.rule);
//! }
//!
//! // The robust detector, its strongest 50 corners.
//! let mut robust = Detector::new(DetectOptions {
//!     detector: DetectorKind::OgmRobust,
//!     robust: RobustParams { min_strength: 12, ..RobustParams::default() },
//!     max_corners: Some(50),
//!     ..DetectOptions::default()
//! });
//! let found = robust.detect(&map)?; // found.robust: the grid angle; k.score: strength in pixels
//!
//! // The GPU backend: device, pipelines and buffers are created once and reused.
//! let gpu = GpuBackend::new(GpuOptions::default())?; // or GpuBackend::open(true, ..) for hardware only
//! let mut on_gpu = Detector::with_backend(DetectOptions::default(), Box::new(gpu));
//! # Ok::<(), ogm_corners::Error>(())
//! ```
//!
//! Keep the [`Detector`] and reuse it: backends keep their set-up between calls. Backends implement the
//! [`Backend`] trait; the CPU reference is `backend::reference::ReferenceBackend`, the GPU one
//! `backend::gpu::GpuBackend`, and [`Detector::with_backend`] runs any of them.
//!
//! A map a GPU mapping pipeline already keeps in a `wgpu::Buffer` (one byte a cell, any offset, any row
//! pitch) is detected where it lies, with only the corners crossing to the host: open the backend on the
//! pipeline's own device with `GpuBackend::from_device(&adapter, device, queue, options)` (or make the
//! buffer on `gpu.device()`), then `gpu.detect_device_map(&DeviceMap { buffer: &grid, offset, width,
//! height, bytes_per_row }, &classes, &rules, false)`. Same keypoints, same order as the map in memory; a
//! map its buffer cannot hold (a pitch under the width, a buffer too small or without `STORAGE`) is an
//! input error.
//!
//! Merging: `merge::align(&a, &b, &MergeOptions) -> Result<Alignment>`, `merge::pair::merge_pair`,
//! `merge::many::run` and `merge::many::merge_maps` (the method: `docs/merging.md`).
//!
//! Runnable examples in `examples/`: `detect_map`, `merge_two`, `merge_folder`, and `device_map`, a map
//! on the GPU detected where it lies, end to end (`cargo run --release --example detect_map -- MAP.yaml`).
//!
//! ## The layers, bottom to top
//!
//! A file imports only its own layer and the layers below it, and no file imports one that imports it
//! back: `tests/house/layering.rs` checks both on the source. Within a module, `mod.rs` and its children
//! may use each other: a parent declares the types its children share and re-exports what they build.
//!
//! 1. **Services** ([`support`]): errors, stopping on a signal, the worker pool, the memory budget, files
//!    written whole, the marks the tool's own outputs carry, drawing, HTML pages.
//! 2. **Maps** ([`map`]): images and their decoders (PGM/PNG), yaml, georeference and thresholds, maps
//!    as rows (streamed), the three states, the synthetic office, a grid turned to the walls.
//! 3. **The backend interface and the reference** ([`backend`]): the trait every backend implements,
//!    keypoints and options; the paper's 256-entry table ([`backend::rules`]); the baselines' parameters
//!    and selection ([`backend::baselines`]: Harris, Shi-Tomasi, Trajkovic-Hedley); the CPU reference
//!    ([`backend::reference`]: one file per WGSL kernel, its twin).
//! 4. **Fast backends**: [`backend::fast`] (the fast CPU path), [`backend::gpu`] (wgpu compute kernels,
//!    bit-identical to the reference).
//! 5. **Detectors and their outputs** ([`detect`]): the detector (a backend driven over a map, in memory
//!    or streamed), the robust form for real maps, a map file to keypoint files, keypoint files, keypoints
//!    drawn on a map.
//! 6. **Merging**: [`merge`] (two maps and many, with no initial poses).
//! 7. **Measuring** ([`measure`]): the harness apart from the algorithm: the detectors' repeatability
//!    and recall, Table I, benchmarks, pair sets with ground truth, synthetic pairs and families,
//!    `merge-eval`.
//!
//! The command line (`src/cli/`, one file per subcommand) sits on top, in the binary.

// Pipelines read as named stages: no function over 120 lines (clippy.toml sets the limit).
#![warn(clippy::too_many_lines)]

/// Like `eprintln!`, but a standard error that cannot be written (a closed pipe: `2>&1 | head`) drops the
/// message instead of panicking: a diagnostic must never be what stops a run.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {{
        use ::std::io::Write as _;
        let _ = ::std::writeln!(::std::io::stderr(), $($arg)*);
    }};
}

// 1. Services.
pub mod support;
// 2. Maps.
pub mod map;
// 3-4. The backends: the rule table, the backend interface, the CPU reference, the fast CPU path, the GPU.
pub mod backend;
// 5. Detectors and their outputs.
pub mod detect;
// 6. Merging.
pub mod merge;
// 7. Measuring.
pub mod measure;

pub use backend::baselines::{Baseline, BaselineParams};
pub use backend::rules::{RuleSet, RuleTable};
pub use detect::detector::{
    Backend, BackendChoice, DetectOptions, Detection, Detector, DetectorKind, Keypoint,
};
pub use map::states::{CellState, ClassTable};
pub use map::{GeoRef, MapImage, OccupancyMap, Thresholds};
pub use support::error::{Error, Result};
