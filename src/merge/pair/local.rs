//! The drift-tolerant local fit of one map's walls on another's: in tiles of the overlap, each shifted
//! by a few pixels, how many walls agree and how many still lie deep in the other map's free space.
//! Bending (SLAM drift) is explained by a few px of local shift; a wrong placement is not.

use crate::backend::{FLAG_DEEP, FLAG_INSIDE};
use crate::merge::pair::prepare::{Prepared, FLAG_NOISE, FLAG_TOUCH};
use crate::merge::transform::Rigid;

/// What [`local_fit`] measures.
#[derive(Clone, Copy, Debug)]
pub(in crate::merge) struct LocalFit {
    /// Share of the measured wall pixels within 1.5 px of `to`'s walls after their tile's best shift
    /// (the local agreement, [`crate::merge::pair::accept::Features::local`]).
    pub(in crate::merge) share: f64,
    /// Wall pixels measured (of those sampled).
    pub(in crate::merge) measured: f64,
    /// Their share of all of `from`'s wall pixels (at most 1).
    pub(in crate::merge) coverage: f64,
    /// Share of the measured wall pixels over 3 px deep in `to`'s free space after their tile's best
    /// shift: the conflict that bending (a few px of local shift) does not explain.
    pub(in crate::merge) residual: f64,
    /// The same fit in counts of sampled wall pixels ([`LocalCounts`]).
    pub(in crate::merge) counts: LocalCounts,
}

/// A local fit's counts of sampled wall pixels (one way, or both ways summed): what the
/// building-independent evidence measures ([`crate::merge::pair::evidence`]) are ratios of.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(in crate::merge) struct LocalCounts {
    /// Wall pixels in the measured tiles (those with enough of them).
    pub(in crate::merge) measured: f64,
    /// Of them, within 1.5 px of the other map's walls after their tile's best shift.
    pub(in crate::merge) agree: f64,
    /// Of them, over 3 px deep in the other map's free space after that shift.
    pub(in crate::merge) deep: f64,
    /// Of them, clutter of their own map ([`FLAG_NOISE`]): what a second robot need not see.
    pub(in crate::merge) noise: f64,
    /// Of the deep ones, clutter of their own map: the contradiction the maps' own noise explains.
    pub(in crate::merge) deep_noise: f64,
    /// Wall pixels (sampled, every tile) landing on the other map's known area, unshifted: the most
    /// the overlap could show to agree.
    pub(in crate::merge) known: f64,
}

impl LocalCounts {
    /// Both ways summed.
    pub(in crate::merge) fn plus(self, o: LocalCounts) -> LocalCounts {
        LocalCounts {
            measured: self.measured + o.measured,
            agree: self.agree + o.agree,
            deep: self.deep + o.deep,
            noise: self.noise + o.noise,
            deep_noise: self.deep_noise + o.deep_noise,
            known: self.known + o.known,
        }
    }

    /// The consistent evidence: walls that agree after the local shifts, less those left deep in free
    /// space.
    pub(in crate::merge) fn consistent(&self) -> f64 {
        self.agree - self.deep
    }
}

/// A sampled wall pixel as the pixel of `to` it lands on, with its own map's flags.
type Landed = ((i64, i64), u8);

