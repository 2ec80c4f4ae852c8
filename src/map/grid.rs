//! The rotated sampling grid of the robust detector ([`crate::detect::robust`]): the map resampled, by nearest
//! neighbour, on a grid turned to the map's dominant wall direction, so that walls run along rows and
//! columns.
//!
//! Every backend samples through the same integer arithmetic, so the CPU and the GPU agree bit for bit:
//! cosine and sine are fixed-point integers with [`FRAC_BITS`] fraction bits, and sample (p, q) reads map
//! pixel `((ox + p cos - q sin + h) >> F, (oy + p sin + q cos + h) >> F)` with `h = 2^(F-1)` (rounding
//! to the nearest pixel centre; a sample exactly half-way between two pixels reads the one nearer the
//! grid's anchor, so that a turned or mirrored map is sampled as the turned or mirrored grid). Every
//! intermediate fits an `i32` (WGSL has no 64-bit integers by default) for maps up to [`MAX_SIDE`] pixels
//! a side.
//!
//! The grid is anchored at a point of the map, its centre by default, so a quarter turn or a mirror of the
//! map turns or mirrors its samples exactly (the sample lattice maps onto itself); at angle 0 it is
//! anchored on the pixel centre at or before the anchor instead, so that every sample is a pixel and none
//! is a tie. Anchored at a point fixed in the world (the map frame's origin), the samples of a crop of the
//! map, or of the map grown by more rows and columns, are those of the map where both see it.

use crate::map::states::{CellState, ClassTable};
use crate::map::MapImage;
use crate::support::error::{Error, Result};

/// Fraction bits of the fixed-point cosine and sine: angles are resolved to about 0.06 degrees, and the
/// sample positions stay exact integers in `i32` up to [`MAX_SIDE`].
pub const FRAC_BITS: u32 = 10;

/// Largest map width or height the rotated grid handles: `ox + p cos - q sin` stays below 2^31.
pub const MAX_SIDE: u32 = 1 << 18;

/// Farthest the grid's anchor may lie from the map's pixel (0, 0), pixels along each axis: its fixed-point
/// coordinates stay in an `i32`.
pub const MAX_ANCHOR: u32 = 1 << 20;

const ONE: i32 = 1 << FRAC_BITS;
const HALF: i32 = 1 << (FRAC_BITS - 1);

/// The integer nearest `v`; exactly half-way, the one nearer `centre` (rounding half away from zero
/// or always up would not follow a mirror of the map about its centre).
fn round_towards(v: f64, centre: f64) -> f64 {
    let k = v.round();
    if (v - v.trunc()).abs() == 0.5 && (v > centre) == (k > v) {
        k - (k - v).signum()
    } else {
        k
    }
}

/// The pixel nearest fixed-point coordinate `v`; exactly half-way, the one nearer `centre` (the same
/// in a turned or mirrored map, unlike always rounding up).
#[inline(always)]
pub fn nearest(v: i32, centre: i32) -> i32 {
    let up = (v + HALF) >> FRAC_BITS;
    up - i32::from(v & (ONE - 1) == HALF && v > centre)
}

/// A grid of samples turned by an angle against the map, covering the whole map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RotatedGrid {
    /// cos(angle) in fixed point ([`FRAC_BITS`]).
    pub cos: i32,
    /// sin(angle) in fixed point.
    pub sin: i32,
    /// Map x of sample (0, 0), fixed point.
    pub ox: i32,
    /// Map y of sample (0, 0), fixed point.
    pub oy: i32,
    /// Map x of the anchor (the map's centre by default), fixed point: ties round towards it.
    pub cx: i32,
    /// Map y of the anchor, fixed point.
    pub cy: i32,
    /// The anchor in the grid's frame, in half samples: a position half-way between two samples is
    /// rounded towards it ([`RotatedGrid::round_sample`]), so a turned map rounds as the turned grid.
    pub centre2: (i64, i64),
    /// The anchor in the whole map's pixels, in half pixels (pixel centres at even values): ties between
    /// keypoints go to the one nearer it.
    pub anchor2: (i64, i64),
    /// Samples per grid row.
    pub width: u32,
    /// Grid rows.
    pub height: u32,
    /// Width of the sampled map (for a [`RotatedGrid::window`], of its crop).
    pub map_width: u32,
    /// Height of the sampled map.
    pub map_height: u32,
    /// The whole map's pixel that the sampled map's pixel (0, 0) is: (0, 0) but for a window's crop.
    pub crop_origin: (u32, u32),
    /// The whole map's size: [`RotatedGrid::round_pixel`] clamps to it.
    pub full_size: (u32, u32),
}

