//! The rule table: counts, symmetry, and the patterns the paper means and does not mean.

use crate::common;
use common::{art, detect};
use ogm_corners::backend::rules::{
    canonical_rule, code_picture, mirror_code, rotate_code, RuleTable,
};
use ogm_corners::RuleSet;

#[test]
fn paper_reading_accepts_44_codes_and_mod2_36() {
    assert_eq!(RuleTable::new(RuleSet::Paper).accepted().count(), 44);
    assert_eq!(RuleTable::new(RuleSet::PaperMod2).accepted().count(), 36);
}

#[test]
fn per_rule_counts() {
    let count = |set, rule| {
        RuleTable::new(set)
            .accepted()
            .filter(|&(_, r)| r == rule)
            .count()
    };
    assert_eq!([4, 5, 6].map(|r| count(RuleSet::Paper, r)), [8, 20, 16]);
    assert_eq!([4, 5, 6].map(|r| count(RuleSet::PaperMod2, r)), [4, 16, 16]);
}

#[test]
fn rule_matches_number_of_occupied_neighbours() {
    for set in [RuleSet::Paper, RuleSet::PaperMod2] {
        for (code, rule) in RuleTable::new(set).accepted() {
            assert_eq!(code.count_ones(), rule as u32, "code {code}");
        }
    }
}

#[test]
fn closed_under_rotation_and_mirroring() {
    for set in [RuleSet::Paper, RuleSet::PaperMod2] {
        let t = RuleTable::new(set);
        for code in 0..=255u8 {
            for k in 0..4 {
                assert_eq!(
                    t.rule(rotate_code(code, k)),
                    t.rule(code),
                    "rotate {code} by {k}"
                );
            }
            assert_eq!(t.rule(mirror_code(code)), t.rule(code), "mirror {code}");
        }
    }
}

#[test]
fn canonical_patterns_match_the_reviewed_pictures() {
    // Reviewed by hand against the pictures in docs/detectors.md: an independent record of what each reading accepts,
    // so a change to the formulas or the rotation shows up here.
    let paper = [
        (27, 4),
        (31, 5),
        (55, 5),
        (57, 4),
        (61, 5),
        (63, 6),
        (94, 5),
        (103, 5),
        (111, 6),
        (123, 6),
        (126, 6),
    ];
    let mod2 = [
        (27, 4),
        (31, 5),
        (55, 5),
        (63, 6),
        (91, 5),
        (103, 5),
        (111, 6),
        (123, 6),
        (126, 6),
    ];
    assert_eq!(RuleTable::new(RuleSet::Paper).canonical(), paper.to_vec());
    assert_eq!(
        RuleTable::new(RuleSet::PaperMod2).canonical(),
        mod2.to_vec()
    );
    // And each canonical code satisfies the formulas in at least one orientation.
    for (code, rule) in paper {
        let any = (0..4).find_map(|k| canonical_rule(rotate_code(code, k), 3));
        assert_eq!(any, Some(rule));
    }
}

#[test]
fn mod2_is_not_a_subset_accident() {
    // The two readings share the rule-6 codes and differ elsewhere: a guard against a swapped modulus.
    let a: Vec<_> = RuleTable::new(RuleSet::Paper).accepted().collect();
    let b: Vec<_> = RuleTable::new(RuleSet::PaperMod2).accepted().collect();
    let six = |v: &Vec<(u8, u8)>| v.iter().filter(|x| x.1 == 6).cloned().collect::<Vec<_>>();
    assert_eq!(six(&a), six(&b));
    assert!(b.iter().any(|x| !a.contains(x)));
}

#[test]
fn rotation_and_mirror_of_codes_are_group_actions() {
    for code in 0..=255u8 {
        assert_eq!(rotate_code(code, 4), code);
        assert_eq!(mirror_code(mirror_code(code)), code);
        assert_eq!(rotate_code(code, 1).count_ones(), code.count_ones());
    }
    // Q (top-left) turns clockwise to P (top-right); mirrored, Q becomes P and A' becomes A.
    assert_eq!(rotate_code(0b0000_0001, 1), 0b0000_0100);
    assert_eq!(mirror_code(0b0000_0001), 0b0000_0100);
    assert_eq!(mirror_code(0b1000_0000), 0b0000_1000);
}

