//! The fast CPU baselines: the reference's score maps and keypoints ([`crate::backend::baselines`]), bit for bit,
//! computed in bands of rows on every core without full-size intermediates.
//!
//! Each band streams its rows through a rolling pipeline (`TensorRows` for Harris and Shi-Tomasi,
//! `TrajkovicRows`), keeping three rows per stage. [`scores`] writes the rows straight into the output
//! map. `keypoints` keeps three rows of scores per band (its rows plus one above and below, for the 3x3
//! local maximum) and emits only sparse candidates: local maxima above a floor. The thresholds that depend
//! on the map's maximum are applied once every band has reported its maximum; until then each band only
//! drops what fails against the largest maximum known so far, which is never above the final one, so
//! nothing that passes the final test is dropped.
//!
//! Bands run compiled for AVX2 where the CPU has it (detected at run time): the inner loops are written
//! for the auto-vectoriser, and twice the lanes of the x86-64 baseline (SSE2) make the detectors about
//! 1.2-1.5x faster.

use std::sync::atomic::{AtomicI64, Ordering};

use rayon::prelude::*;

use super::baseline_tensor::{kernel_supported, TensorRows, TensorScore};
use super::baseline_trajkovic::TrajkovicRows;
use crate::backend::baselines::{self, Baseline, BaselineParams, Candidate, ExactParams};
use crate::map::stream::Rows;
use crate::map::MapImage;
use crate::support::error::Result;

/// Rows per band at least: a band recomputes a few rows of halo (up to three above and below).
const MIN_BAND_ROWS: usize = 32;

/// Bands per thread, so that uneven maps still balance.
const BANDS_PER_THREAD: usize = 4;

/// The per-band scorer of one kind.
enum Scorer<'a> {
    Tensor(TensorRows<'a>),
    Trajkovic(TrajkovicRows<'a>),
}

impl<'a> Scorer<'a> {
    /// A scorer whose first row will be `first` (rows then follow one by one), reading `rows`.
    fn new(kind: Baseline, rows: Rows<'a>, p: &ExactParams, first: usize) -> Self {
        let tensor = |score| Scorer::Tensor(TensorRows::new(rows, p.blur, score, first));
        match kind {
            Baseline::Harris => tensor(TensorScore::Harris { kn: p.kn, kd: p.kd }),
            Baseline::ShiTomasi => tensor(TensorScore::ShiTomasi),
            Baseline::Trajkovic => Scorer::Trajkovic(TrajkovicRows::new(rows, p.t1, p.t2)),
        }
    }

    #[inline(always)]
    fn row(&mut self, y: usize, out: &mut [i64]) {
        match self {
            Scorer::Tensor(t) => t.row(y, out),
            Scorer::Trajkovic(t) => t.row(y, out),
        }
    }
}

/// Whether the fast path covers `p` (every parameter set [`BaselineParams::exact`] makes); other
/// hand-made kernels go to the reference.
fn supported(kind: Baseline, p: &ExactParams) -> bool {
    kind == Baseline::Trajkovic || kernel_supported(p.blur)
}

/// Whether the fast path computes `kind` with `p` itself (otherwise the reference does).
pub fn covers(kind: Baseline, p: &ExactParams) -> bool {
    supported(kind, p)
}

/// Rows per band for `h` rows.
fn band_rows(h: usize) -> usize {
    let threads = rayon::current_num_threads().max(1);
    h.div_ceil(threads * BANDS_PER_THREAD).max(MIN_BAND_ROWS)
}

/// The score map of `kind`, identical to [`crate::backend::baselines::cpu_scores`].
pub fn scores(kind: Baseline, image: &MapImage, params: &ExactParams) -> Vec<i64> {
    if !supported(kind, params) {
        return baselines::cpu_scores(kind, image, params);
    }
    let w = image.width() as usize;
    let band = band_rows(image.height() as usize);
    let mut out = vec![0i64; image.len()];
    out.par_chunks_mut(band * w)
        .enumerate()
        .for_each(|(b, rows)| score_band(kind, Rows::of(image), params, b * band, rows));
    out
}

/// The scores of the rows from `y0` on that `out` holds.
fn score_band(kind: Baseline, image: Rows, p: &ExactParams, y0: usize, out: &mut [i64]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above; that is the only requirement of this call.
        return unsafe { score_band_avx2(kind, image, p, y0, out) };
    }
    score_band_impl(kind, image, p, y0, out);
}

/// [`score_band_impl`] compiled for AVX2 (twice the lanes of the baseline SSE2).
///
/// # Safety
/// The CPU must have AVX2. (An `unsafe fn` keeps Rust 1.85, the crate's minimum, which has no safe
/// `target_feature` functions.)
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn score_band_avx2(
    kind: Baseline,
    image: Rows,
    p: &ExactParams,
    y0: usize,
    out: &mut [i64],
) {
    score_band_impl(kind, image, p, y0, out);
}

