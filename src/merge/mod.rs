//! Map merging: the rigid transform between two robots' maps of one place, found with no initial pose,
//! checked before it is accepted, and the merged map.
//!
//! - [`align`](mod@align): the transform between two maps, verified.
//! - [`transform`]: pixel and world transforms between two maps' frames.
//! - [`compose`](mod@compose): the merged map in A's frame.
//! - [`pair`]: two maps merged end to end (resolutions, alignment, world transform, merged map).
//! - [`global`]: many maps at once: every pair aligned, one consistent placement of all.
//! - [`mosaic`]: the merged map of many placed maps, and its picture.
//! - [`footprint`]: what a merge will hold in memory, known before it allocates.
//! - [`hypotheses`]: where the aligner's hypotheses come from (dense correlation, corners, both).

mod accept;
mod alias;
pub mod align;
mod coarse;
pub mod codec;
pub mod compose;
mod distance;
mod fft;
pub mod footprint;
pub mod global;
pub mod hypotheses;
mod local;
pub mod mosaic;
pub mod pair;
mod prepare;
pub mod prescreen;
mod refine;
pub mod resample;
mod score;
pub mod symmetry;
pub mod transform;

pub use align::{align, Alignment, MergeOptions};
pub use compose::compose;
pub use transform::Rigid;
