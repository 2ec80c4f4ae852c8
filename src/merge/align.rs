//! Aligning map B onto map A with no initial pose (the design measured in a prototype on the shared
//! merge-pairs data, then ported; the README's "Merging maps" gives the figures).
//!
//! Per map, once ([`Prepared`]): the known area's bounding box (plus 8 px); wall pixels (occupied with a
//! free 8-neighbour); the dominant wall direction modulo 90 degrees (projection profile of the wall
//! pixels); exact Euclidean distance maps to the nearest occupied pixel (with that pixel) and into free
//! space; coarse masks of [`CELL`] px cells: walls (any occupied; also dilated by one cell) and free cells
//! (all free, eroded by one cell).
//!
//! Per pair: 20 rotation hypotheses (the two dominant directions' difference, the four quarter turns,
//! offsets of -2..2 degrees); for each, B's coarse masks turned into A's orientation and correlated with
//! A's over every shift by FFT (walls on dilated walls, minus a quarter of walls on free cells either way);
//! the 3 best peaks of each; the 4 best mutually distinct candidates refined by trimmed ICP of B's wall
//! pixels onto A's nearest occupied pixels; the one with the best coarse score is the estimate. It is
//! accepted when a linear rule over three features, fitted on half of the real pairs, clears its
//! threshold with a margin ([`Acceptance`]).

use rustfft::num_complex::Complex32;
use rustfft::FftPlanner;
use serde::Serialize;

use super::fft::{padded, Fft2};
use super::hypotheses::{vote, Hypotheses};
pub use super::prepare::{prepared_bytes, Prepared, CELL};
use super::transform::Rigid;
use crate::backend::Backend;
use crate::cpu::merge_score::FixedRigid;
use crate::cpu::CpuBackend;
use crate::error::{Error, Result};
use crate::map::OccupancyMap;

/// Weight of walls on free space in the coarse score.
const LAMBDA: f32 = 0.25;
/// Rotation offsets tried around each quarter turn, degrees.
const OFFSETS: [f64; 5] = [-2.0, -1.0, 0.0, 1.0, 2.0];
/// Peaks kept per rotation hypothesis.
const PEAKS: usize = 3;
/// Candidates refined.
const REFINED: usize = 4;
/// Two candidates are distinct when they move B's reference points (wall bounding box corners and
/// centroid) by more than this RMS, pixels.
const DISTINCT_PX: f64 = 40.0;
/// Whatever the rule says, an alignment must beat its best distinct alternative's coarse score by this
/// factor: a symmetric map turned by 180 degrees, or a map of noise, is no merge. (The 194 accepted real
/// pairs have 1.052 or more.)
pub const MIN_COARSE_RATIO: f64 = 1.04;
/// Whatever the rule says, an alignment is contradicted when more than this share of the walls that fall
/// in the other map lie over 3 px deep in its free space ([`Features::conflict_fine`]). The highest of the
/// accepted right real pairs of the calibration half is 0.550 (held-out: 0.53); the half-turned offices
/// of the synthetic suite have 0.6-0.7.
pub const MAX_FINE_CONFLICT: f64 = 0.55;

/// Whether an alignment with these features and rule value is accepted: the rule, the ratio floor and the
/// contradiction veto.
pub fn accepts(features: &Features, rule_value: f64) -> bool {
    rule_value >= 0.0
        && features.coarse_ratio >= MIN_COARSE_RATIO
        && features.conflict_fine <= MAX_FINE_CONFLICT
}

/// Largest coarse correlation side.
const MAX_FFT: usize = 2048;

/// How to align.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MergeOptions {
    /// The acceptance test.
    pub accept: Acceptance,
    /// Where the hypotheses come from (the corners are found by [`Prepared::with_corners`]).
    pub hypotheses: Hypotheses,
}

