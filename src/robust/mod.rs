//! The robust OGM detector: the paper's rule table, evaluated where real maps meet its assumptions.
//!
//! Real sensor maps have walls several pixels thick and jagged, turned by any angle, so a room corner is
//! almost never the exact 3 x 3 pattern the rules look for. The robust detector
//! 1. estimates the map's dominant wall direction ([`orientation`]) and samples the map on a grid
//!    turned to it ([`crate::grid`]): walls run along rows and columns;
//! 2. coarsens that grid at several scales (the `coarsen` kernel: a cell is occupied when a quarter of
//!    its samples are), so that a jagged wall is a straight line of cells at some scale;
//! 3. runs the paper's detector, unchanged, on every coarse map: on free cells (concave corners, as in
//!    the paper) and, with the roles of free and occupied swapped, on occupied cells (convex corners:
//!    wall ends and outer corners seen from free space);
//! 4. gives each corner a strength, the length of the shorter of its two walls in pixels
//!    ([`corners`]; halved for convex corners), places it where the centre lines of its walls cross, in the map's own pixels, and
//!    keeps the strongest within [`RobustParams::nms_radius`] across scales.
//!
//! Steps 1 and 4 are host code shared by every backend; 2 and 3 are kernels, so the keypoints are the same
//! on every backend, bit for bit.

pub mod corners;
pub mod orientation;
/// The options, kept with the backend interface ([`crate::backend::robust_params`]) that every backend is
/// given; here under their old name too.
pub use crate::backend::robust_params as params;
pub use crate::backend::robust_params::{grid_samples, robust_working_bytes, RobustParams};

use crate::backend::{Backend, Keypoint};
use crate::cpu::coarsen::{Mosaic, FREE, OCCUPIED};
use crate::error::Result;
use crate::grid::RotatedGrid;
use crate::map::MapImage;
use crate::rules::RuleTable;
use crate::states::{CellState, ClassTable};
use corners::{concave_arms, convex_arms, Arms, Cells, Sampler};
use rayon::prelude::*;

/// How a coarse map is read: its cell values as states; with `swapped`, free and occupied exchanged, so
/// the paper's detector finds convex corners (occupied cells with free neighbours in its patterns).
pub fn coarse_classes(swapped: bool) -> ClassTable {
    let mut states = [CellState::Unknown; 256];
    let (occ, free) = if swapped {
        (CellState::Free, CellState::Occupied)
    } else {
        (CellState::Occupied, CellState::Free)
    };
    states[OCCUPIED as usize] = occ;
    states[FREE as usize] = free;
    ClassTable::from_states(states)
}

/// What the robust detector found besides its keypoints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobustInfo {
    /// The grid angle used, degrees (as quantised, see [`crate::grid::FRAC_BITS`]).
    pub angle: f64,
    /// Corners found before suppression.
    pub candidates: usize,
}

/// Runs the robust detector on `backend`: keypoints in (y, x) order, `score` the strength in pixels,
/// `scale` the coarse scale it fired at, `rule` and `code` those of the coarse cell.
pub fn detect(
    backend: &mut dyn Backend,
    image: &MapImage,
    classes: &ClassTable,
    rules: &RuleTable,
    params: &RobustParams,
) -> Result<(Vec<Keypoint>, RobustInfo)> {
    let scales = params.scales()?;
    let angle = params
        .angle
        .unwrap_or_else(|| orientation::dominant_angle(image, classes));
    let grid = RotatedGrid::new(image.width(), image.height(), angle)?;
    // Between stages, a raised stop (Ctrl-C in Python) ends the detection.
    crate::stop::check()?;
    let coarse = backend.coarsen(image, classes, &grid, &scales, params.cells)?;
    let sampler = Sampler {
        image,
        classes,
        grid: &grid,
        wall_gap: params.wall_gap as i32,
    };
    let mut found = Vec::new();
    for (&scale, map) in scales.iter().zip(&coarse) {
        crate::stop::check()?;
        let cells = Cells::new(map);
        let mosaic = Mosaic::new(&grid, scale);
        let lattice = Lattice::new(&grid, &mosaic);
        let mut masked = map.clone();
        for convex in [false, true] {
            if convex && !params.convex {
                continue;
            }
            lattice.mask(map, &mut masked, if convex { OCCUPIED } else { FREE });
            let hits = backend.detect(&masked, &coarse_classes(convex), rules, false)?;
            // Scored on every core; collected in the order found, so the result does not depend on it.
            let scored: Vec<Candidate> = hits
                .par_iter()
                .filter_map(|&k| score(&cells, &grid, &mosaic, k, convex, params.min_strength))
                .collect();
            found.extend(scored);
        }
    }
    let candidates = found.len();
    // Suppression on the cell positions first, so only the survivors are placed on the map's pixels
    // (placing reads dozens of samples a corner); then again on the placed positions.
    let centre2 = (i64::from(image.width()) - 1, i64::from(image.height()) - 1);
    let survivors = suppress_candidates(found, params.nms_radius, centre2);
    crate::stop::check()?;
    let placed: Vec<Keypoint> = survivors
        .par_iter()
        .map(|c| match c.arms {
            Some(arms) => {
                let k = c.keypoint;
                let at = sampler.place(c.centre, &arms, k.convex, i32::from(k.scale));
                candidate(&grid, at, k, u32::from(k.scale), k.convex, k.score as u32)
            }
            None => c.keypoint,
        })
        .collect();
    let mut kept = suppress(placed, params.nms_radius, centre2);
    kept.sort_unstable();
    Ok((
        kept,
        RobustInfo {
            angle: grid.degrees(),
            candidates,
        },
    ))
}

