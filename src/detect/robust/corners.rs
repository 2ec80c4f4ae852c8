//! What the robust detector adds to a rule that fired on a coarse map: a strength (how far the two walls
//! of the corner run) and a position on the walls themselves, measured on the map's own pixels.
//!
//! Host code over the few cells where a rule fired, shared by every backend.

use crate::map::grid::sample;
use crate::map::grid::RotatedGrid;
use crate::map::states::{CellState, ClassTable};
use crate::map::states::{FREE, OCCUPIED};
use crate::map::MapImage;

/// Longest wall arm measured, in coarse cells.
pub const MAX_ARM_CELLS: i32 = 64;

/// The scale whose layout of cross-sections places every corner finally, whatever scale found it.
pub const CANONICAL_SCALE: i32 = 4;

/// Cross-sections of a wall measured at most, per wall of a corner.
pub const MAX_SECTIONS: i32 = 9;

/// The four axis directions of the coarse grid: up, right, down, left.
const DIRS: [(i32, i32); 4] = [(0, -1), (1, 0), (0, 1), (-1, 0)];

/// A coarse map's cells, read with unknown outside.
pub struct Cells<'a> {
    map: &'a MapImage,
}

impl<'a> Cells<'a> {
    /// Reads `map`, a coarse map written by the coarsening kernel.
    pub fn new(map: &'a MapImage) -> Self {
        Cells { map }
    }

    #[inline]
    fn at(&self, u: i32, v: i32) -> u8 {
        let (w, h) = (self.map.width(), self.map.height());
        if u < 0 || v < 0 || u as u32 >= w || v as u32 >= h {
            crate::map::states::UNKNOWN
        } else {
            self.map.pixels()[v as usize * w as usize + u as usize]
        }
    }
}

/// A corner's two walls: their directions from the corner cell and the shorter arm, in cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Arms {
    /// Cells the shorter of the two walls runs (0 when the corner has no two perpendicular walls).
    pub cells: i32,
    /// Direction of the first wall.
    pub d1: (i32, i32),
    /// Direction of the second wall, perpendicular to the first.
    pub d2: (i32, i32),
}

/// The arms of a concave corner at free cell (u, v): the occupied cells beside it (up, right, down,
/// left) are walls; each wall's arm is how many cells it runs on with free cells along its inner side,
/// going away from the corner. The two longest perpendicular walls make the corner.
pub fn concave_arms(cells: &Cells, u: i32, v: i32) -> Option<Arms> {
    // At most four walls, kept on the stack: this runs for every rule hit.
    let mut found = [(0i32, 0usize); 4];
    let mut n = 0;
    for (i, &(dx, dy)) in DIRS.iter().enumerate() {
        let (wx, wy) = (u + dx, v + dy);
        if cells.at(wx, wy) != OCCUPIED {
            continue;
        }
        let run = [(-dy, dx), (dy, -dx)]
            .iter()
            .map(|&(px, py)| {
                let mut k = 0;
                while k < MAX_ARM_CELLS
                    && cells.at(wx + px * (k + 1), wy + py * (k + 1)) == OCCUPIED
                    && cells.at(u + px * (k + 1), v + py * (k + 1)) == FREE
                {
                    k += 1;
                }
                k
            })
            .max()
            .unwrap_or(0);
        found[n] = (run, i);
        n += 1;
    }
    let found = &mut found[..n];
    // Longest first; equal runs keep the direction order, so the choice is deterministic.
    found.sort_unstable_by_key(|&(run, i)| (std::cmp::Reverse(run), i));
    for a in 0..found.len() {
        for b in a + 1..found.len() {
            let (da, db) = (DIRS[found[a].1], DIRS[found[b].1]);
            if da.0 * db.0 + da.1 * db.1 == 0 {
                return Some(Arms {
                    cells: found[a].0.min(found[b].0),
                    d1: da,
                    d2: db,
                });
            }
        }
    }
    None
}

/// The arms of a convex corner at occupied cell (u, v): two perpendicular walls leave it (occupied
/// cells on two adjacent sides, free cells on the two others), each arm running while the wall's outer
/// side stays free.
pub fn convex_arms(cells: &Cells, u: i32, v: i32) -> Option<Arms> {
    let mut best: Option<Arms> = None;
    for i in 0..4 {
        let (a, b) = (DIRS[i], DIRS[(i + 1) % 4]);
        if cells.at(u + a.0, v + a.1) != OCCUPIED
            || cells.at(u + b.0, v + b.1) != OCCUPIED
            || cells.at(u - a.0, v - a.1) != FREE
            || cells.at(u - b.0, v - b.1) != FREE
        {
            continue;
        }
        let run = |d: (i32, i32), o: (i32, i32)| {
            let mut k = 0;
            while k < MAX_ARM_CELLS
                && cells.at(u + d.0 * (k + 1), v + d.1 * (k + 1)) == OCCUPIED
                && cells.at(u + d.0 * (k + 1) + o.0, v + d.1 * (k + 1) + o.1) == FREE
            {
                k += 1;
            }
            k
        };
        let m = run(a, (-b.0, -b.1)).min(run(b, (-a.0, -a.1)));
        if best.is_none_or(|x| m > x.cells) {
            best = Some(Arms {
                cells: m,
                d1: a,
                d2: b,
            });
        }
    }
    best
}

