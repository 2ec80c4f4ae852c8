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

/// Like `eprintln!`, but a standard error that cannot be written (a closed pipe: `2>&1 | head`) drops the
/// message instead of panicking: a diagnostic must never be what stops a run.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {{
        use ::std::io::Write as _;
        let _ = ::std::writeln!(::std::io::stderr(), $($arg)*);
    }};
}

pub mod backend;
pub mod baselines;
pub mod bench;
pub mod compare;
pub mod cpu;
pub mod decode;
pub mod detector;
pub mod error;
pub mod eval;
pub mod fast;
pub mod files;
pub mod gpu;
pub mod grid;
pub mod map;
pub mod memory;
pub mod merge;
pub mod output;
pub mod overlay;
pub mod plot;
pub mod report;
pub mod robust;
pub mod rules;
pub mod states;
mod stats;
pub mod stop;
pub mod stream;
pub mod streamed;
pub mod synth;

pub use baselines::{Baseline, BaselineParams};
pub use detector::{
    Backend, BackendChoice, DetectOptions, Detection, Detector, DetectorKind, Keypoint,
};
pub use error::{Error, Result};
pub use map::{GeoRef, MapImage, OccupancyMap, Thresholds};
pub use rules::{RuleSet, RuleTable};
pub use states::{CellState, ClassTable};
