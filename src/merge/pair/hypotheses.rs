//! Where the aligner's hypotheses come from: the dense coarse correlation's peaks (the default), corners
//! matched between the maps (the paper's proposal: its detector as "the initial step for a merging map
//! algorithm"), or both. `merge-eval --ablation` compares them on a pair set.
//!
//! Corner hypotheses: each map's strongest corners (crop coordinates); for every rotation hypothesis of the
//! aligner, every corner of B turned and paired with every corner of A votes for the translation that puts
//! one on the other, in 8 px bins; the 3 best-voted bins (3 bins apart) are candidates, their translation
//! the mean of their votes. A candidate is scored like a dense one, by the coarse correlation at its
//! nearest shift, so all candidates meet the same test.

use std::collections::HashMap;

use crate::backend::{DetectOptions, DetectorKind};
use crate::detect::detector::Detector;
use crate::map::OccupancyMap;
use crate::merge::transform::Rigid;
use crate::support::error::Result;

/// Where hypotheses come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Hypotheses {
    /// The dense coarse correlation's peaks.
    #[default]
    Dense,
    /// Corners matched between the maps.
    Corners(DetectorKind),
    /// Both.
    Both(DetectorKind),
}

impl Hypotheses {
    /// The corner detector, when corners are used.
    pub fn detector(self) -> Option<DetectorKind> {
        match self {
            Hypotheses::Dense => None,
            Hypotheses::Corners(d) | Hypotheses::Both(d) => Some(d),
        }
    }

    /// Whether the dense correlation's peaks are candidates.
    pub fn dense(self) -> bool {
        !matches!(self, Hypotheses::Corners(_))
    }

    /// A short name for tables: `dense`, `corners (ogm)`, `both (harris)`.
    pub fn name(self) -> String {
        match self {
            Hypotheses::Dense => "dense".to_string(),
            Hypotheses::Corners(d) => format!("corners ({})", d.name()),
            Hypotheses::Both(d) => format!("both ({})", d.name()),
        }
    }
}

/// Corners kept per map, strongest first (the paper's detector has no strength: evenly spaced ones).
pub const MAX_CORNERS: usize = 200;
/// Translation bin, pixels.
const BIN: f64 = 8.0;
/// Candidates per rotation.
const PER_ROTATION: usize = 3;

/// The corners of `map` by `detector`, map pixels, at most [`MAX_CORNERS`].
pub fn corners(map: &OccupancyMap, detector: DetectorKind) -> Result<Vec<(f64, f64)>> {
    let mut d = Detector::new(DetectOptions {
        detector,
        ..DetectOptions::default()
    });
    let mut k = d.detect(map)?.keypoints;
    // Strongest first, ties in (y, x) order; without strengths, every n-th.
    k.sort_by(|a, b| b.score.cmp(&a.score).then(a.cmp(b)));
    let step = if k.iter().all(|p| p.score == 0) {
        k.len().div_ceil(MAX_CORNERS).max(1)
    } else {
        1
    };
    Ok(k.iter()
        .step_by(step)
        .take(MAX_CORNERS)
        .map(|p| (f64::from(p.x), f64::from(p.y)))
        .collect())
}

/// A translation bin and its votes: how many, and the sums of their x and y.
type Bin = ((i64, i64), (u32, f64, f64));

/// Translation candidates (src crop to dst crop) at rotation `theta_deg` from corner votes.
pub(in crate::merge) fn vote(src: &[(f64, f64)], dst: &[(f64, f64)], theta_deg: f64) -> Vec<Rigid> {
    let rot = Rigid {
        theta_deg,
        tx: 0.0,
        ty: 0.0,
    };
    let mut bins: HashMap<(i64, i64), (u32, f64, f64)> = HashMap::new();
    for &b in src {
        let rb = rot.apply(b);
        for &a in dst {
            let t = (a.0 - rb.0, a.1 - rb.1);
            let key = ((t.0 / BIN).floor() as i64, (t.1 / BIN).floor() as i64);
            let e = bins.entry(key).or_insert((0, 0.0, 0.0));
            *e = (e.0 + 1, e.1 + t.0, e.2 + t.1);
        }
    }
    let mut ranked: Vec<Bin> = bins.into_iter().collect();
    // Most votes first; ties by bin, so the result does not depend on the hash order.
    ranked.sort_by(|x, y| y.1 .0.cmp(&x.1 .0).then(x.0.cmp(&y.0)));
    let mut out: Vec<((i64, i64), Rigid)> = Vec::new();
    for (key, (n, sx, sy)) in ranked {
        if out.len() >= PER_ROTATION || n < 2 {
            break;
        }
        if out
            .iter()
            .all(|(k, _)| (k.0 - key.0).abs() > 3 || (k.1 - key.1).abs() > 3)
        {
            let n = f64::from(n);
            out.push((
                key,
                Rigid {
                    theta_deg,
                    tx: sx / n,
                    ty: sy / n,
                },
            ));
        }
    }
    out.into_iter().map(|(_, t)| t).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn votes_find_the_translation_that_puts_corners_on_corners() {
        let dst = [(10.0, 10.0), (50.0, 12.0), (30.0, 70.0), (80.0, 40.0)];
        let truth = Rigid {
            theta_deg: 30.0,
            tx: 5.0,
            ty: -7.0,
        };
        let inv = truth.inverse();
        let src: Vec<(f64, f64)> = dst.iter().map(|&p| inv.apply(p)).collect();
        let got = vote(&src, &dst, 30.0);
        assert!(!got.is_empty());
        assert!((got[0].tx - 5.0).abs() < 1e-6 && (got[0].ty + 7.0).abs() < 1e-6);
    }
}
