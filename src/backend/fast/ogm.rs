//! The fast twin of [`crate::backend::reference::ogm_corners`]: the same keypoints, 64 pixels at a time.
//!
//! Each row becomes two bit-planes (free, and "sets its bit in the code": occupied, or not free with
//! `unknown_as_occupied`). The eight neighbour planes of a word are shifts of the blocking planes of the
//! rows above, at and below it. A word is skipped unless some free pixel has at least as many blocking
//! neighbours as the smallest accepted code (a bit-sliced count); the few survivors get their code
//! gathered bit by bit and looked up in the one rule table, so the table stays the only statement of the
//! rules. Rows are split into bands across threads; a band keeps only three rows of planes, so the memory
//! beyond the map is a few kilobytes per thread plus the keypoints.

use rayon::prelude::*;

use super::bitplanes::{ogm_sets, plane_rows2_on, words, ValueSet};
use super::simd::{set_bits, Isa, Lanes};
use crate::backend::rules::RuleTable;
use crate::backend::Keypoint;
use crate::map::states::ClassTable;
use crate::map::stream::Rows;
use crate::map::MapImage;

/// Rows per band at least: the rows above and below a band are classified twice, so bands are long.
const MIN_BAND_ROWS: usize = 64;

/// The classification and rule data every band shares.
struct Plan<'a> {
    free: ValueSet,
    blocking: ValueSet,
    table: &'a [u8; 256],
    /// Fewest set bits among the accepted codes: words with no candidate reaching it are skipped.
    min_bits: u32,
    /// Pairs of neighbour planes of which every accepted code sets at least one ([`blocking_pairs`]).
    pairs: Vec<(usize, usize)>,
}

/// The pairs of neighbours (bit i, bit j of the code, i < j) of which every code the table accepts has at
/// least one blocking: clauses the table implies, so a pixel failing any cannot be a corner. Tested in
/// whole vectors before the table is looked at, they leave about a fifth of the candidates that the count
/// alone leaves on office maps (the paper's rules: of two diagonal neighbours on one side, one blocks).
/// At most eight, the first found: each costs two instructions a vector.
fn blocking_pairs(rules: &RuleTable) -> Vec<(usize, usize)> {
    let accepted: Vec<u8> = rules.accepted().map(|(c, _)| c).collect();
    let mut pairs = Vec::new();
    for i in 0..8 {
        for j in i + 1..8 {
            if accepted.iter().all(|&c| c & (1 << i | 1 << j) != 0) {
                pairs.push((i, j));
            }
        }
    }
    pairs.truncate(8);
    pairs
}

/// Every free pixel whose neighbour code `rules` accepts, sorted by (y, x); identical to the reference
/// (classification with `classes`, then [`crate::backend::reference::ogm_corners::ogm_corners`]).
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
    ogm_corners_rows_on(
        Isa::active(),
        rows,
        core,
        classes,
        rules,
        unknown_as_occupied,
    )
}

/// [`ogm_corners`] with the kernels of `isa` (or the widest set below it that the CPU runs): for tests
/// and benchmarks of each kernel; the results are the same on every set.
pub fn ogm_corners_on(
    isa: Isa,
    image: &MapImage,
    classes: &ClassTable,
    rules: &RuleTable,
    unknown_as_occupied: bool,
) -> Vec<Keypoint> {
    let core = (0, image.height() as usize);
    ogm_corners_rows_on(
        isa,
        Rows::of(image),
        core,
        classes,
        rules,
        unknown_as_occupied,
    )
}

/// [`ogm_corners_rows`] on `isa` (see [`ogm_corners_on`]).
pub fn ogm_corners_rows_on(
    isa: Isa,
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
        pairs: blocking_pairs(rules),
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
            corners_in_band_on(isa, rows, y0, (y0 + band).min(core.1), &plan)
        })
        .collect();
    let mut out = Vec::with_capacity(bands.iter().map(Vec::len).sum());
    for b in bands {
        out.extend(b);
    }
    out
}

