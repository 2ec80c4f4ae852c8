//! The GPU backend returns exactly the CPU reference's keypoints, in the same order.
//! Runs on whatever adapter wgpu finds (lavapipe in CI); with CI=true a missing adapter fails.

use crate::common;
use ogm_corners::backend::baselines;
use ogm_corners::backend::gpu::{GpuBackend, GpuOptions};
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::map::synthetic::{office_map, Rng};
use ogm_corners::{
    Backend, Baseline, BaselineParams, ClassTable, MapImage, OccupancyMap, RuleSet, RuleTable,
    Thresholds,
};

pub(crate) const VARIANTS: [(RuleSet, bool); 4] = [
    (RuleSet::Paper, false),
    (RuleSet::Paper, true),
    (RuleSet::PaperMod2, false),
    (RuleSet::PaperMod2, true),
];

/// Asserts CPU and GPU agree on `img` for every rule reading and unknown option; returns the CPU count.
pub(crate) fn assert_same(
    gpu: &mut GpuBackend,
    img: &MapImage,
    thresholds: &Thresholds,
    what: &str,
) -> usize {
    let classes = ClassTable::new(thresholds);
    let mut n = 0;
    for (set, uao) in VARIANTS {
        let rules = RuleTable::new(set);
        let want = ReferenceBackend.detect(img, &classes, &rules, uao).unwrap();
        let got = gpu.detect(img, &classes, &rules, uao).unwrap();
        if got != want {
            let first = got.iter().zip(&want).position(|(a, b)| a != b);
            panic!(
                "{what} ({}x{}, {set}, unknown_as_occupied={uao}): GPU {} keypoints, CPU {}; first difference at {first:?}",
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

#[test]
fn every_three_state_3x3_configuration() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let img = common::all_3x3_configurations();
    let total = assert_same(&mut gpu, &img, &Thresholds::default(), "3^9 configurations");
    assert!(total > 1000, "{total}");
}

#[test]
fn random_maps_of_many_sizes() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let sizes = [
        (1, 1),
        (1, 2),
        (2, 1),
        (1, 9),
        (9, 1),
        (2, 2),
        (3, 3),
        (4, 4),
        (5, 3),
        (3, 5),
        (7, 7),
        (13, 17),
        (31, 29),
        (64, 1),
        (1, 64),
        (65, 65),
        (257, 3),
        (3, 257),
        (1023, 5),
        (250, 250),
    ];
    for (i, (w, h)) in sizes.into_iter().enumerate() {
        for seed in 0..3 {
            let img = common::random_map(w, h, (i * 10 + seed) as u64);
            assert_same(&mut gpu, &img, &Thresholds::default(), "random map");
        }
    }
}

#[test]
fn maps_taller_than_a_slab_run_slab_by_slab() {
    // The keypoint's row field holds 24 bits, so maps taller than 2^24 rows run in slabs; small slabs
    // (with tiles and windows inside them) exercise the same path.
    let img = common::random_map(70, 301, 21);
    for (slab, tile) in [(1u32, None), (7, None), (100, Some((30, 9))), (301, None)] {
        let Some(mut gpu) = common::gpu_backend(GpuOptions {
            slab_rows: slab,
            tile,
            max_keypoints_per_pass: Some(50),
            ..GpuOptions::default()
        }) else {
            return;
        };
        assert_same(&mut gpu, &img, &Thresholds::default(), "slabs");
    }
}

#[test]
fn the_device_scan_matches_the_reference() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let mut rng = Rng::new(8);
    // One block, exactly one, one more, and three levels.
    for n in [0usize, 1, 7, 1023, 1024, 1025, 5000, (1 << 20) + 3] {
        let counts: Vec<u32> = (0..n).map(|_| rng.range(0, 40)).collect();
        assert_eq!(
            gpu.scan(&counts).unwrap(),
            ogm_corners::backend::reference::scan::exclusive_scan(&counts),
            "{n} counts"
        );
    }
}

#[test]
fn a_workgroup_scratch_overflow_reruns_with_more_room() {
    let img = common::random_map(500, 90, 12);
    let Some(mut gpu) = common::gpu_backend(GpuOptions {
        initial_workgroup_scratch: 1,
        ..GpuOptions::default()
    }) else {
        return;
    };
    let n = assert_same(
        &mut gpu,
        &img,
        &Thresholds::default(),
        "one-keypoint scratch",
    );
    assert!(n > 1000, "{n}");
    // The first call overflowed and ran again with room; the grown scratch is kept for the next.
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    let mut fresh = common::gpu_backend(GpuOptions {
        initial_workgroup_scratch: 1,
        ..GpuOptions::default()
    })
    .unwrap();
    let want = ReferenceBackend
        .detect(&img, &classes, &rules, false)
        .unwrap();
    assert_eq!(fresh.detect(&img, &classes, &rules, false).unwrap(), want);
    assert!(fresh.stats().scratch_reruns > 0, "{:?}", fresh.stats());
    assert_eq!(fresh.detect(&img, &classes, &rules, false).unwrap(), want);
    assert_eq!(fresh.stats().scratch_reruns, 0, "{:?}", fresh.stats());
}

#[test]
fn tiled_runs_match_untiled() {
    // Small maps keep the many tiles (each a round trip) quick on a software adapter.
    let img = office_map(120, 80, 4).unwrap();
    let Some(mut whole) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let n = assert_same(&mut whole, &img, &Thresholds::default(), "untiled");
    assert_eq!(whole.stats().tiles, 1);
    assert!(n > 10, "{n}");
    for tile in [(7, 5), (64, 3), (120, 17), (13, 80), (33, 33)] {
        let opts = GpuOptions {
            tile: Some(tile),
            ..GpuOptions::default()
        };
        let mut tiled = common::gpu_backend(opts).unwrap();
        assert_same(&mut tiled, &img, &Thresholds::default(), "tiled");
        assert!(tiled.stats().tiles > 1, "{tile:?} must tile");
    }
    // Random maps with tiny tiles (down to single pixels), odd sizes.
    for tile in [(1, 1), (5, 3)] {
        let opts = GpuOptions {
            tile: Some(tile),
            ..GpuOptions::default()
        };
        let mut tiled = common::gpu_backend(opts).unwrap();
        for (w, h) in [(11, 7), (1, 13), (13, 1)] {
            let img = common::random_map(w, h, u64::from(w * h));
            assert_same(&mut tiled, &img, &Thresholds::default(), "tiled random");
        }
    }
}

#[test]
fn output_grows_and_splits_instead_of_truncating() {
    let img = common::random_map(200, 150, 2);
    let opts = GpuOptions {
        initial_keypoint_capacity: 1,
        max_keypoints_per_pass: Some(7),
        ..GpuOptions::default()
    };
    let Some(mut gpu) = common::gpu_backend(opts) else {
        return;
    };
    let n = assert_same(
        &mut gpu,
        &img,
        &Thresholds::default(),
        "small output buffer",
    );
    let s = gpu.stats();
    assert!(n > 100, "{n}");
    assert!(
        s.write_passes > 10,
        "the output must have taken many passes: {s:?}"
    );
    // Growth alone, without a per-pass cap: a one-keypoint buffer grows to hold them all.
    let mut gpu = common::gpu_backend(GpuOptions {
        initial_keypoint_capacity: 1,
        ..GpuOptions::default()
    })
    .unwrap();
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    let got = gpu.detect(&img, &classes, &rules, false).unwrap();
    assert_eq!(
        got,
        ReferenceBackend
            .detect(&img, &classes, &rules, false)
            .unwrap()
    );
    assert!(gpu.stats().keypoint_capacity >= got.len() as u64 && got.len() > 1);
}

/// The keypoint buffer grows to the whole list, not to what was left of it: after one call on a map, a
/// call on a map like it writes its list in one pass, tiled or not, at odd sizes and past a scan level. The
/// dispatches a map costs are printed and asserted: four a tile (detect, the scan's one level, scatter,
/// finish), two more when a tile's counts need a second scan level.
#[test]
fn a_map_is_written_in_one_pass_once_the_buffer_has_grown() {
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    for (w, h, tile, per_tile) in [
        (301, 199, None, 4),
        (97, 61, None, 4),
        (301, 199, Some((64, 32)), 4),
        (200, 2100, None, 6),
    ] {
        let Some(mut gpu) = common::gpu_backend(GpuOptions {
            initial_keypoint_capacity: 1,
            tile,
            ..GpuOptions::default()
        }) else {
            return;
        };
        let img = common::random_map(w, h, u64::from(w + h));
        let want = ReferenceBackend
            .detect(&img, &classes, &rules, false)
            .unwrap();
        assert_eq!(gpu.detect(&img, &classes, &rules, false).unwrap(), want);
        let first = gpu.stats();
        assert_eq!(gpu.detect(&img, &classes, &rules, false).unwrap(), want);
        let s = gpu.stats();
        println!(
            "{w}x{h} tile {tile:?}: {} keypoints, {} tiles; first call {} write passes, {} dispatches; \
             then {} and {}",
            want.len(),
            s.tiles,
            first.write_passes,
            first.dispatches,
            s.write_passes,
            s.dispatches
        );
        assert!(
            want.len() > 1,
            "{w}x{h}: too few keypoints to grow the buffer"
        );
        assert!(first.write_passes <= 2, "{w}x{h}: {first:?}");
        assert_eq!(s.write_passes, 1, "{w}x{h} tile {tile:?}: {s:?}");
        assert_eq!(
            s.dispatches,
            per_tile * s.tiles,
            "{w}x{h} tile {tile:?}: {s:?}"
        );
        assert!(s.keypoint_capacity >= want.len() as u64);
        assert_eq!(tile.is_some(), s.tiles > 1, "{s:?}");
    }
}

#[test]
fn staged_bands_are_read_in_place_or_copied_with_the_same_keypoints() {
    // Where the device lets kernels read mappable buffers (lavapipe does), the kernel reads each staged
    // band in its staging buffer; copy_bands forces the copy into device memory that other devices take.
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    let img = common::random_map(777, 301, 4);
    let want = ReferenceBackend
        .detect(&img, &classes, &rules, false)
        .unwrap();
    for copy_bands in [false, true] {
        let Some(mut gpu) = common::gpu_backend(GpuOptions {
            copy_bands,
            tile: Some((300, 64)),
            ..GpuOptions::default()
        }) else {
            return;
        };
        assert_eq!(gpu.detect(&img, &classes, &rules, false).unwrap(), want);
        let s = gpu.stats();
        assert!(s.tiles > 4, "{s:?}");
        let copied = copy_bands || !gpu.reads_staging();
        assert_eq!(s.pixel_copies, if copied { s.tiles } else { 0 }, "{s:?}");
        if std::env::var("CI").is_ok_and(|v| v == "true") && !copy_bands {
            // Lavapipe, the CI's adapter, has MAPPABLE_PRIMARY_BUFFERS: the in-place path must run there.
            assert!(gpu.reads_staging(), "{}", gpu.adapter().name);
        }
    }
}

#[test]
fn every_strip_height_matches_the_reference() {
    // Invocations walk strips of 1 to 16 rows (fewer on small maps on a large GPU): odd heights, a
    // strip past the tile's last row, tiles and slabs.
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::PaperMod2);
    let maps = [
        common::random_map(301, 199, 1),
        common::random_map(70, 33, 2),
        common::random_map(2100, 45, 3),
    ];
    for strip in 1..=16 {
        for tile in [None, Some((64, 37))] {
            let Some(mut gpu) = common::gpu_backend(GpuOptions {
                strip_rows: Some(strip),
                tile,
                slab_rows: 150,
                ..GpuOptions::default()
            }) else {
                return;
            };
            for img in &maps {
                let want = ReferenceBackend
                    .detect(img, &classes, &rules, true)
                    .unwrap();
                let got = gpu.detect(img, &classes, &rules, true).unwrap();
                assert_eq!(
                    got,
                    want,
                    "strip {strip}, tile {tile:?}, {}x{}",
                    img.width(),
                    img.height()
                );
            }
        }
    }
}

