//! The robust OGM detector: it finds the corners of turned, jagged rooms the paper's detector misses,
//! the fast path and the reference agree bit for bit, and its options are checked.

use crate::common;
use ogm_corners::backend::fast::FastCpuBackend;
use ogm_corners::backend::reference::coarsen::{self, CellRule};
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::detect::robust::{self, orientation, Anchor, RobustParams};
use ogm_corners::map::grid::RotatedGrid;
use ogm_corners::map::synthetic::Rng;
use ogm_corners::{
    Backend, ClassTable, DetectOptions, Detector, DetectorKind, Keypoint, MapImage, OccupancyMap,
    RuleSet, RuleTable,
};

fn robust_options() -> DetectOptions {
    DetectOptions {
        detector: DetectorKind::OgmRobust,
        ..DetectOptions::default()
    }
}

/// Share of `truth` with a keypoint within `radius` px.
fn recall(truth: &[(f64, f64)], kps: &[Keypoint], radius: f64) -> f64 {
    let hit = truth
        .iter()
        .filter(|t| {
            kps.iter()
                .any(|k| (f64::from(k.x) - t.0).hypot(f64::from(k.y) - t.1) <= radius)
        })
        .count();
    hit as f64 / truth.len() as f64
}

#[test]
fn turned_jagged_rooms_have_their_corners_found_and_their_angle_estimated() {
    for (i, deg) in [0.0, 7.0, 23.0, 38.0, -15.0, 61.0].into_iter().enumerate() {
        let (img, truth) = common::turned_rooms(300, deg, i as u64);
        let angle = orientation::dominant_angle(&img, &ClassTable::default());
        let want = (deg + 45.0f64).rem_euclid(90.0) - 45.0;
        assert!((angle - want).abs() <= 0.5, "{deg}: estimated {angle}");
        let map = OccupancyMap::from_image(img);
        let found = Detector::new(robust_options()).detect(&map).unwrap();
        let paper = Detector::new(DetectOptions::default())
            .detect(&map)
            .unwrap();
        let (r, rp) = (
            recall(&truth, &found.keypoints, 4.0),
            recall(&truth, &paper.keypoints, 4.0),
        );
        // Nine corners (two T-junctions): every one found, few extras (9 keypoints when measured).
        assert!(r >= 0.99, "{deg}: robust recall {r}");
        assert!(
            found.keypoints.len() <= truth.len() + 4,
            "{deg}: {} keypoints for {} corners",
            found.keypoints.len(),
            truth.len()
        );
        // The paper's detector misses some on every one (44-89% when measured).
        assert!(rp < r, "{deg}: the paper's detector found as many ({rp})");
        assert!(
            found.keypoints.windows(2).all(|w| w[0] < w[1]),
            "(y, x) order"
        );
        assert!(found.keypoints.iter().all(|k| k.score > 0 && k.scale >= 2));
        let info = found.robust.unwrap();
        assert!((info.angle - angle).abs() < 0.1);
    }
}

#[test]
fn the_fast_coarsening_equals_the_reference_on_random_maps_angles_and_scales() {
    let classes = ClassTable::default();
    let mut rng = Rng::new(7);
    for seed in 0..40u64 {
        let (w, h) = (rng.range(1, 90), rng.range(1, 90));
        let img = common::random_map(w, h, seed);
        let deg = match seed % 4 {
            0 => 0.0,
            1 => 90.0 * (rng.range(0, 1000) as f64 / 1000.0) - 45.0,
            2 => 45.0,
            _ => -(rng.range(0, 4500) as f64) / 100.0,
        };
        let grid = RotatedGrid::new(w, h, deg).unwrap();
        let scales: Vec<u32> = (1..=15).filter(|_| rng.chance(0.4)).collect();
        let rule = common::some_cell_rule(seed, &mut rng);
        let got = FastCpuBackend
            .coarsen(&img, &classes, &grid, &scales, rule)
            .unwrap();
        for (&s, g) in scales.iter().zip(&got) {
            let want = coarsen::coarsen(&img, &classes, &grid, s, rule);
            assert_eq!(g, &want, "{w}x{h} at {deg} degrees, scale {s}, {rule:?}");
        }
    }
}

