//! Symmetric buildings are never merged at their alias: a hall of k identical wings turns onto itself
//! by every whole wing, at any angle, and a pair cut from it fits nearly as well turned by a wing as at
//! its true pose. The property over the symmetric family (random k, mirrored or not, extra room or not,
//! random windows and turn), the five-fold halls the merger used to place a wing off (one of them
//! where the wrong pose overlaps more than the true one, which nothing contradicts), the half turn
//! of an office whose wrong pose laid a third of its walls across rooms, a hall whose one extra
//! room, in both windows, decides its turn, and a two-wing hall bent 7 degrees off its half turn.

use crate::common;
use ogm_corners::measure::synthetic::{
    extra_room_in_both, extra_room_turns_seen, hall_pair, synthetic_pair, SymmetricKind,
    SyntheticPair, SyntheticSpec,
};
use ogm_corners::merge::pair::align::{align, Alignment, MergeOptions};
use ogm_corners::merge::transform::signed_deg;
use ogm_corners::OccupancyMap;
use proptest::prelude::*;

fn aligned(pair: &SyntheticPair) -> Alignment {
    align(&pair.a, &pair.b, &MergeOptions::default()).unwrap()
}

/// What is wrong when `al` accepts a pose that is not `pair`'s truth: how far it turns from it, and
/// why it was accepted.
fn wrong_accept(pair: &SyntheticPair, al: &Alignment) -> Option<String> {
    (al.accepted && !pair.accurate(&al.transform)).then(|| {
        let off = signed_deg(al.transform.theta_deg - pair.truth.theta_deg);
        format!("accepted {off:.1} deg off: {}", al.explain())
    })
}

/// The five-fold halls of the family (`merge-eval --synthetic --family symmetric`, seed 1) that were
/// merged turned by two wings (144 degrees) and by one (72): both windows hold the hall, and every wing
/// matches every other. Declined now, as ambiguous.
#[test]
fn five_fold_halls_are_never_merged_a_wing_off() {
    for (mirrored, seed) in [(true, 618u64), (false, 703)] {
        let kind = SymmetricKind {
            mirrored,
            ..SymmetricKind::plain(5)
        };
        let pair = hall_pair(kind, seed).unwrap();
        let al = aligned(&pair);
        let wrong = wrong_accept(&pair, &al);
        assert!(wrong.is_none(), "{kind:?}: {wrong:?}");
        if al.score >= 0.0 {
            let why = al.reason.clone().unwrap_or_default();
            assert!(why.starts_with("ambiguous"), "{kind:?}: {why}");
        }
    }
}

/// A five-fold hall whose wrong pose overlaps more than its true one (5 wings with rooms on one side,
/// `hall_pair` seed 348258, found by the property test below): the pose two wings off lays B over more
/// of A than the true pose does, so the true pose keeps only 0.73 of its evidence, under the 0.75 at
/// which an alternative is a rival, and neither window matches itself turned well enough for the
/// self-match to count. Neither pose lays a wall on free space, and both share free space as a merge
/// does: the true pose is a merge the maps allow as well, and the pair is declined for it.
#[test]
fn a_five_fold_hall_whose_wrong_pose_overlaps_more_is_declined_for_its_uncontradicted_turn() {
    let kind = SymmetricKind {
        mirrored: false,
        ..SymmetricKind::plain(5)
    };
    let pair = hall_pair(kind, 348_258).unwrap();
    let al = aligned(&pair);
    let wrong = wrong_accept(&pair, &al);
    assert!(wrong.is_none(), "{wrong:?}");
    let why = al.reason.clone().unwrap_or_default();
    assert!(
        why.starts_with("ambiguous: B also fits A turned by"),
        "{why}"
    );
    assert!(
        al.features.alias_uncontradicted >= 0.25,
        "{:?}",
        al.features
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]

    /// Any hall of the family, any windows and turn: what is accepted is the true pose.
    #[test]
    fn a_symmetric_hall_is_never_merged_wrongly(which in 0..SymmetricKind::suite().len(), seed in 1u64..1_000_000) {
        let kind = SymmetricKind::suite()[which];
        if let Some(pair) = hall_pair(kind, seed) {
            let al = aligned(&pair);
            let wrong = wrong_accept(&pair, &al);
            prop_assert!(wrong.is_none(), "{:?} seed {}: {:?}", kind, seed, wrong);
        }
    }
}

