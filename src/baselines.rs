//! The paper's three baseline detectors: Harris, Shi-Tomasi and Trajkovic-Hedley.
//!
//! Every backend computes a per-pixel integer score map (exact, see the CPU twins in `src/cpu/`); the
//! selection of keypoints from a score map is host code shared by all backends, so the backends agree
//! bit for bit by construction once their score maps do.

use crate::error::{Error, Result};

/// Which baseline.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Baseline {
    /// Harris and Stephens, as OpenCV's cornerHarris plus threshold and 3x3 local maxima.
    Harris,
    /// Shi and Tomasi's minimum eigenvalue, selected as OpenCV's goodFeaturesToTrack does.
    ShiTomasi,
    /// Trajkovic and Hedley's 4-neighbour detector with its two resolutions.
    Trajkovic,
}

/// The detectors' options, with the paper's configuration as defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaselineParams {
    /// Gaussian blur sigma before Harris and Shi-Tomasi (3x3 kernel). Default 1.
    pub sigma: f64,
    /// Harris k (three decimals at most, so it is an exact fraction). Default 0.04.
    pub harris_k: f64,
    /// Harris and Shi-Tomasi quality level: keep scores above quality x the map's maximum. Default 0.01.
    pub quality: f64,
    /// Shi-Tomasi minimum distance between keypoints, pixels. Default 3.
    pub min_distance: f64,
    /// Shi-Tomasi maximum number of keypoints (strongest first); `None` keeps all. Default `None`.
    pub max_corners: Option<usize>,
    /// Trajkovic low-resolution threshold T1 on min(r_A, r_B) (squared grey levels). Default 10000.
    pub t1: u32,
    /// Trajkovic full-resolution threshold T2. Default 20000.
    pub t2: u32,
}

impl Default for BaselineParams {
    fn default() -> Self {
        BaselineParams {
            sigma: 1.0,
            harris_k: 0.04,
            quality: 0.01,
            min_distance: 3.0,
            max_corners: None,
            t1: 10_000,
            t2: 20_000,
        }
    }
}

/// The integer form of the parameters that score maps depend on; every backend uses exactly these.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExactParams {
    /// Fixed-point Gaussian kernel [side, centre, side], sum 256.
    pub blur: [u32; 3],
    /// Harris k = kn / kd.
    pub kn: u32,
    /// Harris k = kn / kd.
    pub kd: u32,
    /// Trajkovic T1.
    pub t1: u32,
    /// Trajkovic T2.
    pub t2: u32,
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

impl BaselineParams {
    /// Checks the options and turns them into exact integers.
    pub fn exact(&self) -> Result<ExactParams> {
        if !(self.sigma.is_finite() && self.sigma > 0.0 && self.sigma <= 100.0) {
            return Err(Error::invalid(format!(
                "sigma must be in (0, 100], got {}",
                self.sigma
            )));
        }
        let k1000 = self.harris_k * 1000.0;
        if !(0.0..=250.0).contains(&k1000) || (k1000 - k1000.round()).abs() > 1e-9 {
            return Err(Error::invalid(format!(
                "harris k must be in [0, 0.25] with at most three decimals, got {}",
                self.harris_k
            )));
        }
        if !(self.quality.is_finite() && self.quality > 0.0 && self.quality < 1.0) {
            return Err(Error::invalid(format!(
                "quality must be in (0, 1), got {}",
                self.quality
            )));
        }
        if !(self.min_distance.is_finite() && self.min_distance >= 0.0) {
            return Err(Error::invalid(format!(
                "min distance must be >= 0, got {}",
                self.min_distance
            )));
        }
        if self.t1 > 1 << 20 || self.t2 > 1 << 20 {
            return Err(Error::invalid("trajkovic thresholds must be at most 2^20"));
        }
        let kn = k1000.round() as u32;
        let g = gcd(kn, 1000).max(1);
        Ok(ExactParams {
            blur: crate::cpu::gaussian_blur::gaussian_kernel(self.sigma),
            kn: kn / g,
            kd: 1000 / g,
            t1: self.t1,
            t2: self.t2,
        })
    }

    /// The quality level in parts per million (exact threshold arithmetic).
    pub fn quality_ppm(&self) -> i128 {
        (self.quality * 1e6).round() as i128
    }
}

/// The CPU reference score map of `kind` (row-major, one i64 per pixel).
pub fn cpu_scores(kind: Baseline, image: &crate::MapImage, p: &ExactParams) -> Vec<i64> {
    use crate::cpu::{gaussian_blur, harris, shi_tomasi, structure_tensor, trajkovic};
    let (w, h) = (image.width(), image.height());
    match kind {
        Baseline::Harris | Baseline::ShiTomasi => {
            let blurred = gaussian_blur::gaussian_blur(image, p.blur);
            let t = structure_tensor::structure_tensor(&blurred, w, h);
            if kind == Baseline::Harris {
                harris::harris(&t, p.kn, p.kd)
            } else {
                shi_tomasi::shi_tomasi(&t)
            }
        }
        Baseline::Trajkovic => trajkovic::trajkovic(image.pixels(), w, h, p.t1, p.t2),
    }
}

use crate::cpu::select_maxima::local_max;

