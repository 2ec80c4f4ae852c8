//! Map merging: the rigid transform between two robots' maps of one place, found with no initial pose,
//! checked before it is accepted, and the merged map.
//!
//! - [`pair`] (`pair/`): two maps: the aligner ([`pair::align`]: hypotheses, scoring, refinement, the
//!   acceptance test and the poses a symmetric or repeating building also offers), and two maps merged end
//!   to end (resolutions, alignment, world transform, merged map).
//! - [`many`] (`many/`): many maps at once: every pair aligned (or those a pre-screen chooses), one
//!   consistent placement of all, the merged map of each group and its picture.
//! - [`transform`] (`transform.rs`): pixel and world transforms between two maps' frames.
//! - [`compose`](mod@compose) (`compose.rs`): the merged map in A's frame, and its overlay;
//!   [`resample`] (`resample.rs`): a map brought to another's resolution.
//! - [`footprint`] (`footprint.rs`): what a merge will hold in memory, known before it allocates.
//!
//! Two maps (`pair/`) and what both use (the files here) sit below many maps (`many/`), which place the
//! pairs the two-map aligner gives: `tests/house/layering.rs` checks that neither imports `many/`.
//! Merging scores its candidates through the `Backend` trait (`score_transforms`, the `merge_score`
//! kernel), so it runs on every backend.

pub mod compose;
pub mod footprint;
pub mod many;
pub mod pair;
pub mod resample;
pub mod transform;

pub use compose::compose;
pub use pair::align::{align, Alignment, MergeOptions, Ranking};
pub use transform::Rigid;
