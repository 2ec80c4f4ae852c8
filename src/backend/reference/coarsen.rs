//! CPU twin of the coarsening kernel (`shaders/coarsen.wgsl`): the map sampled on a rotated grid
//! ([`crate::map::grid`]), every `scale` x `scale` box of samples becoming one coarse cell, **at every grid
//! phase**: a box starts at every sample, not only at multiples of the scale, so that whether a corner is
//! found does not depend on where a block grid falls (a crop, a quarter turn or a mirror moves it).
//!
//! The boxes of one phase (a, b) (those starting at samples `(u scale - a, v scale - b)`) are a coarse map
//! on which the paper's rules run unchanged; the kernel writes the `scale`^2 phases side by side as the
//! tiles of one [`Mosaic`], separated by a line of unknown cells, so the paper's detector runs once over
//! all of them and no corner's 3 x 3 neighbourhood crosses from one phase into another.
//!
//! A cell is occupied when at least 15% of its samples are occupied (a jagged wall a pixel or two thick
//! still fills every cell it crosses), else free when at least 40% are free, else unknown ([`CellRule`]:
//! both shares are options).
//! Samples outside the map are unknown. The coarse map is written with the values of [`OCCUPIED`],
//! [`FREE`] and [`UNKNOWN`], so the paper's detector runs on it unchanged.

use crate::map::grid::{sample, RotatedGrid};
use crate::map::states::{CellState, ClassTable};
use crate::map::MapImage;

/// The coarse cells' values: ROS map_server's.
pub use crate::map::states::{FREE, OCCUPIED, UNKNOWN};

/// Largest scale (samples a side of a cell): a cell's counts fit a byte (the fast path's summed-area
/// tables wrap in `u8`).
pub const MAX_SCALE: u32 = 15;

/// Where the cells of every grid phase lie in a scale's coarse map: phase (a, b) is the tile at column
/// `a`, row `b`, each tile `tile_w` x `tile_h` cells plus one unknown column and row (the gutter).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mosaic {
    /// The scale: samples a side of a cell, and tiles a side of the mosaic.
    pub scale: u32,
    /// Cells a tile row: enough that the cells of every phase cover every sample of the grid.
    pub tile_w: u32,
    /// Cell rows a tile.
    pub tile_h: u32,
}

impl Mosaic {
    /// The layout of `grid`'s cells at `scale`.
    pub fn new(grid: &RotatedGrid, scale: u32) -> Self {
        Mosaic {
            scale,
            tile_w: (grid.width + scale - 1).div_ceil(scale),
            tile_h: (grid.height + scale - 1).div_ceil(scale),
        }
    }

    /// The coarse map's size in cells: (columns, rows).
    pub fn size(&self) -> (u32, u32) {
        (
            (self.tile_w + 1) * self.scale,
            (self.tile_h + 1) * self.scale,
        )
    }

    /// The first sample (p, q) of the cell at column `x`, row `y` of the coarse map; `None` in a gutter.
    #[inline]
    pub fn origin(&self, x: u32, y: u32) -> Option<(i32, i32)> {
        Some((self.column_origin(x)?, self.row_origin(y)?))
    }

    /// The first sample p of the cells of column `x`; `None` in a gutter.
    #[inline]
    pub fn column_origin(&self, x: u32) -> Option<i32> {
        self.axis_origin(x, self.tile_w)
    }

    /// The first sample q of the cells of row `y`; `None` in a gutter.
    #[inline]
    pub fn row_origin(&self, y: u32) -> Option<i32> {
        self.axis_origin(y, self.tile_h)
    }

    fn axis_origin(&self, c: u32, n: u32) -> Option<i32> {
        let (phase, u) = (c / (n + 1), c % (n + 1));
        (u < n).then(|| (u * self.scale) as i32 - phase as i32)
    }

    /// The samples the cells of columns `x0..x1` start at, from the first to one past the last box's end.
    pub fn sample_span(&self, x0: u32, x1: u32, tile: u32) -> (i32, i32) {
        let (s, pitch) = (self.scale as i32, tile as i32 + 1);
        let (x0, x1) = (x0 as i32, x1 as i32 - 1);
        if x0 / pitch != x1 / pitch {
            // Across phases: the whole extent every phase's cells reach.
            return (1 - s, tile as i32 * s);
        }
        let a = x0 / pitch;
        let (u0, u1) = (
            (x0 % pitch).min(tile as i32 - 1),
            (x1 % pitch).min(tile as i32 - 1),
        );
        (u0 * s - a, u1 * s - a + s)
    }
}

