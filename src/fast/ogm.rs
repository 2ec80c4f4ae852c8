//! The fast twin of [`crate::cpu::ogm_corners`]: the same keypoints, 64 pixels at a time.
//!
//! Each row becomes two bit-planes (free, and "sets its bit in the code": occupied, or not free with
//! `unknown_as_occupied`). The eight neighbour planes of a word are shifts of the blocking planes of the
//! rows above, at and below it. A word is skipped unless some free pixel has at least as many blocking
//! neighbours as the smallest accepted code (a bit-sliced count); the few survivors get their code
//! gathered bit by bit and looked up in the one rule table, so the table stays the only statement of the
//! rules. Rows are split into bands across threads; a band keeps only three rows of planes, so the memory
//! beyond the map is a few kilobytes per thread plus the keypoints.

use rayon::prelude::*;

use super::bitplanes::{ogm_sets, plane_row, words, ValueSet};
use crate::backend::Keypoint;
use crate::map::MapImage;
use crate::rules::RuleTable;
use crate::states::ClassTable;

/// Rows per band at least: the rows above and below a band are classified twice, so bands are long.
const MIN_BAND_ROWS: usize = 64;

/// The classification and rule data every band shares.
struct Plan<'a> {
    free: ValueSet,
    blocking: ValueSet,
    table: &'a [u8; 256],
    /// Fewest set bits among the accepted codes: words with no candidate reaching it are skipped.
    min_bits: u32,
}

/// Every free pixel whose neighbour code `rules` accepts, sorted by (y, x); identical to the reference
/// (classification with `classes`, then [`crate::cpu::ogm_corners::ogm_corners`]).
pub fn ogm_corners(
    image: &MapImage,
    classes: &ClassTable,
    rules: &RuleTable,
    unknown_as_occupied: bool,
) -> Vec<Keypoint> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let Some(min_bits) = rules.min_accepted_bits() else {
        return Vec::new();
    };
    let (free, blocking) = ogm_sets(classes, unknown_as_occupied);
    let plan = Plan {
        free,
        blocking,
        table: rules.as_bytes(),
        min_bits,
    };
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let threads = rayon::current_num_threads().max(1);
    // About eight bands per thread balances uneven maps; never shorter than MIN_BAND_ROWS.
    let band = h.div_ceil(threads * 8).max(MIN_BAND_ROWS);
    let bands: Vec<Vec<Keypoint>> = (0..h.div_ceil(band))
        .into_par_iter()
        .map(|b| {
            let y0 = b * band;
            corners_in_band(image.pixels(), w, h, y0, (y0 + band).min(h), &plan)
        })
        .collect();
    let mut out = Vec::with_capacity(bands.iter().map(Vec::len).sum());
    for b in bands {
        out.extend(b);
    }
    out
}

/// The keypoints of rows `y0..y1`, in (y, x) order.
fn corners_in_band(
    px: &[u8],
    w: usize,
    h: usize,
    y0: usize,
    y1: usize,
    plan: &Plan,
) -> Vec<Keypoint> {
    let n = words(w);
    // Three rows of planes, indexed by row mod 3; rows outside the map stay all zero (nothing blocks).
    let mut free = vec![vec![0u64; n]; 3];
    let mut block = vec![vec![0u64; n]; 3];
    let row = |y: usize| &px[y * w..(y + 1) * w];
    let load = |y: usize, free: &mut [Vec<u64>], block: &mut [Vec<u64>]| {
        if y < h {
            plane_row(&plan.free, row(y), &mut free[y % 3]);
            plane_row(&plan.blocking, row(y), &mut block[y % 3]);
        } else {
            free[y % 3].fill(0);
            block[y % 3].fill(0);
        }
    };
    if y0 > 0 {
        load(y0 - 1, &mut free, &mut block);
    }
    load(y0, &mut free, &mut block);
    let mut out = Vec::new();
    for y in y0..y1 {
        load(y + 1, &mut free, &mut block);
        let zero;
        let up: &[u64] = if y > 0 {
            &block[(y + 2) % 3]
        } else {
            zero = vec![0u64; n];
            &zero
        };
        corners_in_row(
            &free[y % 3],
            up,
            &block[y % 3],
            &block[(y + 1) % 3],
            y as u32,
            plan,
            &mut out,
        );
    }
    out
}

/// Plane `r` moved so that bit x holds pixel x - 1 (the left neighbour); nothing left of the map.
#[inline(always)]
fn from_left(r: &[u64], k: usize) -> u64 {
    (r[k] << 1) | if k > 0 { r[k - 1] >> 63 } else { 0 }
}

/// Plane `r` moved so that bit x holds pixel x + 1 (the right neighbour); nothing right of the map.
#[inline(always)]
fn from_right(r: &[u64], k: usize) -> u64 {
    (r[k] >> 1) | if k + 1 < r.len() { r[k + 1] << 63 } else { 0 }
}

/// Bit-sliced sum of eight planes: four words holding bits 0..3 of each pixel's count.
#[inline(always)]
fn count8(n: &[u64; 8]) -> [u64; 4] {
    #[inline(always)]
    fn full_add(a: u64, b: u64, c: u64) -> (u64, u64) {
        let t = a ^ b;
        (t ^ c, (a & b) | (c & t))
    }
    let (s_a, c_a) = full_add(n[0], n[1], n[2]);
    let (s_b, c_b) = full_add(n[3], n[4], n[5]);
    let (s_c, c_c) = (n[6] ^ n[7], n[6] & n[7]);
    let (bit0, c_d) = full_add(s_a, s_b, s_c);
    let (t_s, t_c) = full_add(c_a, c_b, c_c);
    let (bit1, t_c2) = (t_s ^ c_d, t_s & c_d);
    [bit0, bit1, t_c ^ t_c2, t_c & t_c2]
}

/// Per pixel, whether the bit-sliced count is at least `m`.
#[inline(always)]
fn at_least(count: [u64; 4], m: u32) -> u64 {
    if m > 8 {
        return 0;
    }
    let (mut gt, mut eq) = (0u64, !0u64);
    for i in (0..4).rev() {
        if (m >> i) & 1 == 1 {
            eq &= count[i];
        } else {
            gt |= eq & count[i];
            eq &= !count[i];
        }
    }
    gt | eq
}

/// Appends the keypoints of one row, given its free plane and the blocking planes around it.
#[inline]
fn corners_in_row(
    free: &[u64],
    up: &[u64],
    mid: &[u64],
    down: &[u64],
    y: u32,
    plan: &Plan,
    out: &mut Vec<Keypoint>,
) {
    for k in 0..free.len() {
        let f = free[k];
        if f == 0 {
            continue;
        }
        // Bit order of the code (see crate::rules): Q, B, P, A, Q', B', P', A' clockwise from top-left.
        let n = [
            from_left(up, k),
            up[k],
            from_right(up, k),
            from_right(mid, k),
            from_right(down, k),
            down[k],
            from_left(down, k),
            from_left(mid, k),
        ];
        let any = n.iter().fold(0, |a, &b| a | b);
        if f & any == 0 {
            continue;
        }
        let mut cand = f & at_least(count8(&n), plan.min_bits);
        while cand != 0 {
            let j = cand.trailing_zeros();
            cand &= cand - 1;
            let code = n
                .iter()
                .enumerate()
                .fold(0u8, |c, (i, &p)| c | ((((p >> j) & 1) as u8) << i));
            let rule = plan.table[code as usize];
            if rule != 0 {
                out.push(Keypoint::ogm((k * 64) as u32 + j, y, rule, code));
            }
        }
    }
}