#[test]
fn the_backend_is_reused_across_maps() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    // Big then small then big: cached buffers must not leak stale data between calls.
    for (w, h, seed) in [(400, 300, 1), (5, 5, 2), (37, 3, 3), (400, 300, 4)] {
        assert_same(
            &mut gpu,
            &common::random_map(w, h, seed),
            &Thresholds::default(),
            "reuse",
        );
    }
}

#[test]
fn every_real_map() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let mut tiled = common::gpu_backend(GpuOptions {
        tile: Some((100, 70)),
        ..GpuOptions::default()
    })
    .unwrap();
    for p in common::maps::real_maps(&dir) {
        let map = OccupancyMap::load(&p).unwrap();
        let name = p.display().to_string();
        assert_same(&mut gpu, &map.image, &map.thresholds, &name);
        assert_same(&mut tiled, &map.image, &map.thresholds, &name);
    }
}

#[test]
fn a_map_over_128_mib_is_tiled_and_exact() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    // 12000 x 11500 = 138 Mpx, over lavapipe's 128 MiB storage binding.
    let img = office_map(12_000, 11_500, 8).unwrap();
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    let want = ReferenceBackend
        .detect(&img, &classes, &rules, false)
        .unwrap();
    let got = gpu.detect(&img, &classes, &rules, false).unwrap();
    assert_eq!(got.len(), want.len());
    assert!(got == want, "GPU and CPU differ on the large map");
    let limit = gpu
        .adapter()
        .max_storage_buffer_binding_size
        .min(gpu.adapter().max_buffer_size);
    if img.len() as u64 > limit {
        assert!(
            gpu.stats().tiles > 1,
            "a map over the binding limit must be tiled"
        );
    } else {
        eprintln!(
            "note: {} binds {limit} bytes, so the large map fit in one tile",
            gpu.adapter().name
        );
    }
}

