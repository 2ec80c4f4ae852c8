//! Detection: a backend driven over a map, in memory or streamed from its file, and what comes out.
//!
//! - [`detector`]: the [`Detector`](detector::Detector) that picks a backend and runs it over a map
//!   whole or in windows of rows;
//! - [`robust`]: the robust form of the OGM detector for real maps (walls' direction, tiles,
//!   suppression);
//! - [`streamed`]: a map file streamed to keypoint files and a downsampled overlay (what `detect` and
//!   `demo` call);
//! - [`output`]: keypoint files (CSV, JSON); [`overlay`]: keypoints drawn on a map.

pub mod detector;
pub mod output;
pub mod overlay;
pub mod robust;
pub mod streamed;
