//! Many maps placed, end to end ([`run`]): each distinct map prepared once, the pairs aligned (in rounds
//! when screened), then placed.

use super::graph::Placement;
use super::pairs::pairwise_of;
use super::place::{place, refuse_unfounded, vouched};
use super::{cache, rounds, Engine, Local};
use super::{Cache, CacheUse, GlobalOptions, PairRecord, Pairwise, Run, Timing};
use crate::merge::many::prescreen::Signature;
use crate::merge::pair::align::Prepared;
use crate::merge::transform::Rigid;
use crate::support::error::Result;

/// Places `maps`: every distinct map prepared once and every pair of them aligned (both in parallel; in a
/// set of more than [`Prescreen::above`](crate::merge::many::prescreen::Prescreen::above) maps, the pairs the pre-screen chooses, in rounds), then
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
    let (duplicate_of, unique) = distinct(maps);
    let t = Instant::now();
    cache.start(options);
    let keys: Vec<cache::Key> = unique
        .par_iter()
        .map(|&i| cache::Key::of(&maps[i]))
        .collect();
    let m = unique.len();
    let screen = options.prescreen.filter(|p| m > p.above);
    let mut used = CacheUse::default();
    let (prepared, signatures) = prepare_distinct(
        maps,
        &unique,
        &keys,
        cache,
        engine,
        screen.is_some(),
        &mut used,
    )?;
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
    to_maps(
        &mut pairwise,
        &mut placement,
        &unique,
        &duplicate_of,
        &alignable,
    );
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

/// Each map's earlier identical copy (the same pixels and thresholds), if any; and the maps with none.
fn distinct(maps: &[crate::map::OccupancyMap]) -> (Vec<Option<usize>>, Vec<usize>) {
    let duplicate_of: Vec<Option<usize>> = (0..maps.len())
        .map(|i| {
            (0..i).find(|&j| {
                maps[j].image == maps[i].image && maps[j].thresholds == maps[i].thresholds
            })
        })
        .collect();
    let unique = (0..maps.len())
        .filter(|&i| duplicate_of[i].is_none())
        .collect();
    (duplicate_of, unique)
}

/// The preparations of the distinct maps `unique` (and, where a screen needs them, their signatures):
/// those `cache` kept under `keys`, the others made by `engine`; counted in `used`.
fn prepare_distinct(
    maps: &[crate::map::OccupancyMap],
    unique: &[usize],
    keys: &[cache::Key],
    cache: &mut Cache,
    engine: &mut dyn Engine,
    screened: bool,
    used: &mut CacheUse,
) -> Result<(Vec<Prepared>, Vec<Option<Signature>>)> {
    use rayon::prelude::*;
    let mut kept: Vec<Option<cache::Kept>> = keys.iter().map(|k| cache.take_map(k)).collect();
    let m = unique.len();
    let missing: Vec<usize> = (0..m).filter(|&k| kept[k].is_none()).collect();
    used.maps_reused = m - missing.len();
    used.maps_prepared = missing.len();
    let todo: Vec<(usize, &crate::map::OccupancyMap)> =
        missing.iter().map(|&k| (k, &maps[unique[k]])).collect();
    let made = engine.prepare(&todo, screened)?;
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
    if screened {
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
    Ok(kept
        .into_iter()
        .map(|p| p.expect("every map prepared"))
        .unzip())
}

/// The pairs and the placement back in the maps' own indices (of `n` maps: `unique` the distinct
/// ones, `duplicate_of` each copy's first): every copy placed with its first copy, and copies that
/// joined nothing a group of their own where the map has something to align (`alignable`).
fn to_maps(
    pairwise: &mut Pairwise,
    placement: &mut Placement,
    unique: &[usize],
    duplicate_of: &[Option<usize>],
    alignable: &[bool],
) {
    let n = duplicate_of.len();
    pairwise.n = n;
    for e in &mut pairwise.edges {
        (e.a, e.b) = (unique[e.a], unique[e.b]);
    }
    for p in &mut pairwise.pairs {
        (p.a, p.b) = (unique[p.a], unique[p.b]);
    }
    for d in &mut placement.dropped {
        (d.edge.a, d.edge.b) = (unique[d.edge.a], unique[d.edge.b]);
    }
    let mut by_map = Vec::with_capacity(n);
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
                .chain((0..n).filter(|&i| duplicate_of[i] == Some(first)))
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
}
