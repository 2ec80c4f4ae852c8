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

mod cache;
pub mod calibrate;
pub mod codec;
mod engine;
pub mod graph;
mod merged;
pub mod mosaic;
pub mod page;
pub mod posegraph;
pub mod poses;
pub mod prescreen;
pub mod previous;
mod record;
mod rounds;
mod verify;

use serde::Serialize;

use crate::merge::many::prescreen::{Prescreen, Signature};
use crate::merge::pair::align::{align_prepared, MergeOptions, Prepared};
use crate::merge::transform::Rigid;
use crate::support::error::Result;
pub use cache::{content_id, Cache, CacheUse, ContentId};
pub use engine::{Engine, Local};
pub use merged::{merge_maps, merge_maps_cached, merge_maps_with, ManyMerge};
pub use record::{EdgeRecord, PairRecord};
pub use rounds::Round;

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

/// Aligns every pair of `maps` (map `b` onto map `a` for `a < b`), the pairs in parallel; `progress` is
/// told after each pair (pairs done, pairs in all) from whichever thread finished it. Under a raised
/// [`crate::support::stop::Stop`] the pairs not started are skipped and the result is [`crate::Error::Interrupted`].
pub fn align_all(
    maps: &[Prepared],
    options: &GlobalOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Pairwise> {
    let order: Vec<(usize, usize)> = pair_order(maps.len()).collect();
    let records = align_pairs(maps, options, progress, &order)?;
    let all: Vec<(usize, usize, PairRecord)> = order
        .into_iter()
        .zip(records)
        .map(|((a, b), r)| (a, b, r))
        .collect();
    Ok(pairwise_of(maps.len(), &all))
}

/// Every pair of `n` maps, `a` then `b` ascending (`a < b`).
fn pair_order(n: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..n).flat_map(move |a| (a + 1..n).map(move |b| (a, b)))
}

/// Aligns `pairs` of `maps` (map `b` onto map `a`) in parallel, on this process's threads; each pair's
/// record, in the same order. `progress` hears (pairs done, pairs in all).
pub(crate) fn align_pairs(
    maps: &[Prepared],
    options: &GlobalOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
    pairs: &[(usize, usize)],
) -> Result<Vec<PairRecord>> {
    use rayon::prelude::*;
    let done = std::sync::atomic::AtomicUsize::new(0);
    let total = pairs.len();
    // A raised stop ends each pair at its next check and skips the pairs not started.
    let stop = crate::support::stop::current();
    let results: Vec<Result<PairRecord>> = pairs
        .par_iter()
        .map(|&(a, b)| {
            crate::support::stop::with(stop.clone(), || {
                crate::support::stop::check()?;
                // A pair too large to correlate is declined, not the whole set refused.
                let al = match crate::merge::pair::coarse::check_size(
                    (maps[b].w, maps[b].h),
                    (maps[a].w, maps[a].h),
                ) {
                    Err(e) => crate::merge::pair::align::declined(&e.to_string()),
                    Ok(()) => align_prepared(&maps[a], &maps[b], &options.pair)?,
                };
                let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(k, total);
                Ok(PairRecord::of(&maps[a], &maps[b], &al, options))
            })
        })
        .collect();
    // The first error in the pairs' order, whichever thread met it first.
    results.into_iter().collect()
}

/// The record of the aligned `pairs` (`a < b`, ascending, each with its record) of `n` maps: each
/// pair's verdict and its usable candidates as edges.
fn pairwise_of(n: usize, pairs: &[(usize, usize, PairRecord)]) -> Pairwise {
    let mut out = Pairwise {
        n,
        screened_out: (n * n.saturating_sub(1) / 2).saturating_sub(pairs.len()),
        ..Pairwise::default()
    };
    for (a, b, r) in pairs {
        out.pairs.push(r.verdict(*a, *b));
        out.edges.extend(r.edges(*a, *b));
    }
    out
}

/// Half the side of the square of points where a pose-graph constraint is measured, pixels (150, 300 and
/// the moved map's wall bounding box tried on 80 random sets of 3-8 F5 maps: 2, 3 and 3 pairs of 1070
/// derived beyond the success limit, all within 5% of it).
const CONSTRAINT_SPREAD: f64 = 150.0;

/// Where an edge's constraint is measured: its overlap centre and the corners of a square around it
/// (in the moved map's pixels). Where the two maps overlap is where their pairwise transform is right:
/// maps bend, and far from the overlap it may be tens of pixels off.
fn around((x, y): (f64, f64)) -> Vec<(f64, f64)> {
    let r = CONSTRAINT_SPREAD;
    vec![
        (x, y),
        (x - r, y - r),
        (x + r, y - r),
        (x - r, y + r),
        (x + r, y + r),
    ]
}

