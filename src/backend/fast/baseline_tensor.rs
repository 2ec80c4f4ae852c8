//! Harris and Shi-Tomasi scores row by row: blur -> Sobel -> products -> 3x3 window sums -> score, each
//! stage keeping only the three rows the next one reads, so a band of rows needs a few rows of memory.
//!
//! The arithmetic is the reference's ([`crate::backend::reference::gaussian_blur`], [`crate::backend::reference::structure_tensor`],
//! [`crate::backend::reference::harris`], [`crate::backend::reference::shi_tomasi`]) reordered, never approximated:
//! - the 3x3 blur is separable in exact integers (vertical then horizontal, the same sum), with one rounding;
//! - the window sums are horizontal then vertical 3-sums of the same products;
//! - BORDER_REFLECT_101 is applied once per row: rows are picked by reflected index, and each row buffer
//!   carries one reflected column on each side, so the inner loops read plain slices.
//!
//! Every stage reflects its own input (as the reference does on its full-size intermediates); the
//! reflected neighbours of row r are always among the map's rows r - 1..=r + 1, so three rows of each stage
//! are all the next one needs.

use crate::backend::reference::gaussian_blur::reflect101;
use crate::map::stream::Rows;

/// The reflected index of `i` in `0..n` (BORDER_REFLECT_101, as the reference).
#[inline(always)]
fn reflect(i: isize, n: usize) -> usize {
    reflect101(i as i64, n as i64) as usize
}

/// Fills the two pad columns of a row stored at `row[1..=w]`: `row[0]` is column -1, `row[w + 1]` column w.
#[inline(always)]
fn pad<T: Copy>(row: &mut [T], w: usize) {
    row[0] = row[reflect(-1, w) + 1];
    row[w + 1] = row[reflect(w as isize, w) + 1];
}

/// Which score the tensor rows end in.
#[derive(Clone, Copy, Debug)]
pub(super) enum TensorScore {
    /// kd (AC - B^2) - kn (A + C)^2.
    Harris { kn: u32, kd: u32 },
    /// A + C - ceil(sqrt((A - C)^2 + 4 B^2)).
    ShiTomasi,
}

/// Whether the fast path reproduces the reference's blur for `kernel`: with weights summing to at most 256
/// the vertical sums fit a u16 and the blurred values stay in 0..=255 (every kernel `exact` makes qualifies).
pub(super) fn kernel_supported(kernel: [u32; 3]) -> bool {
    kernel.iter().map(|&k| u64::from(k)).sum::<u64>() <= 256
}

/// The rolling pipeline of one band. Rows must be asked for in increasing order, one after the other.
pub(super) struct TensorRows<'a> {
    img: Rows<'a>,
    w: usize,
    h: usize,
    kernel: [u16; 3],
    score: TensorScore,
    /// Blurred rows (values 0..=255), padded; row r in slot r % 3.
    blur: [Vec<i16>; 3],
    next_blur: usize,
    /// Horizontal 3-sums of dx*dx, dx*dy, dy*dy; row r in slot r % 3.
    hsum: [[Vec<i32>; 3]; 3],
    next_hsum: usize,
    /// Scratch: the vertical blur pass, padded.
    vert: Vec<u16>,
    /// Scratch: one row of the three products, padded.
    prod: [Vec<i32>; 3],
}

impl<'a> TensorRows<'a> {
    /// A pipeline over the map rows `img` (holding the rows score row `first` on needs) whose first
    /// score row will be `first`.
    pub(super) fn new(img: Rows<'a>, kernel: [u32; 3], score: TensorScore, first: usize) -> Self {
        debug_assert!(kernel_supported(kernel));
        let (w, h) = (img.width(), img.height());
        TensorRows {
            img,
            w,
            h,
            kernel: kernel.map(|k| k as u16),
            score,
            blur: std::array::from_fn(|_| vec![0; w + 2]),
            next_blur: first.saturating_sub(2),
            hsum: std::array::from_fn(|_| std::array::from_fn(|_| vec![0; w])),
            next_hsum: first.saturating_sub(1),
            vert: vec![0; w + 2],
            prod: std::array::from_fn(|_| vec![0; w + 2]),
        }
    }