impl RotatedGrid {
    /// The grid turned by `degrees` (a positive angle turns clockwise on screen, since y points down),
    /// anchored at the centre of a `map_width` x `map_height` map, covering it with a margin of two samples.
    pub fn new(map_width: u32, map_height: u32, degrees: f64) -> Result<Self> {
        Self::anchored(
            map_width,
            map_height,
            degrees,
            (i64::from(map_width) - 1, i64::from(map_height) - 1),
        )
    }

    /// [`RotatedGrid::new`] anchored at `anchor2` (map pixels, in half pixels: pixel centres at even
    /// values) instead of the map's centre, at most [`MAX_ANCHOR`] pixels from the map's pixel (0, 0).
    pub fn anchored(
        map_width: u32,
        map_height: u32,
        degrees: f64,
        anchor2: (i64, i64),
    ) -> Result<Self> {
        let far = 2 * i64::from(MAX_ANCHOR);
        if anchor2.0.abs() > far || anchor2.1.abs() > far {
            return Err(Error::invalid(format!(
                "the grid's anchor ({}, {}) is more than {MAX_ANCHOR} pixels from the map",
                anchor2.0 as f64 / 2.0,
                anchor2.1 as f64 / 2.0
            )));
        }
        if map_width > MAX_SIDE || map_height > MAX_SIDE {
            return Err(Error::invalid(format!(
                "the robust detector handles maps up to {MAX_SIDE} pixels a side; this one is \
                 {map_width} x {map_height}"
            )));
        }
        if !degrees.is_finite() {
            return Err(Error::Internal(format!(
                "grid angle {degrees} is not finite"
            )));
        }
        let t = degrees.to_radians();
        let cos = (t.cos() * f64::from(ONE)).round() as i32;
        let sin = (t.sin() * f64::from(ONE)).round() as i32;
        let (c, s) = (
            f64::from(cos) / f64::from(ONE),
            f64::from(sin) / f64::from(ONE),
        );
        let det = c * c + s * s;
        let (xc, yc) = (anchor2.0 as f64 / 2.0, anchor2.1 as f64 / 2.0);
        // The map's corners in the grid's frame (the inverse of [[c, -s], [s, c]]), about the anchor.
        // The map alone, not the anchor, which may lie far off it.
        let (mut pmin, mut pmax) = (f64::INFINITY, f64::NEG_INFINITY);
        let (mut qmin, mut qmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for (x, y) in [
            (-0.5, -0.5),
            (f64::from(map_width) - 0.5, -0.5),
            (-0.5, f64::from(map_height) - 0.5),
            (f64::from(map_width) - 0.5, f64::from(map_height) - 0.5),
        ] {
            let (dx, dy) = (x - xc, y - yc);
            let p = (c * dx + s * dy) / det;
            let q = (-s * dx + c * dy) / det;
            pmin = pmin.min(p);
            pmax = pmax.max(p);
            qmin = qmin.min(q);
            qmax = qmax.max(q);
        }
        let (p0, q0) = (pmin.floor() as i64 - 2, qmin.floor() as i64 - 2);
        let width = (pmax.ceil() as i64 + 2 - p0 + 1) as u32;
        let height = (qmax.ceil() as i64 + 2 - q0 + 1) as u32;
        // The anchor in fixed point is exact: a whole number of half pixels.
        let xcf = anchor2.0 << (FRAC_BITS - 1);
        let ycf = anchor2.1 << (FRAC_BITS - 1);
        // At angle 0 the lattice sits on pixel centres (half a pixel off an even side's centre), so no
        // sample is a tie; at any other angle it is anchored at the anchor itself, which a quarter turn
        // or a mirror about it maps onto itself.
        let (ax, ay) = if sin == 0 && cos == ONE {
            (xcf & !i64::from(ONE - 1), ycf & !i64::from(ONE - 1))
        } else {
            (xcf, ycf)
        };
        let ox = ax + p0 * i64::from(cos) - q0 * i64::from(sin);
        let oy = ay + p0 * i64::from(sin) + q0 * i64::from(cos);
        let fixed =
            |v: i64| i32::try_from(v).map_err(|_| Error::Internal("grid origin overflows".into()));
        // The anchor is sample (-p0, -q0), or half a sample further where the lattice sits off it.
        let off = |c: i64, a: i64| i64::from(c != a);
        let centre2 = (-2 * p0 + off(xcf, ax), -2 * q0 + off(ycf, ay));
        Ok(RotatedGrid {
            cos,
            sin,
            ox: fixed(ox)?,
            oy: fixed(oy)?,
            cx: fixed(xcf)?,
            cy: fixed(ycf)?,
            centre2,
            anchor2,
            width,
            height,
            map_width,
            map_height,
            crop_origin: (0, 0),
            full_size: (map_width, map_height),
        })
    }

    /// The samples `offset.0..offset.0 + width`, `offset.1..offset.1 + height` of this grid as a grid of
    /// their own, reading the crop of the map whose top-left pixel is `crop.0`, `crop.1` and whose size is
    /// `crop.2` x `crop.3`. Its samples are this grid's, bit for bit (the fixed-point origin moves by whole
    /// samples and whole pixels; ties still round towards the anchor), wherever the crop holds
    /// the pixels they read; [`RotatedGrid::round_pixel`] still gives the whole map's pixels. The robust
    /// detector works on a map of any size in such windows ([`crate::detect::robust::tiles`]).
    pub fn window(
        &self,
        offset: (i32, i32),
        width: u32,
        height: u32,
        crop: (u32, u32, u32, u32),
    ) -> Self {
        let (p0, q0) = offset;
        let (x0, y0) = (
            (i64::from(crop.0) + i64::from(self.crop_origin.0)) << FRAC_BITS,
            (i64::from(crop.1) + i64::from(self.crop_origin.1)) << FRAC_BITS,
        );
        let (cos, sin) = (i64::from(self.cos), i64::from(self.sin));
        let (p, q) = (i64::from(p0), i64::from(q0));
        // Relative to the whole map's pixel (0, 0) first: `self` may itself be a window.
        let base_x = i64::from(self.ox) + (i64::from(self.crop_origin.0) << FRAC_BITS);
        let base_y = i64::from(self.oy) + (i64::from(self.crop_origin.1) << FRAC_BITS);
        let cx = i64::from(self.cx) + (i64::from(self.crop_origin.0) << FRAC_BITS);
        let cy = i64::from(self.cy) + (i64::from(self.crop_origin.1) << FRAC_BITS);
        RotatedGrid {
            ox: (base_x + p * cos - q * sin - x0) as i32,
            oy: (base_y + p * sin + q * cos - y0) as i32,
            cx: (cx - x0) as i32,
            cy: (cy - y0) as i32,
            centre2: (self.centre2.0 - 2 * p, self.centre2.1 - 2 * q),
            width,
            height,
            map_width: crop.2,
            map_height: crop.3,
            crop_origin: (crop.0 + self.crop_origin.0, crop.1 + self.crop_origin.1),
            full_size: self.full_size,
            ..*self
        }
    }

    /// The sample nearest grid position `(p, q)`; exactly half-way, the one nearer the anchor.
    pub fn round_sample(&self, (p, q): (f64, f64)) -> (i32, i32) {
        let c = |c2: i64| c2 as f64 / 2.0;
        (
            round_towards(p, c(self.centre2.0)) as i32,
            round_towards(q, c(self.centre2.1)) as i32,
        )
    }

    /// The sample nearest the middle of the box of `scale` samples starting at `p` (its middle sample
    /// when `scale` is odd; of the two, the one nearer the anchor when even), one axis: `x`
    /// chooses the axis (0 for p, 1 for q).
    pub fn box_middle(&self, p: i32, scale: u32, axis: usize) -> i32 {
        let twice = 2 * i64::from(p) + i64::from(scale) - 1;
        let c2 = if axis == 0 {
            self.centre2.0
        } else {
            self.centre2.1
        };
        let half = if twice % 2 == 0 {
            twice / 2
        } else if twice > c2 {
            (twice - 1) / 2
        } else {
            (twice + 1) / 2
        };
        half as i32
    }

    /// The whole map's pixel nearest position `(x, y)` of the sampled map ([`RotatedGrid::to_map`]),
    /// clamped to the whole map; exactly half-way, the one nearer the anchor.
    pub fn round_pixel(&self, (x, y): (f64, f64)) -> (u32, u32) {
        let one = f64::from(ONE);
        let r = |v: f64, c: i32, o: u32, n: u32| {
            let k = round_towards(v, f64::from(c) / one) + f64::from(o);
            k.clamp(0.0, f64::from(n.max(1) - 1)) as u32
        };
        (
            r(x, self.cx, self.crop_origin.0, self.full_size.0),
            r(y, self.cy, self.crop_origin.1, self.full_size.1),
        )
    }

    /// The anchor in the whole map's pixels (pixel centres at integers).
    pub fn anchor(&self) -> (f64, f64) {
        (self.anchor2.0 as f64 / 2.0, self.anchor2.1 as f64 / 2.0)
    }

    /// The grid's angle in degrees, as quantised.
    pub fn degrees(&self) -> f64 {
        f64::from(self.sin).atan2(f64::from(self.cos)).to_degrees()
    }

    /// Whether the grid is the map itself shifted (angle 0): sample (p, q) reads pixel (p + dx, q + dy).
    pub fn is_axis_aligned(&self) -> bool {
        self.sin == 0 && self.cos == ONE
    }

    /// The map pixel sample (p, q) reads, possibly outside the map.
    #[inline(always)]
    pub fn source(&self, p: i32, q: i32) -> (i32, i32) {
        let x = self.ox.wrapping_add(p.wrapping_mul(self.cos)) - q.wrapping_mul(self.sin);
        let y = self.oy.wrapping_add(p.wrapping_mul(self.sin)) + q.wrapping_mul(self.cos);
        (nearest(x, self.cx), nearest(y, self.cy))
    }

    /// The row-major index of the map pixel sample (p, q) reads, or `None` outside the map.
    #[inline(always)]
    pub fn source_index(&self, p: i32, q: i32) -> Option<usize> {
        let (x, y) = self.source(p, q);
        (x >= 0 && y >= 0 && (x as u32) < self.map_width && (y as u32) < self.map_height)
            .then(|| y as usize * self.map_width as usize + x as usize)
    }

    /// A point of the grid's frame (samples, fractional) in map pixel coordinates.
    pub fn to_map(&self, p: f64, q: f64) -> (f64, f64) {
        let one = f64::from(ONE);
        let (c, s) = (f64::from(self.cos) / one, f64::from(self.sin) / one);
        (
            f64::from(self.ox) / one + p * c - q * s,
            f64::from(self.oy) / one + p * s + q * c,
        )
    }

    /// Cells of the coarse grid of `scale` x `scale` samples: (columns, rows).
    pub fn coarse_size(&self, scale: u32) -> (u32, u32) {
        (self.width.div_ceil(scale), self.height.div_ceil(scale))
    }

    /// The map rows that samples of rows `q0..q1` and columns `p0..p1` read, clamped to the map:
    /// `None` when none of them falls on a map row. The source y is monotonic in p and in q, so the
    /// extremes are at the rectangle's corners.
    pub fn source_rows(&self, p0: i32, p1: i32, q0: i32, q1: i32) -> Option<(u32, u32)> {
        self.source_range(p0, p1, q0, q1, |x, y| (y, x), self.map_height)
    }

    /// The map columns samples of rows `q0..q1`, columns `p0..p1` read, clamped (see
    /// [`RotatedGrid::source_rows`]).
    pub fn source_cols(&self, p0: i32, p1: i32, q0: i32, q1: i32) -> Option<(u32, u32)> {
        self.source_range(p0, p1, q0, q1, |x, y| (x, y), self.map_width)
    }

    fn source_range(
        &self,
        p0: i32,
        p1: i32,
        q0: i32,
        q1: i32,
        pick: impl Fn(i32, i32) -> (i32, i32),
        limit: u32,
    ) -> Option<(u32, u32)> {
        if p0 >= p1 || q0 >= q1 {
            return None;
        }
        let (mut lo, mut hi) = (i32::MAX, i32::MIN);
        for (p, q) in [(p0, q0), (p1 - 1, q0), (p0, q1 - 1), (p1 - 1, q1 - 1)] {
            let (x, y) = self.source(p, q);
            let v = pick(x, y).0;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        let lo = lo.max(0);
        let hi = hi.min(limit as i32 - 1);
        (lo <= hi).then(|| (lo as u32, hi as u32 + 1))
    }
}

/// The state of sample (p, q) of `grid` over `image`: the nearest map pixel's, unknown outside the map.
#[inline]
pub fn sample(
    image: &MapImage,
    classes: &ClassTable,
    grid: &RotatedGrid,
    p: i32,
    q: i32,
) -> CellState {
    match grid.source_index(p, q) {
        Some(i) => classes.state(image.pixels()[i]),
        None => CellState::Unknown,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_covers_every_map_pixel_and_zero_degrees_is_a_shift() {
        for deg in [0.0, 3.7, -12.0, 30.0, 44.9, -45.0] {
            let g = RotatedGrid::new(37, 23, deg).unwrap();
            let mut seen = vec![false; 37 * 23];
            for q in 0..g.height as i32 {
                for p in 0..g.width as i32 {
                    if let Some(i) = g.source_index(p, q) {
                        seen[i] = true;
                    }
                }
            }
            // Nearest-neighbour sampling at an angle skips some pixels (86% are read at 30 degrees);
            // without the margins, whole edges would be missed.
            let read = seen.iter().filter(|&&s| s).count();
            assert!(
                read * 5 >= seen.len() * 4,
                "{deg}: {read} of {}",
                seen.len()
            );
        }
        let g = RotatedGrid::new(10, 6, 0.0).unwrap();
        assert!(g.is_axis_aligned());
        let (dx, dy) = g.source(0, 0);
        for (p, q) in [(3, 4), (7, 1)] {
            assert_eq!(g.source(p, q), (p + dx, q + dy));
        }
    }

    /// A window of the grid reads, through its crop, the pixels the whole grid reads, ties included, and
    /// names the whole map's pixels.
    #[test]
    fn a_window_samples_and_rounds_as_the_whole_grid() {
        for (w, h, deg) in [
            (37, 23, 0.0),
            (64, 50, 45.0),
            (501, 300, -17.3),
            (40, 41, 90.0),
        ] {
            let g = RotatedGrid::new(w, h, deg).unwrap();
            let (p0, q0) = (5, 3);
            let crop = (2, 1, w - 4, h - 3);
            let win = g.window((p0, q0), g.width - 7, g.height - 4, crop);
            for q in q0..g.height as i32 {
                for p in p0..g.width as i32 {
                    let (x, y) = g.source(p, q);
                    let (cx, cy) = win.source(p - p0, q - q0);
                    assert_eq!((cx + crop.0 as i32, cy + crop.1 as i32), (x, y));
                    for (dp, dq) in [(0.0, 0.0), (0.5, 0.0), (0.25, 0.5), (-0.5, -0.5)] {
                        let (fp, fq) = (f64::from(p) + dp, f64::from(q) + dq);
                        let whole = g.round_pixel(g.to_map(fp, fq));
                        let part =
                            win.round_pixel(win.to_map(fp - f64::from(p0), fq - f64::from(q0)));
                        assert_eq!(part, whole, "{w}x{h} at {deg}: ({fp}, {fq})");
                    }
                }
            }
        }
    }

    /// Anchored at a point fixed to the map's pixels, a crop's grid (the anchor moved with the crop)
    /// reads the pixels the map's grid reads, sample for sample up to a whole shift; and the grid covers
    /// the map alone, wherever the anchor lies.
    #[test]
    fn an_anchored_grid_samples_a_crop_as_the_whole_map() {
        for (deg, anchor2) in [
            (0.0, (-41, 77)),
            (-17.3, (9, 1000)),
            (33.0, (-2_000_001, 5)),
        ] {
            let (w, h) = (301, 200);
            let g = RotatedGrid::anchored(w, h, deg, anchor2).unwrap();
            let c = RotatedGrid::new(w, h, deg).unwrap();
            assert!(g.width.abs_diff(c.width) <= 2 && g.height.abs_diff(c.height) <= 2);
            let (dx, dy) = (37, 11);
            let crop = RotatedGrid::anchored(
                w - dx,
                h - dy,
                deg,
                (anchor2.0 - 2 * i64::from(dx), anchor2.1 - 2 * i64::from(dy)),
            )
            .unwrap();
            // The anchor is sample `centre2 / 2` of both: the crop's sample (p, q) is the map's
            // (p + sp, q + sq).
            let (sp, sq) = (
                (g.centre2.0 - crop.centre2.0) / 2,
                (g.centre2.1 - crop.centre2.1) / 2,
            );
            assert_eq!(g.centre2.0 - crop.centre2.0, 2 * sp);
            let mut compared = 0;
            for q in 0..crop.height as i32 {
                for p in 0..crop.width as i32 {
                    if let Some(i) = crop.source_index(p, q) {
                        let (x, y) = (i as u32 % (w - dx), i as u32 / (w - dx));
                        let whole = g.source(p + sp as i32, q + sq as i32);
                        assert_eq!(whole, (x as i32 + dx as i32, y as i32 + dy as i32), "{deg}");
                        compared += 1;
                    }
                }
            }
            assert!(compared > 40_000, "{compared}");
        }
        assert!(RotatedGrid::anchored(9, 9, 0.0, (1 << 22, 0)).is_err());
    }

    #[test]
    fn to_map_inverts_source_at_sample_centres_and_ranges_bound_the_samples() {
        let g = RotatedGrid::new(500, 300, 17.0).unwrap();
        for (p, q) in [(0, 0), (100, 50), (g.width as i32 - 1, g.height as i32 - 1)] {
            let (x, y) = g.to_map(f64::from(p), f64::from(q));
            assert_eq!((x.round() as i32, y.round() as i32), g.source(p, q));
        }
        let (r0, r1) = g.source_rows(10, 200, 40, 90).unwrap();
        let (c0, c1) = g.source_cols(10, 200, 40, 90).unwrap();
        for q in 40..90 {
            for p in 10..200 {
                let (x, y) = g.source(p, q);
                if (0..500).contains(&x) && (0..300).contains(&y) {
                    assert!((r0 as i32..r1 as i32).contains(&y));
                    assert!((c0 as i32..c1 as i32).contains(&x));
                }
            }
        }
        assert!(RotatedGrid::new(MAX_SIDE + 1, 4, 0.0).is_err());
    }
}
