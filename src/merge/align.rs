//! Aligning map B onto map A with no initial pose (designed in a prototype on the shared merge-pairs data,
//! then extended with the synthetic suite of partial overlaps; the README's "Merging maps" gives the
//! figures).
//!
//! Per map, once ([`Prepared`]): the known area's bounding box (plus 8 px); wall pixels (occupied with a
//! free 8-neighbour); the dominant wall direction modulo 90 degrees (projection profile of the wall
//! pixels); exact Euclidean distance maps to the nearest occupied pixel (with that pixel) and into free
//! space; the scoring kernel's flag bytes; coarse masks at cell sides of [`CELLS`]: walls (a cell with an
//! occupied pixel that is not speckle; also dilated by one cell) and free cells (mostly free, a cell from
//! any wall).
//!
//! Per pair: the finest coarse level whose correlation fits [`FINE_FFT`] cells a side; 20 rotation
//! hypotheses (the two dominant directions' difference, the four quarter turns, offsets of -2..2
//! degrees); for each, B's coarse masks turned into A's orientation and correlated with A's over every
//! shift by FFT (walls on dilated walls, minus walls on free cells either way); the 3 best peaks of each
//! (and corner hypotheses, when asked: [`super::hypotheses`]); the 8 best mutually distinct candidates
//! refined by trimmed ICP of B's wall pixels onto A's nearest wall pixels and verified by the scoring
//! kernel; the estimate is the candidate with the best product of its coarse score (relative to the best)
//! and its drift-tolerant local agreement. It is accepted when a linear rule over three features, fitted
//! on half of the real pairs, clears its threshold with a margin ([`Acceptance`]), and no floor or veto
//! says otherwise ([`accepts`]).

use rustfft::num_complex::Complex32;
use rustfft::FftPlanner;
use serde::Serialize;

use super::fft::{padded, Fft2};
use super::hypotheses::{vote, Hypotheses};
pub use super::prepare::{prepared_bytes, Prepared, CELLS};
use super::transform::Rigid;
use crate::backend::Backend;
use crate::cpu::merge_score::{FixedRigid, ScoreTarget};
use crate::cpu::CpuBackend;
use crate::error::{Error, Result};
use crate::map::OccupancyMap;

/// Weight of walls on free space in the coarse score.
const LAMBDA: f32 = 1.0;
/// Rotation offsets tried around each quarter turn, degrees.
const OFFSETS: [f64; 5] = [-2.0, -1.0, 0.0, 1.0, 2.0];
/// Peaks kept per rotation hypothesis.
const PEAKS: usize = 3;
/// Candidates refined.
const REFINED: usize = 8;
/// Two candidates are distinct when they move B's reference points (wall bounding box corners and
/// centroid) by more than this RMS, pixels.
const DISTINCT_PX: f64 = 40.0;
/// Whatever the rule says, an alignment must beat its best distinct alternative's coarse score by this
/// factor: a symmetric map turned by 180 degrees, or a map of noise, is no merge. (The accepted right
/// real pairs of the calibration half have 1.12 or more.)
pub const MIN_COARSE_RATIO: f64 = 1.1;
/// Whatever the rule says, an alignment is contradicted when more than this share of the walls that fall
/// in the other map lie over 3 px deep in its free space ([`Features::conflict_fine`]). The highest of the
/// accepted right real pairs of the calibration half is 0.550 (held-out: 0.53); the half-turned offices
/// of the synthetic suite have 0.6-0.7.
pub const MAX_FINE_CONFLICT: f64 = 0.55;
/// Whatever the rule says, a merge is ambiguous when either map matches itself under another transform
/// this well ([`self_symmetry`]): the real maps have 0.49 at most, the symmetric arenas of the synthetic
/// suite 0.57-0.79.
pub const MAX_SELF_SYMMETRY: f64 = 0.55;

/// The rule value from which the self-symmetry is measured: the operating curve's lowest offset.
const SYMMETRY_FROM: f64 = -1.0;

