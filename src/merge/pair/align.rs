//! Aligning map B onto map A with no initial pose (designed in a prototype on the shared merge-pairs data,
//! then extended with the synthetic suite of partial overlaps; docs/merging.md gives the
//! figures).
//!
//! Per map, once ([`Prepared`]): the known area's bounding box (plus 8 px); wall pixels (occupied with a
//! free 8-neighbour); the dominant wall direction modulo 90 degrees (projection profile of the wall
//! pixels); exact Euclidean distance maps to the nearest occupied pixel (with that pixel) and into free
//! space; the scoring kernel's flag bytes and point samples; coarse masks at cell sides of [`CELLS`].
//!
//! Per pair: the coarse hypotheses (`coarse.rs`: 20 rotations, FFT correlation over every shift, 32 peaks
//! each, and corner votes when asked: [`crate::merge::pair::hypotheses`]); every hypothesis screened on the full maps
//! by the scoring kernel, tolerantly and strictly; the 8 best distinct ones of the tolerant screening
//! and 4 more of the strict one refined by trimmed ICP of B's wall pixels onto A's nearest wall pixels
//! and verified by the kernel (walls, fine walls, free space); the estimate is the candidate with the
//! best product of its coarse score (relative to the best), drift-tolerant local agreement and
//! consistency ([`Features::choice`]), polished by hill-climbing on the kernel's fine counts. It is
//! accepted when a linear rule over three features, fitted on the real pairs (and checked leaving each
//! building out), clears its threshold with a margin ([`Acceptance`]), and no veto says otherwise ([`accepts`]).

use serde::Serialize;

use crate::backend::Backend;
use crate::backend::ReferenceBackend;
use crate::map::OccupancyMap;
use crate::merge::pair::accept::why_declined;
pub use crate::merge::pair::accept::{
    accepts, contradiction, decline, not_contradicted, Acceptance, Decline, Features, MAX_ALIAS,
    MAX_CONTRADICTION, MAX_FINE_CONFLICT, MAX_SELF_SYMMETRY, MAX_UNCONTRADICTED_ALIAS, MIN_SUPPORT,
};
use crate::merge::pair::alias::add_turns;
pub(in crate::merge) use crate::merge::pair::alias::{alias, Repeats};
pub use crate::merge::pair::alias::{ALIAS_EXTRA_CONFLICT, ALIAS_SELF_MATCH};
pub(in crate::merge) use crate::merge::pair::choose::reference_rms;
use crate::merge::pair::choose::{
    choose, distinct_ratios, refine_all, screened_distinct, Chosen, REFINED, STRICT,
};
pub use crate::merge::pair::choose::{Ranking, MAX_RATIO};
use crate::merge::pair::coarse::{coarse_hypotheses, CoarseSet};
use crate::merge::pair::evidence;
pub use crate::merge::pair::fft::FINE_FFT;
use crate::merge::pair::hypotheses::Hypotheses;
use crate::merge::pair::local::local_fit;
pub use crate::merge::pair::prepare::{kept_bytes, prepared_bytes, Prepared, Symmetry, CELLS};
use crate::merge::pair::refine::{crop_to_map, map_to_crop, verify};
use crate::merge::pair::symmetry::NEAR_IDENTITY_DEG;
use crate::merge::transform::{signed_deg, transform_distance, Rigid, DISTINCT_PX};
use crate::support::error::{Error, Result};

/// The rule value from which the self-symmetry is measured: the operating curve's lowest offset.
const SYMMETRY_FROM: f64 = -8.0;

