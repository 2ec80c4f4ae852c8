//! Whether an alignment is right: the features its verification measures and the acceptance test over
//! them (a rule fitted on the real pairs, and vetoes).

use serde::Serialize;

use crate::merge::transform::{signed_deg, Rigid};

/// Whatever the rule says, an alignment is contradicted when more than this share of the walls that fall
/// in the other map lie over 3 px deep in its free space ([`Features::conflict_fine`]). The highest of the
/// accepted right real pairs of the calibration half is 0.50 (held-out: 0.54); the half-turned offices
/// of the synthetic suite have 0.6-0.7.
pub const MAX_FINE_CONFLICT: f64 = 0.55;
/// Whatever the rule says, a merge is ambiguous when either map matches itself under another transform
/// this well (the aligner's `self_symmetry`; a self-match under a turn only while an alternative pose
/// keeps `SELF_SYMMETRY_ALIAS` of the chosen pose's evidence): the real maps have 0.49 at most, parts
/// of the symmetric arenas of the synthetic suite 0.43-0.79 (those under the limit are the suite's wrong
/// accepts).
pub const MAX_SELF_SYMMETRY: f64 = 0.55;
/// A map that matches itself over [`MAX_SELF_SYMMETRY`] declines a merge only while some alternative
/// pose, no more contradicted than the chosen one ([`Features::alias`]), keeps this share of its
/// evidence: the quarter under which the alternative-pose test drops a pose as no rival. Where every
/// pose its symmetry offers is contradicted (a detail of the overlap that only the chosen pose fits) or
/// keeps under a quarter of the evidence, the map's symmetry has been measured pose by pose and offers
/// no other merge. Among equal halls, the true pose of a pair declined at 0.44-0.75 of a wrong one's
/// evidence (windows that show more of one wing than another): so a map that repeats itself keeps
/// nothing near the chosen pose's evidence unrivalled, and [`MAX_ALIAS`]'s 0.75 is not its limit.
pub const SELF_SYMMETRY_ALIAS: f64 = 0.25;

/// Whatever the rule says, a merge is ambiguous when the maps fit about as well at another pose: one
/// that a map's own symmetry offers (a shift by a period of equal rooms or racks, a turn of a symmetric
/// hall by a whole wing, at any angle) or another of the search's candidates (a turn of the overlap
/// alone): the evidence of that alternative ([`Features::alias`]) at this share of the chosen pose's or
/// more. Evidence is the wall pixels that agree with the other map after a few px of local shift, so
/// the share is in units of the pair's own walls, whatever the building. A right pose of a building with a repeat has its repeat
/// contradicted where the period breaks (walls on free space at the ends, at a missing wall): a share
/// well under 1; a wrong pose among equals has alternatives as good as itself.
pub const MAX_ALIAS: f64 = 0.75;
/// Whatever the rule says, a merge is ambiguous when a distinct pose that nothing in the maps
/// contradicts keeps this share of the chosen pose's evidence or more
/// ([`Features::alias_uncontradicted`]): its walls lie on walls or on unknown space, never deeper than
/// a detail in free space, and it shares free space with the other map as a merge does. Such a pose is a
/// merge the maps allow as well as the chosen one; the chosen pose's larger evidence then says only
/// that it overlaps more, which the windows two robots saw decide, not the building (the five-fold
/// hall whose wrong pose has 1.36 times the true pose's evidence, both with no wall on free space). The
/// quarter is where the alternative-pose test takes a pose for a rival at all. Real maps' right poses
/// keep a few walls in a hundred on free space (clutter, glass), so among them this finds only poses
/// laid beside the other map, which share no free space and are no merge.
pub const MAX_UNCONTRADICTED_ALIAS: f64 = 0.25;
/// Whatever the rule says, a merge rests on at least this many wall pixels (both maps together) within
/// 5 px of the other map's walls ([`Features::support`]): two small partial maps (windows of 120 px) hold
/// a few hundred, and their right and wrong poses then look alike (measured: right 457, wrong 444-735);
/// the accepted right real pairs have 1522 and more, windows of 250 px 2065 and more.
pub const MIN_SUPPORT: f64 = 1000.0;

