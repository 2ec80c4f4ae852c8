//! A PNG of the map with each keypoint marked in colour, for a person to look at.

use std::path::Path;

use image::{Rgb, RgbImage};

use crate::backend::Keypoint;
use crate::map::stream::Rows;
use crate::map::MapImage;
use crate::support::error::Result;

/// Marker colour of each rule: 4 orange, 5 red, 6 blue; the baselines' keypoints (rule 0) magenta.
pub fn rule_colour(rule: u8) -> Rgb<u8> {
    match rule {
        4 => Rgb([255, 140, 0]),
        5 => Rgb([230, 0, 0]),
        6 => Rgb([0, 90, 255]),
        _ => Rgb([200, 0, 200]),
    }
}

/// Longest side of an overlay of a large map; larger maps are shrunk to it, so that an overlay of a huge
/// map stays a viewable PNG of bounded memory.
pub const MAX_OVERLAY_SIDE: u32 = 8192;

/// The integer zoom used for a map: small maps are enlarged so a marker is visible, large ones are not.
pub fn overlay_scale(width: u32, height: u32) -> u32 {
    (1200 / width.max(height)).clamp(1, 8)
}

/// The integer shrink factor for maps over [`MAX_OVERLAY_SIDE`] (1 otherwise).
pub fn overlay_shrink(width: u32, height: u32) -> u32 {
    width.max(height).div_ceil(MAX_OVERLAY_SIDE)
}

/// Draws the map (grey levels as they are) enlarged by [`overlay_scale`] (or, for maps over
/// [`MAX_OVERLAY_SIDE`], shrunk by [`overlay_shrink`], each output pixel the darkest of its block so walls
/// stay visible), each keypoint's cell filled with its rule's colour and circled so that it stands out at
/// any zoom.
pub fn render_overlay(map: &MapImage, keypoints: &[Keypoint]) -> RgbImage {
    let s = overlay_scale(map.width(), map.height());
    let d = overlay_shrink(map.width(), map.height());
    render_overlay_at(map, keypoints, s, d)
}

/// [`render_overlay`] with an explicit zoom `s` (>= 1) or shrink `d` (>= 1).
pub fn render_overlay_at(map: &MapImage, keypoints: &[Keypoint], s: u32, d: u32) -> RgbImage {
    let mut canvas = OverlayCanvas::with_shrink(map.width(), map.height(), d);
    canvas.add_rows(Rows::of(map), (0, map.height() as usize));
    canvas.render_at(keypoints, s)
}

/// The map as an overlay draws it, filled row by row as a streamed detection reads them: each pixel the
/// darkest of its block of `d` x `d` map pixels ([`overlay_shrink`]), so a huge map's overlay needs only
/// its own small picture in memory.
#[derive(Clone)]
pub struct OverlayCanvas {
    width: u32,
    height: u32,
    d: u32,
    grey: Vec<u8>,
    /// Keypoints to mark, by canvas cell (row, column) and rule: at most a few per cell, however many
    /// keypoints a huge map has.
    marks: std::collections::BTreeSet<(u32, u32, u8)>,
}

impl OverlayCanvas {
    /// A canvas for a `width` x `height` map, shrunk by [`overlay_shrink`].
    pub fn new(width: u32, height: u32) -> Self {
        Self::with_shrink(width, height, overlay_shrink(width, height))
    }

    /// A canvas for a `width` x `height` map, shrunk by `d` (>= 1).
    pub fn with_shrink(width: u32, height: u32, d: u32) -> Self {
        let d = d.max(1);
        let n = width.div_ceil(d) as usize * height.div_ceil(d) as usize;
        OverlayCanvas {
            width,
            height,
            d,
            grey: vec![u8::MAX; n],
            marks: Default::default(),
        }
    }

    /// Draws map rows `core` (held in `rows`).
    pub fn add_rows(&mut self, rows: Rows, core: (usize, usize)) {
        let d = self.d as usize;
        let cw = self.width.div_ceil(self.d) as usize;
        for y in core.0..core.1 {
            let out = &mut self.grey[(y / d) * cw..(y / d + 1) * cw];
            if d == 1 {
                for (o, &v) in out.iter_mut().zip(rows.row(y)) {
                    *o = (*o).min(v);
                }
            } else {
                for (o, block) in out.iter_mut().zip(rows.row(y).chunks(d)) {
                    *o = block.iter().fold(*o, |m, &v| m.min(v));
                }
            }
        }
    }

    /// Marks keypoints (their canvas cells and rules).
    pub fn mark(&mut self, keypoints: &[Keypoint]) {
        let d = self.d;
        self.marks
            .extend(keypoints.iter().map(|k| (k.y / d, k.x / d, k.rule)));
    }

    /// The overlay at the zoom [`render_overlay`] uses, with the marks and `keypoints`.
    pub fn render(&mut self, keypoints: &[Keypoint]) -> RgbImage {
        self.render_at(keypoints, overlay_scale(self.width, self.height))
    }