/// Whether an alignment with these features and rule value is accepted: the rule, the ratio floor, the
/// contradiction veto and the self-symmetry test.
pub fn accepts(features: &Features, rule_value: f64) -> bool {
    rule_value >= 0.0
        && features.coarse_ratio >= MIN_COARSE_RATIO
        && features.conflict_fine <= MAX_FINE_CONFLICT
        && features.self_match <= MAX_SELF_SYMMETRY
}

/// The coarse ratio's cap: no distinct alternative at all counts as this.
const MAX_RATIO: f64 = 10.0;
/// Largest coarse correlation side.
const MAX_FFT: usize = 2048;
/// The finest coarse level whose correlation side is at most this is used.
pub const FINE_FFT: usize = 256;

/// How to align.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MergeOptions {
    /// The acceptance test.
    pub accept: Acceptance,
    /// Where the hypotheses come from (the corners are found by [`Prepared::with_corners`]).
    pub hypotheses: Hypotheses,
    /// Decline a merge of a map that matches itself turned or shifted ([`self_symmetry`]).
    pub check_symmetry: bool,
}

impl Default for MergeOptions {
    fn default() -> Self {
        MergeOptions {
            accept: Acceptance::default(),
            hypotheses: Hypotheses::default(),
            check_symmetry: true,
        }
    }
}