#[test]
fn the_fast_path_and_the_reference_find_the_same_robust_keypoints() {
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    let mut maps: Vec<MapImage> = (0..6u64)
        .map(|s| common::turned_rooms(160 + 20 * s as u32, 11.0 * s as f64 - 20.0, s).0)
        .collect();
    maps.extend((0..6u64).map(|s| common::random_map(50 + 7 * s as u32, 40, s)));
    for (i, img) in maps.iter().enumerate() {
        for params in [
            RobustParams::default(),
            RobustParams {
                min_scale: 1,
                max_scale: 15,
                nms_radius: 0,
                min_strength: 0,
                convex: true,
                angle: Some(12.5),
                // Off the map, and not on a pixel: the reference and the fast path agree anywhere.
                anchor: Anchor::Point(-31.5, 207.25),
                cells: CellRule {
                    occupied_pct: 7,
                    free_pct: 55,
                },
                wall_gap: 3,
            },
        ] {
            let want =
                robust::detect(&mut ReferenceBackend, img, &classes, &rules, &params).unwrap();
            let got = robust::detect(&mut FastCpuBackend, img, &classes, &rules, &params).unwrap();
            assert_eq!(got, want, "map {i}, {params:?}");
        }
    }
}

#[test]
fn max_corners_keeps_the_strongest_and_the_paper_detector_refuses_a_cap_it_exceeds() {
    let (img, _) = common::turned_rooms(240, 13.0, 3);
    let map = OccupancyMap::from_image(img);
    let all = Detector::new(robust_options())
        .detect(&map)
        .unwrap()
        .keypoints;
    assert!(all.len() > 5);
    let capped = Detector::new(DetectOptions {
        max_corners: Some(5),
        ..robust_options()
    })
    .detect(&map)
    .unwrap()
    .keypoints;
    assert_eq!(capped.len(), 5);
    let mut scores: Vec<i64> = all.iter().map(|k| k.score).collect();
    scores.sort_unstable_by(|a, b| b.cmp(a));
    let weakest_kept = capped.iter().map(|k| k.score).min().unwrap();
    assert_eq!(weakest_kept, scores[4]);
    assert!(capped.iter().all(|k| all.contains(k)));
    let paper = Detector::new(DetectOptions {
        max_corners: Some(1),
        ..DetectOptions::default()
    })
    .detect(&map);
    let err = paper.unwrap_err();
    assert_eq!(err.exit_code(), 2);
    assert!(err.to_string().contains("no strength"), "{err}");
}

#[test]
fn bad_robust_options_are_refused_with_input_errors() {
    let map = OccupancyMap::from_image(common::turned_rooms(60, 0.0, 1).0);
    for params in [
        RobustParams {
            min_scale: 0,
            ..RobustParams::default()
        },
        RobustParams {
            min_scale: 5,
            max_scale: 4,
            ..RobustParams::default()
        },
        RobustParams {
            max_scale: 17,
            ..RobustParams::default()
        },
        RobustParams {
            angle: Some(f64::NAN),
            ..RobustParams::default()
        },
        RobustParams {
            nms_radius: 5000,
            ..RobustParams::default()
        },
        RobustParams {
            cells: CellRule {
                occupied_pct: 0,
                free_pct: 40,
            },
            ..RobustParams::default()
        },
        RobustParams {
            cells: CellRule {
                occupied_pct: 15,
                free_pct: 101,
            },
            ..RobustParams::default()
        },
        RobustParams {
            wall_gap: 65,
            ..RobustParams::default()
        },
        RobustParams {
            anchor: Anchor::Point(f64::NAN, 3.0),
            ..RobustParams::default()
        },
        RobustParams {
            anchor: Anchor::Point(0.0, -2e6),
            ..RobustParams::default()
        },
    ] {
        let err = Detector::new(DetectOptions {
            robust: params,
            ..robust_options()
        })
        .detect(&map)
        .unwrap_err();
        assert_eq!(err.exit_code(), 2, "{params:?}: {err}");
    }
}

