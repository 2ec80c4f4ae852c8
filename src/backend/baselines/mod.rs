//! The paper's three baseline detectors: Harris, Shi-Tomasi and Trajkovic-Hedley.
//!
//! Every backend computes a per-pixel integer score map (exact, see the CPU twins in `src/backend/reference/`); the
//! selection of keypoints from a score map is host code shared by all backends, so the backends agree
//! bit for bit by construction once their score maps do.
//!
//! This file holds the baselines' options, their exact parameters and the shared keypoint selection;
//! [`streamed`], the candidates over a stream of windows, pruned against the running maximum.

pub mod streamed;

use crate::support::error::{Error, Result};

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
            blur: crate::backend::reference::gaussian_blur::gaussian_kernel(self.sigma),
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
    use crate::backend::reference::{
        gaussian_blur, harris, shi_tomasi, structure_tensor, trajkovic,
    };
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

use crate::backend::reference::select_maxima::local_max;

/// A keypoint candidate (x, y, score).
pub type Candidate = (u32, u32, i64);

/// The selection of [`select`] from the candidates of [`crate::backend::reference::select_maxima::select_maxima`] (every
/// positive 3x3 local maximum, in (y, x) order) and the map's largest score, which is all a backend has to
/// hand over. Identical to [`select`]: Harris keeps the candidates above quality x max, Trajkovic all of
/// them; for Shi-Tomasi a pixel above the threshold t >= 0 is a local maximum of the thresholded map
/// exactly when it is one of the raw map (a neighbour above it is above t too, and one at or below t
/// becomes 0 <= it), and when t < 0 (max < 0) no pixel passes the threshold at all.
pub fn select_candidates(
    kind: Baseline,
    mut candidates: Vec<Candidate>,
    max: i64,
    width: u32,
    height: u32,
    params: &BaselineParams,
) -> Vec<Candidate> {
    let q = params.quality_ppm();
    let above = |v: i64| i128::from(v) * 1_000_000 > q * i128::from(max);
    match kind {
        Baseline::Harris => {
            candidates.retain(|&(_, _, v)| above(v));
            candidates
        }
        Baseline::Trajkovic => candidates,
        Baseline::ShiTomasi => {
            let (w, h) = (width as usize, height as usize);
            candidates.retain(|&(x, y, v)| {
                above(v)
                    && (1..w.saturating_sub(1)).contains(&(x as usize))
                    && (1..h.saturating_sub(1)).contains(&(y as usize))
            });
            greedy_min_distance(candidates, w, h, params)
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
            let (candidates, max) =
                crate::backend::reference::select_maxima::select_maxima(scores, w, h);
            select_candidates(kind, candidates, max, width, height, params)
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

/// goodFeaturesToTrack's greedy pass over the candidates (the reference's `select_shi_tomasi` from its
/// sort on): strongest first, ties the later pixel first; each kept unless a kept one lies closer than the
/// minimum distance; at most `max_corners`; then in (y, x) order.
///
/// The candidates are what a backend hands over ([`select_candidates`]); the memory is bounded by them and
/// [`DENSE_BLOCKS`], not by the map (blocks grow on huge maps: a 100000^2 map would have 1.2 10^8 blocks of
/// 9 pixels).
///
/// The reference looks for kept points in the 3x3 cells (of the minimum distance's size) around a
/// candidate, on a full grid of cells: a vector per cell, as many as the map has pixels for small
/// distances. Here cells are grouped into blocks of at least 8 pixels square, each block a list of its
/// kept points threaded through one array, and a candidate examines exactly the same points: those of the
/// blocks that overlap its 3x3 cells, filtered to those cells.
pub fn greedy_min_distance(
    cands: Vec<Candidate>,
    w: usize,
    h: usize,
    params: &BaselineParams,
) -> Vec<Candidate> {
    greedy_within(cands, w, h, params, DENSE_BLOCKS)
}

/// [`greedy_min_distance`] with at most `max_blocks` blocks.
fn greedy_within(
    cands: Vec<Candidate>,
    w: usize,
    h: usize,
    params: &BaselineParams,
    max_blocks: usize,
) -> Vec<Candidate> {
    let mut cand: Vec<(i64, usize)> = cands
        .into_iter()
        .map(|(x, y, v)| (v, y as usize * w + x as usize))
        .collect();
    cand.sort_unstable_by(|a, b| b.cmp(a));
    let min_d2 = params.min_distance * params.min_distance;
    let cell = params.min_distance.max(1.0).ceil() as usize;
    let (gw, gh) = (w.div_ceil(cell), h.div_ceil(cell));
    // Blocks of at least 8 pixels square; larger on huge maps, so that the heads stay a dense array of at
    // most DENSE_BLOCKS (each block's list is longer, and filtered to the 3x3 cells all the same).
    let mut per_block = 8usize.div_ceil(cell);
    while gw.div_ceil(per_block) * gh.div_ceil(per_block) > max_blocks.max(1) {
        per_block *= 2;
    }
    let (bw, bh) = (gw.div_ceil(per_block), gh.div_ceil(per_block));
    // First kept point of each block, and per kept point (x, y, next in its block); NONE ends a list.
    // Kept points are fewer than the candidates, which fit in memory: u32 indices hold them.
    const NONE: u32 = u32::MAX;
    let mut head = vec![NONE; bw * bh];
    let mut kept: Vec<(u32, u32, u32)> = Vec::new();
    let mut out = Vec::new();
    for (v, i) in cand {
        if params.max_corners.is_some_and(|m| out.len() >= m) {
            break;
        }
        let (x, y) = (i % w, i / w);
        let (cx, cy) = (x / cell, y / cell);
        let (gx0, gx1) = (cx.saturating_sub(1), (cx + 1).min(gw - 1));
        let (gy0, gy1) = (cy.saturating_sub(1), (cy + 1).min(gh - 1));
        let near = (gy0 / per_block..=gy1 / per_block).any(|by| {
            (gx0 / per_block..=gx1 / per_block).any(|bx| {
                let mut k = head[by * bw + bx];
                while k != NONE {
                    let (px, py, next) = kept[k as usize];
                    let (px, py) = (px as usize, py as usize);
                    let in_cells =
                        (gx0..=gx1).contains(&(px / cell)) && (gy0..=gy1).contains(&(py / cell));
                    let (dx, dy) = (px as f64 - x as f64, py as f64 - y as f64);
                    if in_cells && dx * dx + dy * dy < min_d2 {
                        return true;
                    }
                    k = next;
                }
                false
            })
        });
        if !near {
            let b = (cy / per_block) * bw + cx / per_block;
            kept.push((x as u32, y as u32, head[b]));
            head[b] = (kept.len() - 1) as u32;
            out.push((x as u32, y as u32, v));
        }
    }
    out.sort_unstable_by_key(|&(x, y, _)| (y, x));
    out
}

/// Most blocks [`greedy_min_distance`] keeps heads for (64 MiB): huge maps get larger blocks.
pub const DENSE_BLOCKS: usize = 1 << 24;

#[cfg(test)]
mod tests {
    use super::*;

    /// Blocks grown to fit a cap (as on huge maps) examine the same kept points: the reference's greedy
    /// pass, for minimum distances from 0 to 20.
    #[test]
    fn larger_blocks_keep_the_same_points() {
        let (w, h) = (300usize, 200usize);
        let mut rng = crate::map::synthetic::Rng::new(11);
        // Distinct pixels with random scores (many ties).
        let cands: Vec<Candidate> = (0..4000)
            .map(|_| {
                let key = (rng.range(0, w as u32), rng.range(0, h as u32));
                (key, i64::from(rng.range(1, 50)))
            })
            .collect::<std::collections::BTreeMap<_, _>>()
            .into_iter()
            .map(|((x, y), v)| (x, y, v))
            .collect();
        for d in [0.0, 1.0, 2.5, 3.0, 7.0, 20.0] {
            let params = BaselineParams {
                min_distance: d,
                ..BaselineParams::default()
            };
            let reference = min_distance_greedy(
                cands
                    .iter()
                    .map(|&(x, y, v)| (v, y as usize * w + x as usize))
                    .collect(),
                w,
                h,
                &params,
            );
            for cap in [1, 7, 64, DENSE_BLOCKS] {
                let got = greedy_within(cands.clone(), w, h, &params, cap);
                assert_eq!(got, reference, "min distance {d}, {cap} blocks");
            }
        }
    }
}