/// A corner found on a coarse map, at its cell's position, before it is placed on the map's pixels.
struct Candidate {
    /// The keypoint at the cell position (the corner of the free cell where its walls meet; the
    /// occupied cell itself for a convex corner).
    keypoint: Keypoint,
    /// Its walls; `None` for a corner without two perpendicular walls (kept with `min_strength` 0).
    arms: Option<Arms>,
    /// The cell's middle sample.
    centre: (i32, i32),
}

/// The candidate of a rule that fired at coarse cell (`k.x`, `k.y`) of `mosaic`: its walls' strength;
/// `None` below `min_strength`.
fn score(
    cells: &Cells,
    grid: &RotatedGrid,
    mosaic: &Mosaic,
    k: Keypoint,
    convex: bool,
    min_strength: u32,
) -> Option<Candidate> {
    let scale = mosaic.scale;
    let (u, v) = (k.x as i32, k.y as i32);
    // A rule fires only on a free or occupied cell, never in a gutter.
    let (p, q) = mosaic.origin(k.x, k.y)?;
    let c = (grid.box_middle(p, scale, 0), grid.box_middle(q, scale, 1));
    let arms = if convex {
        convex_arms(cells, u, v)
    } else {
        concave_arms(cells, u, v)
    };
    let Some(arms) = arms else {
        return (min_strength == 0).then(|| Candidate {
            keypoint: candidate(grid, samples(c), k, scale, convex, 0),
            arms: None,
            centre: c,
        });
    };
    // Convex corners count half: most are wall ends and door jambs, which people rarely mark
    // (calibrated on half of the annotated maps, see docs/detectors.md).
    let strength = if convex {
        arms.cells as u32 * scale / 2
    } else {
        arms.cells as u32 * scale
    };
    if strength < min_strength {
        return None;
    }
    let s = scale as i32 / 2;
    let at = if convex {
        c
    } else {
        (
            c.0 + (arms.d1.0 + arms.d2.0) * s,
            c.1 + (arms.d1.1 + arms.d2.1) * s,
        )
    };
    Some(Candidate {
        keypoint: candidate(grid, samples(at), k, scale, convex, strength),
        arms: Some(arms),
        centre: c,
    })
}

/// Samples between the boxes whose corners are scored, along each axis, at `scale`: a corner's rule fires
/// at every phase whose box lies in the corner (about scale^2 boxes), and scoring every one would cost
/// scale^2 times what one fixed block grid costs; a lattice of a third of the scale keeps at least 9 of
/// them.
pub fn lattice_step(scale: u32) -> u32 {
    scale.div_ceil(3)
}

/// The boxes a coarse map's rules are evaluated at: those whose middles lie on a lattice of
/// [`lattice_step`] about the map's centre, symmetric under quarter turns and mirrors (a distance of `d`
/// half samples from the centre, along each axis, is on it when `d / 2` is a multiple of the step).
struct Lattice {
    columns: Vec<bool>,
    rows: Vec<bool>,
}

impl Lattice {
    fn new(grid: &RotatedGrid, mosaic: &Mosaic) -> Self {
        let (k, s) = (
            i64::from(lattice_step(mosaic.scale)),
            i64::from(mosaic.scale),
        );
        let on = |p: Option<i32>, c2: i64| {
            p.is_some_and(|p| ((2 * i64::from(p) + s - 1 - c2).abs() / 2) % k == 0)
        };
        let (w, h) = mosaic.size();
        Lattice {
            columns: (0..w)
                .map(|x| on(mosaic.column_origin(x), grid.centre2.0))
                .collect(),
            rows: (0..h)
                .map(|y| on(mosaic.row_origin(y), grid.centre2.1))
                .collect(),
        }
    }

    /// `map` into `out` with every cell of value `centre` off the lattice made unknown: the rules fire
    /// only on cells of that value, and as a neighbour an unknown cell sets no bit of the code, exactly as
    /// the free cell (concave corners) or the occupied one (convex, the roles swapped) it replaces, so the
    /// rules fire on the lattice's cells exactly as on the unmasked map, and nowhere else.
    fn mask(&self, map: &MapImage, out: &mut MapImage, centre: u8) {
        use crate::cpu::coarsen::UNKNOWN;
        let w = map.width() as usize;
        // Per column, what a cell of value `centre` becomes in a row on the lattice (off it, every one
        // becomes unknown): branch-free byte selects the compiler vectorises.
        let off_column: Vec<u8> = self.columns.iter().map(|&on| u8::from(!on)).collect();
        out.pixels_mut()
            .par_chunks_mut(w)
            .zip(map.pixels().par_chunks(w))
            .zip(&self.rows)
            .for_each(|((dst, src), &row_on)| {
                let (dst, src, off) = (&mut dst[..w], &src[..w], &off_column[..w]);
                for x in 0..w {
                    let masked = (src[x] == centre) & (!row_on | (off[x] != 0));
                    dst[x] = if masked { UNKNOWN } else { src[x] };
                }
            });
    }
}