/// Calls `$f::<$V, M>` with the const `M` equal to the runtime `min_bits` (0..=8): the candidate test
/// compiles to the few instructions its threshold needs.
macro_rules! with_min_bits {
    ($m:expr, $f:ident, $V:ty, $($arg:expr),*) => {
        match $m {
            0 => $f::<$V, 0>($($arg),*),
            1 => $f::<$V, 1>($($arg),*),
            2 => $f::<$V, 2>($($arg),*),
            3 => $f::<$V, 3>($($arg),*),
            4 => $f::<$V, 4>($($arg),*),
            5 => $f::<$V, 5>($($arg),*),
            6 => $f::<$V, 6>($($arg),*),
            7 => $f::<$V, 7>($($arg),*),
            _ => $f::<$V, 8>($($arg),*),
        }
    };
}

/// The keypoints of rows `y0..y1`, in (y, x) order, on `isa`, which falls back to the widest set below it that the CPU runs.
fn corners_in_band_on(isa: Isa, px: Rows, y0: usize, y1: usize, plan: &Plan) -> Vec<Keypoint> {
    let isa = isa.capped();
    #[cfg(target_arch = "x86_64")]
    match isa {
        // SAFETY: the CPU runs the set, checked just above; that is the only requirement.
        Isa::Avx512 => return unsafe { band_avx512(px, y0, y1, plan) },
        // SAFETY: as above.
        Isa::Avx2 => return unsafe { band_avx2(px, y0, y1, plan) },
        Isa::Scalar => {}
    }
    with_min_bits!(plan.min_bits, band, u64, Isa::Scalar, px, y0, y1, plan)
}

/// [`band`] compiled for AVX-512: eight words (512 pixels) a step.
///
/// # Safety
/// The CPU must run [`Isa::Avx512`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi,avx2,bmi1,popcnt")]
unsafe fn band_avx512(px: Rows, y0: usize, y1: usize, plan: &Plan) -> Vec<Keypoint> {
    use super::simd::V512;
    with_min_bits!(plan.min_bits, band, V512, Isa::Avx512, px, y0, y1, plan)
}

/// [`band`] compiled for AVX2: four words (256 pixels) a step.
///
/// # Safety
/// The CPU must run [`Isa::Avx2`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,popcnt")]
unsafe fn band_avx2(px: Rows, y0: usize, y1: usize, plan: &Plan) -> Vec<Keypoint> {
    use super::simd::V256;
    with_min_bits!(plan.min_bits, band, V256, Isa::Avx2, px, y0, y1, plan)
}

/// Rows of bit-planes padded for vector loads: a zero word before each row's words (what lies left of
/// pixel 0) and zero words after them (right of the last pixel, and up to a whole vector past the end),
/// so that the loads of a vector and of its neighbours one word left and right stay inside the buffer.
struct PlaneRows {
    words: Vec<u64>,
    stride: usize,
    n: usize,
}

impl PlaneRows {
    fn new(rows: usize, n: usize) -> Self {
        let stride = n.next_multiple_of(8) + 2;
        PlaneRows {
            words: vec![0; rows * stride],
            stride,
            n,
        }
    }

    /// Row `r`'s words (the padding excluded).
    fn row_mut(&mut self, r: usize) -> &mut [u64] {
        let s = r * self.stride + 1;
        &mut self.words[s..s + self.n]
    }

    /// A pointer at row `r`'s word 0 (one padding word lies before it, `stride - n - 1` after), valid
    /// over the whole buffer.
    fn at(&self, r: usize) -> *const u64 {
        assert!(r * self.stride + 1 < self.words.len());
        // SAFETY: inside the buffer, checked just above.
        unsafe { self.words.as_ptr().add(r * self.stride + 1) }
    }
}

