//! The fast CPU baselines (`ogm_corners::backend::fast::baselines`, behind the default `--backend cpu`) against the
//! reference (`ogm_corners::backend::baselines::cpu_scores` then `select`): the same score maps and the same
//! keypoints, bit for bit, on tiny and odd sizes, noise, synthetic office maps, non-default parameters,
//! different band splits (thread counts), random inputs (proptest) and every shared real map.

use crate::common;
use ogm_corners::backend::baselines::{cpu_scores, select, Baseline, BaselineParams, ExactParams};
use ogm_corners::backend::fast::{baselines as fast, FastCpuBackend};
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::map::synthetic::{office_map, Rng};
use ogm_corners::{Backend, MapImage, OccupancyMap};
use proptest::prelude::*;

const KINDS: [Baseline; 3] = [Baseline::Harris, Baseline::ShiTomasi, Baseline::Trajkovic];

type Points = Vec<(u32, u32, i64)>;

fn reference_keypoints(kind: Baseline, img: &MapImage, params: &BaselineParams) -> Points {
    let scores = cpu_scores(kind, img, &params.exact().unwrap());
    select(kind, &scores, img.width(), img.height(), params)
}

fn fast_keypoints(kind: Baseline, img: &MapImage, params: &BaselineParams) -> Points {
    FastCpuBackend
        .baseline_keypoints(kind, img, params)
        .unwrap()
        .into_iter()
        .map(|k| (k.x, k.y, k.score))
        .collect()
}

/// A short account of where two lists first differ (whole lists of a big map would flood the log).
fn first_difference<T: PartialEq + std::fmt::Debug>(fast: &[T], reference: &[T]) -> String {
    let i = fast
        .iter()
        .zip(reference)
        .position(|(a, b)| a != b)
        .unwrap_or(fast.len().min(reference.len()));
    format!(
        "lengths {} (fast) vs {} (reference); first difference at {i}: {:?} vs {:?}",
        fast.len(),
        reference.len(),
        fast.get(i),
        reference.get(i)
    )
}

/// Score maps and keypoints of every kind agree on `img` with `params`.
fn assert_same(img: &MapImage, params: &BaselineParams, label: &str) {
    let exact = params.exact().unwrap();
    for kind in KINDS {
        let reference = cpu_scores(kind, img, &exact);
        let scores = fast::scores(kind, img, &exact);
        assert!(
            scores == reference,
            "{label} {kind:?}: score maps differ: {}",
            first_difference(&scores, &reference)
        );
        let expected = select(kind, &reference, img.width(), img.height(), params);
        let got = fast_keypoints(kind, img, params);
        assert!(
            got == expected,
            "{label} {kind:?} {params:?}: keypoints differ: {}",
            first_difference(&got, &expected)
        );
    }
}

/// Keypoints of every kind agree (the reference's score map is made once per kind).
fn assert_same_keypoints(img: &MapImage, params: &[BaselineParams], label: &str) {
    for kind in KINDS {
        let scores = cpu_scores(kind, img, &params[0].exact().unwrap());
        for p in params {
            assert_eq!(p.exact().unwrap(), params[0].exact().unwrap());
            let expected = select(kind, &scores, img.width(), img.height(), p);
            let got = fast_keypoints(kind, img, p);
            assert!(
                got == expected,
                "{label} {kind:?} {p:?}: keypoints differ: {}",
                first_difference(&got, &expected)
            );
        }
    }
}

/// Uniform noise: every grey level, steep gradients everywhere, many ties at 0.
fn noise(w: u32, h: u32, seed: u64) -> MapImage {
    let mut rng = Rng::new(seed);
    let px = (0..w * h).map(|_| rng.range(0, 256) as u8).collect();
    MapImage::new(w, h, px).unwrap()
}

