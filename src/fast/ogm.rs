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

use super::bitplanes::{ogm_sets, plane_rows2, words, ValueSet};
use crate::backend::Keypoint;
use crate::map::MapImage;
use crate::rules::RuleTable;
use crate::states::ClassTable;
use crate::stream::Rows;

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
    let core = (0, image.height() as usize);
    ogm_corners_rows(Rows::of(image), core, classes, rules, unknown_as_occupied)
}

/// [`ogm_corners`] of rows `core` of a window of rows (which holds the rows above and below the core
/// that the map has).
pub fn ogm_corners_rows(
    rows: Rows,
    core: (usize, usize),
    classes: &ClassTable,
    rules: &RuleTable,
    unknown_as_occupied: bool,
) -> Vec<Keypoint> {
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
    let n = core.1.saturating_sub(core.0);
    if n == 0 {
        return Vec::new();
    }
    let threads = rayon::current_num_threads().max(1);
    // About eight bands per thread balances uneven maps; never shorter than MIN_BAND_ROWS, or on wide
    // maps than a megapixel (a streamed window of a wide map is only a few hundred rows).
    let min_rows = MIN_BAND_ROWS.min(((1usize << 20) / rows.width()).max(4));
    let band = n.div_ceil(threads * 8).max(min_rows);
    let bands: Vec<Vec<Keypoint>> = (0..n.div_ceil(band))
        .into_par_iter()
        .map(|b| {
            let y0 = core.0 + b * band;
            corners_in_band(rows, y0, (y0 + band).min(core.1), &plan)
        })
        .collect();
    let mut out = Vec::with_capacity(bands.iter().map(Vec::len).sum());
    for b in bands {
        out.extend(b);
    }
    out
}

/// The keypoints of rows `y0..y1`, in (y, x) order.
fn corners_in_band(px: Rows, y0: usize, y1: usize, plan: &Plan) -> Vec<Keypoint> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("bmi1") {
        // SAFETY: the CPU has AVX2 and BMI1, checked just above; that is the only requirement.
        return unsafe { corners_in_band_avx2(px, y0, y1, plan) };
    }
    corners_in_band_impl(px, y0, y1, plan)
}

/// [`corners_in_band_impl`] compiled for AVX2 and BMI1 (wider compares, one-instruction bit scans).
///
/// # Safety
/// The CPU must have AVX2 and BMI1.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1")]
unsafe fn corners_in_band_avx2(px: Rows, y0: usize, y1: usize, plan: &Plan) -> Vec<Keypoint> {
    corners_in_band_impl(px, y0, y1, plan)
}

/// See [`corners_in_band`]; inlined into each instruction-set variant.
#[inline(always)]
fn corners_in_band_impl(px: Rows, y0: usize, y1: usize, plan: &Plan) -> Vec<Keypoint> {
    let (w, h) = (px.width(), px.height());
    let n = words(w);
    // Three rows of planes, indexed by row mod 3; rows outside the map stay all zero (nothing blocks).
    let mut free = vec![vec![0u64; n]; 3];
    let mut block = vec![vec![0u64; n]; 3];
    let row = |y: usize| px.row(y);
    let load = |y: usize, free: &mut [Vec<u64>], block: &mut [Vec<u64>]| {
        if y < h {
            let (f, b) = (&mut free[y % 3], &mut block[y % 3]);
            plane_rows2(&plan.free, &plan.blocking, row(y), f, b);
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
