//! The robust OGM detector: the paper's rule table, evaluated where real maps meet its assumptions.
//!
//! Real sensor maps have walls several pixels thick and jagged, turned by any angle, so a room corner is
//! almost never the exact 3 x 3 pattern the rules look for. The robust detector
//! 1. estimates the map's dominant wall direction ([`orientation`]) and samples the map on a grid
//!    turned to it ([`crate::map::grid`]): walls run along rows and columns;
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
//!
//! Steps 2-4 run in a [`Window`] of the turned grid: the whole grid for a map in memory, or the tiles of a
//! map of any size ([`tiles`]), whose suppression ([`mod@suppress`]) decides in each window what it can and
//! leaves the rest to the whole map's, with the same keypoints.
//!
//! The pipeline is this file; each step's own work is in the module it names.

pub mod corners;
pub mod orientation;
pub mod suppress;
pub mod tiles;
/// The options, kept with the backend interface ([`crate::backend::robust_params`]) that every backend is
/// given; here under their old name too.
pub use crate::backend::robust_params as params;
pub use crate::backend::robust_params::{grid_samples, robust_working_bytes, Anchor, RobustParams};

use crate::backend::rules::RuleTable;
use crate::backend::Mosaic;
use crate::backend::{Backend, Keypoint};
use crate::map::grid::RotatedGrid;
use crate::map::states::{CellState, ClassTable};
use crate::map::states::{FREE, OCCUPIED};
use crate::map::MapImage;
use crate::support::error::Result;
use corners::{concave_arms, convex_arms, Arms, Cells, Sampler};
use rayon::prelude::*;
pub use suppress::suppress;
use suppress::Fate;

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
    /// The grid angle used, degrees (as quantised, see [`crate::map::grid::FRAC_BITS`]).
    pub angle: f64,
    /// The point the grid was anchored at, map pixels ([`RobustParams::anchor`]): with the angle, what
    /// `Anchor::Point` and `angle` need to repeat the detection on a crop or a grown copy of the map.
    pub anchor: (f64, f64),
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
    params.scales()?;
    let (w, h) = (image.width(), image.height());
    let anchor2 = params.anchor2(w, h);
    let angle = params
        .angle
        .unwrap_or_else(|| orientation::dominant_angle_about(image, classes, anchor2));
    let grid = RotatedGrid::anchored(w, h, angle, anchor2)?;
    // Between stages, a raised stop (Ctrl-C in Python) ends the detection.
    crate::support::stop::check()?;
    // The map in memory is one window of the tiled path: every corner seen, every fate decided.
    let window = Window {
        image,
        grid,
        offset: (0, 0),
        owned: Span::ALL,
        trusted: Span::ALL,
        settled: Span::ALL,
        placed_settled: Span::ALL,
    };
    let (found, candidates) = detect_window(backend, &window, classes, rules, params)?;
    Ok((
        finish(found, params.nms_radius, &grid),
        RobustInfo {
            angle: grid.degrees(),
            anchor: grid.anchor(),
            candidates,
        },
    ))
}

/// A rectangle of whole-grid samples, `p.0..p.1` by `q.0..q.1` (open ends at the `i64` limits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    /// Columns.
    pub p: (i64, i64),
    /// Rows.
    pub q: (i64, i64),
}

impl Span {
    /// Every sample.
    pub const ALL: Span = Span {
        p: (i64::MIN, i64::MAX),
        q: (i64::MIN, i64::MAX),
    };

    fn contains(&self, (p, q): (f64, f64)) -> bool {
        let inside = |v: f64, (a, b): (i64, i64)| {
            (a == i64::MIN || v >= a as f64) && (b == i64::MAX || v < b as f64)
        };
        inside(p, self.p) && inside(q, self.q)
    }

    /// Grown by `d` samples on every side (an open end stays open; a negative `d` shrinks).
    pub fn grown(&self, d: i64) -> Span {
        let g = |(a, b): (i64, i64)| {
            (
                if a == i64::MIN { a } else { a - d },
                if b == i64::MAX { b } else { b + d },
            )
        };
        Span {
            p: g(self.p),
            q: g(self.q),
        }
    }
}

