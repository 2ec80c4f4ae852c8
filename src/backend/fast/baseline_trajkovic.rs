//! Trajkovic-Hedley scores row by row, lazily: the reference's score is 0 unless the full-resolution
//! min(r_A, r_B) exceeds T2 ([`crate::backend::reference::trajkovic::full_res_score`] returns 0 first thing otherwise), so
//! each row first computes that cheap test for every pixel in one vectorised pass. Only rows with a hit
//! look at the low-resolution candidates (two rows of low-resolution cornerness > T1, cached while the
//! band moves down), and only hits that are candidates run the reference's own score function, so the
//! score is the reference's by construction. On maps most rows have no hit at all.

use crate::backend::reference::trajkovic::full_res_score;
use crate::map::stream::Rows;

/// Marks no row (a cache tag).
const NONE: usize = usize::MAX;

/// The lazy Trajkovic scorer of one band. Rows may be asked for in any order (caches are tagged), but
/// ascending order reuses the low-resolution rows.
pub(super) struct TrajkovicRows<'a> {
    img: Rows<'a>,
    w: usize,
    h: usize,
    /// Low-resolution size.
    lw: usize,
    lh: usize,
    /// T1 and T2, clamped into i32 (the quantities they bound never exceed 2 * 255^2).
    t1: i32,
    t2: i32,
    /// T2 as the reference takes it.
    t2_ref: i64,
    /// Low-resolution image rows, tagged by row; row v in slot v % 3.
    low: [(usize, Vec<i16>); 3],
    /// Low-resolution cornerness > T1 of row v at index u + 1 (u = -1..=lw; 0 on and beyond the
    /// low-resolution border, as the reference's `low_res_cornerness`), tagged; row v in slot v % 2.
    pass: [(usize, Vec<u8>); 2],
    /// Scratch: vertical pair sums of one full-resolution row.
    pairs: Vec<u16>,
    /// Scratch: min(r_A, r_B) > T2 per full-resolution pixel.
    hit: Vec<u8>,
}

impl<'a> TrajkovicRows<'a> {
    /// A scorer over the `w` x `h` image `img` with thresholds `t1`, `t2`.
    pub(super) fn new(img: Rows<'a>, t1: u32, t2: u32) -> Self {
        let (w, h) = (img.width(), img.height());
        let (lw, lh) = (w.div_ceil(2), h.div_ceil(2));
        let clamp = |t: u32| t.min(i32::MAX as u32) as i32;
        TrajkovicRows {
            img,
            w,
            h,
            lw,
            lh,
            t1: clamp(t1),
            t2: clamp(t2),
            t2_ref: i64::from(t2),
            low: std::array::from_fn(|_| (NONE, vec![0; lw])),
            pass: std::array::from_fn(|_| (NONE, vec![0; lw + 2])),
            pairs: vec![0; w],
            hit: vec![0; w],
        }
    }

    /// Writes the scores of row `y` into `out` (`w` long).
    #[inline(always)]
    pub(super) fn row(&mut self, y: usize, out: &mut [i64]) {
        out.fill(0);
        let (w, h) = (self.w, self.h);
        // No low-resolution pixel off its border: no candidates (this covers w < 3 and h < 3 too).
        if self.lw < 3 || self.lh < 3 || y == 0 || y + 1 >= h {
            return;
        }
        let row = |r: usize| self.img.row(r);
        let (up, mid, down) = (row(y - 1), row(y), row(y + 1));
        let t2 = self.t2;
        let hit = &mut self.hit[..w];
        let mut any = 0u8;
        for x in 1..w - 1 {
            let c = i32::from(mid[x]);
            let (a, a2) = (i32::from(mid[x + 1]) - c, i32::from(mid[x - 1]) - c);
            let (b, b2) = (i32::from(up[x]) - c, i32::from(down[x]) - c);
            let m = (a * a + a2 * a2).min(b * b + b2 * b2);
            hit[x] = u8::from(m > t2);
            any |= hit[x];
        }
        if any == 0 {
            return;
        }
        // Low-resolution rows whose candidate ring holds row y, floor((y - 1) / 2)..=floor((y + 1) / 2)
        // off the low-resolution border (the reference's is_candidate).
        let lo = ((y - 1) / 2).max(1);
        let hi = y.div_ceil(2).min(self.lh - 2);
        if lo > hi {
            return;
        }
        self.ensure_pass(lo);
        self.ensure_pass(hi);
        let (p_lo, p_hi) = (&self.pass[lo % 2].1, &self.pass[hi % 2].1);
        let img = self.img;
        let f = |x: i64, y: i64| i64::from(img.row(y as usize)[x as usize]);
        const CHUNK: usize = 32;
        for (k, chunk) in self.hit[..w].chunks(CHUNK).enumerate() {
            if chunk.iter().fold(0, |any, &h| any | h) == 0 {
                continue;
            }
            for (i, _) in chunk.iter().enumerate().filter(|(_, &h)| h != 0) {
                let x = k * CHUNK + i;
                // x is in the rings of u = floor((x - 1) / 2) and floor((x + 1) / 2), at indices u + 1:
                // floor((x + 1) / 2) and one more.
                let j = x.div_ceil(2);
                if (p_lo[j] | p_lo[j + 1] | p_hi[j] | p_hi[j + 1]) != 0 {
                    out[x] = full_res_score(f, x as i64, y as i64, self.t2_ref);
                }
            }
        }
    }

    /// Low-resolution row `v`: 2x2 block means, rounded down, the last row / column repeating the edge.
    #[inline(always)]
    fn ensure_low(&mut self, v: usize) {
        if self.low[v % 3].0 == v {
            return;
        }
        let (w, h) = (self.w, self.h);
        let (r0, r1) = (2 * v, (2 * v + 1).min(h - 1));
        let (a, b) = (self.img.row(r0), self.img.row(r1));
        let pairs = &mut self.pairs[..w];
        for x in 0..w {
            pairs[x] = u16::from(a[x]) + u16::from(b[x]);
        }
        let (tag, out) = &mut self.low[v % 3];
        for (o, p) in out.iter_mut().zip(pairs.chunks_exact(2)) {
            *o = ((p[0] + p[1]) / 4) as i16;
        }
        if w % 2 == 1 {
            out[w / 2] = ((2 * pairs[w - 1]) / 4) as i16;
        }
        *tag = v;
    }

    /// Pass row `v` (1 <= v <= lh - 2).
    #[inline(always)]
    fn ensure_pass(&mut self, v: usize) {
        if self.pass[v % 2].0 == v {
            return;
        }
        for r in v - 1..=v + 1 {
            self.ensure_low(r);
        }
        let lw = self.lw;
        let (above, mid, below) = (
            &self.low[(v - 1) % 3].1[..lw],
            &self.low[v % 3].1[..lw],
            &self.low[(v + 1) % 3].1[..lw],
        );
        let t1 = self.t1;
        let (tag, pass) = &mut self.pass[v % 2];
        let pass = &mut pass[..lw + 2];
        pass.fill(0);
        for u in 1..lw - 1 {
            let c = i32::from(mid[u]);
            let (a, a2) = (i32::from(mid[u + 1]) - c, i32::from(mid[u - 1]) - c);
            let (b, b2) = (i32::from(above[u]) - c, i32::from(below[u]) - c);
            pass[u + 1] = u8::from((a * a + a2 * a2).min(b * b + b2 * b2) > t1);
        }
        *tag = v;
    }
}
