//! The robust detector's options and working memory, kept with the backend interface: the options every
//! backend is given ([`crate::backend::DetectOptions`]) and the memory each one budgets must not depend on
//! the detector ([`crate::detect::robust`]) that sits a layer above the backends.

use crate::backend::reference::coarsen::{CellRule, MAX_SCALE};
#[cfg(doc)]
use crate::map::grid::RotatedGrid;
use crate::map::grid::MAX_ANCHOR;
use crate::map::GeoRef;
use crate::support::error::{Error, Result};

/// Options of the robust detector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobustParams {
    /// Smallest coarse scale, map pixels a cell side.
    pub min_scale: u32,
    /// Largest coarse scale.
    pub max_scale: u32,
    /// Keypoints closer than this (pixels) to a stronger one are dropped.
    pub nms_radius: u32,
    /// Corners whose shorter wall is shorter than this many pixels are dropped (0 keeps corners without
    /// two perpendicular walls).
    pub min_strength: u32,
    /// Look for convex corners too (occupied cells with the free and occupied roles swapped).
    pub convex: bool,
    /// The grid angle in degrees; `None` estimates the map's dominant wall direction.
    pub angle: Option<f64>,
    /// The point the turned grid, its lattice of scored boxes and its ties are anchored at.
    pub anchor: Anchor,
    /// The shares of occupied and free samples that make a coarse cell occupied or free.
    pub cells: CellRule,
    /// Unknown samples a wall's cross-section bridges between occupied ones when a corner is placed on
    /// the walls' centre lines (a wall seen from both sides: two lines of occupied pixels with unknown
    /// ones between them).
    pub wall_gap: u32,
}

/// Where the robust detector's turned grid is anchored: the point that its samples, its lattice of scored
/// boxes and its ties (half-way positions, equal strengths) are laid out from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Anchor {
    /// The origin of the map's world frame (a yaml's or an occupancy grid's `origin` gives it) where the
    /// map has one, else its centre. The frame stays where it is when a map is cropped or grows at its
    /// edges, as a SLAM map does, so the keypoints there stay those of the map wherever both see a
    /// corner's walls (for the same grid angle).
    World,
    /// The map's centre: the keypoints of the map turned by quarter turns or mirrored are exactly the
    /// map's, turned or mirrored.
    Centre,
    /// A point in map pixels (pixel centres at integers; rounded to the nearest half pixel), at most
    /// [`MAX_ANCHOR`] pixels from the map's pixel (0, 0) along each axis.
    Point(f64, f64),
}

/// The most unknown samples [`RobustParams::wall_gap`] may bridge.
pub const MAX_WALL_GAP: u32 = 64;

impl Default for RobustParams {
    /// The defaults the measurements in docs/detectors.md use: scales 2, 3, 4, 6, 8 and 12
    /// ([`scale_ladder`]), walls of 12 px or more,
    /// 4-pixel suppression, convex corners on. The shortest wall and the largest scale were fitted
    /// leave-one-building-out on the annotated maps, together with repeatability under rotation on other
    /// maps (`scripts/figures.py robust-lobo`): every fold chose these.
    fn default() -> Self {
        RobustParams {
            min_scale: 2,
            max_scale: 12,
            nms_radius: 4,
            min_strength: 12,
            convex: true,
            angle: None,
            anchor: Anchor::World,
            cells: CellRule::default(),
            wall_gap: 8,
        }
    }
}

impl RobustParams {
    /// The scales in use, after checking the options.
    pub fn scales(&self) -> Result<Vec<u32>> {
        if self.min_scale < 1 || self.max_scale > MAX_SCALE || self.min_scale > self.max_scale {
            return Err(Error::invalid(format!(
                "robust detector scales must satisfy 1 <= min <= max <= {MAX_SCALE}, got {}..{}",
                self.min_scale, self.max_scale
            )));
        }
        if let Some(a) = self.angle {
            if !a.is_finite() {
                return Err(Error::invalid(format!("grid angle {a} is not finite")));
            }
        }
        if self.nms_radius > 1024 {
            return Err(Error::invalid(format!(
                "suppression radius {} is too large (at most 1024 pixels)",
                self.nms_radius
            )));
        }
        if let Anchor::Point(x, y) = self.anchor {
            if !within_reach(x, y) {
                return Err(Error::invalid(format!(
                    "grid anchor ({x}, {y}) is not a point within {MAX_ANCHOR} pixels of the map"
                )));
            }
        }
        self.cells.check()?;
        if self.wall_gap > MAX_WALL_GAP {
            return Err(Error::invalid(format!(
                "wall gap {} is too large (at most {MAX_WALL_GAP} samples)",
                self.wall_gap
            )));
        }
        Ok(scale_ladder(self.min_scale, self.max_scale))
    }

