//! CPU twin of `shaders/trajkovic.wgsl`: the Trajkovic-Hedley 4-neighbour corner score, exactly.
//!
//! Low resolution: the image is halved by averaging 2x2 blocks (integer mean, rounded down; the last block
//! of an odd side repeats the edge pixel). A low-resolution pixel (u, v), not on its border, whose simple
//! cornerness min(r_A, r_B) exceeds T1 makes the full-resolution pixels x in [2u-1, 2u+2], y in [2v-1, 2v+2]
//! candidates: its own 2x2 block and a one-pixel ring, so a corner on a block boundary is not lost.
//!
//! Full resolution, for a candidate not on the image border, with f the intensities:
//! r_A = (f_A - f_C)^2 + (f_A' - f_C)^2 (horizontal), r_B = (f_B - f_C)^2 + (f_B' - f_C)^2 (vertical);
//! if min(r_A, r_B) <= T2 it is no corner. Otherwise the interpixel approximation:
//! B1 = (f_B - f_A)(f_A - f_C) + (f_B' - f_A')(f_A' - f_C), B2 = (f_B - f_A')(f_A' - f_C) + (f_B' - f_A)(f_A - f_C),
//! B = min(B1, B2), A = r_B - r_A - 2B; R = r_A - B^2 / A when B < 0 and A + B > 0, else min(r_A, r_B).
//! The score is floor(R) (r_A - ceil(B^2 / A), exact in integers), kept when it exceeds T2, else 0.
//! Non-maximum suppression (3x3) is done by the shared selection step.

/// The low-resolution pixel (u, v) of a `w` x `h` image.
#[inline]
pub fn low_res(img: &[u8], w: i64, h: i64, u: i64, v: i64) -> i64 {
    let p = |x: i64, y: i64| i64::from(img[(y.min(h - 1) * w + x.min(w - 1)) as usize]);
    (p(2 * u, 2 * v) + p(2 * u + 1, 2 * v) + p(2 * u, 2 * v + 1) + p(2 * u + 1, 2 * v + 1)) / 4
}

/// min(r_A, r_B) at (x, y) of an image given by `f`.
#[inline]
pub fn simple_cornerness(f: impl Fn(i64, i64) -> i64, x: i64, y: i64) -> i64 {
    let c = f(x, y);
    let r_a = (f(x + 1, y) - c).pow(2) + (f(x - 1, y) - c).pow(2);
    let r_b = (f(x, y - 1) - c).pow(2) + (f(x, y + 1) - c).pow(2);
    r_a.min(r_b)
}

/// ceil(n / d) for n >= 0, d > 0.
#[inline]
pub fn ceil_div(n: i64, d: i64) -> i64 {
    (n + d - 1) / d
}

/// The low-resolution cornerness min(r_A, r_B) of every low-resolution pixel off the low-res border
/// (0 on it), row-major, `(w + 1) / 2` wide.
pub fn low_res_cornerness(img: &[u8], w: i64, h: i64) -> Vec<i64> {
    let (lw, lh) = ((w + 1) / 2, (h + 1) / 2);
    let mut out = vec![0i64; (lw * lh) as usize];
    for v in 1..lh - 1 {
        for u in 1..lw - 1 {
            out[(v * lw + u) as usize] = simple_cornerness(|a, b| low_res(img, w, h, a, b), u, v);
        }
    }
    out
}

/// Whether full-resolution pixel (x, y) is a candidate: a low-resolution pixel whose 2x2 block plus a
/// one-pixel ring holds it, off the low-res border, has cornerness above T1.
pub fn is_candidate(low: &[i64], w: i64, h: i64, x: i64, y: i64, t1: i64) -> bool {
    let (lw, lh) = ((w + 1) / 2, (h + 1) / 2);
    let range =
        |p: i64, n: i64| ((p - 1).div_euclid(2).max(1))..=((p + 1).div_euclid(2).min(n - 2));
    range(y, lh).any(|v| range(x, lw).any(|u| low[(v * lw + u) as usize] > t1))
}

/// The full-resolution score of (x, y) (not on the border), 0 when it is no corner.
pub fn full_res_score(f: impl Fn(i64, i64) -> i64, x: i64, y: i64, t2: i64) -> i64 {
    let c = f(x, y);
    let (a, a2, b, b2) = (f(x + 1, y), f(x - 1, y), f(x, y - 1), f(x, y + 1));
    let r_a = (a - c).pow(2) + (a2 - c).pow(2);
    let r_b = (b - c).pow(2) + (b2 - c).pow(2);
    if r_a.min(r_b) <= t2 {
        return 0;
    }
    let b1 = (b - a) * (a - c) + (b2 - a2) * (a2 - c);
    let b2_ = (b - a2) * (a2 - c) + (b2 - a) * (a - c);
    let bm = b1.min(b2_);
    let am = r_b - r_a - 2 * bm;
    let r = if bm < 0 && am + bm > 0 {
        r_a - ceil_div(bm * bm, am)
    } else {
        r_a.min(r_b)
    };
    if r > t2 {
        r
    } else {
        0
    }
}

/// Trajkovic-Hedley scores of an 8-bit image (0 where no corner), before non-maximum suppression.
pub fn trajkovic(img: &[u8], width: u32, height: u32, t1: u32, t2: u32) -> Vec<i64> {
    let (w, h) = (i64::from(width), i64::from(height));
    let f = |x: i64, y: i64| i64::from(img[(y * w + x) as usize]);
    let mut out = vec![0i64; img.len()];
    let low = low_res_cornerness(img, w, h);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            if is_candidate(&low, w, h, x, y, i64::from(t1)) {
                out[(y * w + x) as usize] = full_res_score(f, x, y, i64::from(t2));
            }
        }
    }
    out
}