/// What a pair declined before any search for want of walls says (a placement tells it apart).
pub(crate) const NO_WALLS: &str = "no walls next to free space";
/// The most candidates an alignment refines (so the most a pair's record may carry).
pub const MAX_CANDIDATES: usize = REFINED + STRICT;
/// How to align.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MergeOptions {
    /// The acceptance test.
    pub accept: Acceptance,
    /// Where the hypotheses come from (the corners are found by [`Prepared::with_corners`]).
    pub hypotheses: Hypotheses,
    /// Decline a merge of a map that matches itself turned or shifted ([`self_symmetry`]).
    pub check_symmetry: bool,
    /// Measure the self-symmetry and the alternative poses whatever the rule value (they are measured
    /// only for what the rule could accept otherwise): what refitting the rule needs
    /// (`merge-eval --cross-validate`).
    pub always_verify: bool,
    /// What orders the candidates for the choice (the choice key by default; the consistent evidence
    /// is measured beside it, not yet the default).
    pub ranking: Ranking,
}

impl Default for MergeOptions {
    fn default() -> Self {
        MergeOptions {
            accept: Acceptance::default(),
            hypotheses: Hypotheses::default(),
            check_symmetry: true,
            always_verify: false,
            ranking: Ranking::default(),
        }
    }
}

/// One refined candidate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Candidate {
    /// B's pixels to A's.
    pub transform: Rigid,
    /// Its verification, with its ratios over the best candidate distinct from it.
    pub features: Features,
    /// The acceptance rule's value minus its threshold for this candidate (its ratios are below 1 when
    /// another candidate is better): the evidence for it that a many-map placement weighs.
    pub score: f64,
}

/// The result of [`align`].
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Alignment {
    /// The best candidate's transform (also when not accepted).
    pub transform: Rigid,
    /// Its verification.
    pub features: Features,
    /// The acceptance rule's value minus its threshold.
    pub score: f64,
    /// Whether it passed.
    pub accepted: bool,
    /// Why not, when not.
    pub reason: Option<String>,
    /// Every refined candidate, the chosen one first.
    pub candidates: Vec<Candidate>,
}

/// Aligns B onto A: the best transform from B's pixels to A's, verified.
pub fn align(a: &OccupancyMap, b: &OccupancyMap, options: &MergeOptions) -> Result<Alignment> {
    align_with(a, b, options, &mut ReferenceBackend)
}

/// `map` prepared as `options` need it: with its corners when the hypotheses use them.
fn prepare_for(map: &OccupancyMap, options: &MergeOptions) -> Result<Prepared> {
    match options.hypotheses.detector() {
        Some(detector) => Prepared::with_corners(map, detector),
        None => Ok(Prepared::new(map)),
    }
}

/// [`align`] with the candidates scored on `backend` ([`align_prepared_with`]).
pub fn align_with(
    a: &OccupancyMap,
    b: &OccupancyMap,
    options: &MergeOptions,
    backend: &mut dyn Backend,
) -> Result<Alignment> {
    align_prepared_with(
        &prepare_for(a, options)?,
        &prepare_for(b, options)?,
        options,
        backend,
    )
}

/// [`align`] on prepared maps (prepare each map once when aligning it with many).
pub fn align_prepared(a: &Prepared, b: &Prepared, options: &MergeOptions) -> Result<Alignment> {
    align_prepared_with(a, b, options, &mut ReferenceBackend)
}

