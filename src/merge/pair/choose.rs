//! A pair's candidates: the coarse hypotheses screened on the full maps and the distinct ones picked,
//! each refined (ICP, the kernel's verification, the drift-tolerant local fit), and the choice among
//! them, polished to a fraction of a pixel. [`crate::merge::pair::align`] runs these stages, then the
//! alternative-pose and acceptance tests.

use crate::backend::Backend;
use crate::merge::pair::accept::Features;
use crate::merge::pair::coarse::{screen, Crop};
use crate::merge::pair::local::{local_both_counts, LocalCounts};
use crate::merge::pair::prepare::Prepared;
use crate::merge::pair::refine::{crop_to_map, icp, polish, verify};
use crate::merge::transform::{transform_distance, Rigid, DISTINCT_PX};
use crate::support::error::Result;

/// The polish's step scales (1: a quarter pixel and 0.1 degree) and rounds at each, at most.
const POLISH_SCALES: [f64; 3] = [4.0, 2.0, 1.0];
const POLISH_ROUNDS: usize = 4;
/// Candidates refined: the best distinct ones of the tolerant screening, then more of the strict one.
pub(in crate::merge) const REFINED: usize = 8;
pub(in crate::merge) const STRICT: usize = 4;
/// The coarse ratio's cap: no distinct alternative at all counts as this.
pub const MAX_RATIO: f64 = 10.0;

/// Every coarse hypothesis screened on the full maps (an even sample of their walls), each at four
/// shifts around it: a coarse peak is off by up to half a cell, and the walls of a building of many
/// like rooms correlate almost as well with a wrong placement at the coarse level. The best distinct
/// ones of the tolerant screening, then more of the strict one, are kept to be refined.
pub(in crate::merge) fn screened_distinct(
    src: &Prepared,
    dst: &Prepared,
    coarse: &[(f64, Crop)],
    cell: usize,
    backend: &mut dyn Backend,
) -> Result<Vec<(f64, Crop)>> {
    let [tolerant, strict] = screen(src, dst, coarse, cell as f64, backend)?;
    crate::support::stop::check()?;
    let mut picked: Vec<(f64, Crop)> = Vec::new();
    for (order, most) in [(&tolerant, REFINED), (&strict, REFINED + STRICT)] {
        for &(i, t) in order {
            if picked.len() >= most {
                break;
            }
            let c = (coarse[i].0, Crop(t));
            if picked
                .iter()
                .all(|p| reference_rms(src, &p.1 .0, &c.1 .0) > DISTINCT_PX)
            {
                picked.push(c);
            }
        }
    }
    Ok(picked)
}

/// The candidates refined: each picked hypothesis fitted by ICP (in the crops' pixels), verified by the
/// kernel, and measured for its local agreement (the choice and its margin over the runner-up need
/// every candidate's).
pub(in crate::merge) struct Refined {
    /// Each candidate's transform between the crops.
    pub(in crate::merge) crops: Vec<Rigid>,
    /// Each one's local agreement, residual conflict and wall pixels measured
    /// ([`local_both`](crate::merge::pair::local::local_both)).
    pub(in crate::merge) locals: Vec<(f64, f64, f64)>,
    /// The same fits' counts, both ways summed (the building-independent measures').
    pub(in crate::merge) counts: Vec<LocalCounts>,
    /// Each one's coarse score, transform between the maps and features, in the coarse order.
    pub(in crate::merge) candidates: Vec<(f64, Rigid, Features)>,
}