#[test]
fn tiny_and_empty_maps_give_no_keypoints_and_no_panic() {
    for (w, h, v) in [
        (1, 1, 254),
        (1, 7, 0),
        (9, 1, 205),
        (3, 3, 0),
        (40, 40, 254),
    ] {
        let map = OccupancyMap::from_image(MapImage::filled(w, h, v).unwrap());
        let found = Detector::new(robust_options()).detect(&map).unwrap();
        assert!(found.keypoints.is_empty(), "{w}x{h} of {v}");
    }
}

/// The phase-free coarsening against its oracle: tile (a, b) of a scale's coarse map is the fixed block
/// grid's coarse map of the same grid moved back by (a, b) samples, for every phase.
#[test]
fn every_phase_tile_is_the_block_coarse_map_of_the_shifted_grid() {
    let classes = ClassTable::default();
    let mut rng = Rng::new(3);
    for seed in 0..8u64 {
        let (w, h) = (rng.range(5, 60), rng.range(5, 60));
        let img = common::random_map(w, h, seed);
        let deg = [0.0, 21.7, -45.0, 8.3][seed as usize % 4];
        let grid = RotatedGrid::new(w, h, deg).unwrap();
        for s in [1, 2, 3, 6, 15] {
            let map = coarsen::coarsen(&img, &classes, &grid, s, CellRule::default());
            let m = coarsen::Mosaic::new(&grid, s);
            assert_eq!((map.width(), map.height()), m.size());
            for b in 0..s {
                for a in 0..s {
                    let (a, b) = (a as i32, b as i32);
                    let moved = RotatedGrid {
                        ox: grid.ox - a * grid.cos + b * grid.sin,
                        oy: grid.oy - a * grid.sin - b * grid.cos,
                        width: m.tile_w * s,
                        height: m.tile_h * s,
                        ..grid
                    };
                    let want =
                        coarsen::coarsen_blocks(&img, &classes, &moved, s, CellRule::default());
                    let (x0, y0) = (a as u32 * (m.tile_w + 1), b as u32 * (m.tile_h + 1));
                    for v in 0..m.tile_h {
                        for u in 0..m.tile_w {
                            assert_eq!(
                                map.get(x0 + u, y0 + v),
                                want.get(u, v),
                                "{w}x{h} at {deg}, scale {s}, phase ({a}, {b}), cell ({u}, {v})"
                            );
                        }
                    }
                    // The gutters are unknown, so no 3 x 3 neighbourhood joins two phases.
                    assert_eq!(map.get(x0 + m.tile_w, y0), coarsen::UNKNOWN);
                    assert_eq!(map.get(x0, y0 + m.tile_h), coarsen::UNKNOWN);
                }
            }
        }
    }
}

/// The robust keypoints of `img` with the angle estimated.
fn robust_keypoints(img: &MapImage) -> Vec<Keypoint> {
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    let params = RobustParams::default();
    robust::detect(&mut FastCpuBackend, img, &classes, &rules, &params)
        .unwrap()
        .0
}

/// `kps` of a `w` x `h` map as positions in the map turned 90 degrees clockwise `k` times (then mirrored
/// left to right when `flip`), as `ogm_corners::measure::detection::{rotate90, mirror}` turn the map.
fn moved(kps: &[Keypoint], w: u32, h: u32, k: u32, flip: bool) -> Vec<(u32, u32)> {
    let mut out: Vec<(u32, u32)> = kps
        .iter()
        .map(|kp| {
            let (mut x, mut y, mut hh) = (kp.x, kp.y, h);
            let mut ww = w;
            for _ in 0..k {
                (x, y) = (hh - 1 - y, x);
                (ww, hh) = (hh, ww);
            }
            if flip {
                x = ww - 1 - x;
            }
            (x, y)
        })
        .collect();
    out.sort_unstable();
    out
}

fn positions(kps: &[Keypoint]) -> Vec<(u32, u32)> {
    let mut out: Vec<(u32, u32)> = kps.iter().map(|k| (k.x, k.y)).collect();
    out.sort_unstable();
    out
}