/// The acceptance rule: `w_conflict * conflict + w_ratio * ln(coarse ratio) + w_inside * inside >=
/// threshold` (weights and threshold from a linear discriminant fitted on the calibration half of the real
/// pairs, the threshold 0.3 standard units above the highest score of a wrong estimate or a negative there).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Acceptance {
    /// Weight of [`Features::conflict`].
    pub w_conflict: f64,
    /// Weight of the log of [`Features::coarse_ratio`].
    pub w_ratio: f64,
    /// Weight of [`Features::inside`].
    pub w_inside: f64,
    /// The threshold.
    pub threshold: f64,
}

impl Default for Acceptance {
    fn default() -> Self {
        Acceptance {
            w_conflict: -5.8301,
            w_ratio: 3.1168,
            w_inside: 1.2226,
            threshold: 0.3749,
        }
    }
}

impl Acceptance {
    /// The rule's value minus its threshold (accept when >= 0).
    pub fn margin(&self, f: &Features) -> f64 {
        self.w_conflict * f.conflict
            + self.w_ratio * f.coarse_ratio.max(1e-3).ln()
            + self.w_inside * f.inside
            - self.threshold
    }
}

/// What the verification measures for a candidate transform.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Features {
    /// Share of both maps' wall pixels (each mapped into the other) that lie more than 20 px deep inside
    /// the other map's free space.
    pub conflict: f64,
    /// The smaller of the two maps' shares of wall pixels that land in the other's known area (or within
    /// 5 px of its walls).
    pub inside: f64,
    /// The coarse correlation score of this candidate.
    pub coarse: f64,
    /// How far it stands out: its coarse score over the best distinct runner-up's (refined transforms
    /// differing by more than 40 px, counting 10 px a degree; large when there is none).
    pub coarse_ratio: f64,
    /// Share of both maps' wall pixels within 5 px of the other's walls.
    pub matched: f64,
    /// Share of both maps' wall pixels within 2 px of the other's walls.
    pub matched_fine: f64,
    /// Share of both maps' wall pixels more than 3 px deep inside the other map's free space (the
    /// contradiction veto, [`MAX_FINE_CONFLICT`]).
    pub conflict_fine: f64,
}

/// One refined candidate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Candidate {
    /// B's pixels to A's.
    pub transform: Rigid,
    /// Its verification.
    pub features: Features,
}

/// The result of [`align`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alignment {
    /// The best candidate's transform (also when not accepted).
    pub transform: Rigid,
    /// Its verification.
    pub features: Features,
    /// The acceptance rule's value minus its threshold.
    pub score: f64,
    /// Whether it passed.
    pub accepted: bool,
    /// Why not, when not.
    pub reason: Option<String>,
    /// Every refined candidate, the chosen one first.
    pub candidates: Vec<Candidate>,
}

/// Rotation matrix entries (cos, sin) of `deg`.
fn cs(deg: f64) -> (f64, f64) {
    let (s, c) = deg.to_radians().sin_cos();
    (c, s)
}

/// A rigid transform in crop coordinates, as (theta, tx, ty).
#[derive(Clone, Copy, Debug)]
struct Crop(Rigid);

/// Aligns B onto A: the best transform from B's pixels to A's, verified.
pub fn align(a: &OccupancyMap, b: &OccupancyMap, options: &MergeOptions) -> Result<Alignment> {
    align_prepared(&Prepared::new(a), &Prepared::new(b), options)
}

/// [`align`] with the candidates scored on `backend` ([`align_prepared_with`]).
pub fn align_with(
    a: &OccupancyMap,
    b: &OccupancyMap,
    options: &MergeOptions,
    backend: &mut dyn Backend,
) -> Result<Alignment> {
    align_prepared_with(&Prepared::new(a), &Prepared::new(b), options, backend)
}

/// [`align`] on prepared maps (prepare each map once when aligning it with many).
pub fn align_prepared(a: &Prepared, b: &Prepared, options: &MergeOptions) -> Result<Alignment> {
    align_prepared_with(a, b, options, &mut CpuBackend)
}

