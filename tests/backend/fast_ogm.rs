//! The fast CPU path returns exactly the reference's OGM keypoints, in the same order, on every kind of map
//! the GPU conformance suite uses, plus grey-level maps under several thresholds and the real shared maps.

use crate::common;
use ogm_corners::backend::fast::bitplanes::{
    interval_scalar, plane_row, plane_rows2, plane_rows2_on, words, ValueSet,
};
use ogm_corners::backend::fast::ogm::ogm_corners_on;
use ogm_corners::backend::fast::simd::Isa;
use ogm_corners::backend::fast::FastCpuBackend;
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::map::synthetic::{office_map, Rng, FREE, OCCUPIED, UNKNOWN};
use ogm_corners::{Backend, ClassTable, MapImage, OccupancyMap, RuleSet, RuleTable, Thresholds};
use proptest::prelude::*;

const VARIANTS: [(RuleSet, bool); 4] = [
    (RuleSet::Paper, false),
    (RuleSet::Paper, true),
    (RuleSet::PaperMod2, false),
    (RuleSet::PaperMod2, true),
];

/// The instruction sets this CPU runs, each of whose kernels is compared with the reference. A CPU without
/// AVX-512 (or AVX2) cannot run those kernels: said loudly, once, so that a run there is not mistaken for
/// one that covered them.
fn isas() -> Vec<Isa> {
    static NOTE: std::sync::Once = std::sync::Once::new();
    let (run, not): (Vec<Isa>, Vec<Isa>) = Isa::ALL.into_iter().partition(|i| i.supported());
    if !not.is_empty() {
        NOTE.call_once(|| {
            eprintln!(
                "NOTE: this CPU does not run the {:?} kernels: they are not tested on this machine \
                 (only {:?})",
                not, run
            )
        });
    }
    run
}

/// Asserts fast == reference on `img` for every rule reading and unknown option, on the backend and on
/// every instruction set's kernels; returns the count.
fn assert_same(img: &MapImage, thresholds: &Thresholds, what: &str) -> usize {
    let classes = ClassTable::new(thresholds);
    let mut n = 0;
    for (set, uao) in VARIANTS {
        let rules = RuleTable::new(set);
        let want = ReferenceBackend.detect(img, &classes, &rules, uao).unwrap();
        let got = FastCpuBackend.detect(img, &classes, &rules, uao).unwrap();
        for isa in isas() {
            let on = ogm_corners_on(isa, img, &classes, &rules, uao);
            assert!(
                on == want,
                "{what} ({}x{}, {set}, unknown_as_occupied={uao}): the {isa:?} kernels found {} \
                 keypoints, the reference {}",
                img.width(),
                img.height(),
                on.len(),
                want.len()
            );
        }
        if got != want {
            let first = got.iter().zip(&want).position(|(a, b)| a != b);
            panic!(
                "{what} ({}x{}, {set}, unknown_as_occupied={uao}): fast {} keypoints, reference {}; \
                 first difference at {first:?}",
                img.width(),
                img.height(),
                got.len(),
                want.len()
            );
        }
        n += want.len();
    }
    n
}

/// Any grey level, so that thresholds decide the states.
fn grey_map(w: u32, h: u32, seed: u64) -> MapImage {
    let mut rng = Rng::new(seed);
    let px = (0..w as usize * h as usize)
        .map(|_| rng.range(0, 256) as u8)
        .collect();
    MapImage::new(w, h, px).unwrap()
}

fn thresholds() -> Vec<Thresholds> {
    let t = |occupied_thresh, free_thresh, negate| Thresholds {
        occupied_thresh,
        free_thresh,
        negate,
    };
    vec![
        Thresholds::default(),
        t(0.65, 0.196, true),
        t(0.5, 0.5, false),
        t(0.9, 0.05, false),
        t(0.3, 0.25, true),
        t(1.0, 0.0, false), // nothing free, nothing occupied
    ]
}

#[test]
fn every_three_state_3x3_configuration() {
    let img = common::all_3x3_configurations();
    let total = assert_same(&img, &Thresholds::default(), "3^9 configurations");
    assert!(total > 1000, "{total}");
}

#[test]
fn random_maps_of_many_sizes_around_word_and_band_edges() {
    let sizes = [
        (1, 1),
        (1, 2),
        (2, 1),
        (1, 9),
        (9, 1),
        (2, 2),
        (3, 3),
        (5, 3),
        (13, 17),
        (63, 5),
        (64, 5),
        (65, 5),
        (127, 3),
        (128, 3),
        (129, 3),
        (64, 1),
        (1, 64),
        (1, 300),
        (191, 130),
        (193, 129),
        (257, 600), // several bands per thread
        (1023, 5),
    ];
    for (i, (w, h)) in sizes.into_iter().enumerate() {
        for seed in 0..3 {
            let img = common::random_map(w, h, (i * 10 + seed) as u64);
            assert_same(&img, &Thresholds::default(), "random map");
        }
    }
}