    /// The three rows of a stage that row `r` of the next one reads: r - 1, r, r + 1, reflected.
    #[inline(always)]
    fn neighbours(&self, r: usize) -> [usize; 3] {
        [
            reflect(r as isize - 1, self.h),
            r,
            reflect(r as isize + 1, self.h),
        ]
    }

    /// Blurs row `r` into its slot.
    #[inline(always)]
    fn blur_row(&mut self, r: usize) {
        let w = self.w;
        let [ra, rc, rb] = self.neighbours(r).map(|y| self.img.row(y));
        let [k0, k1, k2] = self.kernel;
        // Vertical pass: at most 256 * 255, a u16.
        let vert = &mut self.vert[1..=w];
        for x in 0..w {
            vert[x] = k0 * u16::from(ra[x]) + k1 * u16::from(rc[x]) + k2 * u16::from(rb[x]);
        }
        pad(&mut self.vert, w);
        // Horizontal pass: the exact 3x3 sum (< 2^24), rounded once as OpenCV does.
        let (k0, k1, k2) = (u32::from(k0), u32::from(k1), u32::from(k2));
        let v = &self.vert[..w + 2];
        let out = &mut self.blur[r % 3][1..=w];
        for x in 0..w {
            let s = k0 * u32::from(v[x]) + k1 * u32::from(v[x + 1]) + k2 * u32::from(v[x + 2]);
            out[x] = ((s + (1 << 15)) >> 16) as i16;
        }
        pad(&mut self.blur[r % 3], w);
    }

    /// Sobel gradients of blurred row `r`, their products, and the products' horizontal 3-sums.
    #[inline(always)]
    fn hsum_row(&mut self, r: usize) {
        let w = self.w;
        let [ya, yb] = [
            reflect(r as isize - 1, self.h),
            reflect(r as isize + 1, self.h),
        ];
        let (a, c, b) = (
            &self.blur[ya % 3][..w + 2],
            &self.blur[r % 3][..w + 2],
            &self.blur[yb % 3][..w + 2],
        );
        let [pxx, pxy, pyy] = &mut self.prod;
        let (pxx, pxy, pyy) = (&mut pxx[1..=w], &mut pxy[1..=w], &mut pyy[1..=w]);
        for x in 0..w {
            // |gx|, |gy| <= 4 * 255: i16; the products need i32.
            let gx = (a[x + 2] - a[x]) + 2 * (c[x + 2] - c[x]) + (b[x + 2] - b[x]);
            let gy = (b[x] - a[x]) + 2 * (b[x + 1] - a[x + 1]) + (b[x + 2] - a[x + 2]);
            let (gx, gy) = (i32::from(gx), i32::from(gy));
            pxx[x] = gx * gx;
            pxy[x] = gx * gy;
            pyy[x] = gy * gy;
        }
        for (p, out) in self.prod.iter_mut().zip(self.hsum[r % 3].iter_mut()) {
            // The product at a reflected column is the product of the reflected gradients.
            pad(p, w);
            let (p, out) = (&p[..w + 2], &mut out[..w]);
            for x in 0..w {
                out[x] = p[x] + p[x + 1] + p[x + 2];
            }
        }
    }

    /// Blurs the rows not yet blurred, up to `upto`.
    #[inline(always)]
    fn ensure_blur(&mut self, upto: usize) {
        while self.next_blur <= upto {
            self.blur_row(self.next_blur);
            self.next_blur += 1;
        }
    }

    /// Computes the sums of the rows not yet computed, up to `upto`, and the blurred rows they read.
    #[inline(always)]
    fn ensure_hsum(&mut self, upto: usize) {
        while self.next_hsum <= upto {
            let r = self.next_hsum;
            self.ensure_blur((r + 1).min(self.h - 1));
            self.hsum_row(r);
            self.next_hsum += 1;
        }
    }

