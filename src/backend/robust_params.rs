//! The robust detector's options and working memory, kept with the backend interface: the options every
//! backend is given ([`crate::backend::DetectOptions`]) and the memory each one budgets must not depend on
//! the detector ([`crate::robust`]) that sits a layer above the backends.

use crate::cpu::coarsen::MAX_SCALE;
use crate::error::{Error, Result};

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
}

impl Default for RobustParams {
    /// The defaults the measurements in docs/detectors.md use: scales 2 to 10, 4-pixel suppression, convex corners on.
    fn default() -> Self {
        RobustParams {
            min_scale: 2,
            max_scale: 10,
            nms_radius: 4,
            min_strength: 8,
            convex: true,
            angle: None,
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
        Ok((self.min_scale..=self.max_scale).collect())
    }
}

/// Bytes the robust detector holds beyond the map: the coarse maps (under half a byte a grid sample for
/// scales from 2) and the grid's planes on the fast path (a quarter), for a grid of up to
/// [`grid_samples`] samples.
pub fn robust_working_bytes(width: u32, height: u32) -> u64 {
    grid_samples(width, height)
}

/// An upper bound of a rotated grid's samples over any angle: a `w` x `h` map turned by t needs
/// `(w |cos t| + h |sin t|) (w |sin t| + h |cos t|) = w h + (w^2 + h^2) |cos t sin t|` samples, most at 45
/// degrees, `(w + h)^2 / 2`; plus the margins.
pub fn grid_samples(width: u32, height: u32) -> u64 {
    let side = (u64::from(width) + u64::from(height)) * 7072 / 10000 + 8;
    side * side
}
