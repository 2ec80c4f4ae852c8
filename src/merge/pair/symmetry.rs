//! A map's turns onto itself, at any angle: the rotations under which its walls land on its own walls.
//! A building with k identical wings turns onto itself by 360/k degrees, and a pair cut from it can be
//! placed wrongly by exactly such a turn; the aligner's own hypotheses only try the quarter turns of the
//! dominant wall direction, so this sweep looks at every angle.
//!
//! How: at the coarse level the aligner correlates at (cells of 4, 8 or 16 px, at most
//! [`crate::merge::pair::fft::FINE_FFT`] cells a side), the wall cells turned by each angle of a 2 degree sweep about
//! the map's centre are correlated over every shift with the map's own walls dilated by a cell, less its
//! free cells. A turn's score is, at the best shift, the share of the wall cells that land on those walls
//! less the share that land on free space: 1 for the identity, near 1 for a symmetry of the whole map,
//! about the share of the map that repeats for a partial one (a wing, the hall alone), low for a turn
//! that lays walls across rooms. It is a share of the map's own walls, so its scale does not depend on
//! the building. The best local maxima of the sweep away from the identity are refined to a quarter
//! degree.

use rustfft::num_complex::Complex32;
use rustfft::FftPlanner;

use crate::merge::pair::coarse::cells_to_crop;
use crate::merge::pair::fft::{padded, zeros, Fft2, FINE_FFT};
use crate::merge::pair::prepare::{Coarse, Prepared};
use crate::merge::transform::{signed_deg as signed, Rigid};

/// The sweep's step, degrees.
pub const SWEEP_DEG: f64 = 2.0;

/// Turns within this of the identity are the identity seen through the coarse cells, degrees.
pub const NEAR_IDENTITY_DEG: f64 = 10.0;

/// A turn of a map onto itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfTurn {
    /// The angle, degrees in (-180, 180].
    pub theta_deg: f64,
    /// The share of the map's wall cells that land on its walls (dilated by a cell) turned by it, less
    /// the share that land on its free cells, at the best shift: 1 for the identity.
    pub score: f64,
    /// The turn with its best shift, as a transform of the map's crop pixels (its known area's box,
    /// `Prepared::off` from the map's origin) onto its own: good to the coarse cell it was found at
    /// (4 to 16 px), for a fine fit to finish.
    pub crop: Rigid,
}

/// The best local maxima of the turn score away from the identity (at most [`MAX_TURNS`]), best first,
/// refined to a quarter degree; empty for a map with no wall cell.
pub fn self_turns(p: &Prepared) -> Vec<SelfTurn> {
    let Some(level) = level(p) else {
        return Vec::new();
    };
    let sweep = Sweep::new(level);
    if sweep.walls == 0.0 {
        return Vec::new();
    }
    let steps = (360.0 / SWEEP_DEG).round() as usize;
    let scores: Vec<f64> = {
        use rayon::prelude::*;
        (0..steps)
            .into_par_iter()
            .map(|i| sweep.score(i as f64 * SWEEP_DEG))
            .collect()
    };
    let mut peaks: Vec<usize> = (0..steps)
        .filter(|&i| {
            let (prev, next) = ((i + steps - 1) % steps, (i + 1) % steps);
            scores[i] >= scores[prev] && scores[i] > scores[next]
        })
        .filter(|&i| signed(i as f64 * SWEEP_DEG).abs() > NEAR_IDENTITY_DEG)
        .collect();
    peaks.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]));
    peaks.truncate(MAX_TURNS);
    let mut out: Vec<SelfTurn> = {
        use rayon::prelude::*;
        peaks
            .par_iter()
            .map(|&i| sweep.refine(i as f64 * SWEEP_DEG))
            .collect()
    };
    out.sort_by(|a, b| b.score.total_cmp(&a.score));
    out
}

/// The most turns kept (and refined): the best local maxima of the sweep.
pub const MAX_TURNS: usize = 12;

/// The finest coarse level whose turned correlation fits [`FINE_FFT`] cells a side, else the coarsest.
fn level(p: &Prepared) -> Option<&Coarse> {
    let fits = |c: &&Coarse| fft_side(c) <= FINE_FFT;
    p.levels
        .iter()
        .flatten()
        .find(fits)
        .or_else(|| p.levels.iter().flatten().last())
}

