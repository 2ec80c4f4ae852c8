//! How much a set's maps disagree at poses that cycles confirm, and which candidates disagree far more.
//!
//! Two maps at their right pose still put some walls in each other's free space: SLAM drift beyond a
//! few pixels, furniture moved, a door open in one run. How much depends on the robots, the sensor and
//! the building: on the real sensor maps the right poses leave 4-30% of the walls there (after each
//! tile's best shift of a few px, [`Features::residual`](crate::merge::pair::accept::Features)), on clean
//! maps under 7%; a wrong pose among many alike rooms leaves 4-26%. No fixed limit tells them apart, but
//! a set of maps of one fleet measures its own level: its accepted pairs that a cycle of two other
//! accepted pairs confirms. A candidate far above that level is no pose of this fleet's maps, however
//! well its walls correlate.

use serde::Serialize;

use crate::merge::many::Pairwise;

/// Confirmed pairs needed to measure a set's level: with fewer, no candidate is excluded for it (each
/// confirmed pair is itself checked by a cycle, so a few suffice; on the synthetic sets 3 calibrated
/// four more sets than 6 and placed 3 more maps right, none wrong).
pub const MIN_CONFIRMED: usize = 3;
/// A candidate is excluded above the level's median plus this many robust standard deviations
/// (1.4826 median absolute deviations)...
pub const SPREADS: f64 = 4.0;
/// ... or twice the median, whichever is higher ...
pub const MEDIANS: f64 = 2.0;
/// ... and never under this share: the walls a right pose of clean maps leaves in free space where a
/// turned map was resampled and at the edges of what each saw (the synthetic sets' right poses: 7% at
/// most, nearly all under 2%).
pub const FLOOR: f64 = 0.08;

/// A set's level of conflict at confirmed poses ([`calibrate`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Calibration {
    /// Accepted pairs that a cycle of two other accepted pairs confirms.
    pub confirmed: usize,
    /// Their median residual conflict.
    pub median: f64,
    /// The residual conflict above which a candidate is excluded; `None` with fewer than
    /// [`MIN_CONFIRMED`] confirmed pairs.
    pub limit: Option<f64>,
}

impl Calibration {
    /// Whether a candidate with this residual conflict is excluded.
    pub fn excludes(&self, residual: f64) -> bool {
        self.limit.is_some_and(|l| residual > l)
    }
}

/// What the cycles say about one edge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct EdgeEvidence {
    /// Its own weight (the graph's `weight`).
    pub own: f64,
    /// Sum over third maps of the weaker of the two edges through it that compose to this one.
    pub support: f64,
    /// For an accepted edge: sum over third maps through which no two edges compose to it of the weaker
    /// of two accepted edges through it that compose to something else.
    pub contradicted: f64,
    /// For an accepted edge: two other accepted edges through a third map compose to it.
    pub confirmed: bool,
    /// Excluded: its residual conflict is over the set's limit ([`Calibration::limit`]); it neither votes
    /// nor confirms.
    pub excluded: bool,
}

impl EdgeEvidence {
    /// The weight it votes with: its own plus its support, less its contradiction (at least 0; 0 when
    /// excluded).
    pub fn vote(&self) -> f64 {
        if self.excluded {
            return 0.0;
        }
        (self.own + self.support - self.contradicted).max(0.0)
    }
}

/// The level of `pairwise`'s confirmed accepted pairs ([`EdgeEvidence::confirmed`] in `ev`).
pub fn calibrate(pairwise: &Pairwise, ev: &[EdgeEvidence]) -> Calibration {
    let r: Vec<f64> = pairwise
        .edges
        .iter()
        .zip(ev)
        .filter(|(e, v)| e.accepted && v.confirmed)
        .map(|(e, _)| e.residual)
        .filter(|r| r.is_finite())
        .collect();
    let confirmed = r.len();
    if confirmed == 0 {
        return Calibration::default();
    }
    let median = crate::support::stats::median(r.clone());
    let spread =
        1.4826 * crate::support::stats::median(r.iter().map(|x| (x - median).abs()).collect());
    let limit = (confirmed >= MIN_CONFIRMED)
        .then(|| (median + SPREADS * spread).max(MEDIANS * median).max(FLOOR));
    Calibration {
        confirmed,
        median,
        limit,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::many::Edge;
    use crate::merge::Rigid;

    fn edge(residual: f64, accepted: bool) -> Edge {
        Edge {
            a: 0,
            b: 1,
            rank: 0,
            transform: Rigid::IDENTITY,
            score: 1.0,
            accepted,
            at: (0.0, 0.0),
            residual,
        }
    }

    fn set(residuals: &[(f64, bool, bool)]) -> Calibration {
        let pairwise = Pairwise {
            n: 2,
            edges: residuals.iter().map(|&(r, a, _)| edge(r, a)).collect(),
            ..Pairwise::default()
        };
        let ev: Vec<EdgeEvidence> = residuals
            .iter()
            .map(|&(_, _, confirmed)| EdgeEvidence {
                confirmed,
                ..EdgeEvidence::default()
            })
            .collect();
        calibrate(&pairwise, &ev)
    }

    #[test]
    fn a_clean_fleet_excludes_what_a_noisy_one_keeps() {
        // Clean maps: confirmed pairs under 1%; a 15% candidate is far above them.
        let clean: Vec<(f64, bool, bool)> =
            (0..8).map(|k| (0.002 * k as f64, true, true)).collect();
        let c = set(&clean);
        assert_eq!(c.confirmed, 8);
        assert!(c.excludes(0.15) && !c.excludes(0.05), "{c:?}");
        // Real sensor maps: confirmed pairs around 15%; the same 15% (and 28%) is their usual level.
        let noisy: Vec<(f64, bool, bool)> = [0.08, 0.11, 0.13, 0.15, 0.16, 0.18, 0.21, 0.24]
            .iter()
            .map(|&r| (r, true, true))
            .collect();
        let n = set(&noisy);
        assert!(!n.excludes(0.15) && !n.excludes(0.28), "{n:?}");
        assert!(n.excludes(0.6), "{n:?}");
    }

    #[test]
    fn too_few_confirmed_pairs_exclude_nothing() {
        // Unconfirmed or not accepted pairs do not count, whatever their conflict.
        let mut few: Vec<(f64, bool, bool)> = (0..2).map(|_| (0.0, true, true)).collect();
        few.extend([(0.0, true, false), (0.0, false, true), (0.0, false, false)]);
        let c = set(&few);
        assert_eq!(c.confirmed, 2);
        assert_eq!(c.limit, None);
        assert!(!c.excludes(0.9));
    }
}