pub(in crate::merge) fn refine_all(
    src: &Prepared,
    dst: &Prepared,
    picked: &[(f64, Crop)],
    coarse_unit: f64,
    backend: &mut dyn Backend,
) -> Result<Refined> {
    use rayon::prelude::*;
    let crops: Vec<Rigid> = picked
        .par_iter()
        .map(|&(_, Crop(t))| icp(src, dst, t))
        .collect();
    let verified = verify(src, dst, &crops, backend)?;
    crate::support::stop::check()?;
    let (locals, counts): (Vec<(f64, f64, f64)>, Vec<LocalCounts>) = crops
        .par_iter()
        .map(|t| local_both_counts(src, dst, t))
        .unzip();
    let candidates = picked
        .iter()
        .zip(&crops)
        .zip(verified)
        .zip(locals.iter().copied())
        .map(|(((&(score, _), t), mut f), (local, residual, _))| {
            f.coarse = score;
            f.local = local;
            f.residual = residual;
            f.coarse_norm = score / coarse_unit;
            (score, crop_to_map(src, dst, t), f)
        })
        .collect();
    Ok(Refined {
        crops,
        locals,
        counts,
        candidates,
    })
}

/// What orders the refined candidates for the choice (the candidate chosen is the first); also
/// `merge-eval --ranking`'s values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Ranking {
    /// The choice key (`Features::choice`), as `merge` ranks them: the local agreement, the fine
    /// conflict, the free agreement and the coarse score relative to the best candidate's, multiplied.
    #[default]
    Choice,
    /// The consistent evidence, counted as `Features::evidence_ratio` counts it: the wall pixels of
    /// both maps (sampled, each into the other) that agree after their tile's local shift, less those
    /// left deep in the other map's free space. In units of the pair's own walls, with no weight or
    /// exponent fitted to any building; ties keep the choice key's order.
    Evidence,
}

/// The candidates in the order of the choice, the chosen one first and polished.
pub(in crate::merge) struct Chosen {
    /// Coarse score, transform between the maps and features, in the choice's order.
    pub(in crate::merge) refined: Vec<(f64, Rigid, Features)>,
    /// Each one's choice key, in that order.
    pub(in crate::merge) keys: Vec<f64>,
    /// Each one's index among [`Refined`]'s, in that order.
    pub(in crate::merge) order: Vec<usize>,
}

/// The choice: the best product of the coarse score (relative to the best one), the local agreement,
/// the square root of the share of walls not deep in the other map's free space and the fourth power
/// of the share of free space on the other's free space. The coarse score alone prefers a wrong
/// placement laying one map fully over the other to a true, smaller overlap; the local agreement
/// alone, small overlaps of a few matching walls; in a building of many like rooms, a wrong placement
/// matches walls locally but puts others in the other map's rooms. The chosen one is polished to a
/// fraction of a pixel and verified again. With [`Ranking::Evidence`], the candidates are ordered by
/// their consistent evidence instead, the choice key breaking ties.
pub(in crate::merge) fn choose(
    src: &Prepared,
    dst: &Prepared,
    found: &Refined,
    ranking: Ranking,
    backend: &mut dyn Backend,
) -> Result<Chosen> {
    let top = found
        .candidates
        .iter()
        .map(|r| r.0)
        .fold(f64::MIN, f64::max)
        .max(1e-9);
    let key = |r: &(f64, Rigid, Features)| {
        r.2.local * (1.0 - r.2.conflict_fine).max(0.0).sqrt() * r.2.free_agree.powi(4) * r.0 / top
    };
    let unordered: Vec<f64> = found.candidates.iter().map(key).collect();
    let evidence: Vec<f64> = found.counts.iter().map(LocalCounts::consistent).collect();
    let order = ranked(&unordered, &evidence, ranking);
    let mut refined: Vec<(f64, Rigid, Features)> =
        order.iter().map(|&i| found.candidates[i]).collect();
    let keys: Vec<f64> = order.iter().map(|&i| unordered[i]).collect();
    let polished = polish_fully(src, dst, &found.crops[order[0]], backend)?;
    let again = verify(src, dst, &[polished], backend)?[0];
    crate::support::stop::check()?;
    refined[0].1 = crop_to_map(src, dst, &polished);
    refined[0].2 = Features {
        coarse: refined[0].2.coarse,
        local: refined[0].2.local,
        residual: refined[0].2.residual,
        coarse_norm: refined[0].2.coarse_norm,
        ..again
    };
    Ok(Chosen {
        refined,
        keys,
        order,
    })
}