// ---- The baselines: GPU score maps equal the CPU reference's, so the shared selection gives identical
// keypoints.

const BASELINES: [Baseline; 3] = [Baseline::Harris, Baseline::ShiTomasi, Baseline::Trajkovic];

fn assert_same_scores(gpu: &mut GpuBackend, img: &MapImage, what: &str) {
    let p = BaselineParams::default().exact().unwrap();
    for kind in BASELINES {
        let want = baselines::cpu_scores(kind, img, &p);
        let got = gpu.baseline_scores(kind, img, &p).unwrap();
        if got != want {
            let i = got.iter().zip(&want).position(|(a, b)| a != b).unwrap();
            panic!(
                "{what} ({}x{}) {kind:?}: first difference at pixel ({}, {}): GPU {} CPU {}",
                img.width(),
                img.height(),
                i % img.width() as usize,
                i / img.width() as usize,
                got[i],
                want[i]
            );
        }
    }
}

pub(crate) fn grey_map(w: u32, h: u32, seed: u64) -> MapImage {
    let mut rng = Rng::new(seed);
    MapImage::new(w, h, (0..w * h).map(|_| rng.range(0, 256) as u8).collect()).unwrap()
}

#[test]
fn baselines_on_random_maps_of_many_sizes() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let sizes = [
        (1, 1),
        (1, 9),
        (9, 1),
        (2, 2),
        (3, 3),
        (3, 5),
        (5, 4),
        (13, 17),
        (64, 1),
        (257, 3),
        (120, 90),
    ];
    for (i, (w, h)) in sizes.into_iter().enumerate() {
        assert_same_scores(&mut gpu, &common::random_map(w, h, i as u64), "ternary map");
        assert_same_scores(&mut gpu, &grey_map(w, h, i as u64 + 100), "grey map");
    }
    assert_same_scores(&mut gpu, &office_map(300, 200, 5).unwrap(), "office map");
}

