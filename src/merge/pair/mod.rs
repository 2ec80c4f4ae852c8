//! Two maps merged: the aligner that finds the rigid transform between them with no initial pose and
//! checks it before it is accepted, and the pair merged end to end.
//!
//! - [`align`](mod@align): the transform between two maps, verified: a map prepared once (`prepare`:
//!   walls, distance maps, the scoring kernel's flags; `distance`, `fft`), the coarse hypotheses and
//!   their screening (`coarse`, [`hypotheses`]), the scoring kernel's probes (`score`), ICP, the polish
//!   and the verification (`refine`), the candidates screened, refined and chosen (`choose`), the drift-tolerant local fit (`local`), the poses a symmetric or
//!   repeating building also offers ([`symmetry`], `alias`) and the acceptance test (`accept`).
//! - `merged`: two maps merged end to end ([`merge_pair`], [`compose_pair`], [`overlay_pair`]).

pub(in crate::merge) mod accept;
pub(in crate::merge) mod alias;
pub mod align;
pub(in crate::merge) mod choose;
pub(in crate::merge) mod coarse;
pub(in crate::merge) mod distance;
pub(in crate::merge) mod fft;
pub mod hypotheses;
pub(in crate::merge) mod local;
mod merged;
pub(in crate::merge) mod prepare;
pub(in crate::merge) mod refine;
pub(in crate::merge) mod score;
pub mod symmetry;

pub use merged::{at_resolution_of, compose_pair, merge_pair, overlay_pair, PairMerge, Verdict};