/// [`align_prepared`] with the dense scoring of the candidates on `backend` (the transform-scoring
/// kernel, `shaders/merge_score.wgsl`): the same counts, so the same result, on every backend.
pub fn align_prepared_with(
    a: &Prepared,
    b: &Prepared,
    options: &MergeOptions,
    backend: &mut dyn Backend,
) -> Result<Alignment> {
    // In the prototype's terms: src = B (moved), dst = A (reference); transforms map src to dst.
    let (src, dst) = (b, a);
    if !src.can_align() || !dst.can_align() {
        return Err(Error::invalid(
            "a preparation read in its placement form cannot be aligned (it has no distance maps)",
        ));
    }
    if !src.alignable() || !dst.alignable() {
        return Ok(declined(&format!(
            "a map has (almost) {NO_WALLS}: nothing to align"
        )));
    }
    let CoarseSet {
        cell,
        list: coarse,
        unit: coarse_unit,
    } = coarse_hypotheses(src, dst, &options.hypotheses)?;
    // Between stages, a raised stop (Ctrl-C in Python) ends the alignment.
    crate::support::stop::check()?;
    if coarse.is_empty() {
        return Ok(declined(
            "no hypothesis: the maps' corners agree on no placement",
        ));
    }
    let picked = screened_distinct(src, dst, &coarse, cell, backend)?;
    let found = refine_all(src, dst, &picked, coarse_unit, backend)?;
    let Chosen {
        refined,
        keys,
        order,
    } = choose(src, dst, &found, options.ranking, backend)?;
    let (_, best, mut features) = refined[0];
    // How far it stands out, by the choice's key and by the coarse score: over the best distinct
    // alternative's (both before the polish, as the alternatives are).
    (features.coarse_ratio, features.choice_ratio) = distinct_ratios(&refined, &keys, 0);
    features.choice = keys[0];
    let score = options.accept.margin(&features);
    // Only for what could be merged (down to the operating curve's lowest offset): each map's
    // self-match costs an alignment (cached in the map).
    let could = score >= SYMMETRY_FROM && accepts(&features, score);
    let (alternative, unrefuted, symmetry) =
        if options.check_symmetry && (could || options.always_verify) {
            let found = order
                .iter()
                .map(|&i| (crop_to_map(src, dst, &found.crops[i]), found.locals[i]))
                .collect::<Vec<_>>();
            other_poses(src, dst, &best, &mut features, score, &found, backend)?
        } else {
            (None, None, None)
        };
    // Reported beside the decision, not read by it.
    let rivals = (1..refined.len())
        .filter(|&j| transform_distance(&refined[j].1, &best) > DISTINCT_PX)
        .map(|j| found.counts[order[j]]);
    evidence::fill(
        &mut features,
        src,
        dst,
        &found.counts[order[0]],
        rivals,
        symmetry,
    );
    let accepted = accepts(&features, score);
    let reason = decline(&features, score).map(|why| {
        why_declined(
            why,
            &features,
            score,
            &best,
            alternative.as_ref(),
            unrefuted.as_ref(),
        )
    });
    Ok(Alignment {
        transform: best,
        features,
        score,
        accepted,
        reason,
        candidates: candidates_of(&refined, &keys, features, score, options),
    })
}

/// The other poses the maps offer the chosen pose `best` (the alternative-pose test): each map's
/// self-match and the poses its symmetry offers, and the search's own candidates turned from the chosen
/// pose (`found`, between the maps, with their local measures, in the choice's order). Fills in
/// `features`' self-match and alternative-pose measures; returns the best other pose and the best one
/// nothing contradicts, when measured, and the chosen pose's and the best other pose's consistent
/// evidence ([`Features::evidence_ratio`]).
fn other_poses(
    src: &Prepared,
    dst: &Prepared,
    best: &Rigid,
    features: &mut Features,
    score: f64,
    found: &[(Rigid, (f64, f64, f64))],
    backend: &mut dyn Backend,
) -> Result<OtherPoses> {
    // A is the reference (dst), B the moved map (src).
    let (sa, sb) = (
        self_symmetry_with(dst, backend)?,
        self_symmetry_with(src, backend)?,
    );
    features.self_match = sa.value.max(sb.value);
    // The self-match the veto holds whatever the alternatives show: a repeat's (a turn is judged
    // pose by pose).
    features.self_match_held = sa.repeat.max(sb.repeat);
    // The search's own candidates turned from the chosen pose are poses too (a turn of the overlap
    // that neither map's symmetry offers), measured already; shifts are the maps' repeats' to offer.
    let judged = features.self_match_held > MAX_SELF_SYMMETRY;
    let mode = if judged {
        Repeats::Screen
    } else {
        Repeats::Held
    };
    let mut alt = alias(src, dst, best, (sa, sb), found, mode, backend)?;
    if judged {
        // Listing a repeat's lattice costs a few alignments' scoring: only for a pair the screen
        // (a lower bound of the listed alternative) leaves to be merged.
        let unheld = Features {
            alias: alt.ratio,
            self_match_held: 0.0,
            ..*features
        };
        if accepts(&unheld, score) {
            alt = alias(src, dst, best, (sa, sb), found, Repeats::List, backend)?;
        }
    }
    features.alias = alt.ratio;
    features.alias_uncontradicted = alt.uncontradicted;
    if alt.repeats_listed {
        // Every step of the repeat measured: nothing of it needs holding.
        features.self_match_held = 0.0;
    }
    Ok((alt.pose, alt.uncontradicted_pose, alt.consistent))
}