    /// Writes the scores of row `r` into `out` (`w` long).
    #[inline(always)]
    pub(super) fn row(&mut self, r: usize, out: &mut [i64]) {
        self.ensure_hsum((r + 1).min(self.h - 1));
        let rows = self.neighbours(r).map(|y| &self.hsum[y % 3]);
        let ch = |k: usize| [&rows[0][k][..], &rows[1][k][..], &rows[2][k][..]];
        match self.score {
            TensorScore::Harris { kn, kd } => harris_row(ch(0), ch(1), ch(2), kn, kd, out),
            TensorScore::ShiTomasi => shi_tomasi_row(ch(0), ch(1), ch(2), out),
        }
    }
}

/// Pixels the score stage looks at together: a chunk whose window sums are all zero (flat map, most of
/// a map) is written as zeros without the 64-bit arithmetic.
const CHUNK: usize = 16;

/// Scores of one row from the three rows of horizontal sums of each product, `score(A, B, C)` per pixel.
#[inline(always)]
fn score_row(
    xx: [&[i32]; 3],
    xy: [&[i32]; 3],
    yy: [&[i32]; 3],
    out: &mut [i64],
    score: impl Fn(i32, i32, i32) -> i64 + Copy,
) {
    let w = out.len();
    let full = w - w % CHUNK;
    for x0 in (0..full).step_by(CHUNK) {
        // A constant length, so that the chunk's loops vectorise without a scalar remainder.
        score_chunk(xx, xy, yy, x0, &mut out[x0..x0 + CHUNK], score);
    }
    score_chunk(xx, xy, yy, full, &mut out[full..], score);
}

/// [`score_row`] for the pixels `x0..x0 + out.len()`.
#[inline(always)]
fn score_chunk(
    xx: [&[i32]; 3],
    xy: [&[i32]; 3],
    yy: [&[i32]; 3],
    x0: usize,
    out: &mut [i64],
    score: impl Fn(i32, i32, i32) -> i64,
) {
    let n = out.len();
    let [xx0, xx1, xx2] = xx.map(|r| &r[x0..x0 + n]);
    let [xy0, xy1, xy2] = xy.map(|r| &r[x0..x0 + n]);
    let [yy0, yy1, yy2] = yy.map(|r| &r[x0..x0 + n]);
    // A = C = 0 (sums of squares) means no gradient in the window: B = 0 and the score is 0.
    let mut any = 0;
    for x in 0..n {
        any |= xx0[x] | xx1[x] | xx2[x] | yy0[x] | yy1[x] | yy2[x];
    }
    if any == 0 {
        out.fill(0);
        return;
    }
    for x in 0..n {
        // Window sums < 2^24: exact in i32.
        let a = xx0[x] + xx1[x] + xx2[x];
        let b = xy0[x] + xy1[x] + xy2[x];
        let c = yy0[x] + yy1[x] + yy2[x];
        out[x] = score(a, b, c);
    }
}

/// Harris scores of one row.
#[inline(always)]
fn harris_row(
    xx: [&[i32]; 3],
    xy: [&[i32]; 3],
    yy: [&[i32]; 3],
    kn: u32,
    kd: u32,
    out: &mut [i64],
) {
    let (kn, kd) = (u64::from(kn), u64::from(kd));
    score_row(xx, xy, yy, out, |a, b, c| harris_score(a, b, c, kn, kd));
}

/// The reference's kd (AC - B^2) - kn (A + C)^2 for window sums A, C in 0..2^24, in 64-bit wrapping
/// arithmetic, which gives the same bits as its i64 expression; written on u64 so that each product of
/// two values below 2^32 is one 32x32->64 multiply (neither SSE2 nor AVX2 has a 64-bit multiply).
#[inline(always)]
fn harris_score(a: i32, b: i32, c: i32, kn: u64, kd: u64) -> i64 {
    let (a, b, c) = (a as u32, b.unsigned_abs(), c as u32);
    let ac = u64::from(a) * u64::from(c);
    let bb = u64::from(b) * u64::from(b);
    let s = u64::from(a + c);
    kd.wrapping_mul(ac.wrapping_sub(bb))
        .wrapping_sub(kn.wrapping_mul(s * s)) as i64
}