/// The candidates' indices in the order `ranking` puts them: by their choice keys `keys`, or by their
/// consistent evidence `evidence` with the keys breaking ties; equal ones keep the coarse order.
fn ranked(keys: &[f64], evidence: &[f64], ranking: Ranking) -> Vec<usize> {
    let mut order: Vec<usize> = (0..keys.len()).collect();
    // Stable sorts: ties keep the order before.
    order.sort_by(|&x, &y| keys[y].total_cmp(&keys[x]));
    if ranking == Ranking::Evidence {
        order.sort_by(|&x, &y| evidence[y].total_cmp(&evidence[x]));
    }
    order
}

/// Candidate `i`'s consistent coarse score and choice key (`keys`) over the best of the candidates
/// distinct from it (more than [`DISTINCT_PX`] apart), each at most [`MAX_RATIO`] (also when there is
/// none). The consistent coarse score is the coarse score times the share of the walls that no local
/// shift of a few px keeps out of the other map's free space ([`Features::residual`]): the correlation
/// counts walls on walls, and a rival that lays one map over the other (a half turn of an office, a
/// shift by a period) earns it with walls that the other map says are open space. A bent map's true pose
/// correlates less well than such a rival, but its conflicts vanish under the local shifts.
pub(in crate::merge) fn distinct_ratios(
    refined: &[(f64, Rigid, Features)],
    keys: &[f64],
    i: usize,
) -> (f64, f64) {
    let consistent = |r: &(f64, Rigid, Features)| r.0 * (1.0 - r.2.residual).max(0.0);
    let (mut other_coarse, mut other_key) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (j, r) in refined.iter().enumerate() {
        if j != i && transform_distance(&r.1, &refined[i].1) > DISTINCT_PX {
            other_coarse = other_coarse.max(consistent(r));
            other_key = other_key.max(keys[j]);
        }
    }
    let ratio = |mine: f64, other: f64| {
        if other > 0.0 {
            (mine / other).min(MAX_RATIO)
        } else {
            MAX_RATIO
        }
    };
    (
        ratio(consistent(&refined[i]), other_coarse),
        ratio(keys[i], other_key),
    )
}

/// `t` (src crop to dst crop) polished to a fraction of a pixel: hill-climbing from 2 px and 0.4 degree
/// steps down to the finest. ICP stops short of the best fit of a small overlap's few walls, by up to a
/// degree.
fn polish_fully(
    src: &Prepared,
    dst: &Prepared,
    t: &Rigid,
    backend: &mut dyn Backend,
) -> Result<Rigid> {
    let mut polished = *t;
    for scale in POLISH_SCALES {
        for _ in 0..POLISH_ROUNDS {
            let next = polish(src, dst, &polished, scale, backend)?;
            let stayed = next == polished;
            polished = next;
            if stayed {
                break;
            }
        }
    }
    Ok(polished)
}

/// RMS distance between where two transforms put src's reference points.
pub(in crate::merge) fn reference_rms(src: &Prepared, x: &Rigid, y: &Rigid) -> f64 {
    let sum: f64 = src
        .reference
        .iter()
        .map(|&p| {
            let (a, b) = (x.apply(p), y.apply(p));
            (a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)
        })
        .sum();
    (sum / src.reference.len() as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::{ranked, Ranking};

    #[test]
    fn candidates_rank_by_their_choice_key_or_by_their_consistent_evidence() {
        let keys = [0.2, 0.9, 0.5, 0.5];
        let evidence = [300.0, 100.0, 250.0, 300.0];
        assert_eq!(ranked(&keys, &evidence, Ranking::Choice), [1, 2, 3, 0]);
        // Equal evidence: the better choice key first (candidate 3 over 0 despite the coarse order).
        assert_eq!(ranked(&keys, &evidence, Ranking::Evidence), [3, 0, 2, 1]);
        // Equal keys keep the coarse order.
        assert_eq!(ranked(&[0.5, 0.5], &[1.0, 1.0], Ranking::Choice), [0, 1]);
        assert!(ranked(&[], &[], Ranking::Evidence).is_empty());
    }
}