/// What [`other_poses`] returns: the best other pose, the best one nothing contradicts, and the
/// consistent evidence of the chosen pose and of the best other one.
type OtherPoses = (Option<Rigid>, Option<Rigid>, Option<(f64, f64)>);

/// Every candidate as the alignment lists it, the chosen one first (with `features` and rule value
/// `score`): each other one with its ratios over the best candidate distinct from it, and its rule value.
fn candidates_of(
    refined: &[(f64, Rigid, Features)],
    keys: &[f64],
    features: Features,
    score: f64,
    options: &MergeOptions,
) -> Vec<Candidate> {
    refined
        .iter()
        .enumerate()
        .map(|(i, &(_, transform, mut f))| {
            if i == 0 {
                return Candidate {
                    transform,
                    features,
                    score,
                };
            }
            (f.coarse_ratio, f.choice_ratio) = distinct_ratios(refined, keys, i);
            f.choice = keys[i];
            Candidate {
                transform,
                features: f,
                score: options.accept.margin(&f),
            }
        })
        .collect()
}

impl Alignment {
    /// Why, in a sentence: for an accept, how far the chosen pose stands out from the best distinct
    /// candidate and from the poses the maps' repeats offer (a near-ambiguity shows here); for a decline,
    /// the best candidate and what turned it down.
    pub fn explain(&self) -> String {
        let f = &self.features;
        let runner = self
            .candidates
            .iter()
            .skip(1)
            .filter(|c| transform_distance(&c.transform, &self.transform) > DISTINCT_PX)
            .max_by(|x, y| x.score.total_cmp(&y.score));
        let runner = match runner {
            Some(c) => format!(
                "the best distinct candidate ({:.1} deg, ({:.0}, {:.0}) px) has rule value {:.2}",
                c.transform.theta_deg, c.transform.tx, c.transform.ty, c.score
            ),
            None => "no distinct candidate".to_string(),
        };
        let t = &self.transform;
        if self.accepted {
            format!(
                "rule value {:.2} over its threshold; the choice stands {:.2}x and the consistent coarse \
                 score {:.2}x above the best distinct alternative ({runner}); the best other pose (a map's repeat or \
                 turn, or another candidate) has {:.0}% of its evidence (ambiguous from {:.0}%); {:.0} wall \
                 pixels match",
                self.score,
                f.choice_ratio,
                f.coarse_ratio,
                100.0 * f.alias,
                100.0 * MAX_ALIAS,
                f.support
            )
        } else {
            format!(
                "best candidate {:.1} deg, ({:.0}, {:.0}) px, rule value {:.2}: {}; {runner}{}",
                t.theta_deg,
                t.tx,
                t.ty,
                self.score,
                self.reason.as_deref().unwrap_or("not confident"),
                independent(f)
            )
        }
    }
}

/// The building-independent measures of a declined pose ([`Features::evidence_ratio`],
/// [`Features::support_share`], [`Features::excess_conflict`]) as a clause of its explanation: reported
/// beside the decision, which does not read them; empty where they were not measured.
fn independent(f: &Features) -> String {
    if f.evidence_ratio <= 0.0 && f.support_share <= 0.0 {
        return String::new();
    }
    // At the cap, no distinct alternative had any consistent evidence at all.
    let standing = if f.evidence_ratio >= MAX_RATIO {
        "no distinct alternative has consistent evidence".to_string()
    } else {
        format!(
            "its consistent evidence stands {:.2}x the best distinct alternative's",
            f.evidence_ratio
        )
    };
    format!(
        " (in units of the pair's own walls: {standing}, {:.0}% of the walls that fall in the other \
         map's known area agree, and {:.1}% lie on its free space beyond the maps' own clutter)",
        100.0 * f.support_share,
        100.0 * f.excess_conflict
    )
}

