//! The fast twin of [`crate::cpu::coarsen`]: the same coarse maps, bit for bit. The rotated grid is
//! sampled once into two bit-planes (occupied, free), walking each grid row with integer increments (the
//! same sums [`RotatedGrid::source`] computes), and every scale's cells are then counted with popcounts
//! over those planes, rows spread over every core.

use rayon::prelude::*;

use crate::cpu::coarsen::{cell_thresholds, FREE, MAX_SCALE, OCCUPIED, UNKNOWN};
use crate::fast::bitplanes::{self, plane_row, ValueSet};
use crate::grid::{RotatedGrid, FRAC_BITS};
use crate::map::MapImage;
use crate::states::{CellState, ClassTable};

/// The rotated grid's samples as planes: bit p of row q is sample (p, q).
struct Planes {
    words: usize,
    occupied: Vec<u64>,
    free: Vec<u64>,
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
    // One spare zero word per row, so reading a chunk that ends in the next word never branches.
    let words = pw.div_ceil(64) + 1;
    let mut occupied = vec![0u64; words * ph];
    let mut free = vec![0u64; words * ph];
    let state: Vec<u8> = classes.states().iter().map(|&s| s as u8).collect();
    let (mw, mh) = (grid.map_width, grid.map_height);
    let px = image.pixels();
    let half = 1i32 << (FRAC_BITS - 1);
    if grid.is_axis_aligned() {
        // Sample (p, q) is pixel (p + dx, q + dy): each row is the map row's planes, shifted.
        let (dx, dy) = grid.source(0, 0);
        let (occ_set, free_set) = (
            ValueSet::of(classes, &[CellState::Occupied]),
            ValueSet::of(classes, &[CellState::Free]),
        );
        let mw = mw as usize;
        occupied
            .par_chunks_mut(words)
            .zip(free.par_chunks_mut(words))
            .enumerate()
            .for_each_init(
                || vec![0u64; bitplanes::words(mw)],
                |src, (q, (occ_row, free_row))| {
                    let y = q as i64 + i64::from(dy);
                    if y < 0 || y >= i64::from(mh) {
                        return;
                    }
                    let row = &px[y as usize * mw..(y as usize + 1) * mw];
                    for (set, out) in [(&occ_set, occ_row), (&free_set, free_row)] {
                        plane_row(set, row, src);
                        shifted(src, dx, &mut out[..words - 1]);
                    }
                },
            );
        return Planes {
            words,
            occupied,
            free,
        };
    }
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
    let mask = (1u64 << s) - 1;
    let wpr = planes.words;
    let mut out = vec![0u8; cw as usize * ch as usize];
    let (occ_min, free_min) = cell_thresholds(scale);
    out.par_chunks_mut(cw as usize).enumerate().for_each_init(
        || (vec![0u16; cw as usize], vec![0u16; cw as usize]),
        |(n_occ, n_free), (v, row)| {
            n_occ.fill(0);
            n_free.fill(0);
            for r in v * s..v * s + s {
                let occ = &planes.occupied[r * wpr..(r + 1) * wpr];
                let free = &planes.free[r * wpr..(r + 1) * wpr];
                add_row(occ, free, n_occ, n_free, s, mask);
            }
            for ((cell, &a), &b) in row.iter_mut().zip(n_occ.iter()).zip(n_free.iter()) {
                *cell = if u32::from(a) >= occ_min {
                    OCCUPIED
                } else if u32::from(b) >= free_min {
                    FREE
                } else {
                    UNKNOWN
                };
            }
        },
    );
    MapImage::new(cw, ch, out).expect("a grid has at least one cell")
}

/// Adds the set bits of one grid row's planes, cell by cell (`s` bits a cell), to the cells' counts.
fn add_row(occ: &[u64], free: &[u64], n_occ: &mut [u16], n_free: &mut [u16], s: usize, mask: u64) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("popcnt") {
            // SAFETY: the CPU has POPCNT, checked just above.
            return unsafe { add_row_popcnt(occ, free, n_occ, n_free, s, mask) };
        }
    }
    add_row_generic(occ, free, n_occ, n_free, s, mask)
}

/// [`add_row_generic`] compiled with the POPCNT instruction (the x86-64 baseline lacks it, and its
/// software popcount would make this loop several times slower).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt")]
fn add_row_popcnt(
    occ: &[u64],
    free: &[u64],
    n_occ: &mut [u16],
    n_free: &mut [u16],
    s: usize,
    mask: u64,
) {
    add_row_generic(occ, free, n_occ, n_free, s, mask)
}

#[inline(always)]
fn add_row_generic(
    occ: &[u64],
    free: &[u64],
    n_occ: &mut [u16],
    n_free: &mut [u16],
    s: usize,
    mask: u64,
) {
    for (u, (a, b)) in n_occ.iter_mut().zip(n_free.iter_mut()).enumerate() {
        let (k, o) = ((u * s) / 64, (u * s) % 64);
        // Bits o.. of word k, the rest from word k + 1 (a double shift, never by 64).
        let chunk = |p: &[u64]| ((p[k] >> o) | ((p[k + 1] << 1) << (63 - o))) & mask;
        *a += chunk(occ).count_ones() as u16;
        *b += chunk(free).count_ones() as u16;
    }
}

/// `out` bit p = `src` bit p + `dx` (zero outside `src`).
fn shifted(src: &[u64], dx: i32, out: &mut [u64]) {
    let word = |k: i64| -> u64 {
        if k >= 0 && (k as usize) < src.len() {
            src[k as usize]
        } else {
            0
        }
    };
    let (k0, o) = (
        i64::from(dx).div_euclid(64),
        i64::from(dx).rem_euclid(64) as u32,
    );
    for (j, w) in out.iter_mut().enumerate() {
        let k = k0 + j as i64;
        *w = if o == 0 {
            word(k)
        } else {
            (word(k) >> o) | (word(k + 1) << (64 - o))
        };
    }
}
