//! The map's dominant wall direction, modulo 90 degrees: the angle at which the wall boundary pixels
//! line up best along rows and columns (a projection profile, as document-deskewing does).
//!
//! The boundary pixels are the occupied pixels with a free 4-neighbour; for each candidate angle they
//! are projected on both axes of the turned frame and binned, and the angle whose histograms have the
//! largest sum of squared counts wins (straight walls pile their pixels into a few bins). Host code,
//! shared by every backend, so the angle is the same whatever runs the kernels.

use rayon::prelude::*;

use crate::backend::fast::bitplanes::{plane_row, words, ValueSet};
use crate::map::states::{CellState, ClassTable};
use crate::map::MapImage;
use crate::support::error::Result;

/// Boundary pixels used at most: beyond this, a deterministic subset whose choice does not depend on the
/// map's orientation (whole orbits of the map's quarter turns and mirrors are kept or dropped).
pub const MAX_POINTS: usize = 16384;

/// Fraction bits of the fixed-point cosine and sine of the projections.
const TRIG_BITS: u32 = 20;

/// The dominant wall direction in degrees, in [-45, 45): the angle to turn the map by so that its walls
/// run along rows and columns. 0 when the map has no wall boundary.
///
/// Exactly equivariant: a map turned by a quarter turn gets the same angle, a mirrored map the opposite
/// one (every step is integer arithmetic on coordinates about the map's centre, the bins are symmetric
/// about it, and ties are broken symmetrically), so the robust detector samples a turned map on the
/// turned grid.
pub fn dominant_angle(image: &MapImage, classes: &ClassTable) -> f64 {
    let centre = (i64::from(image.width()) - 1, i64::from(image.height()) - 1);
    dominant_angle_about(image, classes, centre)
}

/// [`dominant_angle`] with the bins and the subset laid out about `anchor2` (map pixels, in half pixels)
/// instead of the map's centre: about a point fixed in the world, a crop of the map or the map grown at
/// its edges bins its walls' pixels as the map does, and its angle changes only by the walls it gains or
/// loses.
pub fn dominant_angle_about(image: &MapImage, classes: &ClassTable, anchor2: (i64, i64)) -> f64 {
    let mut rows = ImageRows(image);
    match dominant_angle_of(&mut rows, classes, anchor2) {
        Ok(a) => a,
        Err(_) => unreachable!("a map in memory reads without error"),
    }
}

/// [`dominant_angle_about`] of a map read row by row, twice (once to count its wall boundary, once to take
/// the subset): the same angle, in memory bounded by [`MAX_POINTS`] whatever the map's size.
pub fn dominant_angle_of(
    rows: &mut dyn RowReader,
    classes: &ClassTable,
    anchor2: (i64, i64),
) -> Result<f64> {
    let points = boundary_points(rows, classes, anchor2)?;
    Ok(angle_of_points(&points))
}

/// A map's rows, read top to bottom in passes.
pub trait RowReader {
    /// Width in pixels.
    fn width(&self) -> usize;
    /// Height in pixels.
    fn height(&self) -> usize;
    /// Row `y`: in one pass, rows 0, 1, 2, ... in turn.
    fn row(&mut self, y: usize) -> Result<&[u8]>;
    /// Back to row 0 for another pass.
    fn rewind(&mut self) -> Result<()>;
}

/// The rows of a map in memory.
pub struct ImageRows<'a>(pub &'a MapImage);

impl RowReader for ImageRows<'_> {
    fn width(&self) -> usize {
        self.0.width() as usize
    }
    fn height(&self) -> usize {
        self.0.height() as usize
    }
    fn row(&mut self, y: usize) -> Result<&[u8]> {
        let w = self.width();
        Ok(&self.0.pixels()[y * w..(y + 1) * w])
    }
    fn rewind(&mut self) -> Result<()> {
        Ok(())
    }
}