/// Exact repeatability under the map's symmetries: a quarter turn, a half turn, three quarters and a
/// mirror of the map give the turned keypoints, every one (the angle estimate, the grid's sampling and
/// rounding, the phase-free cells and the tie-breaks are all symmetric about the map's centre).
#[test]
fn quarter_turns_and_mirrors_give_exactly_the_turned_keypoints() {
    use ogm_corners::measure::detection::{mirror, rotate90};
    // (name, map, whether it must have corners: some real maps have none at the default)
    let mut maps: Vec<(String, MapImage, bool)> = (0..4u64)
        .map(|s| {
            let (w, h) = (230 + 9 * s as u32, 200 + 13 * s as u32);
            (format!("office {s}"), common::floor_plan(w, h, s), true)
        })
        .collect();
    maps.extend((0..3u64).map(|s| {
        let deg = 17.0 * s as f64 - 21.0;
        (
            format!("rooms at {deg}"),
            common::turned_rooms(211, deg, s).0,
            true,
        )
    }));
    if let Some(dir) = common::shared_maps() {
        for p in common::maps::real_maps(&dir).into_iter().take(8) {
            let map = OccupancyMap::load(&p).unwrap();
            maps.push((p.display().to_string(), map.image, false));
        }
    }
    let mut real_corners = 0;
    for (name, img, must) in &maps {
        let (w, h) = (img.width(), img.height());
        let base = robust_keypoints(img);
        assert!(!*must || !base.is_empty(), "{name} has corners");
        real_corners += if *must { 0 } else { base.len() };
        let mut turned = img.clone();
        for k in 1..4 {
            turned = rotate90(&turned);
            assert_eq!(
                positions(&robust_keypoints(&turned)),
                moved(&base, w, h, k, false),
                "{name} turned {k} quarter(s)"
            );
        }
        assert_eq!(
            positions(&robust_keypoints(&mirror(img))),
            moved(&base, w, h, 0, true),
            "{name} mirrored"
        );
    }
    // The real maps, when present, bring corners of their own to the check.
    assert!(maps.len() == 7 || real_corners > 20, "{real_corners}");
}

/// The robust keypoints of a shared map (`rel` under the shared maps' folder) read with `thresholds`
/// (the file's own when `None`) and `min_strength`.
fn shared_map_keypoints(
    dir: &std::path::Path,
    rel: &str,
    thresholds: Option<ogm_corners::Thresholds>,
    min_strength: u32,
) -> Vec<Keypoint> {
    let path = dir.join(rel);
    let mut map = OccupancyMap::load(&path)
        .unwrap_or_else(|e| panic!("{} is part of the shared maps: {e}", path.display()));
    if let Some(t) = thresholds {
        map.thresholds = t;
    }
    let mut options = robust_options();
    options.robust.min_strength = min_strength;
    Detector::new(options).detect(&map).unwrap().keypoints
}

/// A failure case: the Willow Garage floor is an anti-aliased drawing, its walls mostly greys between the
/// ROS thresholds (unknown) fringed by light greys (free), so a wall is a broken line of occupied pixels and
/// a dozen rooms give a handful of keypoints. The cause is the reading, not the detector: read with an
/// occupied threshold that makes the greys walls (0.25: values below 191), the same floor gives many times
/// more. The fix for such maps is their yaml's `occupied_thresh`.
#[test]
fn grey_walls_read_as_unknown_give_few_corners_until_the_threshold_makes_them_walls() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let rel = "navigation_tutorials/navigation_stage/stage_config/maps/willow-full.pgm";
    let ros = shared_map_keypoints(&dir, rel, None, RobustParams::default().min_strength);
    let greys_as_walls = ogm_corners::Thresholds {
        occupied_thresh: 0.25,
        ..Default::default()
    };
    let walls = shared_map_keypoints(
        &dir,
        rel,
        Some(greys_as_walls),
        RobustParams::default().min_strength,
    );
    eprintln!(
        "willow-full: {} keypoints at the ROS thresholds, {} with the greys read as walls",
        ros.len(),
        walls.len()
    );
    assert!(ros.len() < 20, "{}", ros.len());
    assert!(
        walls.len() >= 100 && walls.len() >= 8 * ros.len(),
        "{} against {}",
        walls.len(),
        ros.len()
    );
}

