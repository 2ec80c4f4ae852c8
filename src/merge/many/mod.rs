//! Merging many maps at once: every pair aligned, or in a large set the pairs a pre-screen chooses
//! ([`crate::merge::many::prescreen`]; each map prepared once, the pairs in parallel), then
//! one consistent placement of every map chosen over the graph of all pairwise candidates, not only each
//! pair's best one ([`place`]), and the merged map of each group ([`crate::merge::many::mosaic`]).
//!
//! Why a set of maps is easier than a pair: true pairwise transforms agree around cycles (A -> B -> C
//! composes to A -> C) and wrong ones almost never do. So a candidate no single-pair test would accept
//! is used when a cycle confirms it, and an accepted one that cycles contradict is dropped:
//!
//! 1. Every candidate of every pair is an edge weighted by its evidence (the pair rule's value,
//!    [`Candidate::score`](crate::merge::pair::align::Candidate), from [`GlobalOptions::weak_from`]); the ones the pair
//!    test did not accept weigh little, and join groups only through cycles and the mosaic test (3.).
//! 2. Triangles ([`graph`]): an edge gains the weight of each third map through which two other edges
//!    compose to it within [`GlobalOptions::loop_deg`] and [`GlobalOptions::loop_px`]; an accepted edge
//!    loses the weight of each third map through which two accepted edges compose to something else.
//!    The set's own level of conflict at the poses cycles confirm ([`calibrate`]) then excludes the
//!    candidates far above it, and the triangles are counted again without them.
//! 3. Groups grow by agglomeration: the best-supported placement of one group into another (votes of all
//!    edges between them, clustered), taken when an accepted edge stands behind it (or, when only cycles
//!    or several pairs do, when the pair test on the two groups' mosaics agrees), no other placement
//!    comes close, and no overlapping pair of maps it puts together contradicts itself densely.
//! 4. A weighted pose-graph least squares over the edges consistent with the placement ([`posegraph`]).
//!
//! How many maps flow: `merge_maps` (`merged.rs`) brings every map to one resolution and calls `run`
//! (`run.rs`): every pair aligned by the two-map aligner on every core (`pairs.rs`, `align_all`), or, in a
//! set of more than 12 maps (by default), the pairs the pre-screen chooses (`prescreen.rs`: each map's
//! signature and their similarities, the pairs that close cycles and join components; `rounds.rs`: the
//! rounds of alignments); each pair kept as a record (`record.rs`); the work done by an engine
//! (`engine.rs`: this process's threads, or a Python executor over Ray through `codec.rs`, a preparation
//! and a signature as checked bytes); an earlier run's pairs taken up from its `--poses` file
//! (`previous.rs`). Then where every map lands (`place.rs`): the evidence of every candidate around
//! triangles and the groups grown by agglomeration (`graph.rs`), with the set's own level of conflict
//! (`calibrate.rs`), and a pose graph per group (`posegraph.rs`). Each group's merged map and picture come
//! from `mosaic.rs`, the `--poses` and `--init-poses` documents from `poses.rs`, the many-map `merge` page
//! from `page.rs`. This file holds the options and results they share; `cache.rs`, what one placement
//! hands the next; `verify.rs`, a pair's record checked against the maps before a placement uses it.

mod cache;
pub mod calibrate;
pub mod codec;
mod engine;
pub mod graph;
mod merged;
pub mod mosaic;
pub mod page;
mod pairs;
mod place;
pub mod posegraph;
pub mod poses;
pub mod prescreen;
pub mod previous;
mod record;
mod rounds;
mod run;
mod verify;

use serde::Serialize;

use crate::merge::many::prescreen::Prescreen;
use crate::merge::pair::align::MergeOptions;
use crate::merge::transform::Rigid;
pub use cache::{content_id, Cache, CacheUse, ContentId};
pub use engine::{Engine, Local};
pub use merged::{merge_maps, merge_maps_cached, merge_maps_with, ManyMerge};
pub use pairs::align_all;
pub(crate) use pairs::align_pairs;
pub use place::place;
pub use record::{EdgeRecord, PairRecord};
pub use rounds::Round;
pub use run::{run, run_cached, run_with};

/// How to place many maps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlobalOptions {
    /// The pairwise alignment.
    pub pair: MergeOptions,
    /// Candidates whose pair rule value is below this are not used at all.
    pub weak_from: f64,
    /// Two placements of a map agree when they differ by at most this turn, degrees...
    pub loop_deg: f64,
    /// ... and move its walls' centre by at most this, pixels.
    pub loop_px: f64,
    /// Which pairs are aligned in a large set ([`crate::merge::many::prescreen`]); `None`: every pair.
    pub prescreen: Option<Prescreen>,
}