/// A window of the turned grid the robust detector works in: the whole grid for a map in memory, a tile
/// and its halo for a map of any size ([`tiles`]).
pub struct Window<'a> {
    /// The map, or the crop of it that the window's samples read.
    pub image: &'a MapImage,
    /// The window's grid ([`RotatedGrid::window`] of the whole grid).
    pub grid: RotatedGrid,
    /// The window's sample (0, 0) in the whole grid.
    pub offset: (i32, i32),
    /// The cells (by their first sample, in the whole grid) whose corners the window reports: the tiles of
    /// a map's windows share its cells out, each to one.
    pub owned: Span,
    /// The cells whose corners the window measures exactly (their walls and neighbours lie inside it):
    /// `owned` and a ring around it.
    pub trusted: Span,
    /// Where a corner's position (whole-grid samples) has every corner within the suppression radius
    /// among the trusted ones.
    pub settled: Span,
    /// Where a placed corner's position (whole-grid samples) has every placed corner within the radius
    /// among the trusted ones.
    pub placed_settled: Span,
}

/// A corner a window reports: its keypoint at the cell and its cell's middle (whole grid), which the whole
/// map's suppression orders it by, and where it lands on the map's pixels. Kept compact: a large map's
/// windows report hundreds of thousands.
pub struct Found {
    keypoint: Keypoint,
    centre: (i32, i32),
    /// The cell's first sample (whole grid): two cells can share a middle, never a first sample.
    origin: (i32, i32),
    /// `None` for a corner whose placed position its window knows to be suppressed.
    placed: Option<Keypoint>,
}