    /// The picture enlarged by `s` (>= 1), each marked cell (and each of `keypoints`) filled with its rule's
    /// colour and circled so that it stands out at any zoom.
    pub fn render_at(&mut self, keypoints: &[Keypoint], s: u32) -> RgbImage {
        self.render_scaled(keypoints, f64::from(s.max(1)))
    }

    /// The picture enlarged to fit `max_w` x `max_h` (by a zoom that need not be an integer; cells stay
    /// crisp squares of nearest-neighbour pixels), as [`OverlayCanvas::render_at`] marks it. A canvas
    /// larger than the box is drawn at zoom 1: shrink it with [`OverlayCanvas::with_shrink`] first
    /// ([`fit_shrink`]).
    pub fn render_fit(&mut self, keypoints: &[Keypoint], max_w: u32, max_h: u32) -> RgbImage {
        let (cw, ch) = (self.width.div_ceil(self.d), self.height.div_ceil(self.d));
        let f = fit_zoom(cw, ch, max_w, max_h);
        self.render_scaled(keypoints, f)
    }

    /// The picture enlarged by `f` (>= 1, any real zoom) to round(cells x `f`) pixels a side: output pixel
    /// (x, y) shows cell (x * cells / pixels, y * ...), in integers, so every cell, the last included, gets
    /// its pixels; marks as [`OverlayCanvas::render_at`] draws them, filling exactly their cell's pixels,
    /// the ring's radius growing with the zoom up to 18 pixels.
    fn render_scaled(&mut self, keypoints: &[Keypoint], f: f64) -> RgbImage {
        self.mark(keypoints);
        let (f, d) = (f.max(1.0), self.d);
        let (cw, ch) = (self.width.div_ceil(d), self.height.div_ceil(d));
        let (w, h) = (scaled(cw, f), scaled(ch, f));
        // Pixel p of `out` shows cell p * n / out; cell c starts at pixel ceil(c * out / n).
        let cell = |p: u32, n: u32, out: u32| (u64::from(p) * u64::from(n) / u64::from(out)) as u32;
        let start = |c: u32, n: u32, out: u32| {
            (u64::from(c) * u64::from(out))
                .div_ceil(u64::from(n))
                .min(u64::from(out)) as u32
        };
        let xs: Vec<u32> = (0..w).map(|x| cell(x, cw, w)).collect();
        let mut img = RgbImage::new(w, h);
        for y in 0..h {
            let row = &self.grey[(cell(y, ch, h) * cw) as usize..][..cw as usize];
            for (x, &cx) in xs.iter().enumerate() {
                let v = row[cx as usize];
                img.put_pixel(x as u32, y, Rgb([v, v, v]));
            }
        }
        let radius = ((2.0 * f + 2.0).round() as i64).min(18);
        for &(ky, kx, rule) in &self.marks {
            if kx >= cw || ky >= ch {
                continue;
            }
            let colour = rule_colour(rule);
            for y in start(ky, ch, h)..start(ky + 1, ch, h) {
                for x in start(kx, cw, w)..start(kx + 1, cw, w) {
                    img.put_pixel(x, y, colour);
                }
            }
            // Centre of the enlarged cell, in doubled coordinates so that even zooms stay symmetric.
            let cx2 = (f64::from(2 * kx + 1) * f64::from(w) / f64::from(cw)).round() as i64;
            let cy2 = (f64::from(2 * ky + 1) * f64::from(h) / f64::from(ch)).round() as i64;
            ring(&mut img, cx2, cy2, radius, colour);
        }
        img
    }

    /// Writes the overlay as a PNG, atomically ([`crate::support::files::write_atomic`]).
    pub fn write(&mut self, path: &Path, keypoints: &[Keypoint]) -> Result<()> {
        crate::support::files::write_png(path, &self.render(keypoints))
    }
}

/// Pixels of `n` cells at zoom `f` (at least one a cell; none for no cells).
fn scaled(n: u32, f: f64) -> u32 {
    ((f64::from(n) * f).round() as u32).max(n.min(1))
}

/// The largest zoom (>= 1) at which `w` x `h` fits `max_w` x `max_h`.
pub fn fit_zoom(w: u32, h: u32, max_w: u32, max_h: u32) -> f64 {
    let f = (f64::from(max_w) / f64::from(w.max(1))).min(f64::from(max_h) / f64::from(h.max(1)));
    // A hair under, so that rounding never makes the picture a pixel larger than the box.
    (f * (1.0 - 1e-12)).max(1.0)
}

/// The integer shrink that brings `w` x `h` within `max_w` x `max_h` (1 when it fits).
pub fn fit_shrink(w: u32, h: u32, max_w: u32, max_h: u32) -> u32 {
    w.div_ceil(max_w.max(1))
        .max(h.div_ceil(max_h.max(1)))
        .max(1)
}

