//! Synthetic shapes with known corners: every detector finds each corner of a rectangular room, an
//! L-shaped room and a rotated rectangular room (a keypoint within a few pixels of each inner corner).

use ogm_corners::map::synthetic::{FREE, OCCUPIED, UNKNOWN};
use ogm_corners::{Baseline, DetectOptions, Detector, DetectorKind, MapImage, OccupancyMap};

/// A room: free inside `inside`, 2-px walls around it, unknown beyond. `inside(x, y)` on real coordinates.
fn room(w: u32, h: u32, inside: impl Fn(f64, f64) -> bool) -> MapImage {
    let mut px = vec![UNKNOWN; (w * h) as usize];
    let is_in = |x: i64, y: i64| inside(x as f64 + 0.5, y as f64 + 0.5);
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            px[(y * w as i64 + x) as usize] = if is_in(x, y) {
                FREE
            } else if (-2..=2).any(|dy| (-2..=2).any(|dx| is_in(x + dx, y + dy))) {
                OCCUPIED
            } else {
                UNKNOWN
            };
        }
    }
    MapImage::new(w, h, px).unwrap()
}

fn detectors() -> Vec<DetectorKind> {
    vec![
        DetectorKind::Ogm,
        DetectorKind::Baseline(Baseline::Harris),
        DetectorKind::Baseline(Baseline::ShiTomasi),
        DetectorKind::Baseline(Baseline::Trajkovic),
    ]
}

fn assert_finds(img: &MapImage, corners: &[(f64, f64)], tol: f64, what: &str) {
    assert_finds_with(img, corners, tol, what, &detectors());
}

fn assert_finds_with(
    img: &MapImage,
    corners: &[(f64, f64)],
    tol: f64,
    what: &str,
    kinds: &[DetectorKind],
) {
    for &kind in kinds {
        let opts = DetectOptions {
            detector: kind,
            ..DetectOptions::default()
        };
        let kps = Detector::new(opts)
            .detect(&OccupancyMap::from_image(img.clone()))
            .unwrap()
            .keypoints;
        for &(cx, cy) in corners {
            let hit = kps.iter().any(|k| {
                let (dx, dy) = (k.x as f64 + 0.5 - cx, k.y as f64 + 0.5 - cy);
                (dx * dx + dy * dy).sqrt() <= tol
            });
            assert!(
                hit,
                "{what}: {} found no keypoint within {tol} px of corner ({cx}, {cy}); found {:?}",
                kind.name(),
                kps.iter().map(|k| (k.x, k.y)).collect::<Vec<_>>()
            );
        }
    }
}

#[test]
fn rectangle_room() {
    let img = room(60, 40, |x, y| {
        (10.0..50.0).contains(&x) && (8.0..32.0).contains(&y)
    });
    assert_finds(
        &img,
        &[(10.0, 8.0), (50.0, 8.0), (10.0, 32.0), (50.0, 32.0)],
        3.0,
        "rectangle",
    );
}

#[test]
fn l_shaped_room() {
    // An L: the big rectangle minus its top-right quarter. Seen from inside, five corners are concave
    // and one, (35, 30), is reflex: the OGM detector, by design, fires only where free space meets a
    // concave wall corner; the baselines find all six.
    let img = room(70, 60, |x, y| {
        (10.0..60.0).contains(&x) && (10.0..50.0).contains(&y) && !(x >= 35.0 && y < 30.0)
    });
    let concave = [
        (10.0, 10.0),
        (35.0, 10.0),
        (60.0, 30.0),
        (60.0, 50.0),
        (10.0, 50.0),
    ];
    assert_finds(&img, &concave, 3.0, "L-shape");
    let reflex = [(35.0, 30.0)];
    assert_finds_with(
        &img,
        &reflex,
        3.0,
        "L-shape reflex corner",
        &detectors()[1..],
    );
}

#[test]
fn rotated_rectangle_room() {
    // A 40 x 24 rectangle turned by 30 degrees about (50, 50).
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let img = room(100, 100, |x, y| {
        let (dx, dy) = (x - 50.0, y - 50.0);
        let (u, v) = (c * dx + s * dy, -s * dx + c * dy);
        u.abs() < 20.0 && v.abs() < 12.0
    });
    let corners: Vec<(f64, f64)> = [(-20.0, -12.0), (20.0, -12.0), (20.0, 12.0), (-20.0, 12.0)]
        .iter()
        .map(|&(u, v)| (50.0 + c * u - s * v, 50.0 + s * u + c * v))
        .collect();
    assert_finds(&img, &corners, 4.0, "rotated rectangle");
}