/// The GPU's baseline keypoints (selected from the device's candidates) equal the CPU reference's.
fn assert_same_keypoints(
    gpu: &mut GpuBackend,
    img: &MapImage,
    params: &BaselineParams,
    what: &str,
) {
    for kind in BASELINES {
        let want = ReferenceBackend
            .baseline_keypoints(kind, img, params)
            .unwrap();
        let got = gpu.baseline_keypoints(kind, img, params).unwrap();
        assert!(
            got == want,
            "{what} {kind:?} {params:?}: GPU {} keypoints, CPU {}",
            got.len(),
            want.len()
        );
    }
}

#[test]
fn baseline_keypoints_are_selected_on_the_device_exactly() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let mut tiled = common::gpu_backend(GpuOptions {
        tile: Some((40, 30)),
        ..GpuOptions::default()
    })
    .unwrap();
    let settings = [
        BaselineParams::default(),
        BaselineParams {
            quality: 0.001,
            min_distance: 0.0,
            ..BaselineParams::default()
        },
        BaselineParams {
            quality: 0.5,
            min_distance: 7.5,
            max_corners: Some(5),
            ..BaselineParams::default()
        },
    ];
    for (w, h, seed) in [(1, 1, 1), (2, 3, 2), (37, 5, 3), (150, 97, 4)] {
        let grey = grey_map(w, h, seed);
        let office = office_map(w.max(32), h.max(32), seed).unwrap();
        for p in &settings {
            assert_same_keypoints(&mut gpu, &grey, p, "grey");
            assert_same_keypoints(&mut gpu, &office, p, "office");
            assert_same_keypoints(&mut tiled, &grey, p, "grey, tiled");
            assert_same_keypoints(&mut tiled, &office, p, "office, tiled");
        }
    }
    // The candidates and the maximum are the twin's, on the score map the reference computes.
    let img = grey_map(120, 90, 7);
    let exact = BaselineParams::default().exact().unwrap();
    for kind in BASELINES {
        let scores = baselines::cpu_scores(kind, &img, &exact);
        assert_eq!(
            tiled.baseline_candidates(kind, &img, &exact).unwrap(),
            ogm_corners::backend::reference::select_maxima::select_maxima(&scores, 120, 90)
        );
    }
}