/// A half turn that laid a third of B's walls across A's rooms: office_a of the maps-more data cut as
/// `merge-eval --synthetic` cuts it at 30% overlap (the 22-building run's office_a/30/3), accepted before
/// at 180 degrees off with 45% of its walls on free space, because no alternative pose a map's symmetry
/// offered was as consistent with as much support; a candidate the search found half a turn from it,
/// hardly more contradicted, has 0.84 of its evidence, and the decline names that turn.
#[test]
fn a_contradicted_half_turn_is_declined_for_the_clean_pose_half_a_turn_away() {
    let Some(dir) = common::maps_more() else {
        return;
    };
    let map = OccupancyMap::load_yaml(&dir.join("ipa/office_a.yaml")).unwrap();
    // The run's cut seed for its tenth map (office_a), third cut, 30% overlap.
    let seed = 1_000_003 + 9 * 7919 + 3 + 3000;
    let spec = SyntheticSpec {
        overlap: 0.3,
        noise: 0.0,
    };
    let pair = synthetic_pair(&map, &spec, seed).unwrap();
    let al = aligned(&pair);
    let wrong = wrong_accept(&pair, &al);
    assert!(wrong.is_none(), "{wrong:?}");
    if !pair.accurate(&al.transform) {
        let why = al.reason.clone().unwrap_or_default();
        let turn = turned_by(&why).unwrap_or_else(|| panic!("no turn named: {why}"));
        assert!(turn.abs() >= 170.0, "{why}");
    }
}

/// The turn a `why:` line names ("turned by N deg").
fn turned_by(why: &str) -> Option<f64> {
    let rest = why.split("turned by ").nth(1)?;
    rest.split(' ').next()?.parse().ok()
}

/// A four-wing hall with one extra room at the end of a wing, both windows holding the room (the
/// family's `4 wings, one extra room, in both windows` pair 5, seed 1): the half turn lays the room's
/// door on the other map's closed end wall, and the quarter turns, which lay it where neither window
/// has seen (`extra_room_turns_seen` is false), keep too little of the evidence to be rivals; what
/// might decline it is the repeat of the wings' rooms (a shift), but every step of its lattice is
/// listed and measured, none keeps the evidence, and it is merged. The same windows of the same hall
/// without the room are declined for a turn.
#[test]
fn a_halls_extra_room_in_both_windows_tells_its_turns_apart() {
    let aligned = |pair: &SyntheticPair| align(&pair.a, &pair.b, &MergeOptions::default()).unwrap();
    let room = SymmetricKind {
        extra_room: true,
        ..SymmetricKind::plain(4)
    };
    let seed = 613 + 5 * 17 + 4;
    let pair = hall_pair(room, seed).unwrap();
    assert!(extra_room_in_both(room, seed, &pair));
    assert!(!extra_room_turns_seen(room, seed, &pair));
    let al = aligned(&pair);
    assert!(
        al.accepted && pair.accurate(&al.transform),
        "{}",
        al.explain()
    );
    let plain = SymmetricKind {
        extra_room: false,
        ..room
    };
    let pair = hall_pair(plain, seed).unwrap();
    let al = aligned(&pair);
    assert!(!al.accepted, "{}", al.explain());
    let why = al.reason.clone().unwrap_or_default();
    assert!(turned_by(&why).is_some_and(|t| t.abs() > 80.0), "{why}");
}

/// A half turn a little off: a two-wing hall whose second wing is bent 7 degrees back from the half
/// turn (the family's `2 wings, bent 7 deg`), so its wings match each other under a turn of 173 degrees
/// and its hall under one of 180. For these seeds the search ranks first the pose that lays B's wing on
/// A's other wing, 173 degrees from the truth, which a check of the half turn alone does not see. Each
/// is declined; where the wings' repeat of rooms does not decline it first, the decline names the turn.
#[test]
fn a_bent_two_wing_hall_is_never_merged_near_a_half_turn_off() {
    let kind = SymmetricKind {
        bend_deg: 7,
        ..SymmetricKind::plain(2)
    };
    for seed in [11, 25, 29] {
        let pair = hall_pair(kind, seed).unwrap();
        let al = aligned(&pair);
        let off = signed_deg(al.transform.theta_deg - pair.truth.theta_deg).abs();
        assert!((off - 173.0).abs() < 1.0, "seed {seed}: {off:.1} deg off");
        assert!(!al.accepted, "seed {seed}: {}", al.explain());
    }
    let al = aligned(&hall_pair(kind, 25).unwrap());
    let why = al.reason.clone().unwrap_or_default();
    assert!(turned_by(&why).is_some_and(|t| t.abs() > 170.0), "{why}");
}
