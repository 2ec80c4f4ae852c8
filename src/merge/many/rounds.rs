//! Which pairs of a set are aligned: every pair, or, in a large set, the pairs the pre-screen
//! ([`crate::merge::many::prescreen`]) chooses in rounds: each map with its most similar maps first, then the
//! pairs that close the cycles of the accepted ones (their poses so far make them overlap) and that may
//! join their components, until one of those rounds accepts nothing.

use std::collections::{BTreeMap, BTreeSet};

use serde::Serialize;

use crate::merge::many::pairs::pair_order;
use crate::merge::many::prescreen::{self, Prescreen, Signature};
use crate::merge::many::{CacheUse, PairRecord};
use crate::merge::pair::align::Prepared;
use crate::merge::transform::Rigid;
use crate::support::error::Result;

/// One round of a screened set's alignments.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Round {
    /// Pairs aligned.
    pub pairs: usize,
    /// Of them, accepted by the pair test.
    pub accepted: usize,
}

/// Each aligned pair's record, by pair (`a < b`).
pub(super) type Aligned = BTreeMap<(usize, usize), PairRecord>;

/// Aligns a batch of pairs (b onto a): one record each, in order.
pub(super) type AlignBatch<'a> = dyn FnMut(&[(usize, usize)]) -> Result<Vec<PairRecord>> + 'a;

/// Aligns the pairs of `maps` that `screen` chooses (every pair without one) with `align`, each taken
/// from `known` where it has it; the pairs of `start` count as aligned from the start (an earlier run's,
/// carried over: not chosen again). Returns every aligned pair's record by pair (`a < b`) and, when
/// screened, the rounds (the pairs of `start` aside). `signatures` holds every map's when screened.
/// `used` counts the pairs reused and aligned.
pub(super) fn align_rounds(
    maps: &[Prepared],
    signatures: &[Option<Signature>],
    screen: Option<Prescreen>,
    known: &dyn Fn(usize, usize) -> Option<PairRecord>,
    start: Aligned,
    align: &mut AlignBatch<'_>,
    used: &mut CacheUse,
) -> Result<(Aligned, Vec<Round>)> {
    let m = maps.len();
    let similar = screen.map(|_| {
        let s: Vec<&Signature> = signatures.iter().flatten().collect();
        prescreen::similarities(&s)
    });
    // Comparing thousands of signatures takes a while: a raised stop ends the run here.
    crate::support::stop::check()?;
    let mut chosen: Vec<(usize, usize)> = match (screen, &similar) {
        (Some(p), Some(similar)) => {
            let sizes: Vec<f64> = maps.iter().map(|m| m.walls.len() as f64).collect();
            prescreen::pairs(similar, &sizes, p.partners)
        }
        _ => pair_order(m).collect(),
    };
    used.pairs_reused += start.len();
    let mut done = start;
    let mut rounds: Vec<Round> = Vec::new();
    for round in 0.. {
        chosen.retain(|p| !done.contains_key(p));
        let mut records: Vec<Option<PairRecord>> =
            chosen.iter().map(|&(a, b)| known(a, b)).collect();
        let new: Vec<(usize, usize)> = chosen
            .iter()
            .zip(&records)
            .filter(|(_, r)| r.is_none())
            .map(|(p, _)| *p)
            .collect();
        used.pairs_reused += chosen.len() - new.len();
        used.pairs_aligned += new.len();
        let mut aligned = if new.is_empty() {
            Vec::new()
        } else {
            align(&new)?
        };
        if aligned.len() != new.len() {
            return Err(crate::Error::invalid(format!(
                "the engine aligned {} pairs of {}",
                aligned.len(),
                new.len()
            )));
        }
        // Back in the chosen order.
        aligned.reverse();
        for r in records.iter_mut().filter(|r| r.is_none()) {
            *r = aligned.pop();
        }
        let records: Vec<PairRecord> = records.into_iter().flatten().collect();
        let accepted = records.iter().filter(|r| r.accepted).count();
        rounds.push(Round {
            pairs: chosen.len(),
            accepted,
        });
        done.extend(chosen.iter().copied().zip(records));
        let (Some(p), Some(similar)) = (screen.filter(|p| round < p.rounds), &similar) else {
            break;
        };
        // A round that accepted nothing ends them: the next would be chosen from what this one had.
        if round > 0 && accepted == 0 {
            break;
        }
        let accepted: Vec<(usize, usize, Rigid, f64)> = done
            .iter()
            .filter(|(_, r)| r.accepted)
            .map(|(&(a, b), r)| (a, b, r.transform, r.score))
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
