//! The aligner's hypotheses: coarse correlation of the two maps' wall and free-space masks over 20
//! rotations and every shift (FFT), each rotation's best peaks (and corner votes, when asked), then every
//! hypothesis screened on the full maps by the scoring kernel.

use rustfft::num_complex::Complex32;
use rustfft::FftPlanner;

use crate::backend::Backend;
use crate::merge::pair::fft::{padded, zeros, Fft2, FINE_FFT, MAX_FFT};
use crate::merge::pair::hypotheses::{vote, Hypotheses};
use crate::merge::pair::prepare::{Coarse, Prepared, CELLS};
use crate::merge::pair::score::{score_both, Counts, Probe};
use crate::merge::transform::Rigid;
use crate::support::error::{Error, Result};

/// Weight of walls on free space in the coarse score.
const LAMBDA: f32 = 1.0;
/// Rotation offsets tried around each quarter turn, degrees.
const OFFSETS: [f64; 5] = [-2.0, -1.0, 0.0, 1.0, 2.0];
/// Peaks kept per rotation hypothesis.
const PEAKS: usize = 32;

/// Rotation matrix entries (cos, sin) of `deg`.
pub(in crate::merge) fn cs(deg: f64) -> (f64, f64) {
    let (s, c) = deg.to_radians().sin_cos();
    (c, s)
}

/// A transform of coarse cells (`p -> R(theta) p + tc`, cells of `cell` px) as one of crop pixels: a cell's
/// centre is at `cell * p + half` px, so `P -> R P + cell * tc + half - R half`.
pub(in crate::merge) fn cells_to_crop(theta: f64, tc: (f64, f64), cell: usize) -> Rigid {
    let (c, s) = cs(theta);
    let (cell, half) = (cell as f64, (cell as f64 - 1.0) / 2.0);
    Rigid {
        theta_deg: theta,
        tx: cell * tc.0 + half - (c * half - s * half),
        ty: cell * tc.1 + half - (s * half + c * half),
    }
}

/// A rigid transform in crop coordinates, as (theta, tx, ty).
#[derive(Clone, Copy, Debug)]
pub(in crate::merge) struct Crop(pub(in crate::merge) Rigid);

/// The coarse hypotheses of a pair (src crop to dst crop).
pub(in crate::merge) struct CoarseSet {
    /// The correlation's cell side, pixels.
    pub(in crate::merge) cell: usize,
    /// Each hypothesis with its coarse score, best first.
    pub(in crate::merge) list: Vec<(f64, Crop)>,
    /// The coarse score of every wall cell of the smaller map landing on a wall (as the FFT scales it).
    pub(in crate::merge) unit: f64,
}

