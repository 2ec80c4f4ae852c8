//! The synthetic office map: seeded, deterministic, realistic enough to have every state and corners.

use crate::common;
use ogm_corners::map::synthetic::{cluttered_office, office_map, Rng, FREE, OCCUPIED, UNKNOWN};
use ogm_corners::RuleSet;

#[test]
fn same_seed_same_map_other_seed_other_map() {
    let a = office_map(400, 300, 5).unwrap();
    assert_eq!(a, office_map(400, 300, 5).unwrap());
    assert_ne!(a, office_map(400, 300, 6).unwrap());
}

#[test]
fn office_has_all_three_states_unknown_outside_and_corners() {
    let m = office_map(512, 384, 1).unwrap();
    let count = |v: u8| m.pixels().iter().filter(|&&p| p == v).count();
    let (free, occ, unk) = (count(FREE), count(OCCUPIED), count(UNKNOWN));
    assert_eq!(free + occ + unk, m.len(), "only the three ROS values");
    assert!(
        free > m.len() / 2 && occ > m.len() / 100 && unk > m.len() / 20,
        "{free} {occ} {unk}"
    );
    // The border is unknown space outside the building.
    assert!((0..m.width()).all(|x| m.get(x, 0) == UNKNOWN && m.get(x, m.height() - 1) == UNKNOWN));
    let kps = common::detect(&m, RuleSet::Paper, false);
    assert!(kps.len() > 50, "rooms have corners: {}", kps.len());
}

#[test]
fn too_small_is_an_error_not_a_panic() {
    assert!(office_map(31, 100, 1).is_err());
    assert!(office_map(0, 0, 1).is_err());
    for (w, h) in [(32, 32), (33, 200), (200, 33)] {
        office_map(w, h, 9).unwrap();
    }
    // The furnished office too: sides smaller than its largest box are no panic, and it is an error
    // where the office is.
    assert!(cluttered_office(31, 100, 1).is_err());
    for (w, h) in [(32, 32), (33, 200), (200, 33)] {
        for seed in 0..8 {
            cluttered_office(w, h, seed).unwrap();
        }
    }
}

#[test]
fn the_furnished_office_is_the_office_with_boxes_and_an_unexplored_corner() {
    let (plain, furnished) = (
        office_map(400, 300, 5).unwrap(),
        cluttered_office(400, 300, 5).unwrap(),
    );
    assert_eq!(furnished, cluttered_office(400, 300, 5).unwrap());
    let mut boxes = 0;
    for (i, (&p, &f)) in plain.pixels().iter().zip(furnished.pixels()).enumerate() {
        let (x, y) = (i as u32 % 400, i as u32 / 400);
        if x >= 240 && y < 120 {
            assert_eq!(f, UNKNOWN, "({x}, {y}) is in the unexplored corner");
        } else if f != p {
            assert_eq!(f, OCCUPIED, "({x}, {y}): {p} -> {f}");
            boxes += 1;
        }
    }
    assert!(boxes > 100, "furniture drawn: {boxes} pixels");
}

#[test]
fn rng_range_stays_in_bounds() {
    let mut r = Rng::new(3);
    for _ in 0..10_000 {
        let v = r.range(5, 9);
        assert!((5..9).contains(&v));
    }
    assert_eq!(r.range(4, 4), 4);
}

/// FNV-1a of the pixels, to pin the generator's output.
fn fnv(px: &[u8]) -> u64 {
    px.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

#[test]
fn the_generator_is_stable_across_versions() {
    // Benchmarks and published counts refer to these maps; a change to the generator must be deliberate.
    for (w, h, seed, want) in [
        (512, 384, 1, 0xd39d_a041_8069_a169u64),
        (1000, 333, 7, 0x5761_aa81_aae1_3beb),
    ] {
        let m = office_map(w, h, seed).unwrap();
        assert_eq!(
            fnv(m.pixels()),
            want,
            "office_map({w}, {h}, {seed}) changed"
        );
    }
}

#[test]
fn large_maps_are_tiled_with_offices_drawn_in_parallel() {
    use ogm_corners::map::synthetic::{office_map, office_map_parallel};
    // Under two tiles a side it is the plain office map; above, the first tile is an office of its own.
    assert_eq!(
        office_map_parallel(300, 200, 5).unwrap(),
        office_map(300, 200, 5).unwrap()
    );
    let big = office_map_parallel(16_400, 40, 5).unwrap();
    assert_eq!(big, office_map_parallel(16_400, 40, 5).unwrap());
    let first = office_map(8192, 40, 5).unwrap();
    for y in 0..40usize {
        assert_eq!(
            &big.pixels()[y * 16_400..y * 16_400 + 8192],
            &first.pixels()[y * 8192..(y + 1) * 8192],
            "row {y}"
        );
    }
    // The second tile is a different office, not a copy.
    let differs = (0..40usize).any(|y| {
        big.pixels()[y * 16_400 + 8192..y * 16_400 + 16_384]
            != first.pixels()[y * 8192..(y + 1) * 8192]
    });
    assert!(differs, "the second tile repeats the first");
}
