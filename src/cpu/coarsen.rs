//! CPU twin of the coarsening kernel (`shaders/coarsen.wgsl`): the map sampled on a rotated grid
//! ([`crate::grid`]), every `scale` x `scale` block of samples becoming one cell of a coarse map.
//!
//! A cell is occupied when at least 15% of its samples are occupied (a jagged wall a pixel or two thick
//! still fills every cell it crosses), else free when at least 40% are free, else unknown (thresholds
//! calibrated on half of the annotated maps, see docs/detectors.md).
//! Samples outside the map are unknown. The coarse map is written with the values of [`OCCUPIED`],
//! [`FREE`] and [`UNKNOWN`], so the paper's detector runs on it unchanged.

use crate::grid::RotatedGrid;
use crate::map::MapImage;
use crate::states::{CellState, ClassTable};

/// The coarse cells' values: ROS map_server's.
pub use crate::states::{FREE, OCCUPIED, UNKNOWN};

/// Largest scale (samples a side of a cell).
pub const MAX_SCALE: u32 = 16;

/// The fewest occupied samples that make a cell of `scale` occupied, and the fewest free ones that make
/// it free (when it is not occupied).
pub fn cell_thresholds(scale: u32) -> (u32, u32) {
    let n = scale * scale;
    ((3 * n).div_ceil(20).max(1), (2 * n).div_ceil(5).max(1))
}

/// The value of a cell with `occupied` and `free` samples among `scale`^2.
#[inline]
pub fn cell_value(occupied: u32, free: u32, scale: u32) -> u8 {
    let (occ_min, free_min) = cell_thresholds(scale);
    if occupied >= occ_min {
        OCCUPIED
    } else if free >= free_min {
        FREE
    } else {
        UNKNOWN
    }
}

/// The state of sample (p, q) of `grid` over `image`: the nearest map pixel's, unknown outside the map.
#[inline]
pub fn sample(
    image: &MapImage,
    classes: &ClassTable,
    grid: &RotatedGrid,
    p: i32,
    q: i32,
) -> CellState {
    match grid.source_index(p, q) {
        Some(i) => classes.state(image.pixels()[i]),
        None => CellState::Unknown,
    }
}

/// The coarse map of `image` on `grid` at `scale` (1..=[`MAX_SCALE`]):
/// [`RotatedGrid::coarse_size`] cells.
pub fn coarsen(image: &MapImage, classes: &ClassTable, grid: &RotatedGrid, scale: u32) -> MapImage {
    assert!(
        (1..=MAX_SCALE).contains(&scale),
        "scale {scale} out of range"
    );
    let (cw, ch) = grid.coarse_size(scale);
    let mut out = Vec::with_capacity(cw as usize * ch as usize);
    for v in 0..ch {
        for u in 0..cw {
            let (mut occupied, mut free) = (0, 0);
            for j in 0..scale {
                for i in 0..scale {
                    let p = (u * scale + i) as i32;
                    let q = (v * scale + j) as i32;
                    match sample(image, classes, grid, p, q) {
                        CellState::Occupied => occupied += 1,
                        CellState::Free => free += 1,
                        CellState::Unknown => {}
                    }
                }
            }
            out.push(cell_value(occupied, free, scale));
        }
    }
    MapImage::new(cw, ch, out).expect("a grid has at least one cell")
}
