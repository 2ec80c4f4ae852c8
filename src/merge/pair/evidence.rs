//! Measures of a chosen pose in units that do not depend on the building, reported beside the
//! acceptance test (which does not read them yet): how far its evidence stands above the best distinct
//! alternative's, counted the same way ([`Features::evidence_ratio`]); its evidence as a share of what
//! the overlap could show ([`Features::support_share`]); each map's own noise level from the map alone
//! ([`Features::noise_a`], [`Features::noise_b`], [`Features::noise`]); and its contradiction beyond
//! that noise ([`Features::excess_conflict`]). Every one is a ratio of counts of the same pair's wall
//! pixels at the same tolerances (fixed in pixels: they follow the maps' resolution, not the building),
//! so no absolute pixel count enters it.
//!
//! They cost nothing beyond what the alignment measures anyway: the counts ride along in the local
//! fits of the candidates ([`LocalCounts`]) and of the alternative poses, and each map's clutter is
//! marked once when it is prepared.

use crate::merge::pair::accept::Features;
use crate::merge::pair::choose::MAX_RATIO;
use crate::merge::pair::local::LocalCounts;
use crate::merge::pair::prepare::{clutter_share, Prepared};

/// `mine` over `other`, at most [`MAX_RATIO`] (also when `other` has nothing); 0 when `mine` has
/// nothing.
pub(in crate::merge) fn evidence_over(mine: f64, other: f64) -> f64 {
    if mine <= 0.0 {
        0.0
    } else if other <= 0.0 {
        MAX_RATIO
    } else {
        (mine / other).min(MAX_RATIO)
    }
}