/// See [`score_band`]; inlined into each instruction-set variant.
#[inline(always)]
fn score_band_impl(kind: Baseline, image: Rows, p: &ExactParams, y0: usize, out: &mut [i64]) {
    let w = image.width();
    let mut scorer = Scorer::new(kind, image, p, y0);
    for (i, row) in out.chunks_exact_mut(w).enumerate() {
        scorer.row(y0 + i, row);
    }
}

/// The candidates of rows `core` of a window and the window's part of the map's maximum (see
/// `band_candidates`), `None` when the fast path does not cover `params` (the caller takes the
/// reference's route). `known_max` is the largest maximum of the windows before (`i64::MIN` for none):
/// candidates that fail against it may be left out.
pub fn window_candidates(
    kind: Baseline,
    rows: Rows,
    core: (usize, usize),
    params: &BaselineParams,
    known_max: i64,
) -> Result<Option<(Vec<Candidate>, i64)>> {
    let exact = params.exact()?;
    if !supported(kind, &exact) {
        return Ok(None);
    }
    let band = band_rows(core.1 - core.0);
    let q = params.quality_ppm();
    let known_max = AtomicI64::new(known_max);
    let bands: Vec<(Vec<Candidate>, i64)> = (core.0..core.1)
        .step_by(band)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|y0| {
            let y1 = (y0 + band).min(core.1);
            band_candidates(kind, rows, &exact, (y0, y1), q, &known_max)
        })
        .collect();
    // Stands for the reference's `scores.iter().max()` (see `band_candidates`).
    let max = bands.iter().map(|b| b.1).max().unwrap_or(0);
    let mut out = Vec::with_capacity(bands.iter().map(|b| b.0.len()).sum());
    for b in bands {
        out.extend(b.0);
    }
    Ok(Some((out, max)))
}

/// The candidates of rows `y0..y1` in (y, x) order, and the largest local maximum above the floor in those
/// rows (0 if none): the band's part of the map's maximum.
///
/// Candidates are positive 3x3 local maxima (over in-map neighbours, as the reference's `local_max`) above
/// `floor`: 0, and for Harris and Shi-Tomasi the quality threshold of the largest maximum K known so far
/// (this band's or another's, shared through `known_max`). K never exceeds the map's maximum M, so no
/// keypoint is lost. The maximum over all bands is M whenever M matters, that is when M > 0 (else no score
/// is positive; Shi-Tomasi scores are never negative): the pixel holding M is a positive local maximum, so
/// its band reports it unless M <= floor <= K <= M, and then K = M was already some band's report.
///
/// For Shi-Tomasi only pixels off the 1-pixel border are candidates, and a local maximum of the raw scores
/// stands for one of the thresholded map that `goodFeaturesToTrack` looks at: the scores are never
/// negative, so a pixel above the threshold is positive, any neighbour above it is above the threshold too
/// and keeps its value, and any neighbour zeroed was at most the threshold, below the pixel.
fn band_candidates(
    kind: Baseline,
    image: Rows,
    p: &ExactParams,
    (y0, y1): (usize, usize),
    q: i128,
    known_max: &AtomicI64,
) -> (Vec<Candidate>, i64) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above; that is the only requirement of this call.
        return unsafe { band_candidates_avx2(kind, image, p, (y0, y1), q, known_max) };
    }
    band_candidates_impl(kind, image, p, (y0, y1), q, known_max)
}

/// [`band_candidates_impl`] compiled for AVX2 (twice the lanes of the baseline SSE2).
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn band_candidates_avx2(
    kind: Baseline,
    image: Rows,
    p: &ExactParams,
    rows: (usize, usize),
    q: i128,
    known_max: &AtomicI64,
) -> (Vec<Candidate>, i64) {
    band_candidates_impl(kind, image, p, rows, q, known_max)
}

/// See [`band_candidates`]; inlined into each instruction-set variant.
#[inline(always)]
fn band_candidates_impl(
    kind: Baseline,
    image: Rows,
    p: &ExactParams,
    (y0, y1): (usize, usize),
    q: i128,
    known_max: &AtomicI64,
) -> (Vec<Candidate>, i64) {
    let (w, h) = (image.width(), image.height());
    // Score rows y0 - 1..=y1 (those in the map): the band's rows and their neighbours.
    let (s0, s1) = (y0.saturating_sub(1), (y1 + 1).min(h));
    let mut scorer = Scorer::new(kind, image, p, s0);
    let mut rows = [vec![0i64; w], vec![0i64; w], vec![0i64; w]];
    let mut band_max = 0i64;
    let mut out = Vec::new();
    for r in s0..=s1 {
        if r < s1 {
            scorer.row(r, &mut rows[r % 3]);
        }
        // Row r - 1 has its neighbours now (the map's last row has none below).
        let Some(y) = r.checked_sub(1).filter(|y| (y0..y1).contains(y)) else {
            continue;
        };
        // The lowest score a candidate can beat: 0, and for Harris and Shi-Tomasi floor(q K / 10^6)
        // (v 10^6 > q K is v > floor(q K / 10^6) for integers).
        let floor = if kind == Baseline::Trajkovic {
            0
        } else {
            let k = band_max.max(known_max.load(Ordering::Relaxed));
            (q * i128::from(k)).div_euclid(1_000_000).max(0) as i64
        };
        let local = LocalRows {
            above: (y > 0).then(|| &rows[(y + 2) % 3][..]),
            cur: &rows[y % 3][..],
            below: (y + 1 < h).then(|| &rows[(y + 1) % 3][..]),
        };
        // Shi-Tomasi: the first and last rows and columns only count towards the maximum.
        let keep = if kind == Baseline::ShiTomasi {
            (y > 0 && y + 1 < h).then_some((1, w.saturating_sub(1)))
        } else {
            Some((0, w))
        };
        let row_max = emit_row(y, &local, floor, keep, &mut out);
        if row_max > band_max {
            band_max = row_max;
            known_max.fetch_max(row_max, Ordering::Relaxed);
        }
    }
    (out, band_max)
}

