//! Robots exploring a map: what each of a few robots with a range sensor sees while it drives through the
//! free space around its start, each map in its own frame (turned and shifted by a random pose the merger
//! is not told). The demo's robots, and a more realistic shape of partial map than a window: the known
//! area follows the corridors and stops at walls and at the sensor's range.

use std::collections::VecDeque;

use crate::map::states::{CellState, ClassTable};
use crate::map::synthetic::Rng;
use crate::map::{MapImage, OccupancyMap};
use crate::measure::synthetic::{box_points, turned, SyntheticCrop};

/// How the robots explore.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exploration {
    /// Robots.
    pub robots: usize,
    /// The sensor's range, pixels.
    pub range: f64,
    /// Share of the reachable free space each robot drives through, nearest its start first.
    pub share: f64,
    /// Distance from any wall or unknown cell a robot keeps, pixels.
    pub clearance: usize,
}

impl Default for Exploration {
    fn default() -> Self {
        Exploration {
            robots: 3,
            range: 100.0,
            share: 0.5,
            clearance: 4,
        }
    }
}

/// Sensor readings are taken every this many pixels along the robot's reach (a lattice of poses).
const POSE_STEP: usize = 16;

/// Rays a reading casts, all around.
const RAYS: usize = 240;

/// The maps of `how.robots` robots exploring `source`, deterministic in `seed`: robot k starts at the
/// drivable cell nearest the k-th point spread over the known area, drives through the free space
/// nearest its start (by path length, keeping `clearance` from walls) until it has covered `share` of
/// what it can reach, and reads its sensor every 16 pixels: every cell a ray of `range`
/// reaches before the first wall, that wall included. Each map is turned by a random angle into a square
/// canvas with a random margin; its `pose` takes its pixels to the source's. `None` when the source has no
/// drivable space or a robot sees nothing.
pub fn explore(source: &OccupancyMap, how: &Exploration, seed: u64) -> Option<Vec<SyntheticCrop>> {
    let classes = ClassTable::new(&source.thresholds);
    let img = &source.image;
    let (w, h) = (img.width() as usize, img.height() as usize);
    // Cells are indexed in 32 bits where the sensor's hits are kept.
    if (w as u64) * (h as u64) > u64::from(u32::MAX) {
        return None;
    }
    let states: Vec<CellState> = img.pixels().iter().map(|&v| classes.state(v)).collect();
    let drivable = drivable(&states, (w, h), how.clearance);
    // The robots start in the largest connected free space (not in a closed room, or a cupboard).
    let cells = (0..w * h)
        .filter(|&i| drivable[i])
        .fold((vec![false; w * h], Vec::new()), |(mut done, best), i| {
            if done[i] {
                return (done, best);
            }
            let part = flood(&drivable, (w, h), i);
            for &j in &part {
                done[j] = true;
            }
            let best = if part.len() > best.len() { part } else { best };
            (done, best)
        })
        .1;
    if cells.is_empty() || how.robots == 0 {
        return None;
    }
    let (x0, y0, x1, y1) = cells.iter().fold((w, h, 0, 0), |b, &i| {
        let (x, y) = (i % w, i / w);
        (b.0.min(x), b.1.min(y), b.2.max(x), b.3.max(y))
    });
    let mut rng = Rng::new(seed);
    let unit = |r: &mut Rng| f64::from(r.range(0, 1 << 24)) / f64::from(1u32 << 24);
    let mut out = Vec::with_capacity(how.robots);
    for k in 0..how.robots {
        // Starts spread along the longer side of the drivable area, jittered.
        let t = (k as f64 + 0.5 + 0.3 * (unit(&mut rng) - 0.5)) / how.robots as f64;
        let (ex, ey) = ((x1 - x0) as f64, (y1 - y0) as f64);
        let want = if ex >= ey {
            (
                x0 as f64 + t * ex,
                y0 as f64 + (0.3 + 0.4 * unit(&mut rng)) * ey,
            )
        } else {
            (
                x0 as f64 + (0.3 + 0.4 * unit(&mut rng)) * ex,
                y0 as f64 + t * ey,
            )
        };
        let start = *cells.iter().min_by(|&&a, &&b| {
            let d = |i: usize| ((i % w) as f64 - want.0).hypot((i / w) as f64 - want.1);
            d(a).total_cmp(&d(b))
        })?;
        let poses = reach(&drivable, (w, h), start, how.share);
        let seen = sense(&states, (w, h), &poses, how.range);
        let (mut bx0, mut by0, mut bx1, mut by1) = (w, h, 0, 0);
        for i in (0..w * h).filter(|&i| seen[i]) {
            let (x, y) = (i % w, i / w);
            (bx0, by0, bx1, by1) = (bx0.min(x), by0.min(y), bx1.max(x + 1), by1.max(y + 1));
        }
        if bx1 <= bx0 {
            return None;
        }
        let margin = f64::from(rng.range(4, 48));
        let theta = unit(&mut rng) * 360.0;
        let state = |x: usize, y: usize| states[y * w + x];
        let keep = |x: usize, y: usize| seen[y * w + x];
        let value = &mut |s: CellState| s.map_server_value();
        let (px, side, pose, (kx0, ky0, kx1, ky1)) = turned(
            &state,
            (w, h),
            &keep,
            (bx0, by0, bx1, by1),
            theta,
            margin,
            &|p| p,
            value,
        )?;
        out.push(SyntheticCrop {
            map: OccupancyMap::from_image(MapImage::new(side as u32, side as u32, px).ok()?),
            pose: pose.normalized(),
            check_points: box_points(kx0, ky0, kx1, ky1),
        });
    }
    Some(out)
}