/// Fills in `features`' building-independent measures for the chosen pose of `src` (B) onto `dst`
/// (A): `chosen`, its local fit's counts (both ways, before the polish, as the candidates'); `rivals`,
/// the counts of the search's candidates distinct from it; `symmetry`, the chosen pose's and the best
/// alternative pose's consistent evidence where the alternative-pose test measured them.
pub(in crate::merge) fn fill(
    features: &mut Features,
    src: &Prepared,
    dst: &Prepared,
    chosen: &LocalCounts,
    rivals: impl IntoIterator<Item = LocalCounts>,
    symmetry: Option<(f64, f64)>,
) {
    let best_rival = rivals
        .into_iter()
        .map(|c| c.consistent())
        .fold(f64::NEG_INFINITY, f64::max);
    let mut ratio = evidence_over(chosen.consistent(), best_rival);
    if let Some((mine, other)) = symmetry {
        ratio = ratio.min(evidence_over(mine, other));
    }
    features.evidence_ratio = ratio;
    features.support_share = if chosen.known > 0.0 {
        (chosen.agree / chosen.known).min(1.0)
    } else {
        0.0
    };
    (features.noise_a, features.noise_b) = (clutter_share(dst), clutter_share(src));
    let measured = chosen.measured.max(1.0);
    features.noise = chosen.noise / measured;
    features.excess_conflict = (chosen.deep - chosen.deep_noise) / measured;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::states::{FREE, OCCUPIED, UNKNOWN};
    use crate::map::{MapImage, OccupancyMap};
    use crate::measure::synthetic::{synthetic_pair, SyntheticSpec};
    use crate::merge::pair::align::{align, MergeOptions};
    use crate::merge::pair::local::local_both_counts;
    use crate::merge::pair::prepare::{CLUTTER_PX, FLAG_NOISE};
    use crate::merge::transform::Rigid;

    /// The synthetic office with furniture and an unexplored corner.
    fn cluttered_office(w: u32, h: u32, seed: u64) -> MapImage {
        crate::map::synthetic::cluttered_office(w, h, seed).unwrap()
    }

    /// Whether the prepared map marks its pixel (x, y) (the map's own pixels) as clutter.
    fn clutter_at(p: &Prepared, x: usize, y: usize) -> bool {
        let (cx, cy) = (x - p.off.0 as usize, y - p.off.1 as usize);
        p.flags_fine.flags[cy * p.w + cx] & FLAG_NOISE != 0
    }

    #[test]
    fn clutter_is_the_small_occupied_components_and_its_share_of_the_walls_is_the_noise() {
        // A walled 80 x 80 room with one speckle pixel, a box under the clutter side and a long
        // free-standing wall over it.
        let n = 100u32;
        let mut px = vec![UNKNOWN; (n * n) as usize];
        for y in 10..90 {
            for x in 10..90 {
                let wall = x == 10 || y == 10 || x == 89 || y == 89;
                px[(y * n + x) as usize] = if wall { OCCUPIED } else { FREE };
            }
        }
        px[(30 * n + 30) as usize] = OCCUPIED;
        let side = CLUTTER_PX as u32 - 4;
        for y in 50..50 + side {
            for x in 30..30 + side {
                px[(y * n + x) as usize] = OCCUPIED;
            }
        }
        for x in 40..80 {
            px[(30 * n + x) as usize] = OCCUPIED;
        }
        // Two bars, one at the clutter side and one a pixel longer.
        let long = CLUTTER_PX as u32;
        for x in 60..60 + long {
            px[(70 * n + x) as usize] = OCCUPIED;
            px[(80 * n + x - 1) as usize] = OCCUPIED;
        }
        px[(80 * n + 59 + long) as usize] = OCCUPIED;
        let map = OccupancyMap::from_image(MapImage::new(n, n, px).unwrap());
        let p = Prepared::new(&map);
        assert!(clutter_at(&p, 30, 30), "speckle");
        assert!(
            clutter_at(&p, 30, 50) && clutter_at(&p, 31, 51),
            "a small box"
        );
        assert!(!clutter_at(&p, 60, 30), "a long wall");
        assert!(!clutter_at(&p, 10, 50), "the room's wall");
        assert!(clutter_at(&p, 60, 70), "a bar of the clutter side");
        assert!(!clutter_at(&p, 60, 80), "a bar a pixel longer");
        // Its walls: the room's inner ring (316), the speckle (1), the box's ring, the wall's 40
        // pixels and the bars'; the clutter is the speckle, the box and the shorter bar.
        let ring = 4 * (side - 1) as usize;
        let bars = (2 * long + 1) as usize;
        let clutter = 1 + ring + long as usize;
        let want = clutter as f64 / (316 + 1 + ring + 40 + bars) as f64;
        assert!(
            (clutter_share(&p) - want).abs() < 1e-9,
            "{} {want}",
            clutter_share(&p)
        );
    }

    #[test]
    fn a_map_on_itself_agrees_everywhere_and_a_shift_of_it_contradicts() {
        let p = Prepared::new(&OccupancyMap::from_image(cluttered_office(300, 240, 3)));
        let (_, c) = local_both_counts(&p, &p, &Rigid::IDENTITY);
        assert!(c.measured > 1000.0);
        assert_eq!((c.agree, c.deep, c.deep_noise), (c.measured, 0.0, 0.0));
        // Every sampled wall pixel lands on the map's own known area.
        let step = p.walls.len().div_ceil(8000).max(1);
        assert_eq!(c.known, (2 * p.walls.len().div_ceil(step)) as f64);
        assert!(c.measured <= c.known);
        // A shift by more than the local fit's 6 px puts walls in the rooms.
        let shifted = Rigid {
            tx: 19.0,
            ty: 11.0,
            ..Rigid::IDENTITY
        };
        let (_, s) = local_both_counts(&p, &p, &shifted);
        assert!(s.deep > 0.0 && s.consistent() < c.consistent());
        assert!(evidence_over(c.consistent(), s.consistent()) > 1.0);
    }

    #[test]
    fn evidence_ratios_are_capped_and_zero_without_evidence() {
        assert_eq!(evidence_over(100.0, 50.0), 2.0);
        assert_eq!(evidence_over(100.0, 0.0), MAX_RATIO);
        assert_eq!(evidence_over(100.0, -5.0), MAX_RATIO);
        assert_eq!(evidence_over(1000.0, 1.0), MAX_RATIO);
        assert_eq!(evidence_over(0.0, 10.0), 0.0);
        assert_eq!(evidence_over(-3.0, 10.0), 0.0);
    }

    /// A cut office's right pose stands well above its alternatives, with most of what the overlap
    /// could show agreeing; speckle in both parts lands on the other's free space, raising the
    /// residual conflict, and is excused as the maps' own noise: the excess stays where it was.
    #[test]
    fn speckle_raises_the_conflict_but_not_the_excess_over_the_maps_noise() {
        let source = OccupancyMap::from_image(cluttered_office(400, 300, 7));
        let run = |noise: f64| {
            let spec = SyntheticSpec {
                overlap: 0.5,
                noise,
            };
            let pair = synthetic_pair(&source, &spec, 1).unwrap();
            let al = align(&pair.a, &pair.b, &MergeOptions::default()).unwrap();
            let (rot, rms) = pair.errors(&al.transform);
            assert!(rot < 1.0 && rms < 3.0, "noise {noise}: {}", al.explain());
            al.features
        };
        let (clean, speckled) = (run(0.0), run(0.01));
        for f in [&clean, &speckled] {
            // (The office repeats itself: a shift by a room keeps much of the evidence.)
            assert!(f.evidence_ratio > 1.2, "{f:?}");
            assert!(f.support_share > 0.6, "{f:?}");
            assert!(f.excess_conflict <= 0.02, "{f:?}");
        }
        // The office's furniture boxes under the clutter side are its noise already; speckle adds.
        assert!(
            speckled.noise_a > clean.noise_a + 0.05 && speckled.noise_b > clean.noise_b + 0.05,
            "{speckled:?} {clean:?}"
        );
        assert!(speckled.noise > clean.noise, "{speckled:?}");
        assert!(
            speckled.residual > speckled.excess_conflict + 0.01,
            "{speckled:?}"
        );
    }

    #[test]
    fn records_written_before_the_measures_still_read() {
        let mut old = serde_json::to_value(Features::default()).unwrap();
        for k in [
            "evidence_ratio",
            "support_share",
            "noise_a",
            "noise_b",
            "noise",
            "excess_conflict",
        ] {
            old.as_object_mut().unwrap().remove(k).unwrap();
        }
        let f: Features = serde_json::from_value(old).unwrap();
        assert_eq!(f, Features::default());
    }
}