#[test]
fn baselines_tiled_match_untiled() {
    let img = office_map(120, 80, 6).unwrap();
    let grey = grey_map(37, 29, 3);
    for tile in [(8, 6), (2, 2), (64, 16), (120, 10)] {
        let opts = GpuOptions {
            tile: Some(tile),
            ..GpuOptions::default()
        };
        let Some(mut gpu) = common::gpu_backend(opts) else {
            return;
        };
        assert_same_scores(&mut gpu, &img, "tiled office");
        assert!(gpu.stats().tiles > 1, "{tile:?} must tile");
        assert_same_scores(&mut gpu, &grey, "tiled grey");
    }
}

#[test]
fn baselines_with_emulated_int64_match() {
    let opts = GpuOptions {
        emulate_int64: true,
        ..GpuOptions::default()
    };
    let Some(mut gpu) = common::gpu_backend(opts) else {
        return;
    };
    assert!(!gpu.native_int64());
    // Grey maps reach the largest responses (strong gradients everywhere), where 64 bits matter.
    assert_same_scores(&mut gpu, &grey_map(97, 61, 9), "grey, emulated int64");
    assert_same_scores(
        &mut gpu,
        &office_map(200, 150, 2).unwrap(),
        "office, emulated int64",
    );
    let native = common::gpu_backend(GpuOptions::default()).unwrap();
    eprintln!("adapter native int64: {}", native.native_int64());
}

#[test]
fn baselines_on_every_real_map() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let Some(gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let mut gpu_det = ogm_corners::Detector::with_backend(Default::default(), Box::new(gpu));
    for p in common::maps::real_maps(&dir) {
        let map = OccupancyMap::load(&p).unwrap();
        for kind in BASELINES {
            let opts = ogm_corners::DetectOptions {
                detector: ogm_corners::DetectorKind::Baseline(kind),
                ..Default::default()
            };
            let want = ogm_corners::Detector::new(opts).detect(&map).unwrap();
            gpu_det.set_options(opts);
            let got = gpu_det.detect(&map).unwrap();
            assert!(
                got == want,
                "{} {kind:?}: GPU {} CPU {}",
                p.display(),
                got.keypoints.len(),
                want.keypoints.len()
            );
        }
    }
}

#[test]
fn baselines_on_a_map_over_the_binding_limit_are_tiled() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    // The structure tensor takes 16 bytes a pixel: 3000 x 3000 is over lavapipe's 128 MiB binding.
    let img = office_map(3000, 3000, 12).unwrap();
    assert_same_scores(&mut gpu, &img, "large office");
    let limit = gpu
        .adapter()
        .max_storage_buffer_binding_size
        .min(gpu.adapter().max_buffer_size);
    if img.len() as u64 * 16 > limit {
        assert!(gpu.stats().tiles > 1);
    }
}

#[test]
fn maps_stream_through_in_bands_under_a_byte_budget() {
    // Small budgets force many bands: the next band uploads while the current one runs, from the image's
    // own rows when the width is a multiple of four, through the staging copy otherwise.
    for (budget, w, h) in [
        (4096u64, 256u32, 300u32),
        (3000, 257, 211),
        (1 << 14, 1024, 97),
    ] {
        let opts = GpuOptions {
            max_tile_bytes: budget,
            ..GpuOptions::default()
        };
        let Some(mut gpu) = common::gpu_backend(opts) else {
            return;
        };
        let img = office_map(w, h, u64::from(w)).unwrap();
        assert_same(&mut gpu, &img, &Thresholds::default(), "banded office map");
        assert!(gpu.stats().tiles > 2, "{budget} bytes must split {w}x{h}");
        let img = common::random_map(w, h, u64::from(h));
        assert_same(&mut gpu, &img, &Thresholds::default(), "banded random map");
        assert!(gpu.upload_time(&img).unwrap() > std::time::Duration::ZERO);
    }
}