/// Shi-Tomasi scores of one row.
#[inline(always)]
fn shi_tomasi_row(xx: [&[i32]; 3], xy: [&[i32]; 3], yy: [&[i32]; 3], out: &mut [i64]) {
    score_row(xx, xy, yy, out, shi_tomasi_score);
}

/// The reference's S - ceil(sqrt(D)), S = A + C, D = (A - C)^2 + 4 B^2, for the window sums of a
/// structure tensor (A, C in 0..2^24, B^2 <= AC), computed in f64, exactly: D < 2^50 is an exact f64
/// (each term is), sqrt is correctly rounded, and for a non-square D the gap between sqrt(D) and the
/// integer below it (>= 1 / (2 sqrt(D)) > 2^-26) exceeds the f64 spacing there (<= 2^-28), so the
/// ceiling of the rounded root is the exact ceil_sqrt.
#[inline(always)]
fn shi_tomasi_score(a: i32, b: i32, c: i32) -> i64 {
    let (b, d) = (f64::from(b), f64::from(a - c));
    let root = (d * d + 4.0 * b * b).sqrt();
    // ceil() is a libm call and `as` a saturating conversion, neither vectorised on SSE2. With
    // 0 <= root < 2^51, adding 2^52 rounds to an integer, and the bits of 2^52 + n are those of 2^52
    // plus n: both exact, both plain vector arithmetic.
    let near = (root + TWO_52) - TWO_52;
    let ceil = if near < root { near + 1.0 } else { near };
    i64::from(a + c) - (ceil + TWO_52).to_bits().wrapping_sub(TWO_52.to_bits()) as i64
}

/// 2^52: f64 integers up to it are exact, and adding it rounds any smaller non-negative value.
const TWO_52: f64 = 4_503_599_627_370_496.0;

#[cfg(test)]
mod tests {
    use super::{harris_score, shi_tomasi_score};
    use crate::backend::reference::{harris::harris, shi_tomasi::shi_tomasi};
    use crate::map::synthetic::Rng;

    /// Window sums reach 9 * 1020^2.
    const TOP: i32 = 9 * 1020 * 1020;

    /// Tensors [A, B, C] with B^2 <= AC: the extremes, D just below and at perfect squares, random ones.
    fn tensors() -> Vec<[i32; 3]> {
        let mut t = vec![
            [0, 0, 0],
            [TOP, TOP, TOP],
            [TOP, -TOP, TOP],
            [TOP, 0, TOP],
            [TOP, 0, 0],
        ];
        for b in 1..2163 {
            // D = (2 B^2)^2 + 4 B^2 = (2 B^2 + 1)^2 - 1, one below a square; and B = 0: D a square.
            t.push([b + 2 * b * b, b, b]);
            t.push([b + 2 * b * b, -b, b]);
            t.push([3 * b * b, 0, b]);
        }
        let mut rng = Rng::new(3);
        for _ in 0..100_000 {
            let (a, c) = (rng.range(0, TOP as u32 + 1), rng.range(0, TOP as u32 + 1));
            let bound = (f64::from(a) * f64::from(c)).sqrt() as u32;
            let b = rng.range(0, bound + 1) as i32 * if rng.chance(0.5) { -1 } else { 1 };
            t.push([a as i32, b, c as i32]);
        }
        t
    }

    #[test]
    fn scores_equal_the_reference_formulas() {
        let t = tensors();
        let shi = shi_tomasi(&t);
        for (k, [a, b, c]) in t.iter().copied().enumerate() {
            assert_eq!(shi_tomasi_score(a, b, c), shi[k], "[{a}, {b}, {c}]");
        }
        for (kn, kd) in [(1, 25), (0, 1), (1, 4), (123, 1000)] {
            let harris = harris(&t, kn, kd);
            for (k, [a, b, c]) in t.iter().copied().enumerate() {
                let v = harris_score(a, b, c, u64::from(kn), u64::from(kd));
                assert_eq!(v, harris[k], "[{a}, {b}, {c}] {kn}/{kd}");
            }
        }
    }
}