/// The keypoints of rows `y0..y1`: each row's two planes made once (row y + 1 ahead of row y), then the
/// candidate test `V::WORDS` words at a time, with the planes of three rows kept in a small ring (a few
/// kilobytes that stay in the first-level cache, never the map's size).
#[inline(always)]
fn band<V: Candidates, const M: u32>(
    isa: Isa,
    px: Rows,
    y0: usize,
    y1: usize,
    plan: &Plan,
) -> Vec<Keypoint> {
    let (w, h) = (px.width(), px.height());
    let n = words(w);
    // The blocking planes by row mod 3, and a fourth row of zeros (above the map); the free planes by row
    // mod 2. Rows past the map's bottom are zeros: nothing blocks there.
    let mut block = PlaneRows::new(4, n);
    let mut free = PlaneRows::new(2, n);
    let load = |y: usize, block: &mut PlaneRows, free: &mut PlaneRows| {
        let (b, f) = (block.row_mut(y % 3), free.row_mut(y % 2));
        if y < h {
            plane_rows2_on(isa, &plan.free, &plan.blocking, px.row(y), f, b);
        } else {
            b.fill(0);
            f.fill(0);
        }
    };
    if y0 > 0 {
        load(y0 - 1, &mut block, &mut free);
    }
    load(y0, &mut block, &mut free);
    let mut out = Vec::new();
    for y in y0..y1 {
        load(y + 1, &mut block, &mut free);
        let up = if y > 0 { (y + 2) % 3 } else { 3 };
        let rows = [
            free.at(y % 2),
            block.at(up),
            block.at(y % 3),
            block.at((y + 1) % 3),
        ];
        let ahead = px.pixels().get((y + AHEAD - px.first()) * w..);
        let ahead = ahead.map_or(&[][..], |a| &a[..w.min(a.len())]);
        // SAFETY: every row pointer is at word 0 of a padded row of `block` or `free`, which has a
        // readable word before it and `n.next_multiple_of(8) + 1` after it; the CPU runs V's set (the
        // caller's promise).
        unsafe { row_corners::<V, M>(rows, n, y as u32, plan, ahead, &mut out) };
    }
    out
}

/// Appends the keypoints of one row, given pointers at word 0 of its free plane and of the blocking
/// planes of the rows above, at and below it.
///
/// # Safety
/// Each pointer must have a readable word before it and `n.next_multiple_of(8) + 1` after it, zero past
/// word `n - 1`; the CPU must run V's instruction set.
#[inline(always)]
unsafe fn row_corners<V: Candidates, const M: u32>(
    [free, up, mid, down]: [*const u64; 4],
    n: usize,
    y: u32,
    plan: &Plan,
    ahead: &[u8],
    out: &mut Vec<Keypoint>,
) {
    let mut k = 0;
    while k < n {
        prefetch(ahead, k * 64, V::WORDS);
        // SAFETY (every load): k < n, so k - 1 .. k + 1 + WORDS lies in the padding the caller promises.
        let f = unsafe { V::load(free.add(k)) };
        if f.is_zero() {
            k += V::WORDS;
            continue;
        }
        let at = |p: *const u64, d: isize| unsafe { V::load(p.offset(k as isize + d)) };
        let (u, m, d) = (at(up, 0), at(mid, 0), at(down, 0));
        // Bit order of the code (see crate::backend::rules): Q, B, P, A, Q', B', P', A' clockwise from top-left.
        let nb = [
            u.left_neighbour(at(up, -1)),
            u,
            u.right_neighbour(at(up, 1)),
            m.right_neighbour(at(mid, 1)),
            d.right_neighbour(at(down, 1)),
            d,
            d.left_neighbour(at(down, -1)),
            m.left_neighbour(at(mid, -1)),
        ];
        let cand = plan
            .pairs
            .iter()
            .fold(f.and(at_least::<V, M>(&nb)), |c, &(i, j)| {
                c.and(nb[i].or(nb[j]))
            });
        if !cand.is_zero() {
            // SAFETY: the CPU runs V's set (the caller's promise).
            unsafe { V::keypoints(&nb, cand, k, y, plan.table, out) };
        }
        k += V::WORDS;
    }
}

/// Rows ahead of the row being tested whose bytes are prefetched, a vector's width at a time: they are
/// classified in two rows' time, and asking for them while the current row's arithmetic runs keeps the
/// memory busy instead of leaving it idle until the classification stalls on them.
const AHEAD: usize = 2;

/// Asks for the cache lines of `words` 64-byte words of `row` from byte `at` (those that exist).
#[inline(always)]
fn prefetch(row: &[u8], at: usize, words: usize) {
    #[cfg(target_arch = "x86_64")]
    for i in 0..words {
        if let Some(b) = row.get(at + 64 * i) {
            // SAFETY: a prefetch is a hint; it never faults, and `b` is a valid address besides.
            unsafe {
                std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                    b as *const u8 as *const i8,
                )
            };
        }
    }
    let _ = (row, at, words);
}

