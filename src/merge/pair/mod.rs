//! Two maps merged: the aligner that finds the rigid transform between them with no initial pose and
//! checks it before it is accepted, and the pair merged end to end.
//!
//! How two maps flow: [`merge_pair`] brings B to A's resolution (`crate::merge::resample`) and calls
//! `align::align_with`. Each map is prepared once (`align::Prepared`: wall pixels, distance maps, the
//! scoring kernel's flag bytes, coarse masks); `coarse.rs` makes the hypotheses (20 rotations, FFT
//! correlation over every shift, 32 peaks each); every hypothesis is screened on the full maps by the
//! scoring kernel (`Backend::score_transforms`); the best distinct ones are refined by ICP and verified
//! (`refine.rs`), measured by the drift-tolerant local fit (`local.rs`), chosen and polished
//! (`choose.rs`), weighed against the other poses the maps offer and judged by the acceptance rule and
//! its vetoes (`accept.rs`), in the stages of `align.rs`. The outcome: a [`PairMerge`] and its [`Verdict`].
//!
//! - [`align`](mod@align) (`align.rs`): the transform between two maps, verified: its stages in order, and
//!   the self-symmetry;
//! - `prepare.rs`: a map prepared for alignment once (walls, distance maps, the scoring kernel's flags),
//!   with its distance maps (`distance.rs`) and FFTs (`fft.rs`);
//! - `coarse.rs`: the coarse hypotheses and their screening; [`hypotheses`] (`hypotheses.rs`): corner
//!   hypotheses;
//! - `score.rs`: the scoring kernel's probes;
//! - `refine.rs`: ICP, the polish and the verification;
//! - `choose.rs`: the candidates screened, refined and chosen;
//! - `local.rs`: the drift-tolerant local fit;
//! - `alias.rs` and [`symmetry`] (`symmetry.rs`): the alternative poses a symmetric or repeating building
//!   also offers, and the map's turns onto itself;
//! - `accept.rs`: the acceptance test; `evidence.rs`: the building-independent measures reported beside
//!   it (the consistent evidence against the best distinct alternative's, the walls' agreement as a share
//!   of what the overlap could show, each map's clutter and the conflict beyond it);
//! - `merged.rs`: two maps merged end to end ([`merge_pair`], [`compose_pair`], [`overlay_pair`]).
//!
//! A new merge stage goes in the file of its concern (hypotheses in `coarse.rs` or `hypotheses.rs`,
//! refinement in `refine.rs`, the choice in `choose.rs`, acceptance in `accept.rs`; many-map placement
//! under `crate::merge::many`), with dense scoring through `Backend::score_transforms` so that it runs on
//! every backend.

pub(in crate::merge) mod accept;
pub(in crate::merge) mod alias;
pub mod align;
pub(in crate::merge) mod choose;
pub(in crate::merge) mod coarse;
pub(in crate::merge) mod distance;
pub(in crate::merge) mod evidence;
pub(in crate::merge) mod fft;
pub mod hypotheses;
pub(in crate::merge) mod local;
mod merged;
pub(in crate::merge) mod prepare;
pub(in crate::merge) mod refine;
pub(in crate::merge) mod score;
pub mod symmetry;

pub use merged::{at_resolution_of, compose_pair, merge_pair, overlay_pair, PairMerge, Verdict};