#[test]
fn picture_follows_bit_order() {
    assert_eq!(code_picture(0b0000_0001), ["# . .", ". C .", ". . ."]);
    assert_eq!(code_picture(0b0000_1000), [". . .", ". C #", ". . ."]);
    assert_eq!(code_picture(0b0100_0000), [". . .", ". C .", "# . ."]);
}

#[test]
fn concave_room_corner_fires_in_all_four_orientations() {
    // Five occupied neighbours in an L around the free centre: the inside corner of a room.
    let maps = [
        ["###", "#..", "#.."],
        ["###", "..#", "..#"],
        ["..#", "..#", "###"],
        ["#..", "#..", "###"],
    ];
    for m in maps {
        let kps = detect(&art(&m), RuleSet::Paper, false);
        assert!(
            kps.iter().any(|k| (k.x, k.y) == (1, 1) && k.rule == 5),
            "{m:?} gave {kps:?}"
        );
        let mod2 = detect(&art(&m), RuleSet::PaperMod2, false);
        assert!(mod2.iter().any(|k| (k.x, k.y) == (1, 1)), "mod2 {m:?}");
    }
}

#[test]
fn room_of_walls_has_exactly_its_four_corners() {
    let m = art(&["######", "#....#", "#....#", "#....#", "######"]);
    let got: Vec<_> = detect(&m, RuleSet::Paper, false)
        .iter()
        .map(|k| (k.x, k.y, k.rule))
        .collect();
    assert_eq!(got, vec![(1, 1, 5), (4, 1, 5), (1, 3, 5), (4, 3, 5)]);
}

#[test]
fn straight_wall_noise_pixel_and_corridor_are_not_corners() {
    let cases: [&[&str]; 4] = [
        // beside a straight wall
        &["#####", ".....", "....."],
        // beside a single noise pixel
        &[".....", "..#..", "....."],
        // a one-pixel horizontal corridor
        &["#####", ".....", "#####"],
        // a one-pixel vertical corridor
        &["#.#", "#.#", "#.#", "#.#"],
    ];
    for m in cases {
        let kps = detect(&art(m), RuleSet::Paper, false);
        assert!(kps.is_empty(), "{m:?} gave {kps:?}");
        let kps = detect(&art(m), RuleSet::PaperMod2, false);
        assert!(kps.is_empty(), "mod2 {m:?} gave {kps:?}");
    }
}

#[test]
fn unknown_neighbours_count_only_with_the_option() {
    // The L is made of unknown cells: a corner only when unknown counts as occupied.
    let m = art(&["???", "?..", "?.."]);
    assert!(detect(&m, RuleSet::Paper, false).is_empty());
    let kps = detect(&m, RuleSet::Paper, true);
    assert!(kps.iter().any(|k| (k.x, k.y) == (1, 1)), "{kps:?}");
}

#[test]
fn only_free_centres_are_corners() {
    // The same L around an occupied or unknown centre is not a keypoint.
    for centre in ['#', '?'] {
        let row = format!("#{centre}.");
        let m = art(&["###", &row, "#.."]);
        assert!(
            !detect(&m, RuleSet::Paper, false)
                .iter()
                .any(|k| (k.x, k.y) == (1, 1)),
            "centre {centre}"
        );
    }
}

#[test]
fn outside_the_map_counts_as_not_occupied() {
    // Free pixel at the map's corner with an L of walls beyond the edge would be a corner if the border
    // counted as occupied; it must not fire.
    let m = art(&["..", ".."]);
    assert!(detect(&m, RuleSet::Paper, false).is_empty());
    assert!(detect(&m, RuleSet::Paper, true).is_empty());
}

#[test]
fn canonical_codes_cover_every_class() {
    for set in [RuleSet::Paper, RuleSet::PaperMod2] {
        let t = RuleTable::new(set);
        let canon = t.canonical();
        let mut covered: Vec<u8> = canon
            .iter()
            .flat_map(|&(c, _)| (0..4).map(move |k| rotate_code(c, k)))
            .collect();
        covered.sort();
        covered.dedup();
        let all: Vec<u8> = t.accepted().map(|(c, _)| c).collect();
        assert_eq!(covered, all);
    }
    assert_eq!(RuleTable::new(RuleSet::Paper).canonical().len(), 11);
}