/// Whatever the rule says, an alignment is contradicted when its walls on free space and its free space
/// on walls or unknown together exceed this ([`contradiction`]). The accepted right real pairs of the
/// calibration half have 0.020 at most (held-out: 0.023), the right synthetic ones 0.000; wrong placements
/// of the synthetic offices 0.034 and more.
pub const MAX_CONTRADICTION: f64 = 0.03;

/// How much an alignment contradicts itself: the share of the walls falling in the other map that lie over
/// 3 px deep in its free space, times the share of the free pixels falling in its known area that are not
/// on its free pixels. Either alone is high for some right real pairs (drifted walls; free space seen
/// through a door one map has closed), both together only for wrong ones.
pub fn contradiction(features: &Features) -> f64 {
    features.conflict_fine * (1.0 - features.free_agree)
}

/// Whether an alignment with these features and rule value is accepted: the rule, the two contradiction
/// vetoes, the self-symmetry test, the alternative-pose test ([`MAX_ALIAS`], and
/// [`MAX_UNCONTRADICTED_ALIAS`] for a pose nothing contradicts) and the minimum support
/// ([`MIN_SUPPORT`]).
pub fn accepts(features: &Features, rule_value: f64) -> bool {
    rule_value >= 0.0
        && not_contradicted(features)
        && !self_match_vetoes(features)
        && features.alias < MAX_ALIAS
        && features.alias_uncontradicted < MAX_UNCONTRADICTED_ALIAS
        && features.support >= MIN_SUPPORT
}

/// Why an alignment with these features and rule value is declined, in the order its `why:` line
/// says it: the first test that fails. `None` when it is accepted.
pub fn decline(features: &Features, rule_value: f64) -> Option<Decline> {
    if accepts(features, rule_value) {
        return None;
    }
    let vetoed = rule_value >= 0.0;
    Some(if vetoed && features.alias >= MAX_ALIAS {
        Decline::Repeat
    } else if vetoed && features.alias_uncontradicted >= MAX_UNCONTRADICTED_ALIAS {
        Decline::Uncontradicted
    } else if vetoed && features.support < MIN_SUPPORT {
        Decline::LittleSupport
    } else if vetoed && self_match_vetoes(features) {
        Decline::SelfMatch
    } else if vetoed && !not_contradicted(features) {
        Decline::Contradicted
    } else {
        Decline::NotConfident
    })
}

/// The reasons an alignment is declined ([`decline`]), as its `why:` line opens.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Decline {
    /// Another pose (a map's repeat or turn, or another candidate) fits nearly as well ([`MAX_ALIAS`]).
    Repeat,
    /// Another pose that nothing contradicts keeps a quarter of the evidence
    /// ([`MAX_UNCONTRADICTED_ALIAS`]).
    Uncontradicted,
    /// Too few wall pixels match ([`MIN_SUPPORT`]).
    LittleSupport,
    /// A map matches itself turned or shifted ([`MAX_SELF_SYMMETRY`]).
    SelfMatch,
    /// Walls on free space ([`MAX_FINE_CONFLICT`], [`MAX_CONTRADICTION`]).
    Contradicted,
    /// The rule's value is below its threshold.
    NotConfident,
}

impl Decline {
    /// Every reason, in the order they are tested.
    pub const ALL: [Decline; 6] = [
        Decline::Repeat,
        Decline::Uncontradicted,
        Decline::LittleSupport,
        Decline::SelfMatch,
        Decline::Contradicted,
        Decline::NotConfident,
    ];

