//! Greedy suppression of the robust detector's corners: strongest first, a corner is kept unless a kept
//! one lies within the radius. In one window of a map ([`fates`]) it is decided exactly for the corners
//! whose stronger neighbours are all in view, and left open for the others.
//!
//! Whatever order the corners come in, the order of strength is total (ties: the larger scale, then the
//! corner nearer the map's centre, then the rest of the keypoint and a caller's key), so every window of a
//! map and the whole map in one piece decide every corner alike.

use std::cmp::Ordering;

use rayon::prelude::*;

use crate::backend::Keypoint;

/// What the suppression decided for a corner of a window.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fate {
    /// Kept in the whole map too.
    Kept,
    /// Suppressed in the whole map too (a kept corner lies within the radius).
    Suppressed,
    /// Depends on corners the window does not see.
    Open,
}

/// Greedy suppression: strongest first, a keypoint is kept unless a kept one lies within `radius` pixels.
/// Ties go to the larger scale, then to the keypoint nearer the grid's anchor (`centre2`, in half pixels;
/// the map's centre by default, and a quarter turn or a mirror of the map about it keeps the same order), then (y, x) and the
/// rest of the keypoint, so the result does not depend on the order found.
pub fn suppress(found: Vec<Keypoint>, radius: u32, centre2: (i64, i64)) -> Vec<Keypoint> {
    let fates = fates(
        found.len(),
        |i| &found[i],
        radius,
        centre2,
        &|_| true,
        &|a, b| a.cmp(&b),
    );
    found
        .into_iter()
        .zip(fates)
        .filter_map(|(k, f)| (f == Fate::Kept).then_some(k))
        .collect()
}

/// The fate of each of `n` keypoints (`key(i)`, i < n) under greedy suppression, in their order, when the
/// keypoints within `radius` of the one at index `i` that are not among them can only be weaker than it
/// where `settled(i)`; keypoints equal in every field are ordered by `tie` of their indices.
pub fn fates<'a>(
    n: usize,
    key: impl Fn(usize) -> &'a Keypoint + Sync,
    radius: u32,
    centre2: (i64, i64),
    settled: &(dyn Fn(usize) -> bool + Sync),
    tie: &(dyn Fn(usize, usize) -> Ordering + Sync),
) -> Vec<Fate> {
    let mut out = vec![Fate::Suppressed; n];
    let mut kept = Near::new(radius);
    let mut open = Near::new(radius);
    for i in strongest_first(n, &key, centre2, tie) {
        let k = key(i);
        out[i] = if kept.any(k) {
            Fate::Suppressed
        } else if open.any(k) || !settled(i) {
            open.add(k);
            Fate::Open
        } else {
            kept.add(k);
            Fate::Kept
        };
    }
    out
}

/// Indices of the `n` keypoints `key(i)`, strongest first (see [`suppress`]).
fn strongest_first<'a>(
    n: usize,
    key: &(impl Fn(usize) -> &'a Keypoint + Sync),
    centre2: (i64, i64),
    tie: &(dyn Fn(usize, usize) -> Ordering + Sync),
) -> Vec<usize> {
    // The distances once a keypoint, not once a comparison.
    let dist: Vec<i64> = (0..n)
        .map(|i| {
            let k = key(i);
            let (dx, dy) = (
                2 * i64::from(k.x) - centre2.0,
                2 * i64::from(k.y) - centre2.1,
            );
            dx * dx + dy * dy
        })
        .collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.par_sort_unstable_by(|&i, &j| {
        let (a, b) = (key(i), key(j));
        b.score
            .cmp(&a.score)
            .then(b.scale.cmp(&a.scale))
            .then(dist[i].cmp(&dist[j]))
            .then(a.cmp(b))
            .then_with(|| tie(i, j))
    });
    order
}

/// Keypoints by bucket of the radius, to find those within it of a point.
pub(super) struct Near {
    cell: u32,
    r2: i64,
    buckets: Buckets,
}

impl Near {
    pub(super) fn new(radius: u32) -> Self {
        Near {
            cell: radius.max(1),
            r2: i64::from(radius) * i64::from(radius),
            buckets: Buckets::default(),
        }
    }

    /// Whether a keypoint added lies within the radius of `k`.
    pub(super) fn any(&self, k: &Keypoint) -> bool {
        if self.buckets.is_empty() {
            return false;
        }
        let (bx, by) = (k.x / self.cell, k.y / self.cell);
        (bx.saturating_sub(1)..=bx + 1).any(|x| {
            (by.saturating_sub(1)..=by + 1).any(|y| {
                self.buckets.get(&(x, y)).is_some_and(|v| {
                    v.iter().any(|&(px, py)| {
                        let (dx, dy) = (
                            i64::from(px) - i64::from(k.x),
                            i64::from(py) - i64::from(k.y),
                        );
                        dx * dx + dy * dy <= self.r2
                    })
                })
            })
        })
    }

    /// Adds `k`.
    pub(super) fn add(&mut self, k: &Keypoint) {
        self.buckets
            .entry((k.x / self.cell, k.y / self.cell))
            .or_default()
            .push((k.x, k.y));
    }
}

/// Kept keypoints by bucket of `radius` pixels.
type Buckets = std::collections::HashMap<
    (u32, u32),
    Vec<(u32, u32)>,
    std::hash::BuildHasherDefault<CellHasher>,
>;

/// A multiplicative hasher for bucket coordinates: the keys are small integers, not attacker-chosen,
/// and SipHash would be most of the suppression's time.
#[derive(Default)]
struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u32(&mut self, v: u32) {
        self.write_u64(u64::from(v));
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(29) ^ v).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kp(x: u32, y: u32, score: i64) -> Keypoint {
        Keypoint {
            score,
            scale: 4,
            ..Keypoint::scored(x, y, score)
        }
    }

    /// A chain of ever weaker corners a radius apart: the strongest is kept, the next suppressed, the
    /// third kept again. Seen from a window holding only the last two, with the second unsettled, both
    /// stay open; dropping what a window calls suppressed never changes the whole map's answer.
    #[test]
    fn a_window_decides_only_what_it_sees_and_never_wrongly() {
        let all = vec![kp(0, 0, 30), kp(4, 0, 20), kp(8, 0, 10), kp(40, 0, 5)];
        let f = |ks: &[Keypoint], settled: &(dyn Fn(usize) -> bool + Sync)| {
            fates(ks.len(), |i| &ks[i], 4, (0, 0), settled, &|a, b| a.cmp(&b))
        };
        let whole = f(&all, &|_| true);
        assert_eq!(
            whole,
            [Fate::Kept, Fate::Suppressed, Fate::Kept, Fate::Kept]
        );
        let part = &all[1..];
        let seen = f(part, &|i| i != 0);
        assert_eq!(seen, [Fate::Open, Fate::Open, Fate::Kept]);
        // The first corner in view suppresses the second, so the window may drop the second only once it
        // sees the first.
        let part = &all[..3];
        let seen = f(part, &|i| i != 2);
        assert_eq!(seen, [Fate::Kept, Fate::Suppressed, Fate::Open]);
        assert_eq!(suppress(all, 4, (0, 0)).len(), 3);
    }
}