/// Where every map lands: the graph's placement ([`graph::place`]) with each group's poses from the
/// pose graph over the edges it kept ([`posegraph::solve`]); `maps` prepared from `images`.
pub fn place(
    pairwise: &Pairwise,
    maps: &[Prepared],
    images: &[&crate::map::OccupancyMap],
    options: &GlobalOptions,
    backend: &mut dyn crate::backend::Backend,
) -> Result<graph::Placement> {
    // The cycles once to find the confirmed pairs and the set's level; then again without the
    // candidates far above it, so that they neither vote nor confirm others.
    let first = graph::evidence(pairwise, options, None);
    let level = calibrate::calibrate(pairwise, &first);
    let ev = if pairwise.edges.iter().any(|e| level.excludes(e.residual)) {
        graph::evidence(pairwise, options, Some(&level))
    } else {
        first
    };
    let mut placement = graph::place(pairwise, maps, images, &ev, &level, options, backend)?;
    let kept: Vec<posegraph::Kept> = placement
        .kept
        .iter()
        .map(|&i| posegraph::Kept {
            u: pairwise.edges[i].a,
            v: pairwise.edges[i].b,
            accepted: pairwise.edges[i].accepted,
            weight: ev[i].vote(),
        })
        .collect();
    placement.kept = posegraph::rests_on(maps.len(), &kept)
        .into_iter()
        .map(|k| placement.kept[k])
        .collect();
    let start: Vec<Rigid> = placement.maps.iter().map(|m| m.pose).collect();
    for members in &placement.groups {
        let constraints: Vec<posegraph::Constraint> = placement
            .kept
            .iter()
            .filter(|&&i| members.contains(&pairwise.edges[i].a))
            .map(|&i| {
                let e = &pairwise.edges[i];
                posegraph::Constraint {
                    u: e.a,
                    v: e.b,
                    transform: e.transform,
                    points: around(e.at),
                    weight: ev[i].vote(),
                }
            })
            .collect();
        let solved = posegraph::solve(&start, members[0], &constraints);
        // The least squares only spreads the loop errors: a solution that moves a map further than two
        // placements may disagree (an ill-conditioned system) keeps the agglomeration's poses.
        let moved_far = members.iter().any(|&m| {
            let c = maps[m].reference_in_map()[4];
            let (p, q) = (start[m].apply(c), solved[m].apply(c));
            let turn = (start[m].theta_deg - solved[m].theta_deg + 180.0).rem_euclid(360.0) - 180.0;
            // Written so that a NaN counts as moved far.
            !(turn.abs() <= options.loop_deg && (p.0 - q.0).hypot(p.1 - q.1) <= options.loop_px)
        });
        if !moved_far {
            for &m in members {
                placement.maps[m].pose = solved[m];
            }
        }
    }
    Ok(placement)
}

/// Pairs whose records did not hold on the maps (the maps' indices, why).
type Refused = Vec<(usize, usize, String)>;

/// Why each record (map `b` onto map `a`) does not hold on the maps ([`verify`]), `None` where it does;
/// checked in parallel, a raised stop ending the checks not started.
fn why_not_each(
    maps: &[Prepared],
    records: &[((usize, usize), &PairRecord)],
    options: &GlobalOptions,
) -> Result<Vec<Option<String>>> {
    use rayon::prelude::*;
    let stop = crate::support::stop::current();
    records
        .par_iter()
        .map(|&((a, b), r)| {
            crate::support::stop::with(stop.clone(), || {
                crate::support::stop::check()?;
                verify::why_not(&maps[a], &maps[b], r, options)
            })
        })
        .collect()
}

/// The carried records (`start`) that hold on the maps, and the pairs whose records do not, with why.
fn vouched(
    maps: &[Prepared],
    start: rounds::Aligned,
    options: &GlobalOptions,
) -> Result<(rounds::Aligned, Refused)> {
    let records: Vec<((usize, usize), &PairRecord)> = start.iter().map(|(&p, r)| (p, r)).collect();
    let verdicts = why_not_each(maps, &records, options)?;
    let mut refused = Vec::new();
    let mut kept = rounds::Aligned::new();
    for (((a, b), r), why) in start.into_iter().zip(verdicts) {
        match why {
            Some(why) => refused.push((a, b, why)),
            None => {
                kept.insert((a, b), r);
            }
        }
    }
    Ok((kept, refused))
}