/// The coarsening kernel: the GPU's coarse maps equal the CPU twin's on random maps, angles and scales,
/// in one tile and split into many small ones.
#[test]
fn coarsening_matches_the_reference_at_every_angle_and_scale() {
    use ogm_corners::backend::reference::coarsen::coarsen;
    use ogm_corners::map::grid::RotatedGrid;
    for max_tile_bytes in [64 << 20, 700] {
        let Some(mut gpu) = common::gpu_backend(GpuOptions {
            max_tile_bytes,
            ..GpuOptions::default()
        }) else {
            return;
        };
        let classes = ClassTable::default();
        let mut rng = Rng::new(11);
        for seed in 0..12u64 {
            let (w, h) = (rng.range(1, 120), rng.range(1, 120));
            let img = common::random_map(w, h, seed);
            let deg = [0.0, 45.0, -45.0, 90.0, 17.3, -8.6, 33.0, 1.0][seed as usize % 8];
            let grid = RotatedGrid::new(w, h, deg).unwrap();
            let scales: Vec<u32> = if seed % 3 == 0 {
                (1..=15).collect()
            } else {
                vec![2, 3, 5, 8, 10]
            };
            // The default cell rule, or other shares (the kernel takes the thresholds as parameters).
            let rule = common::some_cell_rule(seed, &mut rng);
            let got = gpu.coarsen(&img, &classes, &grid, &scales, rule).unwrap();
            if max_tile_bytes == 700 && w * h > 4000 {
                assert!(gpu.stats().tiles > scales.len(), "{w}x{h} was not split");
            }
            for (&s, g) in scales.iter().zip(&got) {
                assert_eq!(
                    g,
                    &coarsen(&img, &classes, &grid, s, rule),
                    "{w}x{h} at {deg} degrees, scale {s}, tile budget {max_tile_bytes}, {rule:?}"
                );
            }
        }
    }
}

/// The whole robust detector: the GPU backend's keypoints equal the reference's.
#[test]
fn robust_keypoints_match_the_reference() {
    use ogm_corners::detect::robust::{self, RobustParams};
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    let mut maps: Vec<MapImage> = (0..3u64)
        .map(|s| common::turned_rooms(200, 14.0 * s as f64 - 9.0, s).0)
        .collect();
    maps.push(office_map(300, 220, 5).unwrap());
    maps.push(common::random_map(90, 70, 2));
    for (i, img) in maps.iter().enumerate() {
        let params = RobustParams::default();
        let want = robust::detect(&mut ReferenceBackend, img, &classes, &rules, &params).unwrap();
        let got = robust::detect(&mut gpu, img, &classes, &rules, &params).unwrap();
        assert!(!want.0.is_empty() || i == 4, "map {i} has corners");
        assert_eq!(got, want, "map {i}");
    }
}

/// The robust detector in tiles on the GPU (windows of the turned grid reading crops of the map): the
/// keypoints of the whole map on the CPU.
#[test]
fn robust_tiles_on_the_gpu_match_the_whole_map_on_the_cpu() {
    use ogm_corners::detect::robust::tiles::{detect_tiled, ImageReader, TilePlan};
    use ogm_corners::detect::robust::{self, RobustParams};
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    let img = common::turned_rooms(700, 23.0, 9).0;
    // Small scales, so that windows are crops of the map.
    let params = RobustParams {
        min_scale: 2,
        max_scale: 3,
        ..RobustParams::default()
    };
    let want = robust::detect(&mut ReferenceBackend, &img, &classes, &rules, &params).unwrap();
    let plan = TilePlan::with_tile(&params, 60).unwrap();
    // Windows smaller than the turned grid (about 900 samples a side here): crops of the map.
    assert!(plan.window_side() < 750, "{plan:?}");
    let got = detect_tiled(
        &mut gpu,
        &mut ImageReader::new(&img),
        &classes,
        &rules,
        &params,
        &plan,
    )
    .unwrap();
    assert!(want.0.len() >= 8, "{}", want.0.len());
    assert_eq!(got, want);
}