/// How a vector of candidate words becomes keypoints: the codes of the candidates and their rules.
trait Candidates: Lanes {
    /// Appends the keypoints among the candidates `cand` (bit set: a free pixel with enough blocking
    /// neighbours) of the vector at word `k` of row `y`, whose neighbour planes are `nb`, in x order.
    ///
    /// # Safety
    /// The CPU must run the vector's instruction set.
    #[inline(always)]
    unsafe fn keypoints(
        nb: &[Self; 8],
        cand: Self,
        k: usize,
        y: u32,
        table: &[u8; 256],
        out: &mut Vec<Keypoint>,
    ) {
        // SAFETY: the CPU runs the set (the caller's promise).
        let (planes, c) = unsafe { spill(nb, cand) };
        for lane in set_bits(u64::from(cand.nonzero_words())) {
            let lane = lane as usize;
            let p: [u64; 8] = std::array::from_fn(|i| planes[i][lane]);
            let x0 = ((k + lane) * 64) as u32;
            // Room for every candidate of the word, so that each is written and kept or not without a
            // branch (one in five or so is a corner: a branch would be mispredicted often).
            out.reserve(c[lane].count_ones() as usize);
            for j in set_bits(c[lane]) {
                let code = (0..8).fold(0u8, |acc, i| acc | ((((p[i] >> j) & 1) as u8) << i));
                let rule = table[code as usize];
                push_if(out, Keypoint::ogm(x0 + j, y, rule, code), rule != 0);
            }
        }
    }
}

/// The neighbour planes and the candidates of a vector as words in memory, lane by lane.
///
/// # Safety
/// The CPU must run the vector's instruction set.
#[inline(always)]
unsafe fn spill<V: Lanes>(nb: &[V; 8], cand: V) -> ([[u64; 8]; 8], [u64; 8]) {
    let mut planes = [[0u64; 8]; 8];
    let mut c = [0u64; 8];
    // SAFETY: each array holds 8 >= WORDS words; the CPU runs the set (the caller's promise).
    unsafe {
        cand.store(c.as_mut_ptr());
        for (p, v) in planes.iter_mut().zip(nb) {
            v.store(p.as_mut_ptr());
        }
    }
    (planes, c)
}

impl Candidates for u64 {}

#[cfg(target_arch = "x86_64")]
impl Candidates for super::simd::V256 {}

/// AVX-512: the codes of all 64 pixels of a candidate word at once (a masked byte add per neighbour
/// plane), their rules by four-register byte permutes (VBMI), and only the keypoints visited.
#[cfg(target_arch = "x86_64")]
impl Candidates for super::simd::V512 {
    #[inline(always)]
    unsafe fn keypoints(
        nb: &[Self; 8],
        cand: Self,
        k: usize,
        y: u32,
        table: &[u8; 256],
        out: &mut Vec<Keypoint>,
    ) {
        use std::arch::x86_64::*;
        // SAFETY (the whole body): the CPU runs AVX-512 F, BW, VL and VBMI (the caller's promise); every
        // load and store is inside a local array or `table`.
        unsafe {
            let (planes, c) = spill(nb, cand);
            let t = table.as_ptr() as *const __m512i;
            let (t0, t1, t2, t3) = (
                _mm512_loadu_si512(t as *const _),
                _mm512_loadu_si512(t.add(1) as *const _),
                _mm512_loadu_si512(t.add(2) as *const _),
                _mm512_loadu_si512(t.add(3) as *const _),
            );
            for lane in set_bits(u64::from(cand.nonzero_words())) {
                let lane = lane as usize;
                let mut codes = _mm512_setzero_si512();
                for (i, p) in planes.iter().enumerate() {
                    codes = _mm512_mask_add_epi8(codes, p[lane], codes, _mm512_set1_epi8(1 << i));
                }
                // Codes below 128 index t0:t1, the others t2:t3 (bit 6 picks the register of a pair).
                let low = _mm512_permutex2var_epi8(t0, codes, t1);
                let high = _mm512_permutex2var_epi8(t2, codes, t3);
                let rules = _mm512_mask_blend_epi8(_mm512_movepi8_mask(codes), low, high);
                let keep = _mm512_test_epi8_mask(rules, rules) & c[lane];
                if keep == 0 {
                    continue;
                }
                let (mut cb, mut rb) = ([0u8; 64], [0u8; 64]);
                _mm512_storeu_si512(cb.as_mut_ptr() as *mut _, codes);
                _mm512_storeu_si512(rb.as_mut_ptr() as *mut _, rules);
                let x0 = ((k + lane) * 64) as u32;
                out.reserve(keep.count_ones() as usize);
                for j in set_bits(keep) {
                    out.push(Keypoint::ogm(x0 + j, y, rb[j as usize], cb[j as usize]));
                }
            }
        }
    }
}