/// How a cell's samples decide its value: occupied when at least `occupied_pct`% of them are occupied,
/// else free when at least `free_pct`% are free, else unknown.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CellRule {
    /// Share of occupied samples, percent (1..=100), that makes a cell occupied.
    pub occupied_pct: u32,
    /// Share of free samples, percent (1..=100), that makes a cell that is not occupied free.
    pub free_pct: u32,
}

impl Default for CellRule {
    /// 15% and 40%. Checked leave-one-building-out (`scripts/figures.py robust-lobo-cells`, see
    /// docs/detectors.md): lower occupied shares catch walls thinner than 15% of a cell at the larger
    /// scales, but those cells then flicker under rotation; higher ones trade marked-corner recall for
    /// repeatability.
    fn default() -> Self {
        CellRule {
            occupied_pct: 15,
            free_pct: 40,
        }
    }
}

impl CellRule {
    /// Checks the shares (each 1..=100).
    pub fn check(&self) -> crate::support::error::Result<()> {
        for (name, v) in [("occupied", self.occupied_pct), ("free", self.free_pct)] {
            if !(1..=100).contains(&v) {
                return Err(crate::support::error::Error::invalid(format!(
                    "the {name} share of a coarse cell must be 1 to 100 percent, got {v}"
                )));
            }
        }
        Ok(())
    }

    /// The fewest occupied samples that make a cell of `scale` occupied, and the fewest free ones that
    /// make it free (when it is not occupied). A share over 100% (refused by the options, possible
    /// through this type alone) gives `scale^2 + 1`: a count no cell reaches, the same on every path (the
    /// fast path compares in `u8`).
    pub fn thresholds(&self, scale: u32) -> (u32, u32) {
        let n = scale * scale;
        let of = |pct: u32| (pct.min(101) * n).div_ceil(100).clamp(1, n + 1);
        (of(self.occupied_pct), of(self.free_pct))
    }
}

/// The value of a cell with `occupied` and `free` samples among `scale`^2.
#[inline]
pub fn cell_value(occupied: u32, free: u32, scale: u32, rule: CellRule) -> u8 {
    let (occ_min, free_min) = rule.thresholds(scale);
    if occupied >= occ_min {
        OCCUPIED
    } else if free >= free_min {
        FREE
    } else {
        UNKNOWN
    }
}

/// The value of the box of `scale` x `scale` samples starting at sample (p, q).
pub fn box_value(
    image: &MapImage,
    classes: &ClassTable,
    grid: &RotatedGrid,
    (p, q): (i32, i32),
    scale: u32,
    rule: CellRule,
) -> u8 {
    let (mut occupied, mut free) = (0, 0);
    for j in 0..scale as i32 {
        for i in 0..scale as i32 {
            match sample(image, classes, grid, p + i, q + j) {
                CellState::Occupied => occupied += 1,
                CellState::Free => free += 1,
                CellState::Unknown => {}
            }
        }
    }
    cell_value(occupied, free, scale, rule)
}

/// The coarse map of `image` on `grid` at `scale` (1..=[`MAX_SCALE`]), every phase: the
/// [`Mosaic`]'s cells.
pub fn coarsen(
    image: &MapImage,
    classes: &ClassTable,
    grid: &RotatedGrid,
    scale: u32,
    rule: CellRule,
) -> MapImage {
    assert!(
        (1..=MAX_SCALE).contains(&scale),
        "scale {scale} out of range"
    );
    let mosaic = Mosaic::new(grid, scale);
    let (cw, ch) = mosaic.size();
    let mut out = Vec::with_capacity(cw as usize * ch as usize);
    for y in 0..ch {
        for x in 0..cw {
            out.push(match mosaic.origin(x, y) {
                Some(at) => box_value(image, classes, grid, at, scale, rule),
                None => UNKNOWN,
            });
        }
    }
    MapImage::new(cw, ch, out).expect("a grid has at least one cell")
}

/// One phase only, the blocks starting at multiples of `scale` (the coarse map of a fixed block grid,
/// [`RotatedGrid::coarse_size`] cells): the tile (0, 0) of [`coarsen`]'s mosaic, kept as its oracle.
pub fn coarsen_blocks(
    image: &MapImage,
    classes: &ClassTable,
    grid: &RotatedGrid,
    scale: u32,
    rule: CellRule,
) -> MapImage {
    let (cw, ch) = grid.coarse_size(scale);
    let s = scale as i32;
    let out = (0..ch as i32)
        .flat_map(|v| (0..cw as i32).map(move |u| (u * s, v * s)))
        .map(|at| box_value(image, classes, grid, at, scale, rule))
        .collect();
    MapImage::new(cw, ch, out).expect("a grid has at least one cell")
}
