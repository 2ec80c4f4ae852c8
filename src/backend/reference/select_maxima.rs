//! The baselines' candidates: the CPU twin of `shaders/select_maxima.wgsl`.

/// Whether `scores[y * w + x]` is at least every in-map 8-neighbour's score (OpenCV's `val == dilate(val)`).
pub fn local_max(scores: &[i64], w: usize, h: usize, x: usize, y: usize) -> bool {
    let v = scores[y * w + x];
    for ny in y.saturating_sub(1)..(y + 2).min(h) {
        for nx in x.saturating_sub(1)..(x + 2).min(w) {
            if scores[ny * w + nx] > v {
                return false;
            }
        }
    }
    true
}

/// Every pixel whose score is positive and a 3x3 local maximum, in (y, x) order, and the largest score
/// (`i64::MIN` for an empty map): everything the baselines' selections need from a score map
/// ([`crate::backend::baselines::select_candidates`]).
pub fn select_maxima(scores: &[i64], w: usize, h: usize) -> (Vec<(u32, u32, i64)>, i64) {
    let max = scores.iter().copied().max().unwrap_or(i64::MIN);
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let v = scores[y * w + x];
            if v > 0 && local_max(scores, w, h, x, y) {
                out.push((x as u32, y as u32, v));
            }
        }
    }
    (out, max)
}
