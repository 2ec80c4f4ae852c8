//! The repeatability metric: known transforms give the expected scores on synthetic maps.

use ogm_corners::map::synthetic::office_map;
use ogm_corners::measure::detection::{conditions, repeatability, score, Pair, Transform};
use ogm_corners::{Baseline, DetectOptions, Detector, DetectorKind, Keypoint};

fn ogm() -> Detector {
    Detector::new(DetectOptions::default())
}

#[test]
fn ogm_is_exactly_repeatable_under_turns_and_mirror() {
    // The rule table is closed under the eight symmetries of the square, so every keypoint survives.
    for (w, h) in [(300, 200), (201, 157)] {
        let map = office_map(w, h, 3).unwrap();
        for t in [
            Transform::Rot90(1),
            Transform::Rot90(2),
            Transform::Rot90(3),
            Transform::Mirror,
        ] {
            let pair = Pair::new(&map, t).unwrap();
            assert_eq!(
                repeatability(&mut ogm(), &pair, 0.0).unwrap(),
                Some(1.0),
                "{t:?} on {w}x{h}"
            );
        }
    }
}

#[test]
fn harris_is_exactly_repeatable_under_turns() {
    // Sobel and the Gaussian are symmetric, so the Harris response turns with the map.
    let map = office_map(240, 180, 5).unwrap();
    let opts = DetectOptions {
        detector: DetectorKind::Baseline(Baseline::Harris),
        ..Default::default()
    };
    for t in [Transform::Rot90(1), Transform::Rot90(2), Transform::Mirror] {
        let pair = Pair::new(&map, t).unwrap();
        assert_eq!(
            repeatability(&mut Detector::new(opts), &pair, 0.0).unwrap(),
            Some(1.0),
            "{t:?}"
        );
    }
}

#[test]
fn a_pure_integer_shift_is_exact_and_no_noise_changes_nothing() {
    let map = office_map(300, 200, 4).unwrap();
    let shift = Transform::Rotate {
        degrees: 0.0,
        tx: 17.0,
        ty: -9.0,
    };
    assert_eq!(
        repeatability(&mut ogm(), &Pair::new(&map, shift).unwrap(), 0.0).unwrap(),
        Some(1.0)
    );
    let quiet = Transform::Noise {
        speckle: 0.0,
        jitter: 0.0,
        seed: 1,
    };
    assert_eq!(
        repeatability(&mut ogm(), &Pair::new(&map, quiet).unwrap(), 0.0).unwrap(),
        Some(1.0)
    );
    // Heavy noise does cost keypoints.
    let loud = Transform::Noise {
        speckle: 0.05,
        jitter: 0.05,
        seed: 1,
    };
    let r = repeatability(&mut ogm(), &Pair::new(&map, loud).unwrap(), 2.0)
        .unwrap()
        .unwrap();
    assert!(r < 0.95, "{r}");
}

#[test]
fn the_metric_counts_matches_over_the_smaller_set_in_the_shared_region() {
    let map = office_map(100, 100, 1).unwrap();
    let pair = Pair::new(&map, Transform::Overlap { overlap: 0.5 }).unwrap();
    // The crops are 67 px wide, the second starting at x = 33.
    assert_eq!((pair.first.width(), pair.second.width()), (67, 67));
    let k = |x, y| Keypoint::ogm(x, y, 5, 0);
    // First map: (40, 10) is shared and (5, 10) is not; second map: (7, 10) is (40, 10) moved by -33,
    // (8, 30) has no partner, (60, 50) lies outside what the first crop saw.
    let a = [k(40, 10), k(5, 10), k(50, 50)];
    let b = [k(7, 10), k(8, 30), k(60, 50)];
    // Shared: a -> {(7,10), (17,50)}; b seen by first: {(7,10), (8,30)}; one match of min(2, 2).
    assert_eq!(score(&pair, &a, &b, 1.0), Some(0.5));
    assert_eq!(
        score(&pair, &a, &b[2..], 1.0),
        None,
        "nothing of b in the shared region"
    );
    // Tolerance reaches the near miss: (17, 50) vs nothing; (7,10) exact.
    assert_eq!(score(&pair, &a[..1], &b[..1], 0.0), Some(1.0));
}

#[test]
fn conditions_are_seeded() {
    for c in conditions() {
        assert_eq!(c.transform(300, 200, 9, 2), c.transform(300, 200, 9, 2));
    }
    let rot = conditions()
        .into_iter()
        .find(|c| c.name == "rotation")
        .unwrap();
    assert_ne!(rot.transform(300, 200, 9, 1), rot.transform(300, 200, 9, 2));
}
