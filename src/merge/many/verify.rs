//! A pair's record checked against the two maps before a placement uses it. Records that did not come
//! from this process's own alignment (an earlier run's `--poses` file taken up by `merge --from`, an
//! executor's answer in a distributed run) are claims: a file can be edited, an executor can be wrong.
//! Each claim a placement reads is measured again on the maps, cheaply (a few dense counts a candidate,
//! no search):
//!
//! - its shape: at most [`MAX_CANDIDATES`] candidates of distinct, ascending ranks, finite numbers, an
//!   accepted choice that is its first candidate, every other candidate above the weak rule value;
//! - each candidate's pose on the maps: its rule value can be no higher than the maps allow there (the
//!   rule with its coarse ratio at its cap, [`MAX_RATIO`]), it passes the contradiction vetoes, its
//!   overlap centre and drift-tolerant conflict are the maps' own; the choice is where the aligner's
//!   polish leaves it (polished again at the finest step, it moves at most a pixel);
//! - an accepted choice: every veto of the pair test ([`accepts`]) on the maps, the self-symmetry and
//!   the alternative poses a map's repeat offers included (when the maps are held whole).
//!
//! What it cannot measure again without the search itself is the coarse ratio, the standing of the pose
//! among all the others: a record that passes keeps it as it says.

use crate::backend::ReferenceBackend;
use crate::merge::many::{GlobalOptions, PairRecord};
use crate::merge::pair::align::{
    accepts, alias, check, not_contradicted, overlap_centre, reference_rms, self_symmetry_with,
    Features, Prepared, Repeats, MAX_CANDIDATES, MAX_RATIO,
};
use crate::merge::pair::local::local_both;
use crate::merge::pair::refine::{map_to_crop, polish};
use crate::merge::transform::Rigid;
use crate::support::error::Result;

/// How far a candidate's rule value may stand above what the maps allow at its pose: a few pixels'
/// rounding between the pose the aligner verified (in its crop) and the same pose as recorded (in the
/// maps' pixels) moves a count by one, and the rule by far less than this (its values are tenths of
/// their spread over the real pairs).
const SCORE_SLACK: f64 = 0.5;
/// How far a candidate's drift-tolerant conflict may differ from the maps' own at its pose: it is
/// measured there, so only rounding separates them.
const RESIDUAL_SLACK: f64 = 0.005;
/// The same for the choice, whose conflict is measured before its final polish (a pixel or a degree
/// away): -0.03 to +0.07 over the 104 pairs of the real buildings' merge.
const CHOICE_RESIDUAL_SLACK: f64 = 0.1;
/// How far the choice may move when polished again at the finest step (a quarter pixel, a tenth of a
/// degree), pixels (RMS at its walls' box corners and centre): the aligner's polish stops after a few
/// rounds, so it may go on by a step or two (1 of the 104 real pairs: 0.5 px); a pose moved or turned
/// by hand climbs back towards the fit.
const POLISH_SLACK: f64 = 1.0;
/// Rounds of that polish, at most.
const POLISH_ROUNDS: usize = 8;
/// How far a candidate's overlap centre may be from the maps' own, pixels (it is a mean of sampled
/// pixels: the same to the last bits).
const AT_SLACK: f64 = 1e-6;
/// The longest reason a record may give, characters.
const MAX_REASON: usize = 2000;

/// Why `r` (B, `pb`, onto A, `pa`) does not hold on the maps, or `None` when it does. When the maps are
/// held whole ([`Prepared`] able to align), an accepted choice's self-symmetry and alternative poses are
/// measured too.
pub(super) fn why_not(
    pa: &Prepared,
    pb: &Prepared,
    r: &PairRecord,
    options: &GlobalOptions,
) -> Result<Option<String>> {
    if let Some(why) = shape(r, options) {
        return Ok(Some(why));
    }
    if !pa.alignable() || !pb.alignable() {
        return Ok((r.accepted || !r.edges.is_empty()).then(|| {
            "a map has (almost) no walls to align, yet it carries candidates".to_string()
        }));
    }
    let mut backend = ReferenceBackend;
    for e in &r.edges {
        let f = check(pa, pb, &e.transform, &mut backend)?;
        let k = e.rank;
        let most = options.pair.accept.margin(&Features {
            coarse_ratio: MAX_RATIO,
            ..f
        });
        if e.score > most + SCORE_SLACK {
            return Ok(Some(format!(
                "candidate {k} claims rule value {:.2}, where the maps allow at most {most:.2} at its pose",
                e.score
            )));
        }
        if !not_contradicted(&f) {
            return Ok(Some(format!(
                "candidate {k} is contradicted on the maps ({:.0}% of the walls on free space)",
                100.0 * f.conflict_fine
            )));
        }
        let at = overlap_centre(pa, pb, &e.transform);
        if (at.0 - e.at.0).abs() > AT_SLACK
            || (at.1 - e.at.1).abs() > AT_SLACK
            || at.0.is_nan()
            || at.1.is_nan()
        {
            return Ok(Some(format!(
                "candidate {k} names ({:.1}, {:.1}) as where the maps overlap; they overlap at ({:.1}, {:.1})",
                e.at.0, e.at.1, at.0, at.1
            )));
        }
        let residual = local_both(pb, pa, &map_to_crop(pb, pa, &e.transform)).1;
        let slack = if k == 0 {
            CHOICE_RESIDUAL_SLACK
        } else {
            RESIDUAL_SLACK
        };
        if (residual - e.residual).abs() > slack || residual.is_nan() {
            return Ok(Some(format!(
                "candidate {k} claims {:.3} of its walls in free space after the local shifts; the maps \
                 have {residual:.3}",
                e.residual
            )));
        }
        // The aligner leaves its choice where its finest polish ends: polished again, it stays put.
        if k == 0 {
            let moved = polished_again(pa, pb, &e.transform)?;
            if moved > POLISH_SLACK || moved.is_nan() {
                return Ok(Some(format!(
                    "its choice is not where the maps fit best: polished again, it moves {moved:.1} px"
                )));
            }
        }
        if k == 0 && r.accepted {
            if let Some(why) = accepted_holds(pa, pb, &e.transform, f, r.score)? {
                return Ok(Some(why));
            }
        }
    }
    Ok(None)
}

