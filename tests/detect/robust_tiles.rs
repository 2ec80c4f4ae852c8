//! The robust detector over a map in tiles of its turned grid (how it runs on maps of any size) finds the
//! keypoints of the map in memory, bit for bit, whatever the tile size, angle or options.

use crate::common;
use ogm_corners::backend::fast::FastCpuBackend;
use ogm_corners::detect::robust::tiles::{detect_tiled, ImageReader, TilePlan};
use ogm_corners::detect::robust::{self, Anchor, RobustParams};
use ogm_corners::{ClassTable, MapImage, OccupancyMap, RuleSet, RuleTable};

/// Keypoints in memory and in tiles, and the tiles' count.
type Both = (
    Vec<ogm_corners::Keypoint>,
    Vec<ogm_corners::Keypoint>,
    usize,
);

/// The in-memory keypoints and the tiled ones, for tiles of `tile` samples (and no ring around them when
/// `ringless`: exact still, with far more corners left open by the windows).
fn both(
    img: &MapImage,
    classes: &ClassTable,
    params: &RobustParams,
    tile: u32,
    ringless: bool,
) -> Both {
    let rules = RuleTable::new(RuleSet::Paper);
    let (want, info) = robust::detect(&mut FastCpuBackend, img, classes, &rules, params).unwrap();
    let mut plan = TilePlan::with_tile(params, tile).unwrap();
    if ringless {
        plan.ring = 0;
    }
    let (got, tiled) = detect_tiled(
        &mut FastCpuBackend,
        &mut ImageReader::new(img),
        classes,
        &rules,
        params,
        &plan,
    )
    .unwrap();
    assert_eq!(info, tiled, "the angle and the candidate count");
    let (gw, gh) = {
        let (w, h) = (img.width(), img.height());
        let anchor = params.anchor2(w, h);
        let g = ogm_corners::map::grid::RotatedGrid::anchored(w, h, info.angle, anchor).unwrap();
        (g.width, g.height)
    };
    let tiles = (gw.div_ceil(plan.tile) * gh.div_ceil(plan.tile)) as usize;
    (want, got, tiles)
}

/// Synthetic floors, square and turned, with small scales so that small tiles have windows smaller than
/// the map (the halo is 66 cells of the largest scale): tiles of sizes that are and are not multiples of
/// every scale, so the cells' phases fall differently in every window.
#[test]
fn tiles_of_any_size_give_the_keypoints_of_the_whole_map() {
    let classes = ClassTable::default();
    let maps = [
        (common::floor_plan(900, 700, 1), None),
        (common::floor_plan(700, 900, 2), Some(0.0)),
        (common::turned_rooms(800, 17.3, 3).0, None),
        (common::turned_rooms(800, -38.0, 4).0, None),
        (common::turned_rooms(800, 45.0, 5).0, Some(45.0)),
    ];
    for (seed, (img, deg)) in maps.into_iter().enumerate() {
        let params = RobustParams {
            min_scale: 2,
            max_scale: 4,
            angle: deg,
            // A wide radius on some maps: chains of suppression cross the tiles' edges.
            nms_radius: [4, 24][seed % 2],
            // Grids anchored off the map's centre (a world frame's origin) on some: off a pixel, outside.
            anchor: [
                Anchor::Centre,
                Anchor::Point(-57.5, 1234.0),
                Anchor::Point(301.25, 17.0),
            ][seed % 3],
            ..RobustParams::default()
        };
        for (tile, ringless) in [(97, false), (97, true), (256, false), (4096, false)] {
            let (want, got, tiles) = both(&img, &classes, &params, tile, ringless);
            assert!(want.len() >= 8, "map {seed}: {} keypoints", want.len());
            assert_eq!(
                got, want,
                "map {seed} at {deg:?}, tiles of {tile} ({tiles} tiles)"
            );
            if tile < 200 {
                assert!(tiles >= 16, "{tiles} tiles");
            }
        }
    }
}

/// The real maps, at the default options (the halo of the largest scale): the same keypoints in tiles of
/// MIN_TILE samples as in one piece.
#[test]
fn real_maps_in_tiles_give_the_keypoints_of_the_whole_map() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let maps = [
        "turtlebot3/turtlebot3_navigation2/map/map.yaml",
        "mas_domestic_robotics/mdr_environments/brsu-c069/map.yaml",
        "mapstitch_data/maps/tiz_02_rotated/map.yaml",
        "mapstitch_data/maps/hector1_rc15_test_01/map.yaml",
        "mapstitch_data/maps/tiz_01/map.yaml",
    ];
    let mut checked = 0;
    for rel in maps {
        let path = dir.join(rel);
        let map = OccupancyMap::load(&path)
            .unwrap_or_else(|e| panic!("{} is part of the shared maps: {e}", path.display()));
        let classes = ClassTable::new(&map.thresholds);
        let params = RobustParams::default();
        let (want, got, tiles) = both(&map.image, &classes, &params, 256, false);
        assert_eq!(got, want, "{rel} in {tiles} tiles");
        checked += usize::from(tiles > 1);
    }
    assert!(checked >= 3, "{checked} maps were cut into several tiles");
}

/// A plan from a memory size: the largest tile whose window fits, never below the smallest tile.
#[test]
fn a_plan_fits_its_bytes() {
    let params = RobustParams::default();
    let plan = TilePlan::with_bytes(&params, 256 << 20).unwrap();
    assert!(plan.bytes() <= 256 << 20, "{plan:?}");
    let mut bigger = plan;
    bigger.tile += 1;
    assert!(bigger.bytes() > 256 << 20);
    assert!(plan.tile >= 2000, "{plan:?}");
    let tiny = TilePlan::with_bytes(&params, 1 << 20).unwrap();
    assert_eq!(tiny.tile, ogm_corners::detect::robust::tiles::MIN_TILE);
}

/// Two cells of an even scale share a middle sample beside the grid's centre; when a tile's edge falls
/// between them and both fire on the same keypoint, each window must order them alike (by their first
/// samples), or each keeps the twin the other one reports and the corner is lost. A room's corner on the
/// centre column, tiles whose edges fall there.
#[test]
fn twin_cells_on_the_centre_column_split_by_a_tile_edge_keep_their_corner() {
    use ogm_corners::map::grid::RotatedGrid;
    let (w, h, y0, s, arm) = (625u32, 360u32, 40u32, 2i32, 200u32);
    let g = RotatedGrid::new(w, h, 0.0).unwrap();
    assert_eq!(g.centre2.0 % 2, 0);
    let pc = (g.centre2.0 / 2) as i32;
    let xf = g.source(pc - s / 2, 0).0 as u32; // the room's first free column
    let mut px = vec![205u8; (w * h) as usize];
    for y in (y0 - 2)..(y0 + arm) {
        for x in (xf - 2)..(xf + arm) {
            px[(y * w + x) as usize] = if x < xf || y < y0 { 0 } else { 254 };
        }
    }
    let img = MapImage::new(w, h, px).unwrap();
    let classes = ClassTable::default();
    let params = RobustParams {
        min_scale: 2,
        max_scale: 2,
        angle: Some(0.0),
        ..RobustParams::default()
    };
    let mut split = 0;
    for tile in (20..pc).filter(|t| pc % t == 0) {
        let (want, got, _) = both(&img, &classes, &params, tile as u32, false);
        assert!(!want.is_empty());
        assert_eq!(got, want, "tiles of {tile}");
        split += 1;
    }
    assert!(split >= 3, "{split} tilings");
}