/// In 48 px tiles of the overlap, `from`'s walls mapped by `t` into `to`, each tile shifted by up to 6 px
/// to where most of them lie within 1.5 px of `to`'s walls.
pub(in crate::merge) fn local_fit(from: &Prepared, to: &Prepared, t: &Rigid) -> LocalFit {
    const TILE: f64 = 48.0;
    const MIN_POINTS: usize = 24;
    // At most about 8000 wall pixels a map: enough for every tile's share.
    let step = from.walls.len().div_ceil(8000).max(1);
    // Each wall pixel as the pixel of `to` it lands on (rounded once): a shift by whole pixels is then
    // integer arithmetic, the same pixel `to.index` gives for the shifted point.
    let mut tiles: std::collections::BTreeMap<(i64, i64), Vec<Landed>> = Default::default();
    let apply = t.applier();
    let mut known = 0usize;
    for &p in from.walls.iter().step_by(step) {
        let q = apply.apply(p);
        if let Some(i) = to.index(q.0, q.1) {
            known += usize::from(to.flags_free.flags[i] & FLAG_INSIDE != 0);
            let own = from.flags_fine.flags[p.1 as usize * from.w + p.0 as usize];
            tiles
                .entry(((q.0 / TILE).floor() as i64, (q.1 / TILE).floor() as i64))
                .or_default()
                .push((
                    ((q.0 + 0.5).floor() as i64, (q.1 + 0.5).floor() as i64),
                    own,
                ));
        }
    }
    let (w, h) = (to.w as i64, to.h as i64);
    let at = |&((x, y), _): &Landed, dx: i64, dy: i64| {
        let (x, y) = (x + dx, y + dy);
        (x >= 0 && y >= 0 && x < w && y < h).then(|| (y * w + x) as usize)
    };
    // How many of `pts` with all of the flags `own` on their own map, shifted, land on a pixel of
    // `to` with the flag `bit`.
    let landing = |pts: &[Landed], dx: i64, dy: i64, bit: u8, own: u8| {
        pts.iter()
            .filter(|q| {
                q.1 & own == own && at(q, dx, dy).is_some_and(|i| to.flags_fine.flags[i] & bit != 0)
            })
            .count()
    };
    let near = |pts: &[Landed], dx: i64, dy: i64| landing(pts, dx, dy, FLAG_TOUCH, 0);
    let mut c = LocalCounts::default();
    for pts in tiles.values().filter(|p| p.len() >= MIN_POINTS) {
        // Shifts of up to 6 px in steps of 2, then the best one's neighbours.
        let mut best = (0usize, 0i64, 0i64);
        for dy in (-6..=6).step_by(2) {
            for dx in (-6..=6).step_by(2) {
                let c = near(pts, dx, dy);
                if c > best.0 {
                    best = (c, dx, dy);
                }
            }
        }
        let (_, bx, by) = best;
        let mut at = (bx, by);
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (x, y) = (bx + dx, by + dy);
                let c = near(pts, x, y);
                if c > best.0 {
                    (best.0, at) = (c, (x, y));
                }
            }
        }
        c.agree += best.0 as f64;
        c.measured += pts.len() as f64;
        c.noise += pts.iter().filter(|q| q.1 & FLAG_NOISE != 0).count() as f64;
        c.deep += landing(pts, at.0, at.1, FLAG_DEEP, 0) as f64;
        c.deep_noise += landing(pts, at.0, at.1, FLAG_DEEP, FLAG_NOISE) as f64;
    }
    c.known = known as f64;
    let total = c.measured.max(1.0);
    LocalFit {
        share: c.agree / total,
        measured: c.measured,
        coverage: (c.measured * step as f64 / from.walls.len().max(1) as f64).min(1.0),
        residual: c.deep / total,
        counts: c,
    }
}

/// [`local_fit`] both ways (B's walls into A at `t`, A's into B at its inverse), pooled by the wall
/// pixels measured: the agreement, the residual conflict and the pixels measured.
pub(in crate::merge) fn local_both(src: &Prepared, dst: &Prepared, t: &Rigid) -> (f64, f64, f64) {
    let (a, b) = (local_fit(src, dst, t), local_fit(dst, src, &t.inverse()));
    pooled(&a, &b)
}

/// [`local_both`] with the counts of both ways summed ([`LocalCounts`]).
pub(in crate::merge) fn local_both_counts(
    src: &Prepared,
    dst: &Prepared,
    t: &Rigid,
) -> ((f64, f64, f64), LocalCounts) {
    let (a, b) = (local_fit(src, dst, t), local_fit(dst, src, &t.inverse()));
    (pooled(&a, &b), a.counts.plus(b.counts))
}

/// Two ways' fits pooled by the wall pixels measured: the agreement, the residual conflict and the
/// pixels measured.
fn pooled(a: &LocalFit, b: &LocalFit) -> (f64, f64, f64) {
    let n = (a.measured + b.measured).max(1.0);
    (
        (a.share * a.measured + b.share * b.measured) / n,
        (a.residual * a.measured + b.residual * b.measured) / n,
        a.measured + b.measured,
    )
}