/// Refuses an engine's answer for `pairs` unless it is one record a pair and each holds on the maps
/// ([`verify`]): an executor elsewhere may be wrong, and a wrong record would place maps wrongly.
fn refuse_unfounded(
    maps: &[Prepared],
    pairs: &[(usize, usize)],
    records: &[PairRecord],
    options: &GlobalOptions,
) -> Result<()> {
    if records.len() != pairs.len() {
        return Err(crate::Error::invalid(format!(
            "the engine aligned {} pairs of {}",
            records.len(),
            pairs.len()
        )));
    }
    let each: Vec<((usize, usize), &PairRecord)> = pairs.iter().copied().zip(records).collect();
    let verdicts = why_not_each(maps, &each, options)?;
    match pairs
        .iter()
        .zip(verdicts)
        .find_map(|(p, why)| Some((p, why?)))
    {
        Some(((a, b), why)) => Err(crate::Error::invalid(format!(
            "the engine's alignment of map {b} onto map {a} does not hold on the maps: {why}"
        ))),
        None => Ok(()),
    }
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

/// Places `maps`: every distinct map prepared once and every pair of them aligned (both in parallel; in a
/// set of more than [`Prescreen::above`] maps, the pairs the pre-screen chooses, in rounds), then
/// [`place`]d; a map given twice is aligned once and placed with its first copy. `progress` hears (pairs
/// done, pairs in all) of each round; `backend` scores the placement's dense checks.
pub fn run(
    maps: &[crate::map::OccupancyMap],
    options: &GlobalOptions,
    backend: &mut dyn crate::backend::Backend,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Run> {
    run_cached(maps, options, backend, progress, &mut Cache::new())
}

/// [`run`] with the preparations and pair alignments of the last run kept in `cache`: only the maps not
/// seen there are prepared and only the pairs not seen there aligned; the result is [`run`]'s. Pairs
/// carried into the cache from an earlier run's file ([`Cache::carry`]) count as aligned from the start.
pub fn run_cached(
    maps: &[crate::map::OccupancyMap],
    options: &GlobalOptions,
    backend: &mut dyn crate::backend::Backend,
    progress: &(dyn Fn(usize, usize) + Sync),
    cache: &mut Cache,
) -> Result<Run> {
    run_with(maps, options, backend, progress, cache, &mut Local)
}

/// [`run_cached`] with the preparations and pair alignments the cache does not hold computed by
/// `engine` (this process's threads: [`Local`]; or workers elsewhere): the result is the same, to the
/// bit, whichever engine computes them.
pub fn run_with(
    maps: &[crate::map::OccupancyMap],
    options: &GlobalOptions,
    backend: &mut dyn crate::backend::Backend,
    progress: &(dyn Fn(usize, usize) + Sync),
    cache: &mut Cache,
    engine: &mut dyn Engine,
) -> Result<Run> {
    use rayon::prelude::*;
    use std::time::Instant;
    let duplicate_of: Vec<Option<usize>> = (0..maps.len())
        .map(|i| {
            (0..i).find(|&j| {
                maps[j].image == maps[i].image && maps[j].thresholds == maps[i].thresholds
            })
        })
        .collect();
    let unique: Vec<usize> = (0..maps.len())
        .filter(|&i| duplicate_of[i].is_none())
        .collect();
    let t = Instant::now();
    cache.start(options);
    let keys: Vec<cache::Key> = unique
        .par_iter()
        .map(|&i| cache::Key::of(&maps[i]))
        .collect();
    let mut kept: Vec<Option<cache::Kept>> = keys.iter().map(|k| cache.take_map(k)).collect();
    let m = unique.len();
    let screen = options.prescreen.filter(|p| m > p.above);
    let missing: Vec<usize> = (0..m).filter(|&k| kept[k].is_none()).collect();
    let mut used = CacheUse {
        maps_reused: m - missing.len(),
        maps_prepared: missing.len(),
        ..CacheUse::default()
    };
    let todo: Vec<(usize, &crate::map::OccupancyMap)> =
        missing.iter().map(|&k| (k, &maps[unique[k]])).collect();
    let made = engine.prepare(&todo, screen.is_some())?;
    if made.len() != missing.len() {
        return Err(crate::Error::invalid(format!(
            "the engine prepared {} maps of {}",
            made.len(),
            missing.len()
        )));
    }
    for (&k, p) in missing.iter().zip(made) {
        kept[k] = Some(p);
    }
    // A map kept from a run that needed no signature gets one now that a screen needs it.
    if screen.is_some() {
        let stop = crate::support::stop::current();
        kept.par_iter_mut()
            .zip(unique.par_iter())
            .try_for_each(|(kept, &i)| -> Result<()> {
                if let Some((_, s @ None)) = kept {
                    *s = Some(crate::support::stop::with(stop.clone(), || {
                        Signature::of(&maps[i])
                    })?);
                }
                Ok(())
            })?;
    }
    let (prepared, signatures): (Vec<Prepared>, Vec<Option<Signature>>) = kept
        .into_iter()
        .map(|p| p.expect("every map prepared"))
        .unzip();
    let prepare = t.elapsed().as_secs_f64();
    crate::support::stop::check()?;
    let t = Instant::now();
    // An earlier run's records are claims: those the maps do not bear out are aligned again.
    let (start, refused) = vouched(&prepared, cache.carried(&keys), options)?;
    used.pairs_refused = refused.len();
    let checked = engine.checked();
    let (done, rounds) = rounds::align_rounds(
        &prepared,
        &signatures,
        screen,
        &|a, b| cache.pair(&keys[a], &keys[b]),
        start,
        &mut |pairs| {
            let records = engine.align(&prepared, pairs, options, progress)?;
            if !checked {
                refuse_unfounded(&prepared, pairs, &records, options)?;
            }
            Ok(records)
        },
        &mut used,
    )?;
    let pairs: Vec<(usize, usize, PairRecord)> =
        done.into_iter().map(|((a, b), r)| (a, b, r)).collect();
    let mut pairwise = pairwise_of(prepared.len(), &pairs);
    pairwise.rounds = rounds;
    let align = t.elapsed().as_secs_f64();
    crate::support::stop::check()?;
    let t = Instant::now();
    let images: Vec<&crate::map::OccupancyMap> = unique.iter().map(|&i| &maps[i]).collect();
    let mut placement = place(&pairwise, &prepared, &images, options, backend)?;
    // The placement's last round may have ended at a stop: no placement is returned then.
    crate::support::stop::check()?;
    let place = t.elapsed().as_secs_f64();
    let alignable: Vec<bool> = prepared.iter().map(Prepared::alignable).collect();
    let records: Vec<(usize, usize, PairRecord)> = pairs
        .iter()
        .map(|(a, b, r)| (unique[*a], unique[*b], r.clone()))
        .collect();
    let kept = prepared.into_iter().zip(signatures);
    cache.keep(keys.into_iter().zip(kept).collect(), pairs, used);
    cache.refused = refused
        .into_iter()
        .map(|(a, b, why)| (unique[a], unique[b], why))
        .collect();
    // Back to the maps' own indices.
    pairwise.n = maps.len();
    for e in &mut pairwise.edges {
        (e.a, e.b) = (unique[e.a], unique[e.b]);
    }
    for p in &mut pairwise.pairs {
        (p.a, p.b) = (unique[p.a], unique[p.b]);
    }
    for d in &mut placement.dropped {
        (d.edge.a, d.edge.b) = (unique[d.edge.a], unique[d.edge.b]);
    }
    let mut by_map = Vec::with_capacity(maps.len());
    for (i, dup) in duplicate_of.iter().enumerate() {
        let first = dup.unwrap_or(i);
        let k = unique
            .binary_search(&first)
            .expect("a first copy is unique");
        by_map.push(placement.maps[k].clone());
    }
    // Each distinct map with its copies, first copy first.
    let with_copies: Vec<Vec<usize>> = unique
        .iter()
        .map(|&first| {
            std::iter::once(first)
                .chain((0..maps.len()).filter(|&i| duplicate_of[i] == Some(first)))
                .collect()
        })
        .collect();
    for members in &mut placement.groups {
        *members = members
            .iter()
            .flat_map(|&k| with_copies[k].iter().copied())
            .collect();
    }
    placement.maps = by_map;
    // Copies of a map that joined nothing still lie together: a group of their own, in place. A map
    // with nothing to align (no walls) is no group, however many copies.
    for (k, all) in with_copies.into_iter().enumerate() {
        if all.len() > 1 && placement.maps[all[0]].group.is_none() && alignable[k] {
            placement.groups.push(all);
        }
    }
    placement.groups.sort_by_key(|members| members[0]);
    for (g, members) in placement.groups.iter().enumerate() {
        for &m in members {
            let p = &mut placement.maps[m];
            if p.group.is_none() {
                p.pose = Rigid::IDENTITY;
                p.reason = None;
            }
            p.group = Some(g);
        }
    }
    Ok(Run {
        pairwise,
        records,
        placement,
        duplicate_of,
        timing: Timing {
            prepare,
            align,
            place,
        },
    })
}