/// The corners of `window`'s cells that the suppression does not rule out for the whole map, placed, and
/// how many corners its cells had before suppression.
pub fn detect_window(
    backend: &mut dyn Backend,
    window: &Window,
    classes: &ClassTable,
    rules: &RuleTable,
    params: &RobustParams,
) -> Result<(Vec<Found>, usize)> {
    let scales = params.scales()?;
    let grid = &window.grid;
    let image = window.image;
    let coarse = backend.coarsen(image, classes, grid, &scales, params.cells)?;
    let mut found = Vec::new();
    for (&scale, map) in scales.iter().zip(&coarse) {
        crate::support::stop::check()?;
        let cells = Cells::new(map);
        let mosaic = Mosaic::new(grid, scale);
        let lattice = Lattice::new(grid, &mosaic);
        let mut masked = map.clone();
        for convex in [false, true] {
            if convex && !params.convex {
                continue;
            }
            lattice.mask(map, &mut masked, if convex { OCCUPIED } else { FREE });
            let hits = backend.detect(&masked, &coarse_classes(convex), rules, false)?;
            // Scored on every core; collected in the order found (the suppression's order does not
            // depend on it).
            let scored: Vec<Candidate> = hits
                .par_iter()
                .filter_map(|&k| {
                    let c = score(&cells, window, &mosaic, k, convex, params.min_strength)?;
                    window.trusted.contains(samples(c.origin)).then_some(c)
                })
                .collect();
            found.extend(scored);
        }
    }
    drop(coarse);
    let owned = found
        .iter()
        .filter(|c| window.owned.contains(samples(c.origin)))
        .count();
    // Suppression on the cell positions first, so only the survivors are placed on the map's pixels
    // (placing reads dozens of samples a corner); then again on the placed positions ([`finish`]). A
    // corner this window cannot rule out stays, even if another window will.
    let centres = (grid_centre2(grid, window.offset), grid.anchor2);
    let radius = params.nms_radius;
    let fates = candidate_fates(
        found.len(),
        |i| (&found[i].keypoint, found[i].centre, found[i].origin),
        radius,
        centres,
        &|i| window.settled.contains(found[i].at),
    );
    crate::support::stop::check()?;
    // The survivors are placed, those of the ring too: the suppression on the placed positions is then
    // decided here as well where it can be, so that the window reports about one corner a keypoint.
    let survivors: Vec<usize> = (0..found.len())
        .filter(|&i| fates[i] != Fate::Suppressed)
        .collect();
    let sampler = Sampler {
        image,
        classes,
        grid,
        wall_gap: params.wall_gap as i32,
    };
    let off = window.offset;
    let placed: Vec<(Keypoint, (f64, f64))> = survivors
        .par_iter()
        .map(|&i| {
            let c = &found[i];
            let k = c.keypoint;
            match c.arms {
                Some(arms) => {
                    let centre = (c.centre.0 - off.0, c.centre.1 - off.1);
                    let at = sampler.place(centre, &arms, k.convex, i32::from(k.scale));
                    let p = candidate(grid, at, k, u32::from(k.scale), k.convex, k.score as u32);
                    (p, (at.0 + f64::from(off.0), at.1 + f64::from(off.1)))
                }
                None => (k, c.at),
            }
        })
        .collect();
    // A placed corner is settled when every placed corner within the radius comes from the trusted cells
    // and survived their suppression for sure; near the map's edges, where positions are clamped, never.
    let (w, h) = grid.full_size;
    let edge = i64::from(radius) + 3;
    let inland = |k: &Keypoint| {
        let inside = |v: u32, n: u32| i64::from(v) >= edge && i64::from(v) + edge < i64::from(n);
        inside(k.x, w) && inside(k.y, h)
    };
    let fates2 = suppress::fates(
        placed.len(),
        |j| &placed[j].0,
        radius,
        centres.1,
        &|j| {
            fates[survivors[j]] == Fate::Kept
                && window.placed_settled.contains(placed[j].1)
                && inland(&placed[j].0)
        },
        // Corners placed on the same keypoint are ordered by their cells, as every window orders them
        // (by the order found, two windows could each keep the corner the other one reports).
        &|a, b| {
            let (x, y) = (&found[survivors[a]], &found[survivors[b]]);
            x.keypoint.cmp(&y.keypoint).then_with(|| {
                cell_key(x.centre, x.origin, centres.0)
                    .cmp(&cell_key(y.centre, y.origin, centres.0))
            })
        },
    );
    // A corner suppressed for sure on its placed position still suppresses on its cell position in the
    // whole map's first suppression: reported without a position where a corner of another window's
    // cells lies within the radius (whose window may not have seen it suppressed), or where its own first
    // fate is open.
    let mut foreign = suppress::Near::new(radius);
    for c in &found {
        if !window.owned.contains(samples(c.origin)) {
            foreign.add(&c.keypoint);
        }
    }
    let mut out = Vec::new();
    for (j, &i) in survivors.iter().enumerate() {
        let c = &found[i];
        if !window.owned.contains(samples(c.origin)) {
            continue;
        }
        let placed = match (fates[i], fates2[j]) {
            (Fate::Kept, Fate::Suppressed) if !foreign.any(&c.keypoint) => continue,
            (_, Fate::Suppressed) => None,
            _ => Some(placed[j].0),
        };
        out.push(Found {
            keypoint: c.keypoint,
            centre: c.centre,
            origin: c.origin,
            placed,
        });
    }
    Ok((out, owned))
}

/// The keypoints of the corners every window of a map reported ([`detect_window`]), in (y, x) order:
/// the suppression on the cell positions decided for the whole map, then on the placed positions. `grid`
/// is the whole map's grid.
pub fn finish(found: Vec<Found>, radius: u32, grid: &RotatedGrid) -> Vec<Keypoint> {
    let anchor2 = grid.anchor2;
    let fates = candidate_fates(
        found.len(),
        |i| (&found[i].keypoint, found[i].centre, found[i].origin),
        radius,
        (grid.centre2, anchor2),
        &|_| true,
    );
    let placed: Vec<Keypoint> = found
        .iter()
        .zip(fates)
        .filter(|(_, f)| *f == Fate::Kept)
        .filter_map(|(f, _)| f.placed)
        .collect();
    let mut kept = suppress(placed, radius, anchor2);
    kept.sort_unstable();
    kept
}

/// The grid's anchor in the whole grid's half samples, from any window of it.
fn grid_centre2(grid: &RotatedGrid, offset: (i32, i32)) -> (i64, i64) {
    (
        grid.centre2.0 + 2 * i64::from(offset.0),
        grid.centre2.1 + 2 * i64::from(offset.1),
    )
}