    /// A short name, as the `why:` line opens ("ambiguous: ...", "too little to go on: ...").
    pub fn name(self) -> &'static str {
        match self {
            Decline::Repeat => "ambiguous (a repeat's pose)",
            Decline::Uncontradicted => "ambiguous (an uncontradicted pose)",
            Decline::LittleSupport => "too little to go on",
            Decline::SelfMatch => "ambiguous (self-match)",
            Decline::Contradicted => "contradicted",
            Decline::NotConfident => "not confident",
        }
    }
}

/// The `why:` line of an alignment declined for `why` ([`decline`]), in the units its test compares:
/// the chosen pose `best` (of rule value `rule_value`) and, for the alternative-pose tests, the rivals
/// they measured (`alternative`, the best other pose; `unrefuted`, the best one nothing contradicts).
pub(in crate::merge) fn why_declined(
    why: Decline,
    features: &Features,
    rule_value: f64,
    best: &Rigid,
    alternative: Option<&Rigid>,
    unrefuted: Option<&Rigid>,
) -> String {
    let f = features;
    match why {
        Decline::Repeat => ambiguous_why(best, alternative.unwrap_or(best), f.alias),
        Decline::Uncontradicted => {
            uncontradicted_why(best, unrefuted.unwrap_or(best), f.alias_uncontradicted)
        }
        Decline::LittleSupport => format!(
            "too little to go on: {:.0} wall pixels of the two maps match each other (at least \
             {MIN_SUPPORT:.0} are needed to tell a right pose from a wrong one)",
            f.support
        ),
        Decline::SelfMatch if f.self_match_held > MAX_SELF_SYMMETRY => format!(
            "ambiguous: a map matches itself shifted (self-match {:.2} over {MAX_SELF_SYMMETRY}), so \
             it could be merged more than one way",
            f.self_match_held
        ),
        Decline::SelfMatch => self_match_why(best, alternative, f.self_match, f.alias),
        Decline::Contradicted if contradiction(f) > MAX_CONTRADICTION => format!(
            "contradicted: {:.0}% of the walls that fall in the other map lie inside its free space, \
             and {:.1}% of the free space that falls in it on its walls or unknown",
            100.0 * f.conflict_fine,
            100.0 * (1.0 - f.free_agree)
        ),
        Decline::Contradicted => format!(
            "contradicted: {:.0}% of the walls that fall in the other map lie inside its free space",
            100.0 * f.conflict_fine
        ),
        Decline::NotConfident => format!(
            "not confident: {:.0}% of the smaller map's free space falls in the other ({:.1}% of it on \
             occupied or unknown pixels), the consistent coarse score stands {:.2}x the best distinct \
             alternative's (rule value {rule_value:.2} below 0)",
            100.0 * f.free_inside,
            100.0 * (1.0 - f.free_agree),
            f.coarse_ratio
        ),
    }
}

/// The `why:` line of a pair declined for an alternative pose `alt` with `ratio` of the chosen pose
/// `best`'s evidence: how the alternative differs from it (a turn, or a shift when it turns less than a
/// degree), in the units the test compares.
fn ambiguous_why(best: &Rigid, alt: &Rigid, ratio: f64) -> String {
    let how = how_it_differs(best, alt);
    if ratio >= 1.0 {
        format!(
            "ambiguous: B fits A better {how} ({ratio:.2} of its evidence: walls that agree after a few \
             px of local shift), so it could be merged more than one way"
        )
    } else {
        format!(
            "ambiguous: B fits A {how} nearly as well ({ratio:.2} of its evidence: walls that agree \
             after a few px of local shift), so it could be merged more than one way"
        )
    }
}

/// The `why:` line of a pair declined for an alternative pose `alt` that nothing in the maps
/// contradicts, with `ratio` of the chosen pose `best`'s evidence
/// ([`MAX_UNCONTRADICTED_ALIAS`]).
fn uncontradicted_why(best: &Rigid, alt: &Rigid, ratio: f64) -> String {
    format!(
        "ambiguous: B also fits A {} with {ratio:.2} of the evidence and nothing against it (no wall \
         on the other map's free space, a share of free space in common), so it could be merged \
         more than one way",
        how_it_differs(best, alt)
    )
}