/// The selection of [`select`] from the candidates of [`crate::cpu::select_maxima::select_maxima`] (every
/// positive 3x3 local maximum, in (y, x) order) and the map's largest score, which is all a backend has to
/// hand over. Identical to [`select`]: Harris keeps the candidates above quality x max, Trajkovic all of
/// them; for Shi-Tomasi a pixel above the threshold t >= 0 is a local maximum of the thresholded map
/// exactly when it is one of the raw map (a neighbour above it is above t too, and one at or below t
/// becomes 0 <= it), and when t < 0 (max < 0) no pixel passes the threshold at all.
pub fn select_candidates(
    kind: Baseline,
    candidates: &[(u32, u32, i64)],
    max: i64,
    width: u32,
    height: u32,
    params: &BaselineParams,
) -> Vec<(u32, u32, i64)> {
    let q = params.quality_ppm();
    let above = |v: i64| i128::from(v) * 1_000_000 > q * i128::from(max);
    match kind {
        Baseline::Harris => candidates
            .iter()
            .copied()
            .filter(|&(_, _, v)| above(v))
            .collect(),
        Baseline::Trajkovic => candidates.to_vec(),
        Baseline::ShiTomasi => {
            let (w, h) = (width as usize, height as usize);
            let cand = candidates
                .iter()
                .filter(|&&(x, y, v)| {
                    above(v)
                        && (1..w.saturating_sub(1)).contains(&(x as usize))
                        && (1..h.saturating_sub(1)).contains(&(y as usize))
                })
                .map(|&(x, y, v)| (v, y as usize * w + x as usize))
                .collect();
            min_distance_greedy(cand, w, h, params)
        }
    }
}

/// Keypoints (x, y, score) from a score map, in (y, x) order.
pub fn select(
    kind: Baseline,
    scores: &[i64],
    width: u32,
    height: u32,
    params: &BaselineParams,
) -> Vec<(u32, u32, i64)> {
    let (w, h) = (width as usize, height as usize);
    match kind {
        // Harris keeps the positive local maxima with R > quality * max(R); Trajkovic every positive local
        // maximum.
        Baseline::Harris | Baseline::Trajkovic => {
            let (candidates, max) = crate::cpu::select_maxima::select_maxima(scores, w, h);
            select_candidates(kind, &candidates, max, width, height, params)
        }
        // Shi-Tomasi the way goodFeaturesToTrack states it, on the thresholded map: the reference for the
        // candidates route the GPU takes.
        Baseline::ShiTomasi => select_shi_tomasi(scores, w, h, params),
    }
}

/// goodFeaturesToTrack's selection: threshold at quality x max (values at or below become 0), 3x3 local
/// maxima of the thresholded map away from the 1-pixel border, strongest first (ties: the later pixel
/// first, as OpenCV's pointer comparison does), greedily dropping any within `min_distance` of a kept one.
fn select_shi_tomasi(
    scores: &[i64],
    w: usize,
    h: usize,
    params: &BaselineParams,
) -> Vec<(u32, u32, i64)> {
    let max = scores.iter().copied().max().unwrap_or(0);
    let q = params.quality_ppm();
    let thresholded: Vec<i64> = scores
        .iter()
        .map(|&v| {
            if i128::from(v) * 1_000_000 > q * i128::from(max) {
                v
            } else {
                0
            }
        })
        .collect();
    let mut cand: Vec<(i64, usize)> = Vec::new();
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let v = thresholded[y * w + x];
            if v != 0 && local_max(&thresholded, w, h, x, y) {
                cand.push((v, y * w + x));
            }
        }
    }
    min_distance_greedy(cand, w, h, params)
}

/// goodFeaturesToTrack's last step: candidates (score, pixel index) strongest first (ties: the later pixel
/// first), each kept unless within `min_distance` of one kept before, at most `max_corners`; (y, x) order.
fn min_distance_greedy(
    mut cand: Vec<(i64, usize)>,
    w: usize,
    h: usize,
    params: &BaselineParams,
) -> Vec<(u32, u32, i64)> {
    cand.sort_unstable_by(|a, b| b.cmp(a));
    let min_d2 = params.min_distance * params.min_distance;
    let cell = params.min_distance.max(1.0).ceil() as usize;
    let (gw, gh) = (w.div_ceil(cell), h.div_ceil(cell));
    let mut grid: Vec<Vec<(usize, usize)>> = vec![Vec::new(); gw * gh];
    let mut out = Vec::new();
    for (v, i) in cand {
        if params.max_corners.is_some_and(|m| out.len() >= m) {
            break;
        }
        let (x, y) = (i % w, i / w);
        let (cx, cy) = (x / cell, y / cell);
        let near = (cy.saturating_sub(1)..(cy + 2).min(gh)).any(|gy| {
            (cx.saturating_sub(1)..(cx + 2).min(gw)).any(|gx| {
                grid[gy * gw + gx].iter().any(|&(px, py)| {
                    let (dx, dy) = (px as f64 - x as f64, py as f64 - y as f64);
                    dx * dx + dy * dy < min_d2
                })
            })
        });
        if !near {
            grid[cy * gw + cx].push((x, y));
            out.push((x as u32, y as u32, v));
        }
    }
    out.sort_unstable_by_key(|&(x, y, _)| (y, x));
    out
}