/// A failure case: the TurtleBot3 world is a hexagon, its corners 120 degrees. The grid turns to one wall
/// direction; the other two cross it at 60 degrees, so at every scale their walls are staircases whose
/// straight runs along a row or column are one cell long, and a corner's strength (its shorter wall's
/// length) is a single cell: below the default minimum of 12 px at every scale. No keypoint at the default;
/// with `--min-strength 1` the detector fires at the corners, each with a one-cell wall.
#[test]
fn a_hexagon_world_has_no_right_angle_and_gives_no_keypoint_at_the_default() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let rel = "turtlebot3/turtlebot3_navigation2/map/map.yaml";
    let default = shared_map_keypoints(&dir, rel, None, RobustParams::default().min_strength);
    assert!(default.is_empty(), "{default:?}");
    let all = shared_map_keypoints(&dir, rel, None, 1);
    let concave: Vec<&Keypoint> = all.iter().filter(|k| !k.convex).collect();
    assert!(concave.len() >= 6, "{all:?}");
    // Every concave corner's wall is one cell: its strength is its scale.
    assert!(
        concave.iter().all(|k| k.score == i64::from(k.scale)),
        "{concave:?}"
    );
    assert!(all
        .iter()
        .all(|k| k.score < i64::from(RobustParams::default().min_strength)));
}

/// `got` is `want`, or the first difference is shown (not thousands of keypoints).
fn same(got: &[Keypoint], want: &[Keypoint], what: &str) {
    let first = got.iter().zip(want).position(|(a, b)| a != b);
    assert!(
        got.len() == want.len() && first.is_none(),
        "{what}: {} keypoints against {}, first difference at {first:?}: {:?} against {:?}",
        got.len(),
        want.len(),
        first.map(|i| got[i]),
        first.map(|i| want[i]),
    );
}

/// `img`'s pixels from column `x0` and row `y0`, `w` x `h` of them, unknown where `img` has none (a crop,
/// or with negative offsets the map grown at its edges).
fn reframed(img: &MapImage, x0: i64, y0: i64, w: u32, h: u32) -> MapImage {
    let mut px = vec![205u8; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let (sx, sy) = (i64::from(x) + x0, i64::from(y) + y0);
            if sx >= 0 && sy >= 0 && sx < i64::from(img.width()) && sy < i64::from(img.height()) {
                px[(y * w + x) as usize] = img.get(sx as u32, sy as u32);
            }
        }
    }
    MapImage::new(w, h, px).unwrap()
}

/// The map's keypoints with its world frame: 5 cm pixels, the lower-left corner of its pixel
/// (-x0, h0 - 1 - y0) of the first map at world (1, -2) m, as a yaml's origin moves when a map is cropped
/// or grows.
fn keypoints_in_frame(
    img: &MapImage,
    x0: i64,
    bottom: i64,
    params: &RobustParams,
) -> Vec<Keypoint> {
    detect_in_frame(img, x0, bottom, params).keypoints
}

/// [`keypoints_in_frame`]'s whole detection.
fn detect_in_frame(
    img: &MapImage,
    x0: i64,
    bottom: i64,
    params: &RobustParams,
) -> ogm_corners::Detection {
    let mut map = OccupancyMap::from_image(img.clone());
    map.georef = Some(ogm_corners::GeoRef {
        resolution: 0.05,
        origin: [1.0 + 0.05 * x0 as f64, -2.0 + 0.05 * bottom as f64, 0.0],
    });
    Detector::new(DetectOptions {
        robust: *params,
        ..robust_options()
    })
    .detect(&map)
    .unwrap()
}

