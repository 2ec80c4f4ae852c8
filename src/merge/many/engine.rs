//! Where a many-map run's work is done: each map's preparation and each chosen pair's alignment. The
//! run itself (which pairs, the placement) stays in one process; [`Local`] does the work on this
//! process's threads, and another [`Engine`] may hand it to workers elsewhere (the Python
//! `ogm_corners.distributed` sends it to a Ray cluster), with the same result to the bit: preparation
//! and alignment are pure functions of the pixels, the thresholds and the options, and what comes back
//! is exact ([`crate::merge::many::codec`], [`crate::merge::many::PairRecord`]).

use crate::map::OccupancyMap;
use crate::merge::many::prescreen::Signature;
use crate::merge::many::{align_pairs, GlobalOptions, PairRecord};
use crate::merge::pair::align::Prepared;
use crate::support::error::Result;

/// Computes a run's preparations and pair alignments.
pub trait Engine {
    /// Prepares `maps` (each with its index among the run's distinct maps, which [`Engine::align`]
    /// names it by), each with its pre-screen signature when `signatures`; one per map, in order. What
    /// it returns must be able to be placed ([`crate::merge::many::codec::Form::Placement`] at least); only
    /// this engine aligns it.
    fn prepare(
        &mut self,
        maps: &[(usize, &OccupancyMap)],
        signatures: bool,
    ) -> Result<Vec<(Prepared, Option<Signature>)>>;

    /// Aligns `pairs` (map `b` onto map `a`, indices among the run's distinct maps, whose preparations
    /// are `maps`); one record per pair, in order. `progress` hears (pairs done, pairs in all).
    fn align(
        &mut self,
        maps: &[Prepared],
        pairs: &[(usize, usize)],
        options: &GlobalOptions,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Vec<PairRecord>>;

    /// Whether its records are this process's own alignments of the maps handed to it, so need no
    /// checking. Otherwise (the default: an engine elsewhere) each record is checked against the maps
    /// before it is used, and a run with one that does not hold is refused.
    fn checked(&self) -> bool {
        false
    }
}

/// This process's threads (rayon's pool): the maps prepared and the pairs aligned in parallel.
#[derive(Clone, Copy, Debug, Default)]
pub struct Local;

impl Engine for Local {
    fn prepare(
        &mut self,
        maps: &[(usize, &OccupancyMap)],
        signatures: bool,
    ) -> Result<Vec<(Prepared, Option<Signature>)>> {
        use rayon::prelude::*;
        let stop = crate::support::stop::current();
        maps.par_iter()
            .map(|&(_, map)| {
                crate::support::stop::with(stop.clone(), || {
                    // A raised stop skips the maps not yet prepared.
                    crate::support::stop::check()?;
                    let s = signatures.then(|| Signature::of(map)).transpose()?;
                    Ok((Prepared::new(map), s))
                })
            })
            .collect()
    }

    fn align(
        &mut self,
        maps: &[Prepared],
        pairs: &[(usize, usize)],
        options: &GlobalOptions,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Vec<PairRecord>> {
        align_pairs(maps, options, progress, pairs)
    }

    fn checked(&self) -> bool {
        true
    }
}
