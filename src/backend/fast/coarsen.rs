//! The fast twin of [`crate::backend::reference::coarsen`]: the same coarse maps, bit for bit. The rotated grid is
//! sampled once into two bit-planes (occupied, free), walking each grid row with integer increments (the
//! same sums [`RotatedGrid::source`] computes); the planes become two summed-area tables of `u8` (they
//! wrap, but a box of at most 15 x 15 samples counts below 256, so its difference of four corners is
//! exact), and every scale's box at every sample is then four lookups, rows spread over every core.

use rayon::prelude::*;

use crate::backend::fast::bitplanes::{self, plane_row, ValueSet};
use crate::backend::reference::coarsen::{CellRule, Mosaic, FREE, MAX_SCALE, OCCUPIED, UNKNOWN};
use crate::map::grid::{nearest, RotatedGrid};
use crate::map::states::{CellState, ClassTable};
use crate::map::MapImage;

/// The rotated grid's samples as planes: bit p of row q is sample (p, q).
struct Planes {
    words: usize,
    occupied: Vec<u64>,
    free: Vec<u64>,
}

/// Bytes of the planes and summed-area tables for `grid` at scales up to `max_scale`: two bytes and two
/// bits a sample of the grid padded by the largest scale on every side.
pub fn planes_bytes(grid: &RotatedGrid, max_scale: u32) -> u64 {
    let w = u64::from(grid.width) + 3 * u64::from(max_scale) + 1;
    let h = u64::from(grid.height) + 3 * u64::from(max_scale) + 1;
    (w.div_ceil(64) * 8 * 2 + 2 * w) * h
}

/// The coarse maps of `image` on `grid` (every phase, [`Mosaic`]), one per scale in `scales` (each
/// 1..=[`MAX_SCALE`]).
pub fn coarsen(
    image: &MapImage,
    classes: &ClassTable,
    grid: &RotatedGrid,
    scales: &[u32],
    rule: CellRule,
) -> Vec<MapImage> {
    assert!(scales.iter().all(|s| (1..=MAX_SCALE).contains(s)));
    let Some(&top) = scales.iter().max() else {
        return Vec::new();
    };
    // Boxes start from 1 - top (the first phase's first cell) and end by width + 2 top - 2 (the last
    // cell of phase 0, which covers the grid's end).
    let off = top as usize;
    let pw = grid.width as usize + 3 * off;
    let ph = grid.height as usize + 3 * off;
    let planes = sample_planes(image, classes, grid, off as i32, pw, ph);
    let sat = [
        summed_area(&planes.occupied, planes.words, pw, ph),
        summed_area(&planes.free, planes.words, pw, ph),
    ];
    drop(planes);
    scales
        .iter()
        .map(|&s| coarse_map(&sat, grid, s, rule, off, pw + 1))
        .collect()
}

/// The summed-area table of a plane, `u8` wrapping: entry (y, x) of the `(w + 1)` x `(h + 1)` table counts
/// the set bits of rows `< y`, columns `< x`, modulo 256.
fn summed_area(plane: &[u64], words: usize, w: usize, h: usize) -> Vec<u8> {
    let stride = w + 1;
    let mut sat = vec![0u8; stride * (h + 1)];
    // Each row's prefix counts, in parallel; then the rows added down, in parallel over column chunks.
    sat[stride..]
        .par_chunks_mut(stride)
        .enumerate()
        .for_each(|(y, out)| {
            let row = &plane[y * words..(y + 1) * words];
            let mut base = 0u32;
            for (k, &word) in row.iter().enumerate() {
                let x0 = k * 64;
                if x0 >= w {
                    break;
                }
                let n = (w - x0).min(64);
                if word == 0 {
                    out[x0 + 1..x0 + n + 1].fill(base as u8);
                } else {
                    for i in 0..n {
                        let m = if i == 63 { u64::MAX } else { (2u64 << i) - 1 };
                        out[x0 + 1 + i] = (base + (word & m).count_ones()) as u8;
                    }
                }
                base += word.count_ones();
            }
        });
    const CHUNK: usize = 4096;
    let cols: Vec<usize> = (0..stride).step_by(CHUNK).collect();
    let ptr = SatPtr(sat.as_mut_ptr());
    cols.par_iter().for_each(|&c0| {
        let c1 = (c0 + CHUNK).min(stride);
        let p = &ptr;
        for y in 1..=h {
            // SAFETY: every task owns columns c0..c1 of every row; the rows are distinct slices.
            let (above, row) = unsafe {
                (
                    std::slice::from_raw_parts(p.0.add((y - 1) * stride + c0), c1 - c0),
                    std::slice::from_raw_parts_mut(p.0.add(y * stride + c0), c1 - c0),
                )
            };
            for (r, &a) in row.iter_mut().zip(above) {
                *r = r.wrapping_add(a);
            }
        }
    });
    sat
}