/// A SLAM map grows at its edges and is cropped, and its yaml's origin moves with them: the grid anchored
/// at the world frame's origin samples the same pixels, scores the same boxes and breaks ties the same
/// way, so for the same angle the keypoints are the map's, bit for bit, wherever both maps see a corner's
/// walls. Anchored at each map's centre, they are not.
#[test]
fn a_grown_or_cropped_map_in_its_world_frame_keeps_its_keypoints() {
    use ogm_corners::measure::detection::{Pair, Transform};
    let plan = common::floor_plan(1200, 800, 7);
    let turned = Pair::new(
        &plan,
        Transform::Rotate {
            degrees: 23.0,
            tx: 0.0,
            ty: 0.0,
        },
    )
    .unwrap()
    .second;
    let (w, h) = (turned.width(), turned.height());
    let estimated = robust::detect(
        &mut FastCpuBackend,
        &turned,
        &ClassTable::default(),
        &RuleTable::new(RuleSet::Paper),
        &RobustParams::default(),
    )
    .unwrap()
    .1
    .angle;
    let params = RobustParams {
        max_scale: 4,
        angle: Some(estimated),
        ..RobustParams::default()
    };
    let base = keypoints_in_frame(&turned, 0, 0, &params);
    assert!(base.len() >= 30, "{} keypoints", base.len());
    let shifted = |kps: &[Keypoint], dx: i64, dy: i64| -> Vec<Keypoint> {
        kps.iter()
            .map(|k| Keypoint {
                x: (i64::from(k.x) + dx) as u32,
                y: (i64::from(k.y) + dy) as u32,
                ..*k
            })
            .collect()
    };
    // Grown: 37 unknown columns on the left, 11 on the right, 23 rows on top, 5 below. A corner placed
    // outside the map is clamped onto its edge, which the grown map does not have: the edges are left out.
    let grown = reframed(&turned, -37, -23, w + 48, h + 28);
    let off_edges = |kps: &[Keypoint], x0: u32, y0: u32| -> Vec<Keypoint> {
        kps.iter()
            .filter(|k| k.x > x0 && k.y > y0 && k.x < x0 + w - 1 && k.y < y0 + h - 1)
            .copied()
            .collect()
    };
    same(
        &off_edges(&keypoints_in_frame(&grown, -37, -5, &params), 37, 23),
        &off_edges(&shifted(&base, 37, 23), 37, 23),
        "grown",
    );
    // Its wall direction too: estimated about the world origin, the grown map bins its walls' pixels as
    // the map does.
    let angle = |img: &MapImage, x0: i64, bottom: i64| {
        let info = detect_in_frame(img, x0, bottom, &RobustParams::default()).robust;
        info.unwrap().angle
    };
    assert_eq!(
        angle(&grown, -37, -5),
        angle(&turned, 0, 0),
        "grown map's angle"
    );
    // Cropped: the left 250 columns and the bottom 30 rows cut off. The keypoints far enough from the
    // cuts (a window's halo and ring, as the tiles need) are the map's.
    let cut = reframed(&turned, 250, 0, w - 250, h - 30);
    let tiles = ogm_corners::detect::robust::tiles::TilePlan::with_tile(&params, 256).unwrap();
    let reach = i64::from(tiles.halo + tiles.ring);
    let inner = |kps: &[Keypoint]| -> Vec<Keypoint> {
        kps.iter()
            .filter(|k| i64::from(k.x) >= 250 + reach && i64::from(k.y) < i64::from(h) - 30 - reach)
            .copied()
            .collect()
    };
    let want = inner(&base);
    assert!(
        want.len() >= 8,
        "{} keypoints inside the crop, reach {reach}, map {w}x{h}",
        want.len()
    );
    let got = |anchor| {
        let p = RobustParams { anchor, ..params };
        inner(&shifted(&keypoints_in_frame(&cut, 250, 30, &p), 250, 0))
    };
    same(&got(Anchor::World), &want, "cropped");
    // The test can tell: the same crop anchored at its own centre samples other pixels.
    let centred = RobustParams {
        anchor: Anchor::Centre,
        ..params
    };
    assert_ne!(
        inner(&shifted(
            &keypoints_in_frame(&cut, 250, 30, &centred),
            250,
            0
        )),
        inner(&keypoints_in_frame(&turned, 0, 0, &centred)),
        "cropped, anchored at the centres"
    );
}