/// The acceptance rule: `w_conflict * conflict + w_ratio * ln(coarse ratio) + w_inside * inside >=
/// threshold` (weights and threshold from a linear discriminant fitted on the calibration half of the real
/// pairs and every other negative, the threshold 0.3 standard units above the highest score of a wrong
/// estimate or a negative there).
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
            w_conflict: -0.2141,
            w_ratio: 5.1936,
            w_inside: 10.266,
            threshold: 6.2079,
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
    /// Share of both maps' wall pixels landing on an occupied pixel of the other.
    pub matched_fine: f64,
    /// Share of both maps' wall pixels more than 3 px deep inside the other map's free space (the
    /// contradiction veto, [`MAX_FINE_CONFLICT`]).
    pub conflict_fine: f64,
    /// Drift-tolerant local agreement: in 48 px tiles of the overlap, the share of wall pixels within
    /// 1.5 px of the other map's walls after the tile's best shift of up to 6 px (both maps into each
    /// other, weighted by wall pixels). 0 for a candidate whose coarse score could not make it the choice
    /// (not measured).
    pub local: f64,
    /// The coarse score over the smaller map's wall cells (as the FFT scales it).
    pub coarse_norm: f64,
    /// The larger of the two maps' [`self_symmetry`], measured for the chosen candidate when the rule
    /// value is at least -1 (0 otherwise).
    pub self_match: f64,
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
    // The finest level whose correlation fits FINE_FFT cells a side (else the coarsest).
    let sizes = |l: usize| {
        let (s, d) = (src.levels[l].as_ref()?, dst.levels[l].as_ref()?);
        let diag = ((s.ch as f64).hypot(s.cw as f64)).ceil() as usize + 2;
        Some((diag, (d.ch.max(d.cw) + diag).next_power_of_two(), s, d))
    };
    let coarsest = CELLS.len() - 1;
    let (diag, n, sc, dc) = (0..coarsest)
        .filter_map(sizes)
        .find(|l| l.1 <= FINE_FFT)
        .or_else(|| sizes(coarsest))
        .expect("the coarsest level is always prepared");
    let cell = sc.cell;
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
    let fb_wall_dil = spectrum(&dc.cwall_dil, dc.cw, dc.ch);
    let fb_free = spectrum(&dc.cfree, dc.cw, dc.ch);
    let fb_wall = spectrum(&dc.cwall, dc.cw, dc.ch);
    let fb1: Vec<Complex32> = fb_wall_dil
        .iter()
        .zip(&fb_free)
        .map(|(w, f)| w - f * LAMBDA)
        .collect();
    let base = dst.angle - src.angle;
    let ca = ((sc.cw as f64 - 1.0) / 2.0, (sc.ch as f64 - 1.0) / 2.0);
    let cr = ((diag as f64 - 1.0) / 2.0, (diag as f64 - 1.0) / 2.0);
    let half = (cell as f64 - 1.0) / 2.0;
    let thetas: Vec<f64> = (0..4)
        .flat_map(|k| {
            OFFSETS
                .iter()
                .map(move |off| base + 90.0 * f64::from(k) + off)
        })
        .collect();
    // Each hypothesis's correlation spectrum: src's two real masks go through one complex FFT (walls as
    // the real part, free cells as the imaginary one) and are told apart by symmetry.
    use rayon::prelude::*;
    let spectra: Vec<Vec<Complex32>> = thetas
        .par_iter()
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
                    if ax >= 0.0 && ay >= 0.0 && (ax as usize) < sc.cw && (ay as usize) < sc.ch {
                        let idx = ay as usize * sc.cw + ax as usize;
                        z[j * n + i] = Complex32::new(sc.cwall[idx], sc.cfree[idx]);
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
    let firsts: Vec<usize> = (0..thetas.len()).step_by(2).collect();
    let inverses: Vec<Vec<Complex32>> = firsts
        .par_iter()
        .map(|&h| {
            let mut both: Vec<Complex32> = match spectra.get(h + 1) {
                Some(second) => spectra[h]
                    .iter()
                    .zip(second)
                    .map(|(a, b)| a + b * Complex32::new(0.0, 1.0))
                    .collect(),
                None => spectra[h].clone(),
            };
            inv.run(&mut both);
            both
        })
        .collect();
    drop(spectra);
    for (&h, both) in firsts.iter().zip(&inverses) {
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
                    cell as f64 * tc.0 + half - (c * half - s * half),
                    cell as f64 * tc.1 + half - (s * half + c * half),
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
                    (t.tx - half + (c * half - s * half)) / cell as f64 - cr.0
                        + (c * ca.0 - s * ca.1),
                    (t.ty - half + (s * half + c * half)) / cell as f64 - cr.1
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
    let icped: Vec<(f64, Rigid)> = {
        use rayon::prelude::*;
        picked
            .par_iter()
            .map(|&(score, Crop(t))| (score, icp(src, dst, t)))
            .collect()
    };
    let crops: Vec<Rigid> = icped.iter().map(|r| r.1).collect();
    let verified = verify(src, dst, &crops, backend)?;
    // The local agreement of each candidate, in coarse order, skipping those that cannot win the choice
    // below (their coarse share is under the best product so far, and the agreement is at most 1).
    let top = icped.iter().map(|r| r.0).fold(f64::MIN, f64::max).max(1e-9);
    let mut locals = vec![0.0; icped.len()];
    let mut best_key = 0.0;
    for (i, (score, t)) in icped.iter().enumerate() {
        if score / top <= best_key {
            continue;
        }
        let ((a, na, _), (b, nb, _)) = rayon::join(
            || local_agreement(src, dst, t),
            || local_agreement(dst, src, &t.inverse()),
        );
        locals[i] = (a * na + b * nb) / (na + nb).max(1.0);
        best_key = f64::max(best_key, locals[i] * score / top);
    }
    let walls_cells = |c: &super::prepare::Coarse| c.cwall.iter().sum::<f32>();
    let coarse_unit = (n * n) as f64 * f64::from(walls_cells(sc).min(walls_cells(dc)).max(1.0));
    let to_full = |t: &Rigid| crop_to_map(src, dst, t);
    let refined: Vec<(f64, Rigid, Features)> = icped
        .iter()
        .zip(verified)
        .zip(locals)
        .map(|((&(score, t), mut f), local)| {
            f.coarse = score;
            f.local = local;
            f.coarse_norm = score / coarse_unit;
            (score, to_full(&t), f)
        })
        .collect();
    // The candidate whose coarse score, relative to the best one, times its local agreement is highest
    // wins: the coarse score alone prefers a wrong placement laying one map fully over the other to a
    // true, smaller overlap; the local agreement alone, small overlaps of a few matching walls. How far
    // it stands out: its coarse score over the best distinct alternative's (at most 10).
    let key = |r: &(f64, Rigid, Features)| r.2.local * r.0 / top;
    let mut order: Vec<usize> = (0..refined.len()).collect();
    // Stable: ties keep the coarse order.
    order.sort_by(|&x, &y| key(&refined[y]).total_cmp(&key(&refined[x])));
    let mut refined: Vec<(f64, Rigid, Features)> = order.iter().map(|&i| refined[i]).collect();
    // The chosen one polished to a fraction of a pixel, and verified again.
    let polished = polish(src, dst, &crops[order[0]], backend)?;
    let again = verify(src, dst, &[polished], backend)?[0];
    refined[0].1 = to_full(&polished);
    refined[0].2 = Features {
        coarse: refined[0].2.coarse,
        local: refined[0].2.local,
        coarse_norm: refined[0].2.coarse_norm,
        ..again
    };
    let (best_score, best, mut features) = refined[0];
    let runner = refined[1..]
        .iter()
        .filter(|r| transform_distance(&r.1, &best) > DISTINCT_PX)
        .map(|r| r.0)
        .fold(f64::NEG_INFINITY, f64::max);
    features.coarse_ratio = if runner > 0.0 {
        (best_score / runner).min(MAX_RATIO)
    } else {
        MAX_RATIO
    };
    let score = options.accept.margin(&features);
    // Only for what could be merged (down to the operating curve's lowest offset): each map's
    // self-match costs an alignment (cached in the map).
    if options.check_symmetry && score >= SYMMETRY_FROM && accepts(&features, score) {
        features.self_match = self_symmetry_with(a, backend)?.max(self_symmetry_with(b, backend)?);
    }
    let accepted = accepts(&features, score);
    let reason = (!accepted).then(|| {
        if score >= 0.0 && features.self_match > MAX_SELF_SYMMETRY {
            let s = features.self_match;
            return format!(
                "ambiguous: a map matches itself turned or shifted (self-match {s:.2} over \
                 {MAX_SELF_SYMMETRY}), so it could be merged more than one way"
            );
        }
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

/// `t` (src crop to dst crop) moved by up to half a pixel and turned by up to 0.1 degree about src's
/// walls' centre to where most wall pixels of each map land on occupied pixels of the other: 75
/// transforms scored by the kernel at once, the first best one kept (`t` itself first).
fn polish(src: &Prepared, dst: &Prepared, t: &Rigid, backend: &mut dyn Backend) -> Result<Rigid> {
    let c = src.reference[4];
    let mut grid = vec![*t];
    for d in [-0.1, 0.0, 0.1] {
        let (cd, sd) = cs(d);
        // p -> t(R_d (p - c) + c): the same turn about c.
        let shift = (c.0 - (cd * c.0 - sd * c.1), c.1 - (sd * c.0 + cd * c.1));
        let (ct, st) = cs(t.theta_deg);
        let base = Rigid {
            theta_deg: t.theta_deg + d,
            tx: t.tx + ct * shift.0 - st * shift.1,
            ty: t.ty + st * shift.0 + ct * shift.1,
        };
        for dy in [-0.5, -0.25, 0.0, 0.25, 0.5] {
            for dx in [-0.5, -0.25, 0.0, 0.25, 0.5] {
                if d != 0.0 || dx != 0.0 || dy != 0.0 {
                    grid.push(Rigid {
                        tx: base.tx + dx,
                        ty: base.ty + dy,
                        ..base
                    });
                }
            }
        }
    }
    let (a, b) = score_both(src, dst, &grid, true, backend)?;
    let mut best = (0u32, *t);
    for ((x, y), g) in a.iter().zip(&b).zip(&grid) {
        let hits = x[1] + y[1];
        if hits > best.0 {
            best = (hits, *g);
        }
    }
    Ok(best.1)
}

/// Trimmed ICP of src's wall pixels onto dst's nearest wall pixels: 20 iterations, the trimming
/// distance falling from 12 to 4 px, closed-form 2-D rotation and translation each time.
fn icp(src: &Prepared, dst: &Prepared, mut t: Rigid) -> Rigid {
    const ITERS: usize = 20;
    // At most about 6000 wall pixels: enough for a rigid fit.
    let step = src.walls.len().div_ceil(6000).max(1);
    let mut it = 0;
    while it < ITERS {
        let trim = 12.0 + (4.0 - 12.0) * it as f64 / (ITERS - 1) as f64;
        let (mut pairs_p, mut pairs_q) = (Vec::new(), Vec::new());
        // The nearest wall pixel to q itself, not only to q's pixel: in the last iterations, among the
        // nearest wall pixels of q's pixel and its four neighbours (sub-pixel convergence).
        let probes: &[(f64, f64)] = if it + 5 >= ITERS {
            &[(0.0, 0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
        } else {
            &[(0.0, 0.0)]
        };
        for &p in src.walls.iter().step_by(step) {
            let q = t.apply(p);
            let mut target: Option<(f64, f64)> = None;
            let mut best = f64::MAX;
            for &(dx, dy) in probes {
                let Some(i) = dst.index(q.0 + dx, q.1 + dy) else {
                    continue;
                };
                if dst.nearest[i] == u32::MAX {
                    continue;
                }
                let j = dst.nearest[i] as usize;
                let c = ((j % dst.w) as f64, (j / dst.w) as f64);
                let d = (c.0 - q.0).hypot(c.1 - q.1);
                if d < best {
                    (best, target) = (d, Some(c));
                }
            }
            if let Some(target) = target.filter(|_| best < trim) {
                pairs_p.push(p);
                pairs_q.push(target);
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
        // Converged: done after the sub-pixel iterations, else on to them.
        it = match (done, it + 5 >= ITERS) {
            (true, true) => break,
            (true, false) => ITERS - 5,
            _ => it + 1,
        };
    }
    t
}

/// The verification features of each candidate (src crop to dst crop): both maps' walls mapped into the
/// other by the scoring kernel on `backend`, one batch of transforms each way.
fn verify(
    src: &Prepared,
    dst: &Prepared,
    candidates: &[Rigid],
    backend: &mut dyn Backend,
) -> Result<Vec<Features>> {
    let (into_dst, into_src) = score_both(src, dst, candidates, false, backend)?;
    let (fine_dst, fine_src) = score_both(src, dst, candidates, true, backend)?;
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
                    matched: f64::from(ma + mb) / inside_total,
                    matched_fine: f64::from(fa + fb) / inside_total,
                    conflict_fine: f64::from(ga + gb) / inside_total,
                    // The rest is the choice's, filled in by the caller.
                    ..Features::default()
                }
            },
        )
        .collect())
}

/// The scoring kernel's counts for one transform: inside, near, deep.
type Counts = [u32; 3];

/// Per transform (src crop to dst crop), the scoring kernel's counts of src's walls mapped into dst and of
/// dst's walls mapped back by the inverse, against the verification flags or (`fine`) the finer ones.
fn score_both(
    src: &Prepared,
    dst: &Prepared,
    transforms: &[Rigid],
    fine: bool,
    backend: &mut dyn Backend,
) -> Result<(Vec<Counts>, Vec<Counts>)> {
    let fixed = |t: &Rigid| FixedRigid::new(t.theta_deg, t.tx, t.ty);
    let forward: Vec<FixedRigid> = transforms.iter().map(fixed).collect();
    let backward: Vec<FixedRigid> = transforms.iter().map(|t| fixed(&t.inverse())).collect();
    fn flags(p: &Prepared, fine: bool) -> &ScoreTarget {
        if fine {
            &p.flags_fine
        } else {
            &p.flags
        }
    }
    Ok((
        backend.score_transforms(flags(dst, fine), &src.wall_points, &forward)?,
        backend.score_transforms(flags(src, fine), &dst.wall_points, &backward)?,
    ))
}

/// How far apart two transforms are: their translations' distance plus 10 px a degree of turn.
fn transform_distance(x: &Rigid, y: &Rigid) -> f64 {
    let d = (x.theta_deg - y.theta_deg + 180.0).rem_euclid(360.0) - 180.0;
    (x.tx - y.tx).hypot(x.ty - y.ty) + 10.0 * d.abs()
}

/// A transform between the crops of src and dst as one between the maps' own pixels:
/// p_dst = R (p_src - off_src) + t + off_dst.
fn crop_to_map(src: &Prepared, dst: &Prepared, t: &Rigid) -> Rigid {
    let (c, s) = cs(t.theta_deg);
    Rigid {
        theta_deg: t.theta_deg,
        tx: t.tx - (c * src.off.0 - s * src.off.1) + dst.off.0,
        ty: t.ty - (s * src.off.0 + c * src.off.1) + dst.off.1,
    }
    .normalized()
}

/// The inverse of [`crop_to_map`]: a transform between the maps' pixels as one between their crops.
fn map_to_crop(src: &Prepared, dst: &Prepared, t: &Rigid) -> Rigid {
    let (c, s) = cs(t.theta_deg);
    Rigid {
        theta_deg: t.theta_deg,
        tx: t.tx + (c * src.off.0 - s * src.off.1) - dst.off.0,
        ty: t.ty + (s * src.off.0 + c * src.off.1) - dst.off.1,
    }
}

/// The local agreement of `from`'s walls mapped by `t` into `to` ([`Features::local`]), the wall pixels
/// it was measured on (of those sampled), and their share of all of `from`'s wall pixels (at most 1).
fn local_agreement(from: &Prepared, to: &Prepared, t: &Rigid) -> (f64, f64, f64) {
    const TILE: f64 = 48.0;
    const MIN_POINTS: usize = 24;
    // At most about 8000 wall pixels a map: enough for every tile's share.
    let step = from.walls.len().div_ceil(8000).max(1);
    let mut tiles: std::collections::BTreeMap<(i64, i64), Vec<(f64, f64)>> = Default::default();
    for &p in from.walls.iter().step_by(step) {
        let q = t.apply(p);
        if to.index(q.0, q.1).is_some() {
            tiles
                .entry(((q.0 / TILE).floor() as i64, (q.1 / TILE).floor() as i64))
                .or_default()
                .push(q);
        }
    }
    let near = |pts: &[(f64, f64)], dx: f64, dy: f64| {
        pts.iter()
            .filter(|q| {
                to.index(q.0 + dx, q.1 + dy)
                    .is_some_and(|i| to.dist[i] <= 1.5)
            })
            .count()
    };
    let (mut hit, mut total) = (0usize, 0usize);
    for pts in tiles.values().filter(|p| p.len() >= MIN_POINTS) {
        // Shifts of up to 6 px in steps of 2, then the best one's neighbours.
        let mut best = (0usize, 0.0, 0.0);
        for dy in (-6..=6).step_by(2) {
            for dx in (-6..=6).step_by(2) {
                let c = near(pts, f64::from(dx), f64::from(dy));
                if c > best.0 {
                    best = (c, f64::from(dx), f64::from(dy));
                }
            }
        }
        let (_, bx, by) = best;
        for dy in -1..=1 {
            for dx in -1..=1 {
                let c = near(pts, bx + f64::from(dx), by + f64::from(dy));
                best.0 = best.0.max(c);
            }
        }
        hit += best.0;
        total += pts.len();
    }
    let coverage = (total as f64 * step as f64 / from.walls.len().max(1) as f64).min(1.0);
    (hit as f64 / total.max(1) as f64, total as f64, coverage)
}

/// How well `p` matches itself under its best transform other than the identity: its local agreement
/// times the share of the map's wall pixels it was measured on. A map that looks the same turned or
/// shifted (a symmetric arena) can be merged either way; [`MAX_SELF_SYMMETRY`] declines it.
pub fn self_symmetry(p: &Prepared) -> Result<f64> {
    self_symmetry_with(p, &mut CpuBackend)
}

/// [`self_symmetry`] with the self-alignment's scoring on `backend` (the same counts on every backend).
fn self_symmetry_with(p: &Prepared, backend: &mut dyn Backend) -> Result<f64> {
    if let Some(&v) = p.symmetry.get() {
        return Ok(v);
    }
    let options = MergeOptions {
        check_symmetry: false,
        ..MergeOptions::default()
    };
    let al = align_prepared_with(p, p, &options, backend)?;
    let mut best: f64 = 0.0;
    for c in &al.candidates {
        if transform_distance(&c.transform, &Rigid::IDENTITY) <= DISTINCT_PX {
            continue;
        }
        let (share, _, coverage) = local_agreement(p, p, &map_to_crop(p, p, &c.transform));
        best = best.max(share * coverage);
    }
    let _ = p.symmetry.set(best);
    Ok(best)
}
