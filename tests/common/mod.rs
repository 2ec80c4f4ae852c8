//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

pub mod maps;
pub mod run;

use ogm_corners::map::synthetic::{FREE, OCCUPIED, UNKNOWN};
use ogm_corners::{DetectOptions, Detector, Keypoint, MapImage, OccupancyMap, RuleSet};

/// A coarse-cell rule for a twin test: the default on even seeds, else shares drawn from 1% to 120% of a
/// cell's samples (over 100%, which the options refuse, no cell reaches the threshold on any path).
pub fn some_cell_rule(
    seed: u64,
    rng: &mut ogm_corners::map::synthetic::Rng,
) -> ogm_corners::backend::reference::coarsen::CellRule {
    if seed.is_multiple_of(2) {
        ogm_corners::backend::reference::coarsen::CellRule::default()
    } else {
        ogm_corners::backend::reference::coarsen::CellRule {
            occupied_pct: rng.range(1, 121),
            free_pct: rng.range(1, 121),
        }
    }
}

/// Runs the tool's `command` with `args` in `dir`.
pub fn tool_in(dir: &std::path::Path, command: &str, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_ogm-corners"))
        .arg(command)
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// A map from ASCII art: `#` occupied, `.` free, `?` unknown; rows top to bottom.
pub fn art(rows: &[&str]) -> MapImage {
    let h = rows.len() as u32;
    let w = rows[0].len() as u32;
    let px = rows
        .iter()
        .flat_map(|r| {
            assert_eq!(r.len() as u32, w, "ragged art");
            r.bytes().map(|b| match b {
                b'#' => OCCUPIED,
                b'.' => FREE,
                b'?' => UNKNOWN,
                _ => panic!("bad art char {}", b as char),
            })
        })
        .collect();
    MapImage::new(w, h, px).unwrap()
}

/// Three-state maps whose occupied density varies with the seed, so sparse and dense maps both occur.
pub fn random_map(w: u32, h: u32, seed: u64) -> MapImage {
    let mut rng = ogm_corners::map::synthetic::Rng::new(seed);
    let occ = 0.15 + 0.3 * (seed % 4) as f64 / 3.0;
    let px = (0..w as usize * h as usize)
        .map(|_| {
            if rng.chance(occ) {
                OCCUPIED
            } else if rng.chance(0.15) {
                UNKNOWN
            } else {
                FREE
            }
        })
        .collect();
    MapImage::new(w, h, px).unwrap()
}

/// All 3^9 three-state 3x3 neighbourhoods as adjacent 3x3 blocks: each block's centre sees exactly its own
/// block.
pub fn all_3x3_configurations() -> MapImage {
    let (cols, n) = (141u32, 3u32.pow(9));
    let rows = n.div_ceil(cols);
    let (w, h) = (cols * 3, rows * 3);
    let mut px = vec![FREE; (w * h) as usize];
    for c in 0..n {
        let (bx, by) = ((c % cols) * 3, (c / cols) * 3);
        let mut v = c;
        for cell in 0..9 {
            px[((by + cell / 3) * w + bx + cell % 3) as usize] =
                [FREE, UNKNOWN, OCCUPIED][(v % 3) as usize];
            v /= 3;
        }
    }
    MapImage::new(w, h, px).unwrap()
}

/// CPU keypoints of an image with the ROS default thresholds.
pub fn detect(img: &MapImage, rules: RuleSet, unknown_as_occupied: bool) -> Vec<Keypoint> {
    let mut d = Detector::new(DetectOptions {
        rules,
        unknown_as_occupied,
        ..DetectOptions::default()
    });
    d.detect(&OccupancyMap::from_image(img.clone()))
        .unwrap()
        .keypoints
}

/// The folder of real maps (`$OGM_MAPS_DIR`, else `../shared/maps` beside the project), or None with a
/// clear message. Under CI=true a missing folder is a failure, so the real-map checks never silently skip.
pub fn shared_maps() -> Option<PathBuf> {
    shared_dir("OGM_MAPS_DIR", "maps", None, "real maps", "real-map checks")
}

/// The merge-pairs data set (`$OGM_MERGE_PAIRS_DIR`, else `../shared/merge-pairs`), or None with a clear
/// message; under CI=true a missing folder is a failure.
pub fn merge_pairs() -> Option<PathBuf> {
    shared_dir(
        "OGM_MERGE_PAIRS_DIR",
        "merge-pairs",
        Some("corners.json"),
        "merge-pairs data",
        "annotated-corner checks",
    )
}

/// The maps-more data set (`$OGM_MAPS_MORE_DIR`, else `../shared/maps-more`): more buildings, floor
/// plans with furnished copies; None with a clear message, and under CI=true a failure.
pub fn maps_more() -> Option<PathBuf> {
    shared_dir(
        "OGM_MAPS_MORE_DIR",
        "maps-more",
        Some("README.md"),
        "maps-more data",
        "checks on more buildings",
    )
}

/// `$var`, else `../shared/<name>` beside the project, when it is a folder (holding `marker`, if given);
/// otherwise None after saying which `checks` did not run, or a panic under CI=true.
fn shared_dir(
    var: &str,
    name: &str,
    marker: Option<&str>,
    what: &str,
    checks: &str,
) -> Option<PathBuf> {
    let dir = std::env::var_os(var).map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../shared")
            .join(name)
    });
    if dir.is_dir() && marker.is_none_or(|m| dir.join(m).is_file()) {
        return Some(dir);
    }
    let msg = format!(
        "{what} not found at {}: the {checks} did NOT run",
        dir.display()
    );
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("{msg} (CI=true requires them)");
    }
    eprintln!("SKIPPED: {msg}");
    None
}