/// The angle of the wall boundary `points` (half pixels about the anchor).
fn angle_of_points(points: &[(i32, i32)]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    // Angles in tenths of a degree. 1-degree steps with 2-pixel bins find the basin; 0.1-degree steps
    // with 1-pixel bins refine it. Every angle on every core; the scores come back in angle order.
    let coarse: Vec<(i32, u128)> = (-45..45)
        .into_par_iter()
        .map_init(Vec::new, |hist, d| {
            (d * 10, profile(points, d * 10, 2, hist))
        })
        .collect();
    let coarse = best(&coarse).0;
    let fine: Vec<(i32, u128)> = (-10..=10)
        .into_par_iter()
        .map_init(Vec::new, |hist, k| {
            (coarse + k, profile(points, coarse + k, 1, hist))
        })
        .collect();
    // A wall of n pixels scores the same over about 1/n radians: take the middle of the plateau of
    // near-best angles around the best one, not its first angle.
    let b = fine.iter().position(|f| *f == best(&fine)).unwrap_or(0);
    let near = |i: usize| fine[i].1 * 1000 >= fine[b].1 * 999;
    let (mut lo, mut hi) = (b, b);
    while lo > 0 && near(lo - 1) {
        lo -= 1;
    }
    while hi + 1 < fine.len() && near(hi + 1) {
        hi += 1;
    }
    // Half-tenths, exact in f64; back into [-45, 45).
    let fine = f64::from(fine[lo].0 + fine[hi].0) / 20.0;
    (fine + 45.0).rem_euclid(90.0) - 45.0
}

/// The best-scoring angle; ties go to the smaller angle's magnitude, then the positive one (a mirror
/// symmetric map has equal scores at +a and -a, and no choice can follow both).
fn best(scores: &[(i32, u128)]) -> (i32, u128) {
    let key = |&(a, s): &(i32, u128)| {
        (
            s,
            std::cmp::Reverse(a.rem_euclid(900).min(900 - a.rem_euclid(900))),
            a > 0,
        )
    };
    scores.iter().copied().max_by_key(key).unwrap_or((0, 0))
}

/// Sum of squared bin counts of the points projected on both axes of the frame turned by `tenths` of a
/// degree. Points are in half pixels about the anchor; the bins are `bin` pixels wide and centred on
/// multiples of it, a point exactly on a boundary going to the bin nearer the anchor, so the histogram of a
/// map turned or mirrored about it is this one turned or mirrored, in exact integers.
fn profile(points: &[(i32, i32)], tenths: i32, bin: i64, hist: &mut Vec<u32>) -> u128 {
    let t = (f64::from(tenths) / 10.0).to_radians();
    let one = f64::from(1u32 << TRIG_BITS);
    let (c, s) = (
        (t.cos() * one).round() as i64,
        (t.sin() * one).round() as i64,
    );
    let width = (bin * 2) << TRIG_BITS;
    // The bin of a projection: the nearest multiple of the width, ties towards zero.
    let index = |v: i64| v.signum() * ((v.abs() + width / 2 - 1) / width);
    let mut total = 0u128;
    for axis in 0..2 {
        let proj = |&(x, y): &(i32, i32)| {
            let (x, y) = (i64::from(x), i64::from(y));
            if axis == 0 {
                x * c + y * s
            } else {
                -x * s + y * c
            }
        };
        // The bins the points reach (the anchor may lie far off the map: only these are counted).
        let (lo, hi) = points.iter().fold((i64::MAX, i64::MIN), |(lo, hi), p| {
            let i = index(proj(p));
            (lo.min(i), hi.max(i))
        });
        hist.clear();
        hist.resize((hi - lo + 1) as usize, 0);
        for pt in points {
            hist[(index(proj(pt)) - lo) as usize] += 1;
        }
        total += hist
            .iter()
            .map(|&n| u128::from(n) * u128::from(n))
            .sum::<u128>();
    }
    total
}

/// The occupied pixels with a free 4-neighbour, in half pixels about `anchor2` (half pixels; at most
/// [`crate::map::grid::MAX_ANCHOR`] pixels from the map's pixel (0, 0)); at most about [`MAX_POINTS`] of them.
fn boundary_points(
    rows: &mut dyn RowReader,
    classes: &ClassTable,
    anchor2: (i64, i64),
) -> Result<Vec<(i32, i32)>> {
    let mut count = 0usize;
    visit_boundary(rows, classes, &mut |_, _| count += 1)?;
    let stride = count.div_ceil(MAX_POINTS).max(1) as u64;
    let mut points = Vec::with_capacity(count.min(2 * MAX_POINTS));
    let (cx, cy) = anchor2;
    rows.rewind()?;
    visit_boundary(rows, classes, &mut |x, y| {
        let (px, py) = (2 * x as i64 - cx, 2 * y as i64 - cy);
        // The same hash for every point of an orbit of the quarter turns and mirrors about the anchor.
        let (a, b) = (px.unsigned_abs(), py.unsigned_abs());
        let key = (a.max(b) << 32 | a.min(b)).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32;
        if stride == 1 || key % stride == 0 {
            points.push((px as i32, py as i32));
        }
    })?;
    Ok(points)
}