/// The coarse hypotheses of placing src onto dst: the finest coarse level whose correlation fits
/// [`FINE_FFT`] cells a side; rotations of the two maps' dominant directions' difference, the four
/// quarter turns and offsets of -2..2 degrees; for each, src's coarse masks turned into dst's orientation
/// and correlated with dst's over every shift (walls on dilated walls, minus walls on free cells either
/// way) and its [`PEAKS`] best peaks, and, with a detector, the corner votes ([`vote`]).
pub(in crate::merge) fn coarse_hypotheses(
    src: &Prepared,
    dst: &Prepared,
    hypotheses: &Hypotheses,
) -> Result<CoarseSet> {
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
    check_size((src.w, src.h), (dst.w, dst.h))?;
    debug_assert!(n <= MAX_FFT);
    let mut planner = FftPlanner::new();
    let (fwd, inv) = (
        Fft2::new(&mut planner, n, false),
        Fft2::new(&mut planner, n, true),
    );
    let mut scratch = zeros(n);
    let mut spectrum = |m: &[f32], w, h| {
        let mut c = padded(m, w, h, n);
        fwd.run(&mut c, &mut scratch);
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
    let canvas = Canvas {
        n,
        diag,
        cell,
        ca,
        cr,
    };
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
    // A rotation's correlation spectrum.
    let spectrum_of = |theta: f64| -> Vec<Complex32> {
        let mut z = canvas.turned(sc, theta);
        // The spectrum's buffer is the FFT's scratch first: a task holds no more buffers than before.
        let mut out = zeros(n);
        fwd.run(&mut z, &mut out);
        let half_c = Complex32::new(0.5, 0.0);
        let minus_half_i = Complex32::new(0.0, -0.5);
        for (idx, o) in out.iter_mut().enumerate() {
            let (ky, kx) = (idx / n, idx % n);
            let mirror = ((n - ky) % n) * n + (n - kx) % n;
            let (zk, zm) = (z[idx], z[mirror].conj());
            let fa1 = (zk + zm) * half_c; // walls
            let fa2 = (zk - zm) * minus_half_i; // free cells
                                                // corr(s) = sum_q src(q) dst(q + s) = IFFT(conj(FA) FB).
            *o = fa1.conj() * fb1[idx] - fa2.conj() * fb_wall[idx] * LAMBDA;
        }
        out
    };
    // Each rotation's correlation, kept when corner hypotheses are scored on it.
    let want_corners = hypotheses.detector().is_some();
    let k_peaks = if hypotheses.dense() { PEAKS } else { 0 };
    // Two rotations at a time, two real correlations per inverse FFT (the first as the real part, the
    // second as the imaginary): a task holds three n x n buffers, not all rotations' spectra at once.
    let firsts: Vec<usize> = (0..thetas.len()).step_by(2).collect();
    type Found = (Vec<(f64, Crop)>, Vec<Vec<f32>>);
    let found: Vec<Found> = firsts
        .par_iter()
        .map(|&h| {
            let mut both = spectrum_of(thetas[h]);
            // The second rotation's spectrum, once added in, is the inverse FFT's scratch.
            let mut scratch = match thetas.get(h + 1) {
                Some(&second) => {
                    let second = spectrum_of(second);
                    for (a, b) in both.iter_mut().zip(&second) {
                        *a += b * Complex32::new(0.0, 1.0);
                    }
                    second
                }
                None => zeros(n),
            };
            inv.run(&mut both, &mut scratch);
            drop(scratch);
            let (mut peaks_found, mut maps) = (Vec::new(), Vec::new());
            for (which, theta) in thetas[h..(h + 2).min(thetas.len())].iter().enumerate() {
                let vals: Vec<f32> = both
                    .iter()
                    .map(|v| if which == 0 { v.re } else { v.im })
                    .collect();
                peaks_found.extend(canvas.peaks(*theta, &vals, k_peaks));
                if want_corners {
                    maps.push(vals);
                }
            }
            (peaks_found, maps)
        })
        .collect();
    let mut coarse: Vec<(f64, Crop)> = Vec::new();
    let mut maps: Vec<Vec<f32>> = Vec::new();
    for (p, m) in found {
        coarse.extend(p);
        maps.extend(m);
    }
    if want_corners {
        coarse.extend(corner_votes(src, dst, &thetas, &maps, &canvas)?);
    }
    coarse.sort_by(|x, y| y.0.total_cmp(&x.0));
    let walls_cells = |c: &Coarse| c.cwall.iter().sum::<f32>();
    let unit = (n * n) as f64 * f64::from(walls_cells(sc).min(walls_cells(dc)).max(1.0));
    Ok(CoarseSet {
        cell,
        list: coarse,
        unit,
    })
}

/// Where src's turned coarse masks lie in the correlation: its `n` x `n` side, the `diag` x `diag`
/// canvas the masks are turned into, the coarse `cell` (pixels), src's centre `ca` and the canvas's `cr`
/// (in cells).
struct Canvas {
    n: usize,
    diag: usize,
    cell: usize,
    ca: (f64, f64),
    cr: (f64, f64),
}

impl Canvas {
    /// src's coarse masks `sc` turned by `theta` about their centre into the diag x diag canvas (walls as
    /// the real part, free cells as the imaginary), in an n x n array.
    fn turned(&self, sc: &Coarse, theta: f64) -> Vec<Complex32> {
        let (n, diag, ca, cr) = (self.n, self.diag, self.ca, self.cr);
        let (c, s) = cs(theta);
        let mut z = zeros(n);
        for j in 0..diag {
            for i in 0..diag {
                let (dx, dy) = (i as f64 - cr.0, j as f64 - cr.1);
                // Rounded half up by truncation (floor for the values kept; `round` is a libm call).
                let (ax, ay) = (c * dx + s * dy + ca.0 + 0.5, -s * dx + c * dy + ca.1 + 0.5);
                if ax >= 0.0 && ay >= 0.0 && (ax as usize) < sc.cw && (ay as usize) < sc.ch {
                    let idx = ay as usize * sc.cw + ax as usize;
                    z[j * n + i] = Complex32::new(sc.cwall[idx], sc.cfree[idx]);
                }
            }
        }
        z
    }

    /// The `k` best peaks of a rotation's correlation `vals`, each as its score and its transform.
    fn peaks(&self, theta: f64, vals: &[f32], k: usize) -> Vec<(f64, Crop)> {
        let (n, diag, ca, cr) = (self.n, self.diag, self.ca, self.cr);
        let (c, s) = cs(theta);
        let signed = |v: usize| {
            if v < n - diag {
                v as f64
            } else {
                v as f64 - n as f64
            }
        };
        peaks(vals, n, k)
            .into_iter()
            .map(|(idx, best)| {
                let (sx, sy) = (idx % n, idx / n);
                let tc = (
                    cr.0 - (c * ca.0 - s * ca.1) + signed(sx),
                    cr.1 - (s * ca.0 + c * ca.1) + signed(sy),
                );
                (f64::from(best), Crop(cells_to_crop(theta, tc, self.cell)))
            })
            .collect()
    }

    /// The correlation's index nearest to transform `t` at rotation `theta` (the inverse of a peak's
    /// translation above), when it holds that shift.
    fn index_of(&self, theta: f64, t: &Rigid) -> Option<usize> {
        let (n, diag, ca, cr, cell) = (self.n, self.diag, self.ca, self.cr, self.cell);
        let half = (cell as f64 - 1.0) / 2.0;
        let (c, s) = cs(theta);
        let u = (
            (t.tx - half + (c * half - s * half)) / cell as f64 - cr.0 + (c * ca.0 - s * ca.1),
            (t.ty - half + (s * half + c * half)) / cell as f64 - cr.1 + (s * ca.0 + c * ca.1),
        );
        let wrap = |v: f64| {
            let v = v.round() as i64;
            // The shifts the correlation holds: 0..n-diag, and -diag..0 wrapped to the end.
            (-(diag as i64)..(n - diag) as i64)
                .contains(&v)
                .then(|| v.rem_euclid(n as i64) as usize)
        };
        Some(wrap(u.1)? * n + wrap(u.0)?)
    }
}

/// The corners' hypotheses at every rotation ([`vote`]), each with its coarse score: its rotation's
/// correlation `maps[k]` at the nearest shift.
fn corner_votes(
    src: &Prepared,
    dst: &Prepared,
    thetas: &[f64],
    maps: &[Vec<f32>],
    canvas: &Canvas,
) -> Result<Vec<(f64, Crop)>> {
    let (Some(sk), Some(dk)) = (src.corners.as_deref(), dst.corners.as_deref()) else {
        return Err(Error::Internal(
            "corner hypotheses need maps prepared with their corners".to_string(),
        ));
    };
    let mut out = Vec::new();
    for (k, &theta) in thetas.iter().enumerate() {
        for t in vote(sk, dk, theta) {
            if let Some(i) = canvas.index_of(theta, &t) {
                out.push((f64::from(maps[k][i]), Crop(t)));
            }
        }
    }
    Ok(out)
}

/// `coarse`'s hypotheses (src crop to dst crop), best first, by how well each agrees on the full maps at
/// its best of four shifts a quarter `cell` each way, in two orders: tolerant (both maps' sampled walls within 5 px
/// of the other's walls, less twice those over 20 px deep in its free space: a bent real map's walls
/// are often off by more than a few pixels) and strict (less, too, twice those over 8 px deep: a wrong
/// placement in a building of many like rooms puts walls within 20 px of the other's walls everywhere).
/// Each as its index and its best shift's transform.
pub(in crate::merge) fn screen(
    src: &Prepared,
    dst: &Prepared,
    coarse: &[(f64, Crop)],
    cell: f64,
    backend: &mut dyn Backend,
) -> Result<[Vec<(usize, Rigid)>; 2]> {
    // Four shifts a quarter cell each way: every offset of up to half a cell is within a quarter cell
    // of one of them.
    let q = cell / 4.0;
    let shifts = [-q, q];
    let mut grid: Vec<Rigid> = Vec::with_capacity(coarse.len() * 4);
    for &(_, Crop(t)) in coarse {
        for dy in shifts {
            for dx in shifts {
                grid.push(Rigid {
                    tx: t.tx + dx,
                    ty: t.ty + dy,
                    ..t
                });
            }
        }
    }
    let (a, b) = score_both(src, dst, &grid, Probe::Screen, backend)?;
    // Each map's counts weighted by its sample's stride, so both count as their full walls would.
    let (wa, wb) = (
        src.walls.len() as f64 / src.screen_points.len().max(1) as f64,
        dst.walls.len() as f64 / dst.screen_points.len().max(1) as f64,
    );
    // The screening target's counts: [over 8 px deep, near, over 20 px deep].
    let value = |c: &Counts, w: f64, strict: f64| {
        w * (f64::from(c[1]) - 2.0 * f64::from(c[2]) - strict * f64::from(c[0]))
    };
    Ok([0.0, 2.0].map(|strict| {
        // Per hypothesis: its best shift's value and transform (the first best on ties).
        let best: Vec<(f64, Rigid)> = a
            .chunks(4)
            .zip(b.chunks(4))
            .zip(grid.chunks(4))
            .map(|((x, y), g)| {
                let mut best = (f64::MIN, g[0]);
                for k in 0..4 {
                    let v = value(&x[k], wa, strict) + value(&y[k], wb, strict);
                    if v > best.0 {
                        best = (v, g[k]);
                    }
                }
                best
            })
            .collect();
        let mut order: Vec<usize> = (0..coarse.len()).collect();
        // Stable: ties keep the coarse order.
        order.sort_by(|&x, &y| best[y].0.total_cmp(&best[x].0));
        order.into_iter().map(|i| (i, best[i].1)).collect()
    }))
}

/// The `k` highest peaks of an `n` x `n` correlation, as (index, value): the highest value first (ties:
/// the lower index), then each next highest at least 7 cells from every one taken in x or y (not
/// wrapping around).
fn peaks(vals: &[f32], n: usize, k: usize) -> Vec<(usize, f32)> {
    // Each value and index as one integer whose ascending order is the values' descending total order,
    // then the lower index: plain integer selection and sorting, no comparator closure.
    let keyed = |i: usize| -> u64 {
        let b = vals[i].to_bits();
        let ascending = if b >> 31 == 1 { !b } else { b | 0x8000_0000 };
        (u64::from(!ascending) << 32) | i as u64
    };
    // The highest few hundred values per peak hold the peaks almost always; all of them when not.
    let mut m = (k * 256).min(vals.len());
    loop {
        let mut order: Vec<u64> = (0..vals.len()).map(keyed).collect();
        if m < order.len() {
            order.select_nth_unstable(m);
            order.truncate(m);
        }
        order.sort_unstable();
        let mut taken: Vec<(usize, f32)> = Vec::with_capacity(k);
        for &key in &order {
            if taken.len() == k {
                break;
            }
            let i = (key & 0xffff_ffff) as u32;
            let (x, y) = (i as usize % n, i as usize / n);
            if taken
                .iter()
                .all(|&(j, _)| (j % n).abs_diff(x) > 6 || (j / n).abs_diff(y) > 6)
            {
                taken.push((i as usize, vals[i as usize]));
            }
        }
        if taken.len() == k || m == vals.len() {
            return taken;
        }
        m = vals.len();
    }
}

/// What refusing a pair too large to correlate says (a placement tells it apart).
pub(crate) const TOO_LARGE: &str = "too large to align";

/// Refuses maps whose prepared parts (`src` moved onto `dst`, pixels) are too large to align: the
/// correlation at the coarsest cells would be over [`MAX_FFT`] cells a side. Known from the sizes alone,
/// so callers check before preparing.
pub(in crate::merge) fn check_size(src: (usize, usize), dst: (usize, usize)) -> Result<()> {
    let cell = CELLS[CELLS.len() - 1];
    let (sw, sh) = (src.0.div_ceil(cell), src.1.div_ceil(cell));
    let (dw, dh) = (dst.0.div_ceil(cell), dst.1.div_ceil(cell));
    let diag = (sh as f64).hypot(sw as f64).ceil() as usize + 2;
    let n = (dh.max(dw) + diag).next_power_of_two();
    if n > MAX_FFT {
        return Err(Error::invalid(format!(
            "maps whose explored parts span {}x{} and {}x{} pixels are {TOO_LARGE} (at most {} \
             coarse cells across both)",
            src.0, src.1, dst.0, dst.1, MAX_FFT
        )));
    }
    Ok(())
}