/// Faint noise (four grey levels): small scores, so neighbours often differ by one or tie.
fn faint(w: u32, h: u32, seed: u64) -> MapImage {
    let mut rng = Rng::new(seed);
    let px = (0..w * h).map(|_| 100 + rng.range(0, 4) as u8).collect();
    MapImage::new(w, h, px).unwrap()
}

/// Map-like noise: blocks of the three map values with some speckle, so flat runs, steps and corners.
fn blocks(w: u32, h: u32, seed: u64) -> MapImage {
    let mut rng = Rng::new(seed);
    let values = [0u8, 205, 254];
    let cell: Vec<u8> = (0..64).map(|_| values[rng.range(0, 3) as usize]).collect();
    let px = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            if rng.chance(0.02) {
                values[rng.range(0, 3) as usize]
            } else {
                cell[((y / 5 % 8) * 8 + x / 7 % 8) as usize]
            }
        })
        .collect();
    MapImage::new(w, h, px).unwrap()
}

/// Parameter sets that change every part of the computation; all valid.
fn parameter_sets() -> Vec<BaselineParams> {
    let d = BaselineParams::default();
    vec![
        d,
        // Kernel [0, 256, 0] (no blur) and the widest kernel.
        BaselineParams { sigma: 0.2, ..d },
        BaselineParams { sigma: 100.0, ..d },
        BaselineParams { harris_k: 0.0, ..d },
        BaselineParams {
            harris_k: 0.25,
            ..d
        },
        BaselineParams {
            harris_k: 0.123,
            ..d
        },
        // quality_ppm 0 (threshold at 0) and 10^6 (nothing passes).
        BaselineParams { quality: 1e-7, ..d },
        BaselineParams { quality: 0.5, ..d },
        BaselineParams {
            quality: 0.9999999,
            ..d
        },
        BaselineParams {
            min_distance: 0.0,
            ..d
        },
        BaselineParams {
            min_distance: 1.0,
            ..d
        },
        BaselineParams {
            min_distance: 2.5,
            ..d
        },
        BaselineParams {
            min_distance: 11.0,
            ..d
        },
        BaselineParams {
            min_distance: 1e6,
            ..d
        },
        BaselineParams {
            max_corners: Some(0),
            ..d
        },
        BaselineParams {
            max_corners: Some(1),
            ..d
        },
        BaselineParams {
            max_corners: Some(7),
            min_distance: 0.0,
            ..d
        },
        BaselineParams { t1: 0, t2: 0, ..d },
        BaselineParams {
            t1: 500,
            t2: 3000,
            ..d
        },
        BaselineParams {
            t1: 1 << 20,
            t2: 1 << 20,
            ..d
        },
    ]
}

#[test]
fn tiny_and_odd_sizes() {
    let sizes = (1..=9).flat_map(|w| (1..=9).map(move |h| (w, h))).chain([
        (1, 70),
        (70, 1),
        (2, 41),
        (41, 2),
        (3, 35),
        (35, 3),
        (17, 33),
        (33, 65),
        (64, 97),
    ]);
    let d = BaselineParams::default();
    let low = BaselineParams {
        quality: 1e-7,
        min_distance: 0.0,
        t1: 0,
        t2: 0,
        ..d
    };
    for (w, h) in sizes {
        let seed = u64::from(w * 100 + h);
        for (name, img) in [
            ("noise", noise(w, h, seed)),
            ("faint", faint(w, h, seed)),
            ("blocks", blocks(w, h, seed)),
        ] {
            assert_same(&img, &d, &format!("{name} {w}x{h}"));
            assert_same(&img, &low, &format!("{name} {w}x{h} low thresholds"));
        }
        for v in [0u8, 205, 255] {
            assert_same(
                &MapImage::filled(w, h, v).unwrap(),
                &d,
                &format!("flat {v} {w}x{h}"),
            );
        }
    }
}