/// Random flags, points (some landing outside) and transforms (any angle; translations inside, far
/// outside and clamped; the identity) for the scoring kernel.
fn scoring_case(
    w: u32,
    h: u32,
    seed: u64,
) -> (
    ogm_corners::backend::reference::merge_score::ScoreTarget,
    Vec<[u32; 2]>,
    Vec<ogm_corners::backend::reference::merge_score::FixedRigid>,
) {
    use ogm_corners::backend::reference::merge_score::{FixedRigid, ScoreTarget, MAX_SCORE_SIDE};
    let mut rng = Rng::new(seed);
    let flags = (0..w * h).map(|_| rng.range(0, 256) as u8).collect();
    let target = ScoreTarget::new(w, h, flags).unwrap();
    let n = rng.range(1, 3000);
    let mut points: Vec<[u32; 2]> = (0..n)
        .map(|_| [rng.range(0, w + w / 4 + 2), rng.range(0, h + h / 4 + 2)])
        .collect();
    points.extend([
        [0, 0],
        [MAX_SCORE_SIDE - 1, MAX_SCORE_SIDE - 1],
        [w - 1, h - 1],
    ]);
    let mut transforms = vec![FixedRigid::new(0.0, 0.0, 0.0)];
    for k in 0..60 {
        let deg = f64::from(rng.range(0, 7200)) / 20.0 - 180.0;
        let span = f64::from(w.max(h)) * 1.5;
        let shift = |rng: &mut Rng| f64::from(rng.range(0, 10_000)) / 10_000.0 * 2.0 * span - span;
        let (tx, ty) = match k % 10 {
            8 => (1e6, -40_000.0),  // far outside, clamped
            9 => (-33_000.0, 70.5), // outside the largest map
            _ => (shift(&mut rng), shift(&mut rng)),
        };
        transforms.push(FixedRigid::new(deg, tx, ty));
    }
    transforms.extend([
        FixedRigid::new(90.0, f64::from(h), 0.0),
        FixedRigid::new(-45.0, 0.5, -0.5),
    ]);
    (target, points, transforms)
}

/// The scoring kernel: the GPU's counts equal the CPU twin's on random targets of many sizes, in one band
/// and in many small bands and point chunks.
#[test]
fn transform_scores_match_the_reference() {
    use ogm_corners::backend::reference::merge_score::score_transforms;
    let sizes = [
        (1, 1),
        (1, 7),
        (7, 1),
        (5, 3),
        (33, 17),
        (64, 63),
        (301, 1),
        (300, 200),
    ];
    for max_tile_bytes in [64 << 20, 700] {
        let Some(mut gpu) = common::gpu_backend(GpuOptions {
            max_tile_bytes,
            ..GpuOptions::default()
        }) else {
            return;
        };
        for (i, (w, h)) in sizes.into_iter().enumerate() {
            let (target, points, transforms) = scoring_case(w, h, i as u64);
            let want = score_transforms(&target, &points, &transforms).unwrap();
            let got = gpu.score_transforms(&target, &points, &transforms).unwrap();
            assert_eq!(got, want, "{w}x{h}, tile budget {max_tile_bytes}");
            assert!(want.iter().any(|c| c[0] > 0), "{w}x{h}: something lands");
            if max_tile_bytes == 700 && w * h > 700 {
                assert!(gpu.stats().tiles > 2, "{w}x{h} was not split");
            }
        }
        // Empty inputs and bad input: the same answers as the twin.
        let (target, points, transforms) = scoring_case(9, 9, 99);
        assert_eq!(
            gpu.score_transforms(&target, &[], &transforms).unwrap(),
            vec![[0; 3]; transforms.len()]
        );
        assert!(gpu
            .score_transforms(&target, &points, &[])
            .unwrap()
            .is_empty());
        let e = gpu
            .score_transforms(&target, &[[0, 1 << 15]], &transforms)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            score_transforms(&target, &[[0, 1 << 15]], &transforms)
                .unwrap_err()
                .to_string()
        );
    }
}