/// Writes `k` after the end of `out` (which has room for it) and keeps it when `keep`: no branch.
#[inline(always)]
fn push_if(out: &mut Vec<Keypoint>, k: Keypoint, keep: bool) {
    let len = out.len();
    debug_assert!(len < out.capacity());
    out.spare_capacity_mut()[0].write(k);
    // SAFETY: element `len` was just written; the length grows over it only when it is kept.
    unsafe { out.set_len(len + usize::from(keep)) };
}

/// Per pixel, whether at least `M` of the eight neighbour planes are set: a bit-sliced count (full adders
/// of whole vectors) compared with the constant, which the compiler folds to a few instructions.
#[inline(always)]
fn at_least<V: Lanes, const M: u32>(n: &[V; 8]) -> V {
    #[inline(always)]
    fn full_add<V: Lanes>(a: V, b: V, c: V) -> (V, V) {
        let t = a.xor(b);
        (t.xor(c), a.and(b).or(c.and(t)))
    }
    if M == 0 {
        return V::ones();
    }
    if M > 8 {
        return n[0].and_not(n[0]);
    }
    let (s_a, c_a) = full_add(n[0], n[1], n[2]);
    let (s_b, c_b) = full_add(n[3], n[4], n[5]);
    let (s_c, c_c) = (n[6].xor(n[7]), n[6].and(n[7]));
    let (bit0, c_d) = full_add(s_a, s_b, s_c);
    let (t_s, t_c) = full_add(c_a, c_b, c_c);
    let (bit1, t_c2) = (t_s.xor(c_d), t_s.and(c_d));
    let count = [bit0, bit1, t_c.xor(t_c2), t_c.and(t_c2)];
    // count >= M, from the top bit down: greater where count has a 1 above equal bits and M a 0.
    let mut gt: Option<V> = None;
    let mut eq: Option<V> = None;
    for i in (0..4).rev() {
        let c = count[i];
        if (M >> i) & 1 == 1 {
            eq = Some(eq.map_or(c, |e| e.and(c)));
        } else {
            let g = eq.map_or(c, |e| e.and(c));
            gt = Some(gt.map_or(g, |x| x.or(g)));
            eq = Some(eq.map_or(V::ones().and_not(c), |e| e.and_not(c)));
        }
    }
    let eq = eq.expect("four bits");
    gt.map_or(eq, |g| g.or(eq))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::rules::RuleSet;

    /// The pairs are clauses of the table: every accepted code sets a bit of each; and for the paper's
    /// reading they are the four pairs of diagonal neighbours that share a side.
    #[test]
    fn blocking_pairs_hold_for_every_accepted_code() {
        for set in [RuleSet::Paper, RuleSet::PaperMod2] {
            let rules = RuleTable::new(set);
            let pairs = blocking_pairs(&rules);
            for (code, _) in rules.accepted() {
                for &(i, j) in &pairs {
                    assert!(
                        code & (1 << i | 1 << j) != 0,
                        "{set}: code {code} pair {i},{j}"
                    );
                }
            }
        }
        let paper = blocking_pairs(&RuleTable::new(RuleSet::Paper));
        assert_eq!(paper, vec![(0, 2), (0, 6), (2, 4), (4, 6)]);
    }
}