    /// The grid's anchor for a `width` x `height` map, in half pixels ([`RotatedGrid::anchored`]), of
    /// options [`RobustParams::scales`] accepted: the map's centre unless [`RobustParams::anchor`] is a
    /// point ([`Anchor::World`] resolves to a point where the map's frame is known,
    /// [`RobustParams::in_frame`]).
    pub fn anchor2(&self, width: u32, height: u32) -> (i64, i64) {
        match self.anchor {
            Anchor::Point(x, y) => ((2.0 * x).round() as i64, (2.0 * y).round() as i64),
            Anchor::World | Anchor::Centre => (i64::from(width) - 1, i64::from(height) - 1),
        }
    }

    /// These options for a map `height` pixels high that lies in the world at `frame` (`None` where the
    /// map has no frame): [`Anchor::World`] becomes the frame's origin, in pixels, or the map's centre
    /// where there is no frame or its origin lies more than [`MAX_ANCHOR`] pixels away.
    pub fn in_frame(&self, frame: Option<&GeoRef>, height: u32) -> RobustParams {
        let origin = frame.map(|g| g.world_to_point((0.0, 0.0), height));
        let anchor = match (self.anchor, origin) {
            (Anchor::World, Some((x, y))) if within_reach(x, y) => Anchor::Point(x, y),
            (Anchor::World, _) => Anchor::Centre,
            (a, _) => a,
        };
        RobustParams { anchor, ..*self }
    }
}

/// Whether `(x, y)` (map pixels) is a point the grid can be anchored at: finite, and at most
/// [`MAX_ANCHOR`] pixels from the map's pixel (0, 0) along each axis.
fn within_reach(x: f64, y: f64) -> bool {
    let far = f64::from(MAX_ANCHOR);
    x.is_finite() && y.is_finite() && x.abs() <= far && y.abs() <= far
}

impl Anchor {
    /// The anchor a name gives: `world`, `centre` (or `center`); `None` for any other text.
    pub fn named(name: &str) -> Option<Anchor> {
        match name {
            "world" => Some(Anchor::World),
            "centre" | "center" => Some(Anchor::Centre),
            _ => None,
        }
    }
}

/// The scales from `min` to `max`: both ends, and between them the ladder of powers of two and one and a
/// half times them (2, 3, 4, 6, 8, 12). Neighbouring scales are 1.33-1.5 times apart, as scale-space
/// detectors sample scale: a corner fires over a range of scales and is placed the same way whichever
/// finds it, so every integer scale adds time, not corners (measured on the shared maps: the same
/// recall and rotation repeatability as 2, 3, ..., 12 at 55-60% of the time and 70% of the memory).
pub fn scale_ladder(min: u32, max: u32) -> Vec<u32> {
    let rung = |s: u32| s.is_power_of_two() || (s.is_multiple_of(3) && (s / 3).is_power_of_two());
    (min..=max)
        .filter(|&s| s == min || s == max || rung(s))
        .collect()
}

/// Bytes the robust detector holds beyond the map with `params`: a coarse map of every phase per scale
/// (about a byte a grid sample each), the fast path's two summed-area tables (two bytes a sample), its
/// planes, and the rules' hits (about a byte a sample), for a grid of up to [`grid_samples`] samples
/// padded by the largest scale.
pub fn robust_working_bytes(width: u32, height: u32, params: &RobustParams) -> u64 {
    let pad = 3 * u64::from(params.max_scale.min(MAX_SCALE)) + 2;
    let side = |n: u32| u64::from(n) + pad;
    let samples = grid_samples(width, height) + (side(width) + side(height)) * pad * 2;
    let scales = scale_ladder(params.min_scale, params.max_scale.min(MAX_SCALE)).len() as u64;
    samples.saturating_mul(scales + 4)
}

/// An upper bound of a rotated grid's samples over any angle: a `w` x `h` map turned by t needs
/// `(w |cos t| + h |sin t|) (w |sin t| + h |cos t|) = w h + (w^2 + h^2) |cos t sin t|` samples, most at 45
/// degrees, `(w + h)^2 / 2`; plus the margins.
pub fn grid_samples(width: u32, height: u32) -> u64 {
    let side = (u64::from(width) + u64::from(height)) * 7072 / 10000 + 8;
    side * side
}

#[cfg(test)]
mod tests {
    use super::scale_ladder;

    #[test]
    fn the_ladder_keeps_both_ends_and_the_rungs_between() {
        assert_eq!(scale_ladder(2, 12), [2, 3, 4, 6, 8, 12]);
        assert_eq!(scale_ladder(1, 15), [1, 2, 3, 4, 6, 8, 12, 15]);
        assert_eq!(scale_ladder(5, 7), [5, 6, 7]);
        assert_eq!(scale_ladder(9, 11), [9, 11]);
        assert_eq!(scale_ladder(7, 7), [7]);
        assert!(scale_ladder(5, 4).is_empty());
    }
}