/// The table's pointer, shared by the tasks that each add down their own columns.
struct SatPtr(*mut u8);
// SAFETY: the tasks write disjoint columns (see summed_area).
unsafe impl Sync for SatPtr {}

/// The planes of samples `(i - off, j - off)` for `i < pw`, `j < ph`.
fn sample_planes(
    image: &MapImage,
    classes: &ClassTable,
    grid: &RotatedGrid,
    off: i32,
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
    if grid.is_axis_aligned() {
        // Sample (p, q) is pixel (p + dx, q + dy): each row is the map row's planes, shifted.
        let (dx, dy) = grid.source(-off, -off);
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
            let q = q as i32 - off;
            // The same sums as RotatedGrid::source, one step of (cos, sin) per sample.
            let mut x = grid.ox - off * grid.cos - q * grid.sin;
            let mut y = grid.oy - off * grid.sin + q * grid.cos;
            for p in 0..pw {
                let (sx, sy) = (nearest(x, grid.cx), nearest(y, grid.cy));
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

/// The [`Mosaic`] of `scale` from the summed-area tables (`stride` entries a row) of the samples padded by
/// `off`.
fn coarse_map(
    sat: &[Vec<u8>; 2],
    grid: &RotatedGrid,
    scale: u32,
    rule: CellRule,
    off: usize,
    stride: usize,
) -> MapImage {
    let mosaic = Mosaic::new(grid, scale);
    let (cw, ch) = mosaic.size();
    let (tw, th) = (mosaic.tile_w as usize, mosaic.tile_h as usize);
    let s = scale as usize;
    let (occ_min, free_min) = rule.thresholds(scale);
    let (occ_min, free_min) = (occ_min as u8, free_min as u8);
    // Box origins p run from 1 - s (index off + 1 - s of the padded samples) to tw s - 1.
    let first = off + 1 - s;
    let n = tw * s;
    let mut out = vec![UNKNOWN; cw as usize * ch as usize];
    out.par_chunks_mut(cw as usize).enumerate().for_each_init(
        || vec![0u8; n],
        |values, (y, row)| {
            let (b, v) = (y / (th + 1), y % (th + 1));
            if v == th {
                return; // the gutter row
            }
            // Sample row q = v s - b; its boxes' rows, as table rows (padded index).
            let r0 = off + v * s - b;
            let (top, bottom) = (r0 * stride, (r0 + s) * stride);
            let [occ, free] = sat;
            // The four corners of every box of the row as slices the loop zips: no bounds checks, so
            // it vectorises.
            fn corners(t: &[u8], a: usize, b: usize, s: usize, n: usize) -> [&[u8]; 4] {
                [
                    &t[a..a + n],
                    &t[a + s..a + s + n],
                    &t[b..b + n],
                    &t[b + s..b + s + n],
                ]
            }
            let (a, b) = (top + first, bottom + first);
            let [o00, o01, o10, o11] = corners(occ, a, b, s, n);
            let [f00, f01, f10, f11] = corners(free, a, b, s, n);
            let values = &mut values[..n];
            for k in 0..n {
                let o = o11[k]
                    .wrapping_sub(o01[k])
                    .wrapping_sub(o10[k])
                    .wrapping_add(o00[k]);
                let f = f11[k]
                    .wrapping_sub(f01[k])
                    .wrapping_sub(f10[k])
                    .wrapping_add(f00[k]);
                let v = if f >= free_min { FREE } else { UNKNOWN };
                values[k] = if o >= occ_min { OCCUPIED } else { v };
            }
            // Phase a's cell u starts at p = u s - a, values[p - (1 - s)].
            for a in 0..s {
                let tile = &mut row[a * (tw + 1)..a * (tw + 1) + tw];
                let start = s - 1 - a;
                for (u, cell) in tile.iter_mut().enumerate() {
                    *cell = values[start + u * s];
                }
            }
        },
    );
    MapImage::new(cw, ch, out).expect("a grid has at least one cell")
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