#[test]
fn grey_maps_under_many_thresholds() {
    for (i, t) in thresholds().iter().enumerate() {
        for (w, h) in [(70, 70), (200, 131)] {
            let img = grey_map(w, h, i as u64);
            assert_same(&img, t, &format!("grey map, thresholds {t:?}"));
        }
    }
}

#[test]
fn uniform_maps_and_a_rule_table_with_no_codes() {
    for v in [FREE, UNKNOWN, OCCUPIED] {
        let img = MapImage::filled(130, 70, v).unwrap();
        assert_same(&img, &Thresholds::default(), "uniform map");
    }
}

#[test]
fn synthetic_office_maps() {
    for (w, h, seed) in [(1024, 768, 1), (777, 1301, 7), (2048, 257, 3)] {
        let img = office_map(w, h, seed).unwrap();
        let n = assert_same(&img, &Thresholds::default(), "office map");
        assert!(n > 0, "the office map has corners");
    }
}

#[test]
fn real_shared_maps() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let maps = common::maps::real_maps(&dir);
    assert!(!maps.is_empty(), "no maps under {}", dir.display());
    for path in maps {
        let map = OccupancyMap::load(&path).unwrap();
        assert_same(&map.image, &map.thresholds, &path.display().to_string());
    }
}

#[test]
fn planes_match_membership_for_intervals_tables_and_empty_sets() {
    let mut rng = Rng::new(42);
    let row: Vec<u8> = (0..300).map(|_| rng.range(0, 256) as u8).collect();
    let mut sets = vec![
        ValueSet::Empty,
        ValueSet::from_members(&[true; 256]),
        ValueSet::from_members(&(0..256).map(|v| v >= 250).collect::<Vec<_>>()),
        ValueSet::from_members(&(0..256).map(|v| v <= 100).collect::<Vec<_>>()),
        ValueSet::from_members(
            &(0..256)
                .map(|v| (17..=200).contains(&v))
                .collect::<Vec<_>>(),
        ),
    ];
    assert!(sets[2..]
        .iter()
        .all(|s| matches!(s, ValueSet::Interval { .. })));
    let odd = ValueSet::from_members(&(0..256).map(|v| v % 3 == 0).collect::<Vec<_>>());
    assert!(matches!(odd, ValueSet::Table(_)));
    sets.push(odd);
    for set in &sets {
        for len in [0, 1, 15, 16, 63, 64, 65, 128, 300] {
            let mut out = vec![!0u64; words(len) + 1];
            plane_row(set, &row[..len], &mut out);
            for x in 0..words(len) * 64 {
                let bit = (out[x / 64] >> (x % 64)) & 1 == 1;
                let want = x < len && set.contains(row[x]);
                assert_eq!(bit, want, "{set:?}, len {len}, pixel {x}");
            }
        }
    }
}

proptest! {
    #[test]
    fn simd_and_portable_interval_planes_agree(
        bytes in proptest::collection::vec(any::<u8>(), 64),
        lo in any::<u8>(),
        span in any::<u8>(),
    ) {
        let mut out = [0u64; 1];
        plane_row(&ValueSet::Interval { lo, span }, &bytes, &mut out);
        prop_assert_eq!(out[0], interval_scalar(lo, span, &bytes));
    }

    /// Two planes from one pass (AVX2 where the CPU has it) are the two planes one by one.
    #[test]
    fn two_planes_from_one_pass_agree(
        bytes in proptest::collection::vec(any::<u8>(), 0..300),
        (la, sa, lb, sb) in (any::<u8>(), any::<u8>(), any::<u8>(), any::<u8>()),
        table in any::<bool>(),
    ) {
        let a = ValueSet::Interval { lo: la, span: sa };
        let b = if table {
            ValueSet::from_members(&(0..256).map(|v| v % 3 == 0).collect::<Vec<_>>())
        } else {
            ValueSet::Interval { lo: lb, span: sb }
        };
        let n = words(bytes.len());
        let (mut fa, mut fb) = (vec![0u64; n], vec![0u64; n]);
        plane_rows2(&a, &b, &bytes, &mut fa, &mut fb);
        let (mut ga, mut gb) = (vec![0u64; n], vec![0u64; n]);
        plane_row(&a, &bytes, &mut ga);
        plane_row(&b, &bytes, &mut gb);
        prop_assert_eq!((&fa, &fb), (&ga, &gb));
        for isa in isas() {
            let (mut ha, mut hb) = (vec![0u64; n], vec![0u64; n]);
            plane_rows2_on(isa, &a, &b, &bytes, &mut ha, &mut hb);
            prop_assert_eq!((&ha, &hb), (&ga, &gb), "{:?}", isa);
        }
    }

    #[test]
    fn small_random_maps(w in 1u32..80, h in 1u32..80, seed in any::<u64>()) {
        assert_same(&common::random_map(w, h, seed), &Thresholds::default(), "proptest map");
    }
}