/// The side of a correlation of `c` with itself turned: the map and its diagonal.
fn fft_side(c: &Coarse) -> usize {
    (c.cw.max(c.ch) + diagonal(c)).next_power_of_two()
}

fn diagonal(c: &Coarse) -> usize {
    (c.cw as f64).hypot(c.ch as f64).ceil() as usize + 2
}

/// One map's sweep: its dilated walls' spectrum, kept for every angle.
struct Sweep<'a> {
    c: &'a Coarse,
    n: usize,
    diag: usize,
    fwd: Fft2,
    inv: Fft2,
    /// The conjugate spectrum of the dilated walls.
    target: Vec<Complex32>,
    /// Wall cells.
    walls: f64,
}

impl<'a> Sweep<'a> {
    fn new(c: &'a Coarse) -> Sweep<'a> {
        let n = fft_side(c);
        let mut planner = FftPlanner::new();
        let (fwd, inv) = (
            Fft2::new(&mut planner, n, false),
            Fft2::new(&mut planner, n, true),
        );
        // Walls on (dilated) walls count for, walls on free space against: a turn that lays the walls
        // across rooms scores low however dense the walls are.
        let contrast: Vec<f32> = c
            .cwall_dil
            .iter()
            .zip(&c.cfree)
            .map(|(w, f)| w - f)
            .collect();
        let mut target = padded(&contrast, c.cw, c.ch, n);
        fwd.run(&mut target, &mut zeros(n));
        for v in &mut target {
            *v = v.conj();
        }
        let walls = c.cwall.iter().map(|&v| f64::from(v)).sum();
        Sweep {
            c,
            n,
            diag: diagonal(c),
            fwd,
            inv,
            target,
            walls,
        }
    }

    /// The turn score of `theta` degrees.
    fn score(&self, theta: f64) -> f64 {
        self.peak(theta).0
    }

    /// The turn score of `theta` degrees and the correlation's index where it peaks (the shift).
    fn peak(&self, theta: f64) -> (f64, usize) {
        let (c, n, diag) = (self.c, self.n, self.diag);
        let (s, co) = theta.to_radians().sin_cos();
        let centre = ((c.cw as f64 - 1.0) / 2.0, (c.ch as f64 - 1.0) / 2.0);
        let mid = (diag as f64 - 1.0) / 2.0;
        // The wall cells turned by theta about the map's centre into a diag x diag canvas (nearest cell).
        let mut z = zeros(n);
        let mut kept = 0.0f64;
        for j in 0..diag {
            for i in 0..diag {
                let (dx, dy) = (i as f64 - mid, j as f64 - mid);
                let (x, y) = (
                    co * dx + s * dy + centre.0 + 0.5,
                    -s * dx + co * dy + centre.1 + 0.5,
                );
                if x >= 0.0 && y >= 0.0 && (x as usize) < c.cw && (y as usize) < c.ch {
                    let v = c.cwall[y as usize * c.cw + x as usize];
                    z[j * n + i].re = v;
                    kept += f64::from(v);
                }
            }
        }
        if kept == 0.0 {
            return (0.0, 0);
        }
        let mut scratch = zeros(n);
        self.fwd.run(&mut z, &mut scratch);
        for (v, t) in z.iter_mut().zip(&self.target) {
            *v *= t;
        }
        self.inv.run(&mut z, &mut scratch);
        let (at, peak) =
            z.iter().enumerate().fold(
                (0, 0.0f32),
                |b, (i, v)| if v.re > b.1 { (i, v.re) } else { b },
            );
        // The inverse FFT is unnormalised; a turn lands each wall cell on at most one, so the share is
        // of the cells turned (the nearest-cell turn may drop or repeat a few).
        ((f64::from(peak) / (n * n) as f64 / kept).min(1.0), at)
    }

    /// The turn of `theta` degrees at the shift of correlation index `at`, in crop pixels. The
    /// correlation at shift k is the sum over q of the target at q times the turned walls at q + k: a
    /// map cell p lands on the canvas at R (p - centre) + mid, and from there on the map cell k less.
    fn transform(&self, theta: f64, at: usize) -> Rigid {
        let (c, n, diag) = (self.c, self.n, self.diag);
        // A shift in (-(map side), diag): the canvas holds the turned map, the map is what it lands on.
        let wrap = |v: usize| {
            if v < diag {
                v as f64
            } else {
                v as f64 - n as f64
            }
        };
        let (k, mid) = ((wrap(at % n), wrap(at / n)), (diag as f64 - 1.0) / 2.0);
        let centre = ((c.cw as f64 - 1.0) / 2.0, (c.ch as f64 - 1.0) / 2.0);
        let (s, co) = theta.to_radians().sin_cos();
        // In cells: p -> R p + tc.
        let tc = (
            mid - (co * centre.0 - s * centre.1) - k.0,
            mid - (s * centre.0 + co * centre.1) - k.1,
        );
        cells_to_crop(theta, tc, c.cell).normalized()
    }

    /// The best turn within a sweep step of `theta`, to a quarter degree.
    fn refine(&self, theta: f64) -> SelfTurn {
        let (mut best, (mut top, mut at)) = (theta, self.peak(theta));
        let mut t = theta - SWEEP_DEG;
        while t <= theta + SWEEP_DEG {
            let (v, i) = self.peak(t);
            if v > top {
                (best, top, at) = (t, v, i);
            }
            t += 0.25;
        }
        SelfTurn {
            theta_deg: signed(best),
            score: top,
            crop: self.transform(best, at),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::OccupancyMap;
    use crate::measure::synthetic::{symmetric_plan, SymmetricKind};

    fn turns_of(img: crate::map::MapImage) -> Vec<SelfTurn> {
        self_turns(&Prepared::new(&OccupancyMap::from_image(img)))
    }

    /// A hall with k identical wings turns onto itself by every multiple of 360/k degrees, and those are
    /// its best turns; half a wing's turn scores far lower.
    #[test]
    fn a_k_wing_hall_turns_onto_itself_by_each_whole_wing() {
        for k in 3..=8u8 {
            let kind = SymmetricKind {
                mirrored: k % 2 == 0,
                ..SymmetricKind::plain(k)
            };
            let (img, hall) = symmetric_plan(kind, u64::from(k)).unwrap();
            let p = Prepared::new(&OccupancyMap::from_image(img));
            let turns = self_turns(&p);
            let cell = level(&p).unwrap().cell as f64;
            let step = 360.0 / f64::from(k);
            let near = |t: &SelfTurn, a: f64| signed(t.theta_deg - a).abs() <= 2.0;
            for m in 1..k {
                let a = signed(step * f64::from(m));
                let t = turns
                    .iter()
                    .find(|t| near(t, a))
                    .unwrap_or_else(|| panic!("{k} wings: no turn near {a}: {turns:?}"));
                assert!(t.score > 0.85, "{k} wings, {a} deg: {t:?}");
                // The turn is about the hall's centre: its transform keeps it in place, to a cell or so.
                let c = (hall.0 - p.off.0, hall.1 - p.off.1);
                let moved = t.crop.apply(c);
                let off = (moved.0 - c.0).hypot(moved.1 - c.1);
                assert!(
                    off <= 1.5 * cell,
                    "{k} wings, {a} deg: the centre moves {off:.1} px"
                );
            }
            // Nothing between the wings' turns scores like them.
            let between = turns
                .iter()
                .filter(|t| (1..k).all(|m| !near(t, signed(step * f64::from(m)))))
                .map(|t| t.score)
                .fold(0.0, f64::max);
            let worst_whole = turns
                .iter()
                .filter(|t| (1..k).any(|m| near(t, signed(step * f64::from(m)))))
                .map(|t| t.score)
                .fold(1.0, f64::min);
            assert!(
                between < worst_whole - 0.15,
                "{k} wings: {between:.3} between, {worst_whole:.3} at whole turns: {turns:?}"
            );
        }
    }

    /// An office of the generator (rooms of different sizes) has no turn onto itself as good as a
    /// symmetric hall's (0.99 and more): the score ranks the turns, the aligner's fine fit will judge
    /// them.
    #[test]
    fn an_office_of_unequal_rooms_has_no_whole_turn() {
        for seed in [1u64, 2, 3] {
            for (w, h, most) in [(640, 480, 0.8), (1024, 768, 0.9)] {
                let turns = turns_of(crate::map::synthetic::office_map(w, h, seed).unwrap());
                let best = turns.first().map_or(0.0, |t| t.score);
                assert!(best < most, "seed {seed}, {w}x{h}: {turns:?}");
            }
        }
    }

    #[test]
    fn a_map_with_no_walls_has_no_turns() {
        let img = crate::map::MapImage::filled(64, 64, crate::map::states::FREE).unwrap();
        assert!(turns_of(img).is_empty());
    }
}
