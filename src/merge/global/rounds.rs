//! Which pairs of a set are aligned: every pair, or, in a large set, the pairs the pre-screen
//! ([`crate::merge::prescreen`]) chooses in rounds: each map with its most similar maps first, then the
//! pairs that close the cycles of the accepted ones (their poses so far make them overlap) and that may
//! join their components, until one of those rounds accepts nothing.

use std::collections::{BTreeMap, BTreeSet};

use serde::Serialize;

use super::{align_pairs, pair_order, CacheUse, GlobalOptions};
use crate::error::Result;
use crate::merge::align::{Alignment, Prepared};
use crate::merge::prescreen::{self, Prescreen, Signature};
use crate::merge::transform::Rigid;

/// One round of a screened set's alignments.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Round {
    /// Pairs aligned.
    pub pairs: usize,
    /// Of them, accepted by the pair test.
    pub accepted: usize,
}

/// Each aligned pair's alignment, by pair (`a < b`).
pub(super) type Aligned = BTreeMap<(usize, usize), Alignment>;

/// Aligns the pairs of `maps` that `screen` chooses (every pair without one), each taken from `known`
/// where it has it; returns every aligned pair's alignment by pair (`a < b`) and, when screened, the
/// rounds. `signatures` holds every map's when screened. `used` counts the pairs reused and aligned.
pub(super) fn align_rounds(
    maps: &[Prepared],
    signatures: &[Option<Signature>],
    screen: Option<Prescreen>,
    options: &GlobalOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
    known: &dyn Fn(usize, usize) -> Option<Alignment>,
    used: &mut CacheUse,
) -> Result<(Aligned, Vec<Round>)> {
    let m = maps.len();
    let similar = screen.map(|_| {
        let s: Vec<&Signature> = signatures.iter().flatten().collect();
        prescreen::similarities(&s)
    });
    let mut chosen: Vec<(usize, usize)> = match (screen, &similar) {
        (Some(p), Some(similar)) => prescreen::pairs(similar, p.partners),
        _ => pair_order(m).collect(),
    };
    let mut done = Aligned::new();
    let mut rounds: Vec<Round> = Vec::new();
    for round in 0.. {
        let pairs: Vec<(usize, usize, Option<Alignment>)> =
            chosen.iter().map(|&(a, b)| (a, b, known(a, b))).collect();
        used.pairs_reused += pairs.iter().filter(|p| p.2.is_some()).count();
        used.pairs_aligned += pairs.iter().filter(|p| p.2.is_none()).count();
        let alignments = align_pairs(maps, options, progress, pairs)?;
        let accepted = alignments.iter().filter(|al| al.accepted).count();
        rounds.push(Round {
            pairs: chosen.len(),
            accepted,
        });
        done.extend(chosen.iter().copied().zip(alignments));
        let (Some(p), Some(similar)) = (screen.filter(|p| round < p.rounds), &similar) else {
            break;
        };
        // A round that accepted nothing ends them: the next would be chosen from what this one had.
        if round > 0 && accepted == 0 {
            break;
        }
        let accepted: Vec<(usize, usize, Rigid, f64)> = done
            .iter()
            .filter(|(_, al)| al.accepted)
            .map(|(&(a, b), al)| (a, b, al.transform, al.score))
            .collect();
        let aligned: BTreeSet<(usize, usize)> = done.keys().copied().collect();
        let forest = prescreen::forest(m, &accepted);
        let overlap =
            |u: usize, v: usize, t: &Rigid| prescreen::predicted_overlap(&maps[u], &maps[v], t);
        let mut next: BTreeSet<(usize, usize)> =
            prescreen::closing_pairs(&forest, &aligned, &overlap, p.per_round)
                .into_iter()
                .collect();
        next.extend(prescreen::joining_pairs(similar, &forest, &aligned));
        chosen = next.into_iter().collect();
        if chosen.is_empty() {
            break;
        }
    }
    if screen.is_none() {
        rounds.clear();
    }
    Ok((done, rounds))
}