/// A GPU backend for conformance tests, or None with a loud message. Under CI=true a missing adapter is
/// a failure: GPU tests never silently skip there.
pub fn gpu_backend(
    options: ogm_corners::backend::gpu::GpuOptions,
) -> Option<ogm_corners::backend::gpu::GpuBackend> {
    match ogm_corners::backend::gpu::GpuBackend::new(options) {
        Ok(b) => Some(b),
        Err(e) => {
            if std::env::var("CI").is_ok_and(|v| v == "true") {
                panic!("CI=true requires a GPU adapter (lavapipe will do): {e}");
            }
            eprintln!("SKIPPED: GPU conformance checks did NOT run: {e}");
            None
        }
    }
}

/// A map of rectangular rooms with jagged walls about 3 px thick, turned by `degrees` about the map's
/// centre, unknown outside the rooms; and the rooms' true corners (where the walls' centre lines meet),
/// in map pixels. Deterministic in `seed`.
pub fn turned_rooms(size: u32, degrees: f64, seed: u64) -> (MapImage, Vec<(f64, f64)>) {
    let c = f64::from(size) / 2.0;
    let s = f64::from(size) * 0.7;
    // Rooms in the turned frame, about the centre: (u0, v0, u1, v1).
    let rooms = [
        (-0.3 * s, -0.3 * s, 0.05 * s, 0.02 * s),
        (0.05 * s, -0.3 * s, 0.3 * s, 0.1 * s),
        (-0.3 * s, 0.02 * s, 0.05 * s, 0.3 * s),
    ];
    let (sn, cs) = degrees.to_radians().sin_cos();
    let hash = |x: u32, y: u32| {
        let mut z = (u64::from(x) << 32 | u64::from(y)) ^ seed.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) % 1000) as f64 / 1000.0
    };
    let mut px = vec![UNKNOWN; (size * size) as usize];
    for y in 0..size {
        for x in 0..size {
            let (dx, dy) = (f64::from(x) - c, f64::from(y) - c);
            // Inverse turn: map -> room frame.
            let (u, v) = (dx * cs + dy * sn, -dx * sn + dy * cs);
            let half = 1.5 + 0.9 * (hash(x, y) - 0.5);
            let mut state = UNKNOWN;
            for &(u0, v0, u1, v1) in &rooms {
                let inside = u > u0 - half && u < u1 + half && v > v0 - half && v < v1 + half;
                if !inside {
                    continue;
                }
                let edge = (u - u0)
                    .abs()
                    .min((u - u1).abs())
                    .min((v - v0).abs())
                    .min((v - v1).abs());
                if edge <= half {
                    state = OCCUPIED;
                    break;
                }
                state = FREE;
            }
            px[(y * size + x) as usize] = state;
        }
    }
    let mut corners: Vec<(f64, f64)> = Vec::new();
    for &(u0, v0, u1, v1) in &rooms {
        for (u, v) in [(u0, v0), (u1, v0), (u0, v1), (u1, v1)] {
            let p = (c + u * cs - v * sn, c + u * sn + v * cs);
            if !corners.iter().any(|q| (q.0 - p.0).hypot(q.1 - p.1) < 3.0) {
                corners.push(p);
            }
        }
    }
    (MapImage::new(size, size, px).unwrap(), corners)
}

/// The synthetic office with furniture and an unexplored corner
/// ([`ogm_corners::map::synthetic::cluttered_office`]).
pub fn cluttered_office(w: u32, h: u32, seed: u64) -> MapImage {
    ogm_corners::map::synthetic::cluttered_office(w, h, seed).unwrap()
}

/// An aperiodic floor plan: the map split recursively at seeded random places into rooms (walls 3 px,
/// a door of 12-20 px in each split wall), free inside, unknown around the building: unlike the
/// synthetic office's grid of equal rooms, no shift or turn maps it onto itself.
pub fn floor_plan(w: u32, h: u32, seed: u64) -> MapImage {
    let mut px = vec![UNKNOWN; (w * h) as usize];
    let (x0, y0, x1, y1) = (10, 10, w - 10, h - 10);
    for y in y0..y1 {
        for x in x0..x1 {
            let edge = x < x0 + 3 || y < y0 + 3 || x >= x1 - 3 || y >= y1 - 3;
            px[(y * w + x) as usize] = if edge { OCCUPIED } else { FREE };
        }
    }
    let mut rng = ogm_corners::map::synthetic::Rng::new(seed);
    let mut rooms = vec![(x0 + 3, y0 + 3, x1 - 3, y1 - 3)];
    while let Some((ax, ay, bx, by)) = rooms.pop() {
        let (rw, rh) = (bx - ax, by - ay);
        if rw < 90 && rh < 90 {
            continue;
        }
        if rw >= rh {
            let cut = ax + rng.range(rw / 4, rw * 3 / 4);
            let door = ay + rng.range(5, rh.saturating_sub(25).max(6));
            let dlen = rng.range(12, 21);
            for y in ay..by {
                for x in cut..cut + 3 {
                    if !(door..door + dlen).contains(&y) {
                        px[(y * w + x) as usize] = OCCUPIED;
                    }
                }
            }
            rooms.push((ax, ay, cut, by));
            rooms.push((cut + 3, ay, bx, by));
        } else {
            let cut = ay + rng.range(rh / 4, rh * 3 / 4);
            let door = ax + rng.range(5, rw.saturating_sub(25).max(6));
            let dlen = rng.range(12, 21);
            for y in cut..cut + 3 {
                for x in ax..bx {
                    if !(door..door + dlen).contains(&x) {
                        px[(y * w + x) as usize] = OCCUPIED;
                    }
                }
            }
            rooms.push((ax, ay, bx, cut));
            rooms.push((ax, cut + 3, bx, by));
        }
    }
    MapImage::new(w, h, px).unwrap()
}