/// A declined alignment with no candidate.
pub(crate) fn declined(why: &str) -> Alignment {
    Alignment {
        transform: Rigid::IDENTITY,
        features: Features::default(),
        score: f64::NEG_INFINITY,
        accepted: false,
        reason: Some(why.to_string()),
        candidates: Vec::new(),
    }
}

/// The verification features of `t` (B's pixels to A's) on the full maps, as [`align`] measures its
/// candidates' (the coarse score and local agreement aside): what checks a placement that no pair
/// chose.
pub(in crate::merge) fn check(
    a: &Prepared,
    b: &Prepared,
    t: &Rigid,
    backend: &mut dyn Backend,
) -> Result<Features> {
    Ok(verify(b, a, &[map_to_crop(b, a, t)], backend)?[0])
}

/// Where `t` (B's pixels to A's) makes the maps overlap, in B's pixels: the mean of B's sampled wall
/// pixels that land in A's crop (its known area's box and margin) (B's walls' centre when none do). Two estimates of a pair are
/// compared there: maps bend, so estimates that agree where the maps overlap can differ far from it.
pub(in crate::merge) fn overlap_centre(a: &Prepared, b: &Prepared, t: &Rigid) -> (f64, f64) {
    let apply = map_to_crop(b, a, t).applier();
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0usize);
    for p in &b.screen_points {
        let p = (f64::from(p[0]), f64::from(p[1]));
        let q = apply.apply(p);
        if a.index(q.0, q.1).is_some() {
            (sx, sy, n) = (sx + p.0, sy + p.1, n + 1);
        }
    }
    if n == 0 {
        return b.reference_in_map()[4];
    }
    (sx / n as f64 + b.off.0, sy / n as f64 + b.off.1)
}

/// How well `p` matches itself under its best transform other than the identity: its local agreement
/// times the share of the map's wall pixels it was measured on. A map that looks the same turned or
/// shifted (a symmetric arena) can be merged either way; [`MAX_SELF_SYMMETRY`] declines it.
pub fn self_symmetry(p: &Prepared) -> Result<f64> {
    Ok(self_symmetry_with(p, &mut ReferenceBackend)?.value)
}

/// [`self_symmetry`] with the self-alignment's scoring on `backend` (the same counts on every backend),
/// with the self-transforms that offer alternative poses ([`ALIAS_SELF_MATCH`]); cached in the map.
pub(in crate::merge) fn self_symmetry_with<'p>(
    p: &'p Prepared,
    backend: &mut dyn Backend,
) -> Result<&'p Symmetry> {
    if let Some(v) = p.symmetry.get() {
        return Ok(v);
    }
    let start = std::time::Instant::now();
    let options = MergeOptions {
        check_symmetry: false,
        ..MergeOptions::default()
    };
    let al = align_prepared_with(p, p, &options, backend)?;
    let mut out = Symmetry::default();
    for c in &al.candidates {
        if transform_distance(&c.transform, &Rigid::IDENTITY) <= DISTINCT_PX {
            continue;
        }
        let l = local_fit(p, p, &map_to_crop(p, p, &c.transform));
        let matched = l.share * l.coverage;
        out.value = out.value.max(matched);
        if signed_deg(c.transform.theta_deg).abs() <= NEAR_IDENTITY_DEG {
            out.repeat = out.repeat.max(matched);
        }
        if matched >= ALIAS_SELF_MATCH {
            out.transforms.push(c.transform);
        }
    }
    add_turns(p, &mut out);
    out.ms = start.elapsed().as_secs_f64() * 1e3;
    Ok(p.symmetry.get_or_init(|| out))
}