/// [`align_prepared`] with the dense scoring of the candidates on `backend` (the transform-scoring
/// kernel, `shaders/merge_score.wgsl`): the same counts, so the same result, on every backend.
pub fn align_prepared_with(
    a: &Prepared,
    b: &Prepared,
    options: &MergeOptions,
    backend: &mut dyn Backend,
) -> Result<Alignment> {
    // In the prototype's terms: src = B (moved), dst = A (reference); transforms map src to dst.
    let (src, dst) = (b, a);
    if src.walls.len() < 20 || dst.walls.len() < 20 {
        return Ok(declined(
            "a map has (almost) no walls next to free space: nothing to align",
        ));
    }
    let diag = ((src.ch as f64).hypot(src.cw as f64)).ceil() as usize + 2;
    let n = (dst.ch.max(dst.cw) + diag).next_power_of_two();
    if n > MAX_FFT {
        return Err(Error::invalid(format!(
            "maps whose explored parts span {}x{} and {}x{} pixels are too large to align (at most {} \
             coarse cells across both)",
            src.w,
            src.h,
            dst.w,
            dst.h,
            MAX_FFT
        )));
    }
    let mut planner = FftPlanner::new();
    let (fwd, inv) = (
        Fft2::new(&mut planner, n, false),
        Fft2::new(&mut planner, n, true),
    );
    let spectrum = |m: &[f32], w, h| {
        let mut c = padded(m, w, h, n);
        fwd.run(&mut c);
        c
    };
    let fb_wall_dil = spectrum(&dst.cwall_dil, dst.cw, dst.ch);
    let fb_free = spectrum(&dst.cfree, dst.cw, dst.ch);
    let fb_wall = spectrum(&dst.cwall, dst.cw, dst.ch);
    let fb1: Vec<Complex32> = fb_wall_dil
        .iter()
        .zip(&fb_free)
        .map(|(w, f)| w - f * LAMBDA)
        .collect();
    let base = dst.angle - src.angle;
    let ca = ((src.cw as f64 - 1.0) / 2.0, (src.ch as f64 - 1.0) / 2.0);
    let cr = ((diag as f64 - 1.0) / 2.0, (diag as f64 - 1.0) / 2.0);
    let half = (CELL as f64 - 1.0) / 2.0;
    let thetas: Vec<f64> = (0..4)
        .flat_map(|k| {
            OFFSETS
                .iter()
                .map(move |off| base + 90.0 * f64::from(k) + off)
        })
        .collect();
    // Each hypothesis's correlation spectrum: src's two real masks go through one complex FFT (walls as
    // the real part, free cells as the imaginary one) and are told apart by symmetry.
    let spectra: Vec<Vec<Complex32>> = thetas
        .iter()
        .map(|&theta| {
            let (c, s) = cs(theta);
            // src's coarse masks turned by theta about their centre into a diag x diag canvas.
            let mut z = vec![Complex32::new(0.0, 0.0); n * n];
            for j in 0..diag {
                for i in 0..diag {
                    let (dx, dy) = (i as f64 - cr.0, j as f64 - cr.1);
                    let (ax, ay) = (
                        (c * dx + s * dy + ca.0).round(),
                        (-s * dx + c * dy + ca.1).round(),
                    );
                    if ax >= 0.0 && ay >= 0.0 && (ax as usize) < src.cw && (ay as usize) < src.ch {
                        let idx = ay as usize * src.cw + ax as usize;
                        z[j * n + i] = Complex32::new(src.cwall[idx], src.cfree[idx]);
                    }
                }
            }
            fwd.run(&mut z);
            let half_c = Complex32::new(0.5, 0.0);
            let minus_half_i = Complex32::new(0.0, -0.5);
            (0..n * n)
                .map(|idx| {
                    let (ky, kx) = (idx / n, idx % n);
                    let mirror = ((n - ky) % n) * n + (n - kx) % n;
                    let (zk, zm) = (z[idx], z[mirror].conj());
                    let fa1 = (zk + zm) * half_c; // walls
                    let fa2 = (zk - zm) * minus_half_i; // free cells
                                                        // corr(s) = sum_q src(q) dst(q + s) = IFFT(conj(FA) FB).
                    fa1.conj() * fb1[idx] - fa2.conj() * fb_wall[idx] * LAMBDA
                })
                .collect()
        })
        .collect();
    let mut coarse: Vec<(f64, Crop)> = Vec::new();
    // Each rotation's correlation, kept when corner hypotheses are scored on it.
    let want_corners = options.hypotheses.detector().is_some();
    let mut maps: Vec<Vec<f32>> = Vec::new();
    // Two real correlations per inverse FFT: the first as the real part, the second as the imaginary.
    for h in (0..thetas.len()).step_by(2) {
        let mut both: Vec<Complex32> = match spectra.get(h + 1) {
            Some(second) => spectra[h]
                .iter()
                .zip(second)
                .map(|(a, b)| a + b * Complex32::new(0.0, 1.0))
                .collect(),
            None => spectra[h].clone(),
        };
        inv.run(&mut both);
        for (which, theta) in thetas[h..(h + 2).min(thetas.len())].iter().enumerate() {
            let (c, s) = cs(*theta);
            let mut vals: Vec<f32> = both
                .iter()
                .map(|v| if which == 0 { v.re } else { v.im })
                .collect();
            if want_corners {
                maps.push(vals.clone());
            }
            let peaks = if options.hypotheses.dense() { PEAKS } else { 0 };
            for _ in 0..peaks {
                let (idx, &best) = vals
                    .iter()
                    .enumerate()
                    .max_by(|x, y| x.1.total_cmp(y.1).then(y.0.cmp(&x.0)))
                    .expect("non-empty correlation");
                let (sx, sy) = (idx % n, idx / n);
                let signed = |v: usize| {
                    if v < n - diag {
                        v as f64
                    } else {
                        v as f64 - n as f64
                    }
                };
                let tc = (
                    cr.0 - (c * ca.0 - s * ca.1) + signed(sx),
                    cr.1 - (s * ca.0 + c * ca.1) + signed(sy),
                );
                let t = (
                    CELL as f64 * tc.0 + half - (c * half - s * half),
                    CELL as f64 * tc.1 + half - (s * half + c * half),
                );
                coarse.push((
                    f64::from(best),
                    Crop(Rigid {
                        theta_deg: *theta,
                        tx: t.0,
                        ty: t.1,
                    }),
                ));
                for yy in sy.saturating_sub(6)..(sy + 7).min(n) {
                    for xx in sx.saturating_sub(6)..(sx + 7).min(n) {
                        vals[yy * n + xx] = f32::MIN;
                    }
                }
            }
        }
    }
    if want_corners {
        if src.corners.is_none() || dst.corners.is_none() {
            return Err(Error::Internal(
                "corner hypotheses need maps prepared with their corners".to_string(),
            ));
        }
        let (sk, dk) = (
            src.corners.as_deref().unwrap_or(&[]),
            dst.corners.as_deref().unwrap_or(&[]),
        );
        for (k, &theta) in thetas.iter().enumerate() {
            let (c, s) = cs(theta);
            for t in vote(sk, dk, theta) {
                // Its coarse score: the correlation at the nearest shift (the inverse of the peak's
                // translation above).
                let u = (
                    (t.tx - half + (c * half - s * half)) / CELL as f64 - cr.0
                        + (c * ca.0 - s * ca.1),
                    (t.ty - half + (s * half + c * half)) / CELL as f64 - cr.1
                        + (s * ca.0 + c * ca.1),
                );
                let wrap = |v: f64| {
                    let v = v.round() as i64;
                    // The shifts the correlation holds: 0..n-diag, and -diag..0 wrapped to the end.
                    (-(diag as i64)..(n - diag) as i64)
                        .contains(&v)
                        .then(|| v.rem_euclid(n as i64) as usize)
                };
                let (Some(sx), Some(sy)) = (wrap(u.0), wrap(u.1)) else {
                    continue;
                };
                coarse.push((f64::from(maps[k][sy * n + sx]), Crop(t)));
            }
        }
    }
    if coarse.is_empty() {
        return Ok(declined(
            "no hypothesis: the maps' corners agree on no placement",
        ));
    }
    coarse.sort_by(|x, y| y.0.total_cmp(&x.0));
    let mut picked: Vec<(f64, Crop)> = Vec::new();
    for c in coarse {
        if picked
            .iter()
            .all(|p| reference_rms(src, &p.1 .0, &c.1 .0) > DISTINCT_PX)
        {
            picked.push(c);
        }
        if picked.len() >= REFINED {
            break;
        }
    }
    let icped: Vec<(f64, Rigid)> = picked
        .iter()
        .map(|&(score, Crop(t))| (score, icp(src, dst, t)))
        .collect();
    let verified = verify(src, dst, &icped, backend)?;
    let refined: Vec<(f64, Rigid, Features)> = icped
        .iter()
        .zip(verified)
        .map(|(&(score, t), mut f)| {
            f.coarse = score;
            // Back to the maps' own pixels: p_dst = R (p_src - off_src) + t + off_dst.
            let (c, s) = cs(t.theta_deg);
            let full = Rigid {
                theta_deg: t.theta_deg,
                tx: t.tx - (c * src.off.0 - s * src.off.1) + dst.off.0,
                ty: t.ty - (s * src.off.0 + c * src.off.1) + dst.off.1,
            }
            .normalized();
            (score, full, f)
        })
        .collect();
    let dist = |x: &Rigid, y: &Rigid| {
        let d = (x.theta_deg - y.theta_deg + 180.0).rem_euclid(360.0) - 180.0;
        (x.tx - y.tx).hypot(x.ty - y.ty) + 10.0 * d.abs()
    };
    // The best coarse score wins (tried: the best full-resolution wall support when the coarse level is
    // ambiguous; it accepted 1 wrong pair and 4 negatives of the real set). How far it stands out: over
    // the best distinct alternative's.
    let (best_score, best, mut features) = refined[0];
    let runner = refined[1..]
        .iter()
        .filter(|r| dist(&r.1, &best) > DISTINCT_PX)
        .map(|r| r.0)
        .fold(f64::NEG_INFINITY, f64::max);
    features.coarse_ratio = best_score / runner.max(1e-9);
    let score = options.accept.margin(&features);
    let accepted = accepts(&features, score);
    let reason = (!accepted).then(|| {
        if score >= 0.0 && features.conflict_fine > MAX_FINE_CONFLICT {
            return format!(
                "contradicted: {:.0}% of the walls that fall in the other map lie inside its free space",
                100.0 * features.conflict_fine
            );
        }
        if score >= 0.0 {
            return format!(
                "ambiguous: the best distinct alternative scores {:.0}% of the best (a map that looks the \
                 same turned or shifted)",
                100.0 / features.coarse_ratio
            );
        }
        format!(
            "not confident: {:.0}% of the walls cross free space, {:.0}% of the smaller map's walls fall in \
             the other, coarse score {:.2}x the best distinct alternative (rule value {score:.2} below 0)",
            100.0 * features.conflict,
            100.0 * features.inside,
            features.coarse_ratio
        )
    });
    let candidates = refined
        .iter()
        .map(|&(_, transform, features)| Candidate {
            transform,
            features,
        })
        .collect();
    Ok(Alignment {
        transform: best,
        features,
        score,
        accepted,
        reason,
        candidates,
    })
}

