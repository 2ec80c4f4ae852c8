//! How the OGM kernel classifies pixel values: in the form the host picks for each state (one-sided
//! compares where a state's values reach 0 or 255, as the ROS thresholds' do; the general interval, wrapping
//! ones included; the 256-entry table otherwise), every one against the CPU reference. Runs on whatever
//! adapter wgpu finds (lavapipe in CI); with CI=true a missing adapter fails.

use super::gpu_conformance::{assert_same, grey_map, VARIANTS};
use crate::common;
use ogm_corners::backend::gpu::GpuOptions;
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::map::synthetic::Rng;
use ogm_corners::{Backend, CellState, ClassTable, MapImage, RuleTable, Thresholds};

#[test]
fn odd_thresholds_and_negate() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let mut rng = Rng::new(11);
    let px = (0..300 * 200).map(|_| rng.range(0, 256) as u8).collect();
    let img = MapImage::new(300, 200, px).unwrap();
    for t in [
        Thresholds::default(),
        Thresholds {
            negate: true,
            ..Thresholds::default()
        },
        Thresholds {
            negate: false,
            occupied_thresh: 0.5,
            free_thresh: 0.5,
        },
    ] {
        assert_same(&mut gpu, &img, &t, "grey map");
    }
}

#[test]
fn class_tables_that_are_not_intervals() {
    // The kernel classifies by interval compares when each state's values are an interval (the ROS
    // thresholds always give that) and falls back to the table otherwise: exercise the fallback, and the
    // empty sets.
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let img = common::random_map(300, 77, 5);
    let mut rng = Rng::new(3);
    let states = [CellState::Free, CellState::Unknown, CellState::Occupied];
    let scattered: [CellState; 256] = std::array::from_fn(|_| states[rng.range(0, 3) as usize]);
    let grey = grey_map(190, 130, 9);
    for table in [
        scattered,
        [CellState::Unknown; 256],
        [CellState::Free; 256],
        std::array::from_fn(|v| {
            if v % 2 == 0 {
                CellState::Free
            } else {
                CellState::Occupied
            }
        }),
    ] {
        let classes = ClassTable::from_states(table);
        for map in [&img, &grey] {
            for (set, uao) in VARIANTS {
                let rules = RuleTable::new(set);
                let want = ReferenceBackend.detect(map, &classes, &rules, uao).unwrap();
                assert_eq!(gpu.detect(map, &classes, &rules, uao).unwrap(), want);
            }
        }
    }
}

/// A class table whose free and occupied values are the given intervals (`lo..=lo + span`, mod 256),
/// unknown elsewhere.
fn interval_table(free: (u8, u8), occupied: (u8, u8)) -> ClassTable {
    let within = |v: u8, (lo, span): (u8, u8)| v.wrapping_sub(lo) <= span;
    ClassTable::from_states(std::array::from_fn(|v| {
        let v = v as u8;
        if within(v, free) {
            CellState::Free
        } else if within(v, occupied) {
            CellState::Occupied
        } else {
            CellState::Unknown
        }
    }))
}

#[test]
fn intervals_in_the_middle_and_wrapping_ones() {
    // Intervals touching neither end take the general compare; wrapping ones too; single values at
    // either end take the one-sided ones.
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let img = common::random_map(300, 77, 5);
    let grey = grey_map(190, 130, 9);
    for (free, occupied) in [
        ((100, 50), (0, 40)),
        ((200, 55), (50, 40)),
        ((250, 11), (100, 20)),
        ((0, 0), (255, 0)),
        ((1, 253), (255, 1)),
        ((30, 30), (180, 30)),
    ] {
        let classes = interval_table(free, occupied);
        for map in [&img, &grey] {
            for (set, uao) in VARIANTS {
                let rules = RuleTable::new(set);
                let want = ReferenceBackend.detect(map, &classes, &rules, uao).unwrap();
                let got = gpu.detect(map, &classes, &rules, uao).unwrap();
                assert_eq!(got, want, "free {free:?} occupied {occupied:?} {set} {uao}");
            }
        }
    }
}
