//! The drift-tolerant local fit of one map's walls on another's: in tiles of the overlap, each shifted
//! by a few pixels, how many walls agree and how many still lie deep in the other map's free space.
//! Bending (SLAM drift) is explained by a few px of local shift; a wrong placement is not.

use crate::backend::FLAG_DEEP;
use crate::merge::pair::prepare::{Prepared, FLAG_TOUCH};
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
}

/// In 48 px tiles of the overlap, `from`'s walls mapped by `t` into `to`, each tile shifted by up to 6 px
/// to where most of them lie within 1.5 px of `to`'s walls.
pub(in crate::merge) fn local_fit(from: &Prepared, to: &Prepared, t: &Rigid) -> LocalFit {
    const TILE: f64 = 48.0;
    const MIN_POINTS: usize = 24;
    // At most about 8000 wall pixels a map: enough for every tile's share.
    let step = from.walls.len().div_ceil(8000).max(1);
    // Each wall pixel as the pixel of `to` it lands on (rounded once): a shift by whole pixels is then
    // integer arithmetic, the same pixel `to.index` gives for the shifted point.
    let mut tiles: std::collections::BTreeMap<(i64, i64), Vec<(i64, i64)>> = Default::default();
    let apply = t.applier();
    for &p in from.walls.iter().step_by(step) {
        let q = apply.apply(p);
        if to.index(q.0, q.1).is_some() {
            tiles
                .entry(((q.0 / TILE).floor() as i64, (q.1 / TILE).floor() as i64))
                .or_default()
                .push(((q.0 + 0.5).floor() as i64, (q.1 + 0.5).floor() as i64));
        }
    }
    let (w, h) = (to.w as i64, to.h as i64);
    let at = |&(x, y): &(i64, i64), dx: i64, dy: i64| {
        let (x, y) = (x + dx, y + dy);
        (x >= 0 && y >= 0 && x < w && y < h).then(|| (y * w + x) as usize)
    };
    // How many of `pts`, shifted, land on a pixel of `to` with the flag `bit`.
    let landing = |pts: &[(i64, i64)], dx: i64, dy: i64, bit: u8| {
        pts.iter()
            .filter(|q| at(q, dx, dy).is_some_and(|i| to.flags_fine.flags[i] & bit != 0))
            .count()
    };
    let near = |pts: &[(i64, i64)], dx: i64, dy: i64| landing(pts, dx, dy, FLAG_TOUCH);
    let deep = |pts: &[(i64, i64)], dx: i64, dy: i64| landing(pts, dx, dy, FLAG_DEEP);
    let (mut hit, mut total, mut conflicts) = (0usize, 0usize, 0usize);
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
        hit += best.0;
        total += pts.len();
        conflicts += deep(pts, at.0, at.1);
    }
    LocalFit {
        share: hit as f64 / total.max(1) as f64,
        measured: total as f64,
        coverage: (total as f64 * step as f64 / from.walls.len().max(1) as f64).min(1.0),
        residual: conflicts as f64 / total.max(1) as f64,
    }
}

/// [`local_fit`] both ways (B's walls into A at `t`, A's into B at its inverse), pooled by the wall
/// pixels measured: the agreement, the residual conflict and the pixels measured.
pub(in crate::merge) fn local_both(src: &Prepared, dst: &Prepared, t: &Rigid) -> (f64, f64, f64) {
    let (a, b) = (local_fit(src, dst, t), local_fit(dst, src, &t.inverse()));
    let n = (a.measured + b.measured).max(1.0);
    (
        (a.share * a.measured + b.share * b.measured) / n,
        (a.residual * a.measured + b.residual * b.measured) / n,
        a.measured + b.measured,
    )
}
