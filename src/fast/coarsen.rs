//! The fast twin of [`crate::cpu::coarsen`]: the same coarse maps, bit for bit. The rotated grid is
//! sampled once into two bit-planes (occupied, free), walking each grid row with integer increments (the
//! same sums [`RotatedGrid::source`] computes), and every scale's cells are then counted with popcounts
//! over those planes, rows spread over every core.

use rayon::prelude::*;

use crate::cpu::coarsen::{cell_value, MAX_SCALE};
use crate::grid::{RotatedGrid, FRAC_BITS};
use crate::map::MapImage;
use crate::states::{CellState, ClassTable};

/// The rotated grid's samples as planes: bit p of row q is sample (p, q).
struct Planes {
    words: usize,
    occupied: Vec<u64>,
    free: Vec<u64>,
}

impl Planes {
    /// `bits` bits of row `q` of `plane` from bit `p` (bits <= 64).
    #[inline(always)]
    fn bits(&self, plane: &[u64], q: usize, p: usize, bits: usize) -> u64 {
        let row = &plane[q * self.words..(q + 1) * self.words];
        let (k, o) = (p / 64, p % 64);
        let mut v = row[k] >> o;
        if o + bits > 64 {
            v |= row[k + 1] << (64 - o);
        }
        if bits == 64 {
            v
        } else {
            v & ((1u64 << bits) - 1)
        }
    }
}

/// Bytes of the planes for `grid` at scales up to `max_scale`: two bits a sample.
pub fn planes_bytes(grid: &RotatedGrid, max_scale: u32) -> u64 {
    let w = u64::from(grid.width) + u64::from(max_scale);
    let h = u64::from(grid.height) + u64::from(max_scale);
    w.div_ceil(64) * 8 * 2 * h
}

/// The coarse maps of `image` on `grid`, one per scale in `scales` (each 1..=[`MAX_SCALE`]).
pub fn coarsen(
    image: &MapImage,
    classes: &ClassTable,
    grid: &RotatedGrid,
    scales: &[u32],
) -> Vec<MapImage> {
    assert!(scales.iter().all(|s| (1..=MAX_SCALE).contains(s)));
    let Some(&top) = scales.iter().max() else {
        return Vec::new();
    };
    // Every scale's cells inside the padded extent.
    let pw = scales
        .iter()
        .map(|&s| grid.coarse_size(s).0 * s)
        .max()
        .unwrap_or(0)
        .max(top) as usize;
    let ph = scales
        .iter()
        .map(|&s| grid.coarse_size(s).1 * s)
        .max()
        .unwrap_or(0) as usize;
    let planes = sample_planes(image, classes, grid, pw, ph);
    scales
        .iter()
        .map(|&s| coarse_map(&planes, grid, s))
        .collect()
}

fn sample_planes(
    image: &MapImage,
    classes: &ClassTable,
    grid: &RotatedGrid,
    pw: usize,
    ph: usize,
) -> Planes {
    let words = pw.div_ceil(64);
    let mut occupied = vec![0u64; words * ph];
    let mut free = vec![0u64; words * ph];
    let state: Vec<u8> = classes.states().iter().map(|&s| s as u8).collect();
    let (mw, mh) = (grid.map_width, grid.map_height);
    let px = image.pixels();
    let half = 1i32 << (FRAC_BITS - 1);
    occupied
        .par_chunks_mut(words)
        .zip(free.par_chunks_mut(words))
        .enumerate()
        .for_each(|(q, (occ_row, free_row))| {
            let q = q as i32;
            // The same sums as RotatedGrid::source, one step of (cos, sin) per sample.
            let mut x = grid.ox - q * grid.sin + half;
            let mut y = grid.oy + q * grid.cos + half;
            for p in 0..pw {
                let (sx, sy) = (x >> FRAC_BITS, y >> FRAC_BITS);
                x += grid.cos;
                y += grid.sin;
                if (sx as u32) < mw && (sy as u32) < mh {
                    let s = state[px[sy as usize * mw as usize + sx as usize] as usize];
                    let bit = 1u64 << (p % 64);
                    if s == CellState::Occupied as u8 {
                        occ_row[p / 64] |= bit;
                    } else if s == CellState::Free as u8 {
                        free_row[p / 64] |= bit;
                    }
                }
            }
        });
    Planes {
        words,
        occupied,
        free,
    }
}

fn coarse_map(planes: &Planes, grid: &RotatedGrid, scale: u32) -> MapImage {
    let (cw, ch) = grid.coarse_size(scale);
    let s = scale as usize;
    let mut out = vec![0u8; cw as usize * ch as usize];
    out.par_chunks_mut(cw as usize)
        .enumerate()
        .for_each(|(v, row)| {
            for (u, cell) in row.iter_mut().enumerate() {
                let (mut occ, mut free) = (0, 0);
                for q in v * s..v * s + s {
                    occ += planes.bits(&planes.occupied, q, u * s, s).count_ones();
                    free += planes.bits(&planes.free, q, u * s, s).count_ones();
                }
                *cell = cell_value(occ, free, scale);
            }
        });
    MapImage::new(cw, ch, out).expect("a grid has at least one cell")
}