/// More transforms than one dispatch's rows of workgroups (65535 on most adapters): the host batches
/// them.
#[test]
fn transform_scores_are_batched_beyond_the_dispatch_limit() {
    use ogm_corners::backend::reference::merge_score::{score_transforms, FixedRigid, ScoreTarget};
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let mut rng = Rng::new(5);
    let target =
        ScoreTarget::new(16, 16, (0..256).map(|_| rng.range(0, 8) as u8).collect()).unwrap();
    let points: Vec<[u32; 2]> = (0..40)
        .map(|_| [rng.range(0, 20), rng.range(0, 20)])
        .collect();
    let transforms: Vec<FixedRigid> = (0..70_000)
        .map(|k| {
            FixedRigid::new(
                f64::from(k % 360),
                f64::from(k % 23) - 8.0,
                f64::from(k % 19) - 4.0,
            )
        })
        .collect();
    let want = score_transforms(&target, &points, &transforms).unwrap();
    let got = gpu.score_transforms(&target, &points, &transforms).unwrap();
    assert_eq!(got.len(), transforms.len());
    let first = got.iter().zip(&want).position(|(a, b)| a != b);
    assert_eq!(first, None, "first difference");
    if gpu.adapter().max_compute_workgroups_per_dimension < 70_000 {
        assert!(gpu.stats().tiles >= 2, "{:?}", gpu.stats());
    }
}

/// The merger with its candidates scored on the GPU gives exactly the CPU's alignment.
#[test]
fn merging_with_gpu_scoring_equals_the_cpu() {
    use ogm_corners::measure::synthetic::{synthetic_pair, SyntheticSpec};
    use ogm_corners::merge::pair::align::{align_prepared, align_prepared_with, Prepared};
    use ogm_corners::merge::MergeOptions;
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let source = OccupancyMap::from_image(common::cluttered_office(400, 300, 5));
    for seed in 1..3 {
        let spec = SyntheticSpec {
            overlap: 0.6,
            noise: 0.01,
        };
        let p = synthetic_pair(&source, &spec, seed).unwrap();
        let (a, b) = (Prepared::new(&p.a), Prepared::new(&p.b));
        let want = align_prepared(&a, &b, &MergeOptions::default()).unwrap();
        let got = align_prepared_with(&a, &b, &MergeOptions::default(), &mut gpu).unwrap();
        assert_eq!(got, want, "seed {seed}");
    }
}

#[test]
fn maps_wider_than_one_workgroup_and_tiles_at_its_edges() {
    // A workgroup spans 2048 pixels of a row: maps and tiles around that width, several columns of
    // workgroups, a one-keypoint scratch and windowed output.
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    for (w, h) in [
        (2049u32, 20u32),
        (2048, 3),
        (4200, 37),
        (6001, 5),
        (2080, 17),
        (4097, 1),
    ] {
        let img = common::random_map(w, h, u64::from(w + h));
        assert_same(&mut gpu, &img, &Thresholds::default(), "wide");
    }
    let img = common::random_map(5000, 45, 3);
    for tile in [(2048u32, 40u32), (2047, 40), (2046, 17), (2100, 15)] {
        let mut tiled = common::gpu_backend(GpuOptions {
            tile: Some(tile),
            initial_workgroup_scratch: 1,
            ..GpuOptions::default()
        })
        .unwrap();
        assert_same(&mut tiled, &img, &Thresholds::default(), "wide tiled");
    }
    let mut windowed = common::gpu_backend(GpuOptions {
        initial_keypoint_capacity: 3,
        max_keypoints_per_pass: Some(1001),
        initial_workgroup_scratch: 2,
        tile: Some((3000, 23)),
        ..GpuOptions::default()
    })
    .unwrap();
    let img = common::random_map(4500, 60, 7);
    assert_same(&mut windowed, &img, &Thresholds::default(), "wide windowed");
}

#[test]
fn more_candidates_than_the_first_list_buffer_holds() {
    // The candidate buffer starts at 4096 entries; a grey map has more, so the list grows and the scatter
    // runs again over the scores still on the device.
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let img = grey_map(400, 300, 5);
    let exact = BaselineParams::default().exact().unwrap();
    for kind in BASELINES {
        let scores = baselines::cpu_scores(kind, &img, &exact);
        let got = gpu.baseline_candidates(kind, &img, &exact).unwrap();
        if kind != Baseline::Trajkovic {
            assert!(got.0.len() > 4096, "{kind:?}: {} candidates", got.0.len());
        }
        assert_eq!(
            got,
            ogm_corners::backend::reference::select_maxima::select_maxima(&scores, 400, 300)
        );
    }
    for p in [
        BaselineParams::default(),
        BaselineParams {
            quality: 0.000_000_4, // rounds to 0 ppm
            min_distance: 0.0,
            ..BaselineParams::default()
        },
    ] {
        assert_same_keypoints(&mut gpu, &img, &p, "big grey");
    }
}