/// How far the choice `t` (B's pixels to A's) moves when polished again at the finest step, pixels.
fn polished_again(pa: &Prepared, pb: &Prepared, t: &Rigid) -> Result<f64> {
    let start = map_to_crop(pb, pa, t);
    let mut at = start;
    for _ in 0..POLISH_ROUNDS {
        let next = polish(pb, pa, &at, 1.0, &mut ReferenceBackend)?;
        if next == at {
            break;
        }
        at = next;
    }
    Ok(reference_rms(pb, &start, &at))
}

/// Why an accepted choice `t` with features `f` measured on the maps and rule value `score` fails the
/// pair test's vetoes, or `None`. The self-symmetry and alternative poses need the maps whole; a
/// placement-only preparation (a distributed run's) is checked without them.
fn accepted_holds(
    pa: &Prepared,
    pb: &Prepared,
    t: &Rigid,
    mut f: Features,
    score: f64,
) -> Result<Option<String>> {
    if pa.can_align() && pb.can_align() {
        let mut backend = ReferenceBackend;
        let (sa, sb) = (
            self_symmetry_with(pa, &mut backend)?,
            self_symmetry_with(pb, &mut backend)?,
        );
        f.self_match = sa.value.max(sb.value);
        f.self_match_held = sa.repeat.max(sb.repeat);
        // An accepted pair: its repeats' lattices listed, as the pair test lists them for a merge.
        let found = alias(pb, pa, t, (sa, sb), &[], Repeats::List, &mut backend)?;
        f.alias = found.ratio;
        f.alias_uncontradicted = found.uncontradicted;
        if found.repeats_listed {
            f.self_match_held = 0.0;
        }
    }
    Ok((!accepts(&f, score)).then(|| {
        format!(
            "it says accepted, but the pair test's vetoes decline its pose on the maps (support {:.0}, \
             walls on free space {:.0}%, self-match {:.2}, alternative {:.0}%, uncontradicted \
             alternative {:.0}%)",
            f.support,
            100.0 * f.conflict_fine,
            f.self_match,
            100.0 * f.alias,
            100.0 * f.alias_uncontradicted
        )
    }))
}

/// Why `r`'s shape is not one an alignment makes, or `None`.
fn shape(r: &PairRecord, options: &GlobalOptions) -> Option<String> {
    let finite = |t: &Rigid| t.theta_deg.is_finite() && t.tx.is_finite() && t.ty.is_finite();
    if r.edges.len() > MAX_CANDIDATES {
        return Some(format!(
            "it carries {} candidates; an alignment refines at most {MAX_CANDIDATES}",
            r.edges.len()
        ));
    }
    if r.reason.as_ref().is_some_and(|s| s.len() > MAX_REASON) {
        return Some("its reason is over 2000 characters long".to_string());
    }
    if !finite(&r.transform) || r.score.is_nan() || r.score == f64::INFINITY {
        return Some("its choice has a number that is not finite".to_string());
    }
    if r.score == f64::NEG_INFINITY && (r.accepted || !r.edges.is_empty()) {
        return Some("it has no candidate's rule value, yet it carries candidates".to_string());
    }
    if r.accepted != r.reason.is_none() {
        return Some(
            "its reason and its verdict disagree (a reason is given exactly when declined)"
                .to_string(),
        );
    }
    let mut last = None;
    for e in &r.edges {
        let numbers = [e.score, e.at.0, e.at.1, e.residual];
        if !finite(&e.transform) || numbers.iter().any(|v| !v.is_finite()) {
            return Some(format!(
                "candidate {} has a number that is not finite",
                e.rank
            ));
        }
        if e.rank >= MAX_CANDIDATES || last.is_some_and(|l| e.rank <= l) {
            return Some(format!(
                "its candidates' ranks are not distinct, ascending and below {MAX_CANDIDATES}"
            ));
        }
        last = Some(e.rank);
        if !(0.0..=1.0).contains(&e.residual) {
            return Some(format!("candidate {} has a share outside 0..1", e.rank));
        }
        let choice = e.rank == 0;
        if choice && (e.transform != r.transform || e.score.to_bits() != r.score.to_bits()) {
            return Some("its first candidate is not its choice".to_string());
        }
        // Finite: checked above.
        if !(choice && r.accepted) && e.score < options.weak_from {
            return Some(format!(
                "candidate {} is below the weak rule value, where no candidate is kept",
                e.rank
            ));
        }
    }
    if r.accepted && (r.score < 0.0 || r.edges.first().is_none_or(|e| e.rank != 0)) {
        return Some("it says accepted, without a choice of rule value 0 or more".to_string());
    }
    None
}