/// The `why:` line of a pair declined because a map matches itself (`self_match`, over
/// [`MAX_SELF_SYMMETRY`]) and the alternative pose `alt` it offers keeps `ratio` of the
/// chosen pose `best`'s evidence, hardly more contradicted.
fn self_match_why(best: &Rigid, alt: Option<&Rigid>, self_match: f64, ratio: f64) -> String {
    let limit = MAX_SELF_SYMMETRY;
    let alt = alt.map_or_else(
        || "at another pose".to_string(),
        |alt| how_it_differs(best, alt),
    );
    format!(
        "ambiguous: a map matches itself (self-match {self_match:.2} over {limit}), \
         and B fits A {alt} with {ratio:.2} of the evidence and hardly more walls on free space, so it \
         could be merged more than one way"
    )
}

/// How `alt` differs from `best`: "turned by 120 deg from the chosen pose (theta .., t (.., ..))", or
/// "shifted by .. px ..." when it turns less than a degree.
fn how_it_differs(best: &Rigid, alt: &Rigid) -> String {
    let turn = signed_deg(alt.theta_deg - best.theta_deg);
    let how = if turn.abs() >= 1.0 {
        format!("turned by {turn:.0} deg")
    } else {
        // Where the alternative puts B's origin, from where the chosen pose does.
        format!(
            "shifted by {:.0} px",
            (alt.tx - best.tx).hypot(alt.ty - best.ty)
        )
    };
    let alt = alt.normalized();
    format!(
        "{how} from the chosen pose (theta {:.1} deg, t ({:.0}, {:.0}))",
        alt.theta_deg, alt.tx, alt.ty
    )
}

/// Whether a map's self-match declines an alignment: its held part ([`Features::self_match_held`], a
/// repeat's) over [`MAX_SELF_SYMMETRY`], or the rest over it while an alternative pose keeps
/// [`SELF_SYMMETRY_ALIAS`] of its evidence. A building turns onto itself by a few turns, all of which
/// the alternative-pose test measures; a repeat is one step of a lattice whose other steps and
/// combinations no search lists, so the steps it does list being contradicted says nothing of the rest
/// (measured: judged pose by pose, the warehouse family's repeats let 15 poses a period off through).
pub fn self_match_vetoes(features: &Features) -> bool {
    features.self_match_held > MAX_SELF_SYMMETRY
        || (features.self_match > MAX_SELF_SYMMETRY && features.alias >= SELF_SYMMETRY_ALIAS)
}

/// Whether an alignment passes the two contradiction vetoes ([`MAX_FINE_CONFLICT`],
/// [`MAX_CONTRADICTION`]).
pub fn not_contradicted(features: &Features) -> bool {
    features.conflict_fine <= MAX_FINE_CONFLICT && contradiction(features) <= MAX_CONTRADICTION
}

/// The acceptance rule: `w_coarse * ln(coarse ratio) + w_free_inside * free inside + w_free_disagree *
/// ln(1.01 - free agree) >= threshold`. Weights from a logistic regression of "accurate" on the three
/// inputs over every real pair and negative (a unit ridge on the standardised weights); the threshold
/// 0.3 standard deviations of the rule's values above the highest value of any wrong estimate or negative
/// there, vetoed or not: the rule alone must decline every wrong one it was fitted on, so that no veto's
/// limit is what keeps a new building safe. `merge-eval --cross-validate` fits the same recipe without
/// each building and judges the one left out. The values are in tenths of their spread over the real
/// pairs (one standard deviation is 10): the many-map placement weighs candidates on that scale. (The
/// choice ratio was an input before: it moves with the coarse ratio, and with both the fit on two
/// buildings weighed them against each other.)
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Acceptance {
    /// Weight of the log of [`Features::coarse_ratio`].
    pub w_coarse: f64,
    /// Weight of [`Features::free_inside`].
    pub w_free_inside: f64,
    /// Weight of the log of 1.01 less [`Features::free_agree`].
    pub w_free_disagree: f64,
    /// The threshold.
    pub threshold: f64,
}