impl Default for GlobalOptions {
    fn default() -> Self {
        GlobalOptions {
            pair: MergeOptions::default(),
            weak_from: graph::WEAK_FROM,
            loop_deg: graph::LOOP_DEG,
            loop_px: graph::LOOP_PX,
            prescreen: Some(Prescreen::default()),
        }
    }
}

impl GlobalOptions {
    /// The defaults with each map of a large set aligned with its `partners` most similar maps first
    /// ([`Prescreen::partners`]); 0 aligns every pair.
    pub fn with_partners(partners: usize) -> GlobalOptions {
        GlobalOptions {
            prescreen: (partners > 0).then(|| Prescreen {
                partners,
                ..Prescreen::default()
            }),
            ..GlobalOptions::default()
        }
    }
}

/// One pairwise candidate: map `b`'s pixels to map `a`'s (`a < b`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Edge {
    /// The reference map's index.
    pub a: usize,
    /// The moved map's index.
    pub b: usize,
    /// Its rank among the pair's candidates (0: the pair's choice).
    pub rank: usize,
    /// B's pixels to A's.
    pub transform: Rigid,
    /// The pair rule's value for it.
    pub score: f64,
    /// Whether the pair test accepted it (the choice only).
    pub accepted: bool,
    /// Where it makes the maps overlap, in B's pixels (`overlap_centre` in the aligner): where it is
    /// compared with other estimates of B's placement.
    pub at: (f64, f64),
    /// Its walls in the other map's free space once each tile of the overlap has had a few px of shift
    /// ([`Features::residual`](crate::merge::pair::accept::Features)): what [`calibrate`] weighs against the set's
    /// own level.
    pub residual: f64,
}

impl Edge {
    /// [`Edge::at`] in map `of`'s pixels (`of` is `a` or `b`).
    pub fn at_in(&self, of: usize) -> (f64, f64) {
        if of == self.b {
            self.at
        } else {
            self.transform.apply(self.at)
        }
    }
}

impl Edge {
    /// The transform from the other map's pixels to map `to`'s (`to` is `a` or `b`).
    pub fn toward(&self, to: usize) -> Rigid {
        if to == self.a {
            self.transform
        } else {
            self.transform.inverse()
        }
    }

    /// The other map.
    pub fn other(&self, of: usize) -> usize {
        if of == self.a {
            self.b
        } else {
            self.a
        }
    }
}

/// The pair test's verdict on one pair.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PairVerdict {
    /// The reference map.
    pub a: usize,
    /// The moved map.
    pub b: usize,
    /// Whether the pair test accepted its choice.
    pub accepted: bool,
    /// Its choice (B's pixels to A's).
    pub transform: Rigid,
    /// Its rule value.
    pub score: f64,
    /// Why not, when not.
    pub reason: Option<String>,
}

/// The pairs of a set of maps aligned: every pair, or those the pre-screen chose.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Pairwise {
    /// How many maps.
    pub n: usize,
    /// Every usable candidate of every aligned pair, pair by pair (`a` then `b` ascending), best first.
    pub edges: Vec<Edge>,
    /// Each aligned pair's verdict, in the same order.
    pub pairs: Vec<PairVerdict>,
    /// Pairs of distinct maps the pre-screen left out ([`GlobalOptions::prescreen`]).
    pub screened_out: usize,
    /// When the set was screened: the pairs aligned in each round (the most similar maps first, then
    /// the pairs closing cycles and joining components) and how many of them the pair test accepted.
    pub rounds: Vec<Round>,
}

/// Seconds spent on each stage of [`run`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Timing {
    /// Preparing every map (in parallel).
    pub prepare: f64,
    /// Aligning the pairs (in parallel; when screened, the signatures' comparison too).
    pub align: f64,
    /// The placement over the graph and the pose graph.
    pub place: f64,
}

impl Timing {
    /// All stages.
    pub fn total(&self) -> f64 {
        self.prepare + self.align + self.place
    }
}

/// Many maps placed ([`run`]).
#[derive(Clone, Debug, Serialize)]
pub struct Run {
    /// The pairs of distinct maps aligned: every pair, or those the pre-screen chose (indices of the maps
    /// as given).
    pub pairwise: Pairwise,
    /// Each aligned pair's record (the maps' indices as given, `a < b` among distinct maps), as a later
    /// run may take them up again ([`Cache::carry`]).
    #[serde(skip)]
    pub records: Vec<(usize, usize, PairRecord)>,
    /// Where every map lands (a duplicate where its first copy does, in its group after it).
    pub placement: graph::Placement,
    /// For each map, the earlier map it is a copy of (the same pixels and thresholds), if any.
    pub duplicate_of: Vec<Option<usize>>,
    /// Where the time went.
    pub timing: Timing,
}
