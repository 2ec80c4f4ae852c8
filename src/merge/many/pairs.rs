//! Every pair of a set aligned by the two-map aligner, in parallel: the first stage of [`super::run`].

use super::{GlobalOptions, PairRecord, Pairwise};
use crate::merge::pair::align::{align_prepared, Prepared};
use crate::support::error::Result;

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
pub(super) fn pair_order(n: usize) -> impl Iterator<Item = (usize, usize)> {
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
pub(super) fn pairwise_of(n: usize, pairs: &[(usize, usize, PairRecord)]) -> Pairwise {
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