/// Samples the map through the grid (the coarsening kernel's own sampling).
pub struct Sampler<'a> {
    /// The map.
    pub image: &'a MapImage,
    /// Its classification.
    pub classes: &'a ClassTable,
    /// The grid.
    pub grid: &'a RotatedGrid,
    /// Unknown samples a wall's cross-section bridges between occupied ones
    /// ([`crate::detect::robust::RobustParams::wall_gap`]): a person marks the middle of a wall seen from both
    /// sides.
    pub wall_gap: i32,
}

impl Sampler<'_> {
    /// The median centre of the wall met walking `walk` from `base + j along` for t in `ts`, over the
    /// cross-sections `js`: where the wall's centre line lies along `walk`, in samples from `base`. The
    /// wall runs from the first occupied sample to the last one before a free sample, bridging up to
    /// `wall_gap` unknown ones. `None` when no cross-section meets a wall.
    fn wall_centre(
        &self,
        base: (i32, i32),
        walk: (i32, i32),
        along: (i32, i32),
        js: std::ops::Range<i32>,
        ts: std::ops::Range<i32>,
    ) -> Option<f64> {
        let mut mids: Vec<i32> = Vec::new();
        // At most MAX_SECTIONS cross-sections, evenly strided: the median needs no more.
        let step = js.len().div_ceil(MAX_SECTIONS as usize).max(1);
        for j in js.step_by(step) {
            let (bp, bq) = (base.0 + along.0 * j, base.1 + along.1 * j);
            let mut run: Option<(i32, i32)> = None;
            for t in ts.clone() {
                let st = sample(
                    self.image,
                    self.classes,
                    self.grid,
                    bp + walk.0 * t,
                    bq + walk.1 * t,
                );
                match (st, run) {
                    (CellState::Occupied, None) => run = Some((t, t)),
                    (CellState::Occupied, Some((s, _))) => run = Some((s, t)),
                    (CellState::Free, Some(_)) => break,
                    (CellState::Unknown, Some((_, e))) if t - e > self.wall_gap => break,
                    _ => {}
                }
            }
            if let Some((s, e)) = run {
                mids.push(s + e); // twice the centre: exact in integers
            }
        }
        if mids.is_empty() {
            return None;
        }
        mids.sort_unstable();
        let n = mids.len();
        let twice = if n % 2 == 1 {
            f64::from(mids[n / 2])
        } else {
            (f64::from(mids[n / 2 - 1]) + f64::from(mids[n / 2])) / 2.0
        };
        Some(twice / 2.0)
    }

    /// The corner's position in grid samples: where the centre lines of its two walls cross, measured on
    /// cross-sections along each arm near the corner. `centre` is the corner cell's middle sample.
    ///
    /// The first estimate comes from cross-sections laid out from the coarse cell at its scale; it is then
    /// measured twice more from the estimate itself, at [`CANONICAL_SCALE`] whatever scale found the
    /// corner, so that where a corner lands depends on its walls, not on where the grid's cells fell or
    /// which scale won the suppression (repeatability under turns and crops gains 1-4 points).
    pub fn place(&self, centre: (i32, i32), arms: &Arms, convex: bool, scale: i32) -> (f64, f64) {
        let mut at = self.place_from(centre, arms, convex, scale);
        let (d1, d2) = (arms.d1, arms.d2);
        // Concave corners are measured from inside the free corner, this far back from the estimate.
        let back = 2 + CANONICAL_SCALE / 2;
        let arms = Arms { cells: 3, ..*arms };
        for _ in 0..2 {
            let corner = self.grid.round_sample(at);
            let base = if convex {
                corner
            } else {
                (
                    corner.0 - (d1.0 + d2.0) * back,
                    corner.1 - (d1.1 + d2.1) * back,
                )
            };
            at = self.place_from(base, &arms, convex, CANONICAL_SCALE);
        }
        at
    }

    /// One measurement of [`Sampler::place`] from `centre` (the free cell's middle for a concave corner,
    /// the corner for a convex one), its cross-sections laid out for `scale`.
    fn place_from(&self, centre: (i32, i32), arms: &Arms, convex: bool, scale: i32) -> (f64, f64) {
        let (d1, d2) = (arms.d1, arms.d2);
        let len = (arms.cells * scale).clamp(scale, 3 * scale);
        let at = |m1: f64, m2: f64, n1: (i32, i32), n2: (i32, i32)| {
            (
                f64::from(centre.0) + f64::from(n1.0) * m1 + f64::from(n2.0) * m2,
                f64::from(centre.1) + f64::from(n1.1) * m1 + f64::from(n2.1) * m2,
            )
        };
        let neg = |d: (i32, i32)| (-d.0, -d.1);
        if !convex {
            // Each wall is crossed walking towards it from the free cell, along the other wall's arm.
            let reach = 0..3 * scale + 2;
            let m1 = self.wall_centre(centre, d1, neg(d2), 0..len + 1, reach.clone());
            let m2 = self.wall_centre(centre, d2, neg(d1), 0..len + 1, reach);
            match (m1, m2) {
                (Some(m1), Some(m2)) => at(m1, m2, d1, d2),
                // The diagonal cell, where the two walls meet.
                _ => at(f64::from(scale), f64::from(scale), d1, d2),
            }
        } else {
            // Each arm is crossed from its free outer side, beyond the corner cell.
            let reach = -2 * scale..2 * scale + 1;
            let m1 = self.wall_centre(centre, d2, d1, scale..scale + len + 1, reach.clone());
            let m2 = self.wall_centre(centre, d1, d2, scale..scale + len + 1, reach);
            match (m1, m2) {
                (Some(m1), Some(m2)) => at(m1, m2, d2, d1),
                _ => at(0.0, 0.0, d1, d2),
            }
        }
    }
}