/// [`render_overlay`] filling `max_w` x `max_h`: shrunk by [`fit_shrink`] (darkest of each block) when
/// larger, then enlarged by [`fit_zoom`], any real factor, nearest neighbour.
pub fn render_overlay_fit(
    map: &MapImage,
    keypoints: &[Keypoint],
    max_w: u32,
    max_h: u32,
) -> RgbImage {
    let d = fit_shrink(map.width(), map.height(), max_w, max_h);
    let mut canvas = OverlayCanvas::with_shrink(map.width(), map.height(), d);
    canvas.add_rows(Rows::of(map), (0, map.height() as usize));
    canvas.render_fit(keypoints, max_w, max_h)
}

/// A one-pixel-wide circle of `radius` around the doubled-coordinate centre (cx2 / 2, cy2 / 2).
pub fn ring(img: &mut RgbImage, cx2: i64, cy2: i64, radius: i64, colour: Rgb<u8>) {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let (r_in, r_out) = (2 * radius - 1, 2 * radius + 1);
    let x0 = (cx2 / 2 - radius - 1).max(0);
    let y0 = (cy2 / 2 - radius - 1).max(0);
    for y in y0..(cy2 / 2 + radius + 2).min(h) {
        for x in x0..(cx2 / 2 + radius + 2).min(w) {
            let (dx, dy) = (2 * x + 1 - cx2, 2 * y + 1 - cy2);
            let d2 = dx * dx + dy * dy;
            if d2 >= r_in * r_in && d2 <= r_out * r_out {
                img.put_pixel(x as u32, y as u32, colour);
            }
        }
    }
}

/// Bytes [`render_overlay`] and its PNG encoding allocate for a `width` x `height` map (the RGB picture,
/// and at most as much again for the compressed stream the encoder keeps, and the grey canvas), for
/// memory budgets.
pub fn overlay_bytes(width: u32, height: u32) -> u64 {
    let (s, d) = (
        u64::from(overlay_scale(width, height)),
        u64::from(overlay_shrink(width, height)),
    );
    let side = |n: u32| u64::from(n).div_ceil(d) * s;
    7 * side(width) * side(height)
}

/// Renders and writes the overlay as a PNG, atomically ([`crate::support::files::write_atomic`]).
pub fn write_overlay(path: &Path, map: &MapImage, keypoints: &[Keypoint]) -> Result<()> {
    crate::support::files::write_png(path, &render_overlay(map, keypoints))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A map of `w` x `h` free pixels with a wall on its last row and last column.
    fn walled(w: u32, h: u32) -> MapImage {
        let mut m = MapImage::filled(w, h, 254).unwrap();
        let px = m.pixels_mut();
        for x in 0..w as usize {
            px[(h as usize - 1) * w as usize + x] = 0;
        }
        for y in 0..h as usize {
            px[y * w as usize + w as usize - 1] = 0;
        }
        m
    }

    #[test]
    fn a_fitted_overlay_fills_its_box_and_keeps_the_last_row_and_column() {
        // 533x200 into 300x300: shrunk by 2 to 267x100 cells, enlarged by 300/267 (not an integer). Where
        // pixels are taken as floor(x / zoom), rows 198-199 of the map never reach the picture.
        for (w, h, bw, bh) in [(533, 200, 300, 300), (100, 37, 560, 400), (7, 5, 300, 300)] {
            let pic = render_overlay_fit(&walled(w, h), &[], bw, bh);
            let (pw, ph) = pic.dimensions();
            assert!(pw <= bw && ph <= bh, "{w}x{h}: {pw}x{ph} over {bw}x{bh}");
            assert!(
                pw >= bw - 1 || ph >= bh - 1,
                "{w}x{h}: {pw}x{ph} does not fill {bw}x{bh}"
            );
            assert!(
                (0..pw).all(|x| pic.get_pixel(x, ph - 1).0 == [0, 0, 0]),
                "{w}x{h}: last row"
            );
            assert!(
                (0..ph).all(|y| pic.get_pixel(pw - 1, y).0 == [0, 0, 0]),
                "{w}x{h}: last column"
            );
        }
    }

    #[test]
    fn a_mark_fills_exactly_its_cells_pixels_at_any_zoom() {
        let map = MapImage::filled(10, 4, 254).unwrap();
        let k = Keypoint {
            rule: 5,
            ..Keypoint::scored(1, 2, 0)
        };
        let mut canvas = OverlayCanvas::with_shrink(10, 4, 1);
        canvas.add_rows(Rows::of(&map), (0, 4));
        // Zoom 2.5: cell column 1 is pixels 3..5 (x * 10 / 25 == 1), cell row 2 is pixels 5..8
        // (y * 4 / 10 == 2).
        let pic = canvas.clone().render_fit(&[k], 25, 100);
        assert_eq!(pic.dimensions(), (25, 10));
        let red = rule_colour(5);
        for y in 4..9 {
            for x in 2..6 {
                let inside = (3..5).contains(&x) && (5..8).contains(&y);
                // The ring (radius 7) lies well outside the cell's block and the pixels around it.
                assert_eq!(*pic.get_pixel(x, y) == red, inside, "({x}, {y})");
            }
        }
        // At whole zooms the picture is what render_at draws.
        let whole = canvas.clone().render_fit(&[k], 30, 12);
        assert_eq!(whole, canvas.render_at(&[k], 3));
    }
}