impl Default for Acceptance {
    fn default() -> Self {
        Acceptance {
            w_coarse: 6.6958,
            w_free_inside: 16.2069,
            w_free_disagree: -4.3527,
            threshold: 20.9029,
        }
    }
}

impl Acceptance {
    /// The rule's value minus its threshold (accept when >= 0).
    pub fn margin(&self, f: &Features) -> f64 {
        self.w_coarse * f.coarse_ratio.max(1e-3).ln()
            + self.w_free_inside * f.free_inside
            + self.w_free_disagree * (1.01 - f.free_agree).max(1e-3).ln()
            - self.threshold
    }
}

/// What the verification measures for a candidate transform.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct Features {
    /// Share of both maps' wall pixels (each mapped into the other) that lie more than 20 px deep inside
    /// the other map's free space.
    pub conflict: f64,
    /// The smaller of the two maps' shares of wall pixels that land in the other's known area (or within
    /// 5 px of its walls).
    pub inside: f64,
    /// The coarse correlation score of this candidate.
    pub coarse: f64,
    /// How far it stands out: its coarse score times one less its [`Features::residual`] (the share of its
    /// walls that local shifts leave in the other map's free space), over the best distinct runner-up's
    /// (refined transforms differing by more than 40 px, counting 10 px a degree; at most 10, also when
    /// there is none).
    pub coarse_ratio: f64,
    /// Share of both maps' wall pixels within 5 px of the other's walls.
    pub matched: f64,
    /// How many wall pixels of both maps lie within 5 px of the other's walls: the evidence in absolute
    /// terms ([`MIN_SUPPORT`]).
    pub support: f64,
    /// Share of both maps' wall pixels landing on an occupied pixel of the other.
    pub matched_fine: f64,
    /// Share of both maps' wall pixels more than 3 px deep inside the other map's free space (the
    /// contradiction veto, [`MAX_FINE_CONFLICT`]).
    pub conflict_fine: f64,
    /// Drift-tolerant local agreement: in 48 px tiles of the overlap, the share of wall pixels within
    /// 1.5 px of the other map's walls after the tile's best shift of up to 6 px (both maps into each
    /// other, weighted by wall pixels). 0 for a candidate whose coarse score could not make it the choice
    /// (not measured).
    pub local: f64,
    /// Drift-tolerant conflict: in the same tiles after the same shifts, the share of wall pixels over
    /// 3 px deep in the other map's free space. A bent map's conflicts vanish under a few px of local
    /// shift; a wrong pose's do not.
    pub residual: f64,
    /// The coarse score over the smaller map's wall cells (as the FFT scales it).
    pub coarse_norm: f64,
    /// The choice's key: the local agreement times the square root of one less the fine conflict times
    /// the fourth power of the free agreement times the coarse score relative to the best candidate's
    /// (before the polish).
    pub choice: f64,
    /// How far the choice stands out: its key over the best distinct alternative's (at most 10).
    pub choice_ratio: f64,
    /// The smaller of the two maps' shares of (sampled) free pixels that land in the other's known area:
    /// two maps laid side by side along a wall share walls but no free space.
    pub free_inside: f64,
    /// Of the free pixels landing in the other's known area, the share on its free pixels.
    pub free_agree: f64,
    /// The evidence of the best alternative pose that is hardly more contradicted than the chosen one,
    /// over the chosen one's: evidence is the wall pixels (both maps into each other) within 1.5 px of
    /// the other's walls after their 48 px tile's best shift of up to 6 px. The alternatives are the chosen pose moved by either map's self-transforms
    /// (its repeats and its turns onto itself at any angle) and the search's other distinct candidates
    /// ([`MAX_ALIAS`]; measured with the self-match, 0 otherwise). Above 1 when an alternative has more.
    pub alias: f64,
    /// The larger of the two maps' `self_symmetry` (the aligner's), measured for the chosen candidate when the rule
    /// value is at least -1 (0 otherwise).
    pub self_match: f64,
    /// The self-match the veto holds whatever the alternative poses show (`self_match_vetoes`): the
    /// part of [`Features::self_match`] under a shift (a map that repeats itself).
    #[serde(default)]
    pub self_match_held: f64,
    /// [`Features::alias`] among the alternatives that nothing in the maps contradicts: fewer of their
    /// walls deep in the other map's free space after the local shifts than a detail needs to be seen
    /// against none, and a share of free space in the other map's known area at least a quarter of the
    /// chosen pose's ([`MAX_UNCONTRADICTED_ALIAS`]; 0 without one).
    #[serde(default)]
    pub alias_uncontradicted: f64,
    /// Building-independent (reported, not yet decided on): the chosen pose's consistent evidence over
    /// the best distinct alternative's, both counted the same way: the wall pixels of both maps
    /// (sampled, each into the other) within 1.5 px of the other map's walls after their 48 px tile's
    /// best shift of up to 6 px, less those left over 3 px deep in its free space. The alternatives are
    /// the search's candidates more than 40 px apart (10 px a degree; all measured before the polish,
    /// the chosen one too) and, where the alternative-pose test ran, the poses the maps' symmetries and
    /// the turned candidates offer (against the polished pose). The lower of the two ratios, at most 10
    /// (also with no alternative); 0 when the chosen pose's own count is not positive, or in a record
    /// measured before it existed. A ratio of two counts of the same pair's walls at the same
    /// tolerances (fixed in pixels, so they scale with the map's resolution, not its building).
    #[serde(default)]
    pub evidence_ratio: f64,
    /// Building-independent (reported): the chosen pose's agreeing wall pixels (as
    /// [`Features::evidence_ratio`] counts them, before the deep ones are taken off) over the wall pixels
    /// of both maps that land on the other map's known area at all: a share of what the overlap could
    /// show at most, whatever its size (where [`MIN_SUPPORT`] is a pixel count). At most 1: the agreeing
    /// walls are counted after their tile's shift, the known ones before it, so the ratio is clamped.
    #[serde(default)]
    pub support_share: f64,
    /// Map A's own noise level, from A alone: the share of its wall pixels that are clutter (occupied
    /// components at most 16 px a side: speckle, a chair, a person), which a second robot need not
    /// see and whose walls may then lie in its free space at the right pose.
    #[serde(default)]
    pub noise_a: f64,
    /// Map B's, as [`Features::noise_a`].
    #[serde(default)]
    pub noise_b: f64,
    /// The same in the overlap: the share of the wall pixels the chosen pose's local fit measured
    /// (both ways) that are their own map's clutter, in the units of [`Features::residual`].
    #[serde(default)]
    pub noise: f64,
    /// Building-independent (reported): the chosen pose's contradiction beyond what the maps' own
    /// noise explains: the share of the measured wall pixels over 3 px deep in the other map's free
    /// space after the local shifts ([`Features::residual`]) that are not their own map's clutter.
    #[serde(default)]
    pub excess_conflict: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn right() -> Features {
        Features {
            choice_ratio: 3.0,
            coarse_ratio: 2.0,
            free_inside: 0.6,
            free_agree: 0.97,
            conflict_fine: 0.3,
            support: 4000.0,
            ..Features::default()
        }
    }

    #[test]
    fn a_typical_right_real_pair_passes_and_each_veto_declines_it() {
        let f = right();
        let margin = Acceptance::default().margin(&f);
        assert!(margin > 0.0 && accepts(&f, margin), "{margin}");
        // Walls on free space and free space on walls together: contradicted, whatever the rule says.
        let both = Features {
            conflict_fine: 0.5,
            free_agree: 0.92,
            ..f
        };
        assert!(contradiction(&both) > MAX_CONTRADICTION);
        assert!(!accepts(&both, 10.0));
        let deep = Features {
            conflict_fine: 0.6,
            free_agree: 0.99,
            ..f
        };
        assert!(!accepts(&deep, 10.0));
        // A map that matches itself, with an alternative pose keeping a third of the evidence.
        let symmetric = Features {
            self_match: 0.6,
            alias: 0.3,
            ..f
        };
        assert!(!accepts(&symmetric, 10.0));
        // ... and where each pose its symmetry offers is contradicted, or keeps under a quarter of the
        // evidence: the symmetry offers no other merge, unless the map repeats itself (a lattice).
        let judged = Features {
            alias: 0.2,
            ..symmetric
        };
        assert!(accepts(&judged, 10.0));
        // A map that repeats itself (its self-match under a shift held): declined whatever the
        // alternatives.
        assert!(!accepts(
            &Features {
                self_match_held: 0.6,
                alias: 0.0,
                ..judged
            },
            10.0
        ));
        assert!(!accepts(
            &Features {
                self_match_held: 0.6,
                ..judged
            },
            10.0
        ));
        // An alternative pose as consistent with most of the support: ambiguous.
        assert!(!accepts(&Features { alias: 0.8, ..f }, 10.0));
        // A few hundred matched wall pixels: too little to tell right from wrong.
        assert!(!accepts(
            &Features {
                support: 500.0,
                ..f
            },
            10.0
        ));
    }

    #[test]
    fn the_rule_grows_with_the_shared_free_space_and_the_margin() {
        let rule = Acceptance::default();
        let f = right();
        let less = |g: Features| rule.margin(&g) < rule.margin(&f);
        assert!(less(Features {
            free_inside: 0.3,
            ..f
        }));
        assert!(less(Features {
            free_agree: 0.9,
            ..f
        }));
        assert!(less(Features {
            coarse_ratio: 1.0,
            ..f
        }));
        // Two maps side by side along a wall share walls but hardly any free space: declined.
        let touching = Features {
            free_inside: 0.02,
            ..f
        };
        assert!(rule.margin(&touching) < 0.0);
    }

    /// A decline's reason is the first test that fails, in the order the `why:` line is chosen: the
    /// vetoes only when the rule's value would accept.
    #[test]
    fn a_decline_names_the_first_test_that_fails() {
        let ok = Features {
            support: 5000.0,
            free_agree: 1.0,
            ..Features::default()
        };
        assert_eq!(decline(&ok, 1.0), None);
        assert_eq!(decline(&ok, -1.0), Some(Decline::NotConfident));
        let cases = [
            (
                Features {
                    alias: 0.9,
                    support: 10.0,
                    ..ok
                },
                Decline::Repeat,
            ),
            (
                Features {
                    alias: 0.5,
                    alias_uncontradicted: 0.3,
                    support: 10.0,
                    ..ok
                },
                Decline::Uncontradicted,
            ),
            (
                Features {
                    support: 10.0,
                    self_match: 0.9,
                    ..ok
                },
                Decline::LittleSupport,
            ),
            (
                Features {
                    self_match: 0.9,
                    alias: 0.5,
                    conflict_fine: 0.9,
                    ..ok
                },
                Decline::SelfMatch,
            ),
            (
                Features {
                    conflict_fine: 0.9,
                    ..ok
                },
                Decline::Contradicted,
            ),
        ];
        for (f, want) in cases {
            assert_eq!(decline(&f, 1.0), Some(want), "{f:?}");
            // Below the threshold the rule's verdict comes first.
            assert_eq!(decline(&f, -1.0), Some(Decline::NotConfident), "{f:?}");
        }
    }
}