/// Free cells at least `clearance` pixels (in x and y) from any cell that is not free.
fn drivable(states: &[CellState], (w, h): (usize, usize), clearance: usize) -> Vec<bool> {
    let free: Vec<bool> = states.iter().map(|&s| s == CellState::Free).collect();
    // Separable erosion: a row pass, then a column pass.
    let mut rows = vec![false; w * h];
    for y in 0..h {
        let line = &free[y * w..(y + 1) * w];
        for x in 0..w {
            let (a, b) = (x.saturating_sub(clearance), (x + clearance + 1).min(w));
            rows[y * w + x] = x >= clearance && x + clearance < w && line[a..b].iter().all(|&f| f);
        }
    }
    let mut out = vec![false; w * h];
    for x in 0..w {
        for y in clearance..h.saturating_sub(clearance) {
            out[y * w + x] = (y - clearance..=y + clearance).all(|yy| rows[yy * w + x]);
        }
    }
    out
}

/// The sensor poses of a robot starting at `start`: drivable cells in order of path length from it
/// (4-connected), up to `share` of those it can reach, thinned to a lattice of [`POSE_STEP`] pixels.
fn reach(
    drivable: &[bool],
    (w, h): (usize, usize),
    start: usize,
    share: f64,
) -> Vec<(usize, usize)> {
    let order = flood(drivable, (w, h), start);
    let keep = ((order.len() as f64 * share.clamp(0.0, 1.0)).ceil() as usize).max(1);
    order
        .into_iter()
        .take(keep)
        .map(|i| (i % w, i / w))
        .filter(|&(x, y)| {
            x % POSE_STEP == 0 && y % POSE_STEP == 0 || (x, y) == (start % w, start / w)
        })
        .collect()
}

/// The drivable cells connected to `start` (4-connected), in order of path length from it.
fn flood(drivable: &[bool], (w, h): (usize, usize), start: usize) -> Vec<usize> {
    let mut order = Vec::new();
    let mut seen = vec![false; w * h];
    let mut queue = VecDeque::from([start]);
    seen[start] = true;
    while let Some(i) = queue.pop_front() {
        order.push(i);
        let (x, y) = (i % w, i / w);
        let next = [
            (x > 0).then(|| i - 1),
            (x + 1 < w).then(|| i + 1),
            (y > 0).then(|| i - w),
            (y + 1 < h).then(|| i + w),
        ];
        for j in next.into_iter().flatten() {
            if drivable[j] && !seen[j] {
                seen[j] = true;
                queue.push_back(j);
            }
        }
    }
    order
}

/// Cells the sensor sees from `poses`: along each of [`RAYS`] rays up to `range` pixels, every cell
/// until the first occupied one, which is seen too; unknown cells stop a ray unseen.
fn sense(
    states: &[CellState],
    (w, h): (usize, usize),
    poses: &[(usize, usize)],
    range: f64,
) -> Vec<bool> {
    use rayon::prelude::*;
    let dirs: Vec<(f64, f64)> = (0..RAYS)
        .map(|r| (r as f64 * std::f64::consts::TAU / RAYS as f64).sin_cos())
        .map(|(s, c)| (c, s))
        .collect();
    let seen: Vec<Vec<u32>> = poses
        .par_iter()
        .map(|&(px, py)| {
            let mut hit = Vec::new();
            for &(dx, dy) in &dirs {
                let mut t = 0.0;
                while t <= range {
                    let (x, y) = ((px as f64 + dx * t).round(), (py as f64 + dy * t).round());
                    if x < 0.0 || y < 0.0 || x >= w as f64 || y >= h as f64 {
                        break;
                    }
                    let i = y as usize * w + x as usize;
                    match states[i] {
                        CellState::Unknown => break,
                        CellState::Occupied => {
                            hit.push(i as u32);
                            break;
                        }
                        CellState::Free => hit.push(i as u32),
                    }
                    t += 0.5;
                }
            }
            hit
        })
        .collect();
    let mut out = vec![false; w * h];
    for i in seen.into_iter().flatten() {
        out[i as usize] = true;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn robots_see_overlapping_parts_within_range_and_their_poses_are_exact() {
        let source =
            OccupancyMap::from_image(crate::map::synthetic::office_map(400, 300, 2).unwrap());
        let robots = explore(&source, &Exploration::default(), 7).unwrap();
        assert_eq!(robots.len(), 3);
        let classes = ClassTable::new(&source.thresholds);
        for r in &robots {
            let img = &r.map.image;
            let mut known = 0;
            for y in 0..img.height() {
                for x in 0..img.width() {
                    let s = classes.state(img.get(x, y));
                    if s == CellState::Unknown {
                        continue;
                    }
                    known += 1;
                    // Every known cell is the source's state at the place the pose puts it.
                    let (sx, sy) = r.pose.apply((f64::from(x), f64::from(y)));
                    let at = source.image.get(sx.round() as u32, sy.round() as u32);
                    assert_eq!(classes.state(at), s, "({x}, {y}) -> ({sx:.1}, {sy:.1})");
                }
            }
            // A part, not the whole building, and not a speck.
            assert!(known > 5_000 && known < 300 * 400, "{known}");
        }
        // Deterministic in the seed.
        let again = explore(&source, &Exploration::default(), 7).unwrap();
        assert_eq!(again[1].map.image, robots[1].map.image);
    }
}