#[test]
fn noise_and_blocks_with_every_parameter_set() {
    for (name, img) in [
        ("noise", noise(61, 150, 7)),
        ("faint", faint(80, 70, 9)),
        ("blocks", blocks(150, 97, 8)),
    ] {
        for p in parameter_sets() {
            assert_same(&img, &p, name);
        }
    }
}

#[test]
fn office_maps() {
    let d = BaselineParams::default();
    for (w, h, seed) in [(64, 48, 1), (301, 203, 2), (512, 256, 3)] {
        let img = office_map(w, h, seed).unwrap();
        assert_same(&img, &d, &format!("office {w}x{h}"));
    }
    let img = office_map(400, 300, 4).unwrap();
    let sets: Vec<BaselineParams> = parameter_sets()
        .into_iter()
        .filter(|p| p.exact().unwrap() == d.exact().unwrap())
        .collect();
    assert_same_keypoints(&img, &sets, "office 400x300");
}

#[test]
fn any_band_split_gives_the_same_result() {
    // Bands depend on the number of threads; rows near band edges need the neighbouring bands' rows.
    let img = blocks(97, 301, 11);
    let office = office_map(128, 260, 5).unwrap();
    let d = BaselineParams::default();
    let exact = d.exact().unwrap();
    let expected: Vec<(Vec<i64>, Points, Points)> = KINDS
        .iter()
        .map(|&k| {
            (
                cpu_scores(k, &img, &exact),
                reference_keypoints(k, &img, &d),
                reference_keypoints(k, &office, &d),
            )
        })
        .collect();
    for threads in [1, 3, 8] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            for (kind, (scores, points, office_points)) in KINDS.iter().zip(&expected) {
                assert!(
                    fast::scores(*kind, &img, &exact) == *scores,
                    "{threads} threads {kind:?}"
                );
                assert_eq!(
                    fast_keypoints(*kind, &img, &d),
                    *points,
                    "{threads} threads {kind:?}"
                );
                assert_eq!(
                    fast_keypoints(*kind, &office, &d),
                    *office_points,
                    "{threads} threads {kind:?} office"
                );
            }
        });
    }
}

#[test]
fn the_backends_agree_through_the_backend_trait() {
    let img = office_map(333, 222, 9).unwrap();
    let d = BaselineParams::default();
    let exact = d.exact().unwrap();
    for kind in KINDS {
        assert_eq!(
            FastCpuBackend.baseline_keypoints(kind, &img, &d).unwrap(),
            ReferenceBackend.baseline_keypoints(kind, &img, &d).unwrap(),
            "{kind:?}"
        );
        assert!(
            FastCpuBackend.baseline_scores(kind, &img, &exact).unwrap()
                == ReferenceBackend
                    .baseline_scores(kind, &img, &exact)
                    .unwrap(),
            "{kind:?}"
        );
    }
}

#[test]
fn invalid_parameters_are_refused_like_the_reference() {
    let img = blocks(20, 20, 1);
    let d = BaselineParams::default();
    for p in [
        BaselineParams { sigma: 0.0, ..d },
        BaselineParams {
            harris_k: 0.0005,
            ..d
        },
        BaselineParams { quality: 1.0, ..d },
        BaselineParams {
            min_distance: -1.0,
            ..d
        },
        BaselineParams {
            t2: (1 << 20) + 1,
            ..d
        },
    ] {
        assert!(p.exact().is_err());
        for kind in KINDS {
            assert!(
                FastCpuBackend.baseline_keypoints(kind, &img, &p).is_err(),
                "{kind:?} {p:?}"
            );
        }
    }
}

