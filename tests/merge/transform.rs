//! Rotating or mirroring a map by multiples of 90 degrees rotates or mirrors its keypoints exactly.

use crate::common;
use common::detect;
use ogm_corners::backend::rules::{mirror_code, rotate_code};
use ogm_corners::map::synthetic::{FREE, OCCUPIED, UNKNOWN};
use ogm_corners::{Keypoint, MapImage, RuleSet};
use proptest::prelude::*;

/// Turns the image 90 degrees clockwise: pixel (x, y) goes to (h - 1 - y, x).
fn rotate(img: &MapImage) -> MapImage {
    let (w, h) = (img.width(), img.height());
    let mut px = vec![0; img.len()];
    for y in 0..h {
        for x in 0..w {
            let (nx, ny) = (h - 1 - y, x);
            px[(ny * h + nx) as usize] = img.get(x, y);
        }
    }
    MapImage::new(h, w, px).unwrap()
}

/// Mirrors left to right: pixel (x, y) goes to (w - 1 - x, y).
fn mirror(img: &MapImage) -> MapImage {
    let (w, h) = (img.width(), img.height());
    let mut px = vec![0; img.len()];
    for y in 0..h {
        for x in 0..w {
            px[(y * w + w - 1 - x) as usize] = img.get(x, y);
        }
    }
    MapImage::new(w, h, px).unwrap()
}

fn rotate_kps(kps: &[Keypoint], h: u32) -> Vec<Keypoint> {
    let mut v: Vec<_> = kps
        .iter()
        .map(|k| Keypoint {
            x: h - 1 - k.y,
            y: k.x,
            rule: k.rule,
            code: rotate_code(k.code, 1),
            ..*k
        })
        .collect();
    v.sort();
    v
}

fn mirror_kps(kps: &[Keypoint], w: u32) -> Vec<Keypoint> {
    let mut v: Vec<_> = kps
        .iter()
        .map(|k| Keypoint {
            x: w - 1 - k.x,
            rule: k.rule,
            code: mirror_code(k.code),
            ..*k
        })
        .collect();
    v.sort();
    v
}

fn map_strategy() -> impl Strategy<Value = MapImage> {
    (1u32..24, 1u32..24).prop_flat_map(|(w, h)| {
        // Walls are common enough that every rule fires on some maps.
        proptest::collection::vec(
            prop_oneof![3 => Just(FREE), 2 => Just(OCCUPIED), 1 => Just(UNKNOWN)],
            (w * h) as usize,
        )
        .prop_map(move |px| MapImage::new(w, h, px).unwrap())
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn dihedral_transforms_move_keypoints_exactly(
        img in map_strategy(),
        mod2 in any::<bool>(),
        uao in any::<bool>(),
    ) {
        let set = if mod2 { RuleSet::PaperMod2 } else { RuleSet::Paper };
        let base = detect(&img, set, uao);
        // All four rotations, each also mirrored: the eight symmetries of the square.
        let mut cur = img.clone();
        let mut cur_kps = base.clone();
        for _ in 0..4 {
            let m = mirror(&cur);
            prop_assert_eq!(detect(&m, set, uao), mirror_kps(&cur_kps, cur.width()));
            let next = rotate(&cur);
            let next_kps = rotate_kps(&cur_kps, cur.height());
            prop_assert_eq!(detect(&next, set, uao), next_kps.clone());
            cur = next;
            cur_kps = next_kps;
        }
        prop_assert_eq!(cur, img);
        prop_assert_eq!(cur_kps, base);
    }
}

#[test]
fn random_maps_do_fire_every_rule() {
    // Guards the property test against passing on maps where nothing fires.
    let mut rng = ogm_corners::map::synthetic::Rng::new(7);
    let mut seen = [false; 7];
    for _ in 0..50 {
        let px = (0..24 * 24)
            .map(|_| match rng.range(0, 6) {
                0..=2 => FREE,
                3 | 4 => OCCUPIED,
                _ => UNKNOWN,
            })
            .collect();
        let img = MapImage::new(24, 24, px).unwrap();
        for k in detect(&img, RuleSet::Paper, false) {
            seen[k.rule as usize] = true;
        }
    }
    assert_eq!(&seen[4..], &[true, true, true]);
}