/// A declined alignment with no candidate.
pub(crate) fn declined(why: &str) -> Alignment {
    Alignment {
        transform: Rigid::IDENTITY,
        features: Features::default(),
        score: f64::NEG_INFINITY,
        accepted: false,
        reason: Some(why.to_string()),
        candidates: Vec::new(),
    }
}

/// RMS distance between where two transforms put src's reference points.
fn reference_rms(src: &Prepared, x: &Rigid, y: &Rigid) -> f64 {
    let sum: f64 = src
        .reference
        .iter()
        .map(|&p| {
            let (a, b) = (x.apply(p), y.apply(p));
            (a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)
        })
        .sum();
    (sum / src.reference.len() as f64).sqrt()
}

/// Trimmed ICP of src's wall pixels onto dst's nearest occupied pixels: 20 iterations, the trimming
/// distance falling from 12 to 4 px, closed-form 2-D rotation and translation each time.
fn icp(src: &Prepared, dst: &Prepared, mut t: Rigid) -> Rigid {
    const ITERS: usize = 20;
    let step = if src.walls.len() > 6000 { 2 } else { 1 };
    for it in 0..ITERS {
        let trim = 12.0 + (4.0 - 12.0) * it as f64 / (ITERS - 1) as f64;
        let (mut pairs_p, mut pairs_q) = (Vec::new(), Vec::new());
        for &p in src.walls.iter().step_by(step) {
            let q = t.apply(p);
            let Some(i) = dst.index(q.0, q.1) else {
                continue;
            };
            if f64::from(dst.dist[i]) < trim && dst.nearest[i] != u32::MAX {
                let j = dst.nearest[i] as usize;
                pairs_p.push(p);
                pairs_q.push(((j % dst.w) as f64, (j / dst.w) as f64));
            }
        }
        if pairs_p.len() < 20 {
            break;
        }
        let n = pairs_p.len() as f64;
        let mean = |v: &[(f64, f64)]| {
            let s = v.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
            (s.0 / n, s.1 / n)
        };
        let (mp, mq) = (mean(&pairs_p), mean(&pairs_q));
        let (mut sxx, mut sxy) = (0.0, 0.0);
        for (p, q) in pairs_p.iter().zip(&pairs_q) {
            let (px, py, qx, qy) = (p.0 - mp.0, p.1 - mp.1, q.0 - mq.0, q.1 - mq.1);
            sxx += px * qx + py * qy;
            sxy += px * qy - py * qx;
        }
        let theta = sxy.atan2(sxx).to_degrees();
        let (c, s) = cs(theta);
        let next = Rigid {
            theta_deg: theta,
            tx: mq.0 - (c * mp.0 - s * mp.1),
            ty: mq.1 - (s * mp.0 + c * mp.1),
        };
        let done = (next.theta_deg - t.theta_deg).abs() < 1e-4
            && (next.tx - t.tx).abs() < 1e-3
            && (next.ty - t.ty).abs() < 1e-3;
        t = next;
        if done {
            break;
        }
    }
    t
}