#[test]
fn hand_made_exact_parameters_match_too() {
    // `scores` takes any ExactParams: kernels that `exact` never makes go through the reference, and
    // huge thresholds must not wrap.
    let img = noise(40, 37, 3);
    let d = BaselineParams::default().exact().unwrap();
    for p in [
        ExactParams {
            blur: [100, 100, 100],
            ..d
        },
        ExactParams {
            blur: [0, 1, 0],
            ..d
        },
        ExactParams {
            blur: [10, 200, 30],
            ..d
        },
        ExactParams { kn: 1, kd: 3, ..d },
        ExactParams {
            t1: u32::MAX,
            t2: 5,
            ..d
        },
        ExactParams {
            t1: 5,
            t2: u32::MAX,
            ..d
        },
        ExactParams { t1: 0, t2: 0, ..d },
    ] {
        for kind in KINDS {
            assert!(
                fast::scores(kind, &img, &p) == cpu_scores(kind, &img, &p),
                "{kind:?} {p:?}"
            );
        }
    }
}

#[test]
fn every_shared_map() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let maps = common::maps::real_maps(&dir);
    assert!(
        maps.len() >= 20,
        "expected the shared maps, found {}",
        maps.len()
    );
    let d = BaselineParams::default();
    let mut total = 0;
    for p in &maps {
        let img = OccupancyMap::load(p)
            .unwrap_or_else(|e| panic!("{e}"))
            .image;
        let name = p.strip_prefix(&dir).unwrap().display().to_string();
        for kind in KINDS {
            let expected = reference_keypoints(kind, &img, &d);
            let got = fast_keypoints(kind, &img, &d);
            assert!(
                got == expected,
                "{name} {kind:?}: keypoints differ: {}",
                first_difference(&got, &expected)
            );
            total += got.len();
        }
        // Whole score maps on a crop (the reference is slow on whole maps in the test profile).
        let (w, h) = (img.width().min(300), img.height().min(200));
        let (x0, y0) = ((img.width() - w) / 2, (img.height() - h) / 2);
        let crop = (y0..y0 + h)
            .flat_map(|y| (x0..x0 + w).map(move |x| (x, y)))
            .map(|(x, y)| img.get(x, y))
            .collect();
        let crop = MapImage::new(w, h, crop).unwrap();
        let exact = d.exact().unwrap();
        for kind in KINDS {
            assert!(
                fast::scores(kind, &crop, &exact) == cpu_scores(kind, &crop, &exact),
                "{name} {kind:?}: score maps of the centre crop differ"
            );
        }
    }
    assert!(
        total > 10_000,
        "the shared maps have many baseline keypoints: {total}"
    );
}

/// A random small image: arbitrary bytes, faint noise, or map values in blocks (flat runs, steps, ties).
fn image_strategy() -> impl Strategy<Value = MapImage> {
    (1u32..40, 1u32..90, any::<u64>(), 0..3).prop_map(|(w, h, seed, style)| match style {
        0 => noise(w, h, seed),
        1 => faint(w, h, seed),
        _ => blocks(w, h, seed),
    })
}

fn params_strategy() -> impl Strategy<Value = BaselineParams> {
    (
        prop::sample::select(vec![0.2, 0.5, 0.8, 1.0, 1.7, 3.0, 100.0]),
        0u32..=250,
        prop::sample::select(vec![1e-7, 1e-4, 0.01, 0.05, 0.3, 0.9, 0.9999999]),
        prop_oneof![Just(0.0), Just(1.0), 0.0f64..12.0],
        prop::option::of(0usize..30),
        0u32..80_000,
        0u32..80_000,
    )
        .prop_map(
            |(sigma, k, quality, min_distance, max_corners, t1, t2)| BaselineParams {
                sigma,
                harris_k: f64::from(k) / 1000.0,
                quality,
                min_distance,
                max_corners,
                t1,
                t2,
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_images_and_parameters(img in image_strategy(), p in params_strategy()) {
        let exact = p.exact().unwrap();
        for kind in KINDS {
            let reference = cpu_scores(kind, &img, &exact);
            prop_assert_eq!(fast::scores(kind, &img, &exact), reference.clone(), "{:?}", kind);
            let expected = select(kind, &reference, img.width(), img.height(), &p);
            prop_assert_eq!(fast_keypoints(kind, &img, &p), expected, "{:?}", kind);
        }
    }
}