/// [`suppress`] over candidates, keeping their walls.
fn suppress_candidates(found: Vec<Candidate>, radius: u32, centre2: (i64, i64)) -> Vec<Candidate> {
    let keys: Vec<Keypoint> = found.iter().map(|c| c.keypoint).collect();
    let mut slots: Vec<Option<Candidate>> = found.into_iter().map(Some).collect();
    suppressed_order(&keys, radius, centre2)
        .into_iter()
        .filter_map(|i| slots[i].take())
        .collect()
}

/// A sample position as a point of the grid's frame.
fn samples((p, q): (i32, i32)) -> (f64, f64) {
    (f64::from(p), f64::from(q))
}

/// A keypoint at grid position `(p, q)` (samples), rounded to the nearest map pixel inside the map (ties
/// towards the map's centre).
fn candidate(
    grid: &RotatedGrid,
    (p, q): (f64, f64),
    k: Keypoint,
    scale: u32,
    convex: bool,
    strength: u32,
) -> Keypoint {
    let (x, y) = grid.round_pixel(grid.to_map(p, q));
    Keypoint {
        x,
        y,
        rule: k.rule,
        code: k.code,
        score: i64::from(strength),
        scale: scale as u8,
        convex,
    }
}

/// Greedy suppression: strongest first, a keypoint is kept unless a kept one lies within `radius` pixels.
/// Ties go to the larger scale, then to the keypoint nearer the map's centre (`centre2`, in half pixels:
/// a quarter turn or a mirror of the map about its centre keeps the same order), then (y, x) and the
/// rest of the keypoint, so the result does not depend on the order found.
pub fn suppress(found: Vec<Keypoint>, radius: u32, centre2: (i64, i64)) -> Vec<Keypoint> {
    suppressed_order(&found, radius, centre2)
        .into_iter()
        .map(|i| found[i])
        .collect()
}

/// [`suppress`] as indices into `found`, strongest first.
fn suppressed_order(found: &[Keypoint], radius: u32, centre2: (i64, i64)) -> Vec<usize> {
    let mut order: Vec<usize> = (0..found.len()).collect();
    let dist = |k: &Keypoint| {
        let (dx, dy) = (
            2 * i64::from(k.x) - centre2.0,
            2 * i64::from(k.y) - centre2.1,
        );
        dx * dx + dy * dy
    };
    order.par_sort_unstable_by(|&i, &j| {
        let (a, b) = (&found[i], &found[j]);
        b.score
            .cmp(&a.score)
            .then(b.scale.cmp(&a.scale))
            .then(dist(a).cmp(&dist(b)))
            .then(a.cmp(b))
            .then(i.cmp(&j))
    });
    let cell = radius.max(1);
    let r2 = i64::from(radius) * i64::from(radius);
    let mut buckets: Buckets = Default::default();
    let mut kept = Vec::new();
    for i in order {
        let k = &found[i];
        let (bx, by) = (k.x / cell, k.y / cell);
        let near = (bx.saturating_sub(1)..=bx + 1).any(|x| {
            (by.saturating_sub(1)..=by + 1).any(|y| {
                buckets.get(&(x, y)).is_some_and(|v| {
                    v.iter().any(|&(px, py)| {
                        let (dx, dy) = (
                            i64::from(px) - i64::from(k.x),
                            i64::from(py) - i64::from(k.y),
                        );
                        dx * dx + dy * dy <= r2
                    })
                })
            })
        });
        if !near {
            buckets.entry((bx, by)).or_default().push((k.x, k.y));
            kept.push(i);
        }
    }
    kept
}

/// Kept keypoints by bucket of `radius` pixels.
type Buckets = std::collections::HashMap<
    (u32, u32),
    Vec<(u32, u32)>,
    std::hash::BuildHasherDefault<CellHasher>,
>;

/// A multiplicative hasher for bucket coordinates: the keys are small integers, not attacker-chosen,
/// and SipHash would be most of the suppression's time.
#[derive(Default)]
struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u32(&mut self, v: u32) {
        self.write_u64(u64::from(v));
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(29) ^ v).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sample_bound_holds_at_every_angle() {
        for (w, h) in [(1, 1), (10, 1000), (1585, 1585), (4096, 300)] {
            for deg in [0.0, 10.0, 30.0, 44.0, 45.0, -45.0, 77.0] {
                let g = RotatedGrid::new(w, h, deg).unwrap();
                let n = u64::from(g.width) * u64::from(g.height);
                assert!(n <= grid_samples(w, h), "{w}x{h} at {deg}: {n}");
            }
        }
    }
}