/// Calls `f(x, y)` for every occupied pixel with a free 4-neighbour, row by row, reading each row once.
fn visit_boundary(
    rows: &mut dyn RowReader,
    classes: &ClassTable,
    f: &mut dyn FnMut(usize, usize),
) -> Result<()> {
    let (w, h) = (rows.width(), rows.height());
    if w == 0 || h == 0 {
        return Ok(());
    }
    let occ = ValueSet::of(classes, &[CellState::Occupied]);
    let free = ValueSet::of(classes, &[CellState::Free]);
    let n = words(w);
    // Occupied of rows y and y + 1; free of rows y - 1, y, y + 1.
    let (mut o, mut o_next) = (vec![0u64; n], vec![0u64; n]);
    let mut fr = vec![vec![0u64; n]; 3];
    let first = rows.row(0)?;
    plane_row(&occ, first, &mut o_next);
    plane_row(&free, first, &mut fr[2]);
    for y in 0..h {
        std::mem::swap(&mut o, &mut o_next);
        fr.rotate_left(1);
        if y + 1 < h {
            let r = rows.row(y + 1)?;
            plane_row(&occ, r, &mut o_next);
            plane_row(&free, r, &mut fr[2]);
        } else {
            fr[2].fill(0);
        }
        let (up, mid, down) = (&fr[0], &fr[1], &fr[2]);
        for k in 0..n {
            let left = (mid[k] << 1) | if k > 0 { mid[k - 1] >> 63 } else { 0 };
            let right = (mid[k] >> 1) | if k + 1 < n { mid[k + 1] << 63 } else { 0 };
            let mut b = o[k] & (up[k] | down[k] | left | right);
            while b != 0 {
                let j = b.trailing_zeros() as usize;
                b &= b - 1;
                f(k * 64 + j, y);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A room of `side` pixels turned by `degrees`: its walls' direction is what the estimate finds.
    fn turned_room(degrees: f64) -> MapImage {
        let n = 240u32;
        let (s, c) = degrees.to_radians().sin_cos();
        let mut px = vec![205u8; (n * n) as usize];
        for y in 0..n {
            for x in 0..n {
                let (dx, dy) = (f64::from(x) - 120.0, f64::from(y) - 120.0);
                let (u, v) = (dx * c + dy * s, -dx * s + dy * c);
                let m = u.abs().max(v.abs());
                px[(y * n + x) as usize] = if m < 70.0 {
                    254
                } else if m < 74.0 {
                    0
                } else {
                    205
                };
            }
        }
        MapImage::new(n, n, px).unwrap()
    }

    #[test]
    fn the_angle_of_a_turned_room_is_found_modulo_90_degrees() {
        for deg in [0.0, 7.0, -20.0, 33.3, 80.0] {
            let got = dominant_angle(&turned_room(deg), &ClassTable::default());
            let want = (deg + 45.0f64).rem_euclid(90.0) - 45.0;
            assert!((got - want).abs() <= 0.3, "{deg}: got {got}");
        }
        let blank = MapImage::filled(50, 40, 254).unwrap();
        assert_eq!(dominant_angle(&blank, &ClassTable::default()), 0.0);
    }

    #[test]
    fn about_an_anchor_far_off_the_map_the_angle_is_found_too() {
        // The histograms span the points, not the anchor's distance (a million pixels here).
        let far = 2 * i64::from(crate::map::grid::MAX_ANCHOR);
        for anchor2 in [(far, -far), (-far, 3), (479, 479)] {
            let got = dominant_angle_about(&turned_room(-20.0), &ClassTable::default(), anchor2);
            assert!((got + 20.0).abs() <= 0.3, "{anchor2:?}: got {got}");
        }
    }
}