/// The fates of `n` corners (`corner(i)`: the keypoint at its cell and the cell's middle, whole grid) under
/// the suppression on cell positions ([`suppress::fates`]), in a map whose grid's anchor is `grid_c2` (half
/// samples of the whole grid) and `map_c2` (half pixels of the whole map). Corners equal as keypoints are
/// ordered by their cell's middle, nearer the anchor first (then by its position), so every window orders them
/// alike.
fn candidate_fates<'a>(
    n: usize,
    corner: impl Fn(usize) -> (&'a Keypoint, (i32, i32), (i32, i32)) + Sync,
    radius: u32,
    (grid_c2, map_c2): ((i64, i64), (i64, i64)),
    settled: &(dyn Fn(usize) -> bool + Sync),
) -> Vec<Fate> {
    suppress::fates(n, |i| corner(i).0, radius, map_c2, settled, &|i, j| {
        let (a, b) = (corner(i), corner(j));
        cell_key(a.1, a.2, grid_c2).cmp(&cell_key(b.1, b.2, grid_c2))
    })
}

/// The order of a cell (its middle `c` and first sample `o`, whole grid) among corners equal as keypoints:
/// middle nearer the grid's anchor `grid_c2` (half samples) first, then by the middle's position, then by
/// the first sample's (two cells of an even scale share a middle beside the centre); the same in every
/// window, and no two cells of one scale tie.
fn cell_key(c: (i32, i32), o: (i32, i32), grid_c2: (i64, i64)) -> (i64, i32, i32, i32, i32) {
    let (dp, dq) = (
        2 * i64::from(c.0) - grid_c2.0,
        2 * i64::from(c.1) - grid_c2.1,
    );
    (dp * dp + dq * dq, c.1, c.0, o.1, o.0)
}

/// A corner found on a coarse map, at its cell's position, before it is placed on the map's pixels.
pub struct Candidate {
    /// The keypoint at the cell position (the corner of the free cell where its walls meet; the
    /// occupied cell itself for a convex corner).
    keypoint: Keypoint,
    /// Its walls; `None` for a corner without two perpendicular walls (kept with `min_strength` 0).
    arms: Option<Arms>,
    /// The cell's middle sample, in the whole grid.
    centre: (i32, i32),
    /// The cell's first sample, in the whole grid.
    origin: (i32, i32),
    /// The keypoint's position in whole-grid samples.
    at: (f64, f64),
}

/// The candidate of a rule that fired at coarse cell (`k.x`, `k.y`) of `mosaic`: its walls' strength;
/// `None` below `min_strength`.
fn score(
    cells: &Cells,
    window: &Window,
    mosaic: &Mosaic,
    k: Keypoint,
    convex: bool,
    min_strength: u32,
) -> Option<Candidate> {
    let (grid, off) = (&window.grid, window.offset);
    let scale = mosaic.scale;
    let (u, v) = (k.x as i32, k.y as i32);
    // A rule fires only on a free or occupied cell, never in a gutter.
    let (p, q) = mosaic.origin(k.x, k.y)?;
    let c = (grid.box_middle(p, scale, 0), grid.box_middle(q, scale, 1));
    // Positions in the whole grid, so that every window of a map names a corner alike.
    let origin = (p + off.0, q + off.1);
    let shift = |(a, b): (i32, i32)| (a + off.0, b + off.1);
    let arms = if convex {
        convex_arms(cells, u, v)
    } else {
        concave_arms(cells, u, v)
    };
    let Some(arms) = arms else {
        return (min_strength == 0).then(|| Candidate {
            keypoint: candidate(grid, samples(c), k, scale, convex, 0),
            arms: None,
            centre: shift(c),
            origin,
            at: samples(shift(c)),
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
        centre: shift(c),
        origin,
        at: samples(shift(at)),
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
/// [`lattice_step`] about the grid's anchor (the map's centre by default), symmetric under quarter turns
/// and mirrors about it (a distance of `d` half samples from the anchor, along each axis, is on it when `d / 2` is a multiple of the step).
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
        use crate::map::states::UNKNOWN;
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

/// A sample position as a point of the grid's frame.
fn samples((p, q): (i32, i32)) -> (f64, f64) {
    (f64::from(p), f64::from(q))
}

/// A keypoint at grid position `(p, q)` (samples), rounded to the nearest map pixel inside the map (ties
/// towards the grid's anchor).
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
