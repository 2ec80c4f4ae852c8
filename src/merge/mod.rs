//! Map merging: the rigid transform between two robots' maps of one place, found with no initial pose,
//! checked before it is accepted, and the merged map.
//!
//! - [`align`]: the transform between two maps, verified.
//! - [`transform`]: pixel and world transforms between two maps' frames.
//! - [`compose`]: the merged map in A's frame.
//! - [`pairs`]: pair sets with ground truth and their success test (`merge-eval`).

pub mod align;
pub mod compose;
pub mod eval;
pub mod pairs;
pub mod transform;

pub use align::{align, Alignment, MergeOptions};
pub use compose::compose;
pub use transform::Rigid;
