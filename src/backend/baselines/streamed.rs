//! The baselines' selection over a stream of windows, in memory bounded by the candidates, not the pixels.
//!
//! Harris and Shi-Tomasi keep scores above quality x the map's maximum, which is known only after the last
//! row. Each window hands over its candidates (positive 3x3 local maxima) and its part of the maximum; the
//! list drops, from time to time, the candidates that fail against the largest maximum seen so far. That
//! maximum never exceeds the map's, so nothing that passes the final threshold is dropped, and the final
//! selection ([`super::select_candidates`]: the threshold, then for Shi-Tomasi the greedy
//! minimum distance in strength order and `max_corners`) sees exactly the candidates it would see on the
//! whole map. The semantics are the in-memory ones, unchanged.

use super::{select_candidates, Baseline, BaselineParams, Candidate};

/// Candidates held before the first prune.
const FIRST_PRUNE: usize = 1 << 16;

/// The candidates of the windows seen so far.
pub struct CandidateList {
    kind: Baseline,
    q: i128,
    list: Vec<Candidate>,
    max: i64,
    /// The list is pruned when it reaches this length.
    prune_at: usize,
}

impl CandidateList {
    /// An empty list for `kind` with `params`' quality level.
    pub fn new(kind: Baseline, params: &BaselineParams) -> Self {
        CandidateList {
            kind,
            q: params.quality_ppm(),
            list: Vec::new(),
            max: i64::MIN,
            prune_at: FIRST_PRUNE,
        }
    }

    /// The largest maximum handed over so far (`i64::MIN` before any).
    pub fn known_max(&self) -> i64 {
        self.max
    }

    /// Adds one window's candidates, in (y, x) order after those already added, and its maximum.
    pub fn add(&mut self, candidates: Vec<Candidate>, max: i64) {
        self.max = self.max.max(max);
        if self.list.is_empty() {
            self.list = candidates;
        } else {
            self.list.extend_from_slice(&candidates);
        }
        if self.list.len() >= self.prune_at {
            self.prune();
            // Amortised: prune again when the survivors have doubled.
            self.prune_at = (2 * self.list.len()).max(FIRST_PRUNE);
        }
    }

    /// Drops the candidates that cannot pass against the maximum known so far.
    fn prune(&mut self) {
        if self.kind == Baseline::Trajkovic {
            return; // every positive local maximum is a keypoint
        }
        let (q, max) = (self.q, self.max);
        self.list
            .retain(|c| i128::from(c.2) * 1_000_000 > q * i128::from(max));
        self.list.shrink_to(2 * self.list.len());
    }

    /// Candidates held now (for memory reports and tests).
    pub fn len(&self) -> usize {
        self.list.len()
    }

    /// Whether none is held.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// The keypoints of a `width` x `height` map, (y, x) order: the in-memory selection.
    pub fn finish(self, width: u32, height: u32, params: &BaselineParams) -> Vec<Candidate> {
        let max = if self.max == i64::MIN { 0 } else { self.max };
        select_candidates(self.kind, self.list, max, width, height, params)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pruning against a growing maximum keeps exactly what the final threshold keeps.
    #[test]
    fn pruning_keeps_what_the_final_selection_keeps() {
        let params = BaselineParams::default();
        let mut list = CandidateList::new(Baseline::Harris, &params);
        let mut all = Vec::new();
        let mut max = 0;
        for y in 0..300_000u32 {
            // Scores that grow down the map, so early candidates fail late.
            let v = i64::from(y % 1000) * i64::from(y / 1000 + 1);
            let c = (y % 7, y, v);
            all.push(c);
            max = max.max(v);
            list.add(vec![c], v);
        }
        assert!(list.len() < all.len());
        let got = list.finish(7, 300_000, &params);
        let want = select_candidates(Baseline::Harris, all, max, 7, 300_000, &params);
        assert_eq!(got, want);
        assert!(!got.is_empty());
    }
}