/// A score row and its neighbours in the map.
struct LocalRows<'a> {
    above: Option<&'a [i64]>,
    cur: &'a [i64],
    below: Option<&'a [i64]>,
}

/// Pushes the local maxima of row `y` above `floor` (>= 0) whose column is in the range `keep`, and returns
/// the largest local maximum above `floor` in the whole row (0 if none).
#[inline(always)]
fn emit_row(
    y: usize,
    rows: &LocalRows,
    floor: i64,
    keep: Option<(usize, usize)>,
    out: &mut Vec<Candidate>,
) -> i64 {
    const CHUNK: usize = 16;
    let cur = rows.cur;
    let w = cur.len();
    let mut row_max = 0;
    for (k, chunk) in cur.chunks(CHUNK).enumerate() {
        // Few scores beat the floor. SSE2 has no 64-bit compare, but floor - v is negative exactly when
        // v > floor (no overflow: 0 <= floor and |v| < 2^58 for every valid parameter set), so an OR tells.
        if chunk
            .iter()
            .fold(0i64, |any, &v| any | floor.wrapping_sub(v))
            >= 0
        {
            continue;
        }
        for (i, &v) in chunk.iter().enumerate() {
            if v <= floor {
                continue;
            }
            let x = k * CHUNK + i;
            let (l, r) = (x.saturating_sub(1), (x + 2).min(w));
            let beaten = |row: Option<&[i64]>| row.is_some_and(|s| s[l..r].iter().any(|&n| n > v));
            if beaten(Some(cur)) || beaten(rows.above) || beaten(rows.below) {
                continue;
            }
            row_max = row_max.max(v);
            if keep.is_some_and(|(x0, x1)| (x0..x1).contains(&x)) {
                out.push((x as u32, y as u32, v));
            }
        }
    }
    row_max
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::synthetic::{office_map, Rng};

    /// The band functions as compiled without AVX2 (the integration tests run the AVX2 variant wherever
    /// the CPU has it): scores and candidates agree with the reference.
    #[test]
    fn baseline_instruction_set_variant_matches_the_reference() {
        let mut rng = Rng::new(5);
        let noise: Vec<u8> = (0..57 * 83).map(|_| rng.range(0, 256) as u8).collect();
        let params = BaselineParams::default();
        let exact = params.exact().unwrap();
        for image in [
            MapImage::new(57, 83, noise).unwrap(),
            office_map(150, 70, 2).unwrap(),
        ] {
            let (w, h) = (image.width() as usize, image.height() as usize);
            for kind in [Baseline::Harris, Baseline::ShiTomasi, Baseline::Trajkovic] {
                let reference = baselines::cpu_scores(kind, &image, &exact);
                let mut scores = vec![0; w * h];
                for (b, rows) in scores.chunks_mut(40 * w).enumerate() {
                    score_band_impl(kind, Rows::of(&image), &exact, 40 * b, rows);
                }
                assert!(scores == reference, "{kind:?}");
                let known = AtomicI64::new(i64::MIN);
                let q = params.quality_ppm();
                let bands: Vec<_> = [(0, 30), (30, 31), (31, h)]
                    .into_iter()
                    .map(|rows| {
                        band_candidates_impl(kind, Rows::of(&image), &exact, rows, q, &known)
                    })
                    .collect();
                let expected = baselines::select(kind, &reference, w as u32, h as u32, &params);
                let max = bands.iter().map(|b| b.1).max().unwrap();
                let got: Vec<Candidate> = bands
                    .into_iter()
                    .flat_map(|b| b.0)
                    .filter(|c| {
                        kind == Baseline::Trajkovic
                            || i128::from(c.2) * 1_000_000 > q * i128::from(max)
                    })
                    .collect();
                match kind {
                    Baseline::ShiTomasi => {
                        assert_eq!(baselines::greedy_min_distance(got, w, h, &params), expected)
                    }
                    _ => assert_eq!(got, expected, "{kind:?}"),
                }
            }
        }
    }
}