/// The verification features of each candidate (src crop to dst crop): both maps' walls mapped into the
/// other by the scoring kernel on `backend`, one batch of transforms each way.
fn verify(
    src: &Prepared,
    dst: &Prepared,
    candidates: &[(f64, Rigid)],
    backend: &mut dyn Backend,
) -> Result<Vec<Features>> {
    let fixed = |t: &Rigid| FixedRigid::new(t.theta_deg, t.tx, t.ty);
    let forward: Vec<FixedRigid> = candidates.iter().map(|(_, t)| fixed(t)).collect();
    let backward: Vec<FixedRigid> = candidates
        .iter()
        .map(|(_, t)| fixed(&t.inverse()))
        .collect();
    let into_dst = backend.score_transforms(&dst.flags, &src.wall_points, &forward)?;
    let into_src = backend.score_transforms(&src.flags, &dst.wall_points, &backward)?;
    let fine_dst = backend.score_transforms(&dst.flags_fine, &src.wall_points, &forward)?;
    let fine_src = backend.score_transforms(&src.flags_fine, &dst.wall_points, &backward)?;
    Ok(into_dst
        .iter()
        .zip(&into_src)
        .zip(fine_dst.iter().zip(&fine_src))
        .map(
            |((&[ia, ma, da], &[ib, mb, db]), (&[_, fa, ga], &[_, fb, gb]))| {
                let inside_total = f64::from((ia + ib).max(1));
                Features {
                    conflict: f64::from(da + db) / inside_total,
                    inside: (f64::from(ia) / src.walls.len().max(1) as f64)
                        .min(f64::from(ib) / dst.walls.len().max(1) as f64),
                    coarse: 0.0,
                    coarse_ratio: 0.0,
                    matched: f64::from(ma + mb) / inside_total,
                    matched_fine: f64::from(fa + fb) / inside_total,
                    conflict_fine: f64::from(ga + gb) / inside_total,
                }
            },
        )
        .collect())
}
