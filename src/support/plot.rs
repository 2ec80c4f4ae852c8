//! Small raster drawing for the pictures the tool writes: a 5x7 bitmap font and line plots.
//!
//! Hand-rolled to keep the dependency list short: the pictures need only labels and a few lines.

use image::{Rgb, RgbImage};

/// 5x7 glyphs, one string of 7 rows of 5 pixels each ('#' set).
#[rustfmt::skip]
const GLYPHS: &[(char, [&str; 7])] = &[
    ('A', [" ### ", "#   #", "#   #", "#####", "#   #", "#   #", "#   #"]),
    ('B', ["#### ", "#   #", "#   #", "#### ", "#   #", "#   #", "#### "]),
    ('C', [" ### ", "#   #", "#    ", "#    ", "#    ", "#   #", " ### "]),
    ('D', ["#### ", "#   #", "#   #", "#   #", "#   #", "#   #", "#### "]),
    ('E', ["#####", "#    ", "#    ", "#### ", "#    ", "#    ", "#####"]),
    ('F', ["#####", "#    ", "#    ", "#### ", "#    ", "#    ", "#    "]),
    ('G', [" ### ", "#   #", "#    ", "# ###", "#   #", "#   #", " ####"]),
    ('H', ["#   #", "#   #", "#   #", "#####", "#   #", "#   #", "#   #"]),
    ('I', [" ### ", "  #  ", "  #  ", "  #  ", "  #  ", "  #  ", " ### "]),
    ('J', ["  ###", "   # ", "   # ", "   # ", "   # ", "#  # ", " ##  "]),
    ('K', ["#   #", "#  # ", "# #  ", "##   ", "# #  ", "#  # ", "#   #"]),
    ('L', ["#    ", "#    ", "#    ", "#    ", "#    ", "#    ", "#####"]),
    ('M', ["#   #", "## ##", "# # #", "# # #", "#   #", "#   #", "#   #"]),
    ('N', ["#   #", "##  #", "# # #", "#  ##", "#   #", "#   #", "#   #"]),
    ('O', [" ### ", "#   #", "#   #", "#   #", "#   #", "#   #", " ### "]),
    ('P', ["#### ", "#   #", "#   #", "#### ", "#    ", "#    ", "#    "]),
    ('Q', [" ### ", "#   #", "#   #", "#   #", "# # #", "#  # ", " ## #"]),
    ('R', ["#### ", "#   #", "#   #", "#### ", "# #  ", "#  # ", "#   #"]),
    ('S', [" ####", "#    ", "#    ", " ### ", "    #", "    #", "#### "]),
    ('T', ["#####", "  #  ", "  #  ", "  #  ", "  #  ", "  #  ", "  #  "]),
    ('U', ["#   #", "#   #", "#   #", "#   #", "#   #", "#   #", " ### "]),
    ('V', ["#   #", "#   #", "#   #", "#   #", "#   #", " # # ", "  #  "]),
    ('W', ["#   #", "#   #", "#   #", "# # #", "# # #", "## ##", "#   #"]),
    ('X', ["#   #", "#   #", " # # ", "  #  ", " # # ", "#   #", "#   #"]),
    ('Y', ["#   #", "#   #", " # # ", "  #  ", "  #  ", "  #  ", "  #  "]),
    ('Z', ["#####", "    #", "   # ", "  #  ", " #   ", "#    ", "#####"]),
    ('0', [" ### ", "#   #", "#  ##", "# # #", "##  #", "#   #", " ### "]),
    ('1', ["  #  ", " ##  ", "  #  ", "  #  ", "  #  ", "  #  ", " ### "]),
    ('2', [" ### ", "#   #", "    #", "   # ", "  #  ", " #   ", "#####"]),
    ('3', ["#####", "   # ", "  #  ", "   # ", "    #", "#   #", " ### "]),
    ('4', ["   # ", "  ## ", " # # ", "#  # ", "#####", "   # ", "   # "]),
    ('5', ["#####", "#    ", "#### ", "    #", "    #", "#   #", " ### "]),
    ('6', ["  ## ", " #   ", "#    ", "#### ", "#   #", "#   #", " ### "]),
    ('7', ["#####", "    #", "   # ", "  #  ", " #   ", " #   ", " #   "]),
    ('8', [" ### ", "#   #", "#   #", " ### ", "#   #", "#   #", " ### "]),
    ('9', [" ### ", "#   #", "#   #", " ####", "    #", "   # ", " ##  "]),
    ('-', ["     ", "     ", "     ", "#####", "     ", "     ", "     "]),
    ('.', ["     ", "     ", "     ", "     ", "     ", " ##  ", " ##  "]),
    (',', ["     ", "     ", "     ", "     ", " ##  ", "  #  ", " #   "]),
    (':', ["     ", " ##  ", " ##  ", "     ", " ##  ", " ##  ", "     "]),
    ('%', ["##   ", "##  #", "   # ", "  #  ", " #   ", "#  ##", "   ##"]),
    ('(', ["   # ", "  #  ", " #   ", " #   ", " #   ", "  #  ", "   # "]),
    (')', [" #   ", "  #  ", "   # ", "   # ", "   # ", "  #  ", " #   "]),
    ('/', ["     ", "    #", "   # ", "  #  ", " #   ", "#    ", "     "]),
    ('_', ["     ", "     ", "     ", "     ", "     ", "     ", "#####"]),
    (' ', ["     "; 7]),
];

/// What an unknown character draws: a box.
const BOX: [&str; 7] = [
    "#####", "#   #", "#   #", "#   #", "#   #", "#   #", "#####",
];

/// The glyph of `c` (letters in either case).
fn glyph(c: char) -> [&'static str; 7] {
    let c = c.to_ascii_uppercase();
    GLYPHS
        .iter()
        .find(|(g, _)| *g == c)
        .map_or(BOX, |(_, rows)| *rows)
}

/// Width in pixels of `text` drawn at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    text.chars().count() as u32 * 6 * scale
}

/// Draws `text` with its top-left corner at (x, y), each font pixel `scale` x `scale`; clipped at the edges.
pub fn draw_text(img: &mut RgbImage, x: i64, y: i64, text: &str, scale: u32, colour: Rgb<u8>) {
    let s = i64::from(scale);
    for (i, c) in text.chars().enumerate() {
        for (row, bits) in glyph(c).iter().enumerate() {
            for (col, b) in bits.bytes().enumerate() {
                if b == b'#' {
                    let px = x + (i as i64 * 6 + col as i64) * s;
                    let py = y + row as i64 * s;
                    fill(img, px, py, s, s, colour);
                }
            }
        }
    }
}

/// Fills a rectangle, clipped at the image's edges.
pub fn fill(img: &mut RgbImage, x: i64, y: i64, w: i64, h: i64, colour: Rgb<u8>) {
    let (iw, ih) = (i64::from(img.width()), i64::from(img.height()));
    for yy in y.max(0)..(y + h).min(ih) {
        for xx in x.max(0)..(x + w).min(iw) {
            img.put_pixel(xx as u32, yy as u32, colour);
        }
    }
}

/// A line `thickness` pixels wide from (x0, y0) to (x1, y1).
pub fn line(
    img: &mut RgbImage,
    (x0, y0): (f64, f64),
    (x1, y1): (f64, f64),
    thickness: i64,
    colour: Rgb<u8>,
) {
    let steps = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as i64).max(1);
    for i in 0..=steps {
        let t = i as f64 / steps as f64;
        let (x, y) = (x0 + (x1 - x0) * t, y0 + (y1 - y0) * t);
        fill(
            img,
            x.round() as i64 - thickness / 2,
            y.round() as i64 - thickness / 2,
            thickness,
            thickness,
            colour,
        );
    }
}

/// Height of one row of a legend, pixels.
pub const LEGEND_ROW: u32 = 22;

/// Width of a legend entry: a 14-pixel swatch, its label at scale 2, a gap.
fn legend_entry_width(label: &str) -> u32 {
    20 + text_width(label, 2) + 18
}

/// Where each entry of a legend goes within `width` pixels: (x, row), entries wrapping to a new row when
/// the next would pass the width.
fn legend_layout<S: AsRef<str>>(width: u32, entries: &[(S, Rgb<u8>)]) -> Vec<(u32, u32)> {
    let (mut row, mut x) = (0, 0);
    let mut at = Vec::with_capacity(entries.len());
    for (label, _) in entries {
        let w = legend_entry_width(label.as_ref());
        if x > 0 && x + w > width {
            (row, x) = (row + 1, 0);
        }
        at.push((x, row));
        x += w;
    }
    at
}

/// Rows a legend of `entries` takes within `width` pixels.
pub fn legend_rows<S: AsRef<str>>(width: u32, entries: &[(S, Rgb<u8>)]) -> u32 {
    legend_layout(width, entries)
        .last()
        .map_or(1, |&(_, row)| row + 1)
}

/// Draws colour swatches with their labels from (x, y), wrapping within `width` pixels, a row
/// [`LEGEND_ROW`] pixels high ([`legend_rows`] rows).
pub fn draw_legend<S: AsRef<str>>(
    img: &mut RgbImage,
    x: i64,
    y: i64,
    width: u32,
    entries: &[(S, Rgb<u8>)],
) {
    for ((label, colour), (cx, row)) in entries.iter().zip(legend_layout(width, entries)) {
        let (lx, ly) = (x + i64::from(cx), y + i64::from(row * LEGEND_ROW));
        fill(img, lx, ly, 14, 14, Rgb([60, 60, 60]));
        fill(img, lx + 1, ly + 1, 12, 12, *colour);
        draw_text(img, lx + 20, ly, label.as_ref(), 2, Rgb([0, 0, 0]));
    }
}

/// `img` with a white band below it holding a legend of `entries` (the picture widened with white to
/// 400 pixels when narrower, so that the legend stays readable): what the `merge --overlay` pictures carry.
pub fn with_legend<S: AsRef<str>>(img: &RgbImage, entries: &[(S, Rgb<u8>)]) -> RgbImage {
    let width = img.width().max(400);
    let band = 10 + legend_rows(width - 20, entries) * LEGEND_ROW;
    let mut out = RgbImage::from_pixel(width, img.height() + band, Rgb([255, 255, 255]));
    image::imageops::overlay(&mut out, img, 0, 0);
    draw_legend(
        &mut out,
        10,
        i64::from(img.height()) + 8,
        width - 20,
        entries,
    );
    out
}

/// The smallest box (x0, y0, x1, y1), ends exclusive, holding every (x, y) of a `w` x `h` raster that
/// `keep` keeps, grown by `margin` within the raster; None when it keeps none.
pub fn bounding_box(
    w: u32,
    h: u32,
    margin: u32,
    keep: impl Fn(u32, u32) -> bool,
) -> Option<(u32, u32, u32, u32)> {
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for y in 0..h {
        for x in 0..w {
            if keep(x, y) {
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
            }
        }
    }
    (x1 > x0).then(|| {
        (
            x0.saturating_sub(margin),
            y0.saturating_sub(margin),
            (x1 + margin).min(w),
            (y1 + margin).min(h),
        )
    })
}

/// The part of `img` that is not `background`, with `margin` pixels around it (all of it when it is all
/// background): what a picture of a map shows once the unknown around it is cut away.
pub fn crop_to_content(img: &RgbImage, background: Rgb<u8>, margin: u32) -> RgbImage {
    let (w, h) = img.dimensions();
    match bounding_box(w, h, margin, |x, y| *img.get_pixel(x, y) != background) {
        Some((x0, y0, x1, y1)) => {
            image::imageops::crop_imm(img, x0, y0, x1 - x0, y1 - y0).to_image()
        }
        None => img.clone(),
    }
}

/// `img` scaled to fit `max_w` x `max_h` (aspect kept) by any real factor: enlarged by nearest neighbour
/// (pixels stay crisp squares), shrunk by keeping the highest-`rank`ed pixel of each block (ties: the
/// first), so thin walls and conflicts survive what plain sampling would drop.
pub fn fit_image(img: &RgbImage, max_w: u32, max_h: u32, rank: impl Fn(Rgb<u8>) -> u8) -> RgbImage {
    let (w, h) = (img.width().max(1), img.height().max(1));
    let f = (f64::from(max_w) / f64::from(w)).min(f64::from(max_h) / f64::from(h));
    let (ow, oh) = (
        ((f64::from(w) * f).round() as u32).clamp(1, max_w.max(1)),
        ((f64::from(h) * f).round() as u32).clamp(1, max_h.max(1)),
    );
    // Output pixel p covers source [start(p), start(p + 1)), at least one pixel.
    let span = |p: u32, out: u32, n: u32| {
        let s = |q: u32| ((u64::from(q) * u64::from(n)) / u64::from(out)) as u32;
        let a = s(p).min(n - 1);
        (a, s(p + 1).clamp(a + 1, n))
    };
    let xs: Vec<(u32, u32)> = (0..ow).map(|x| span(x, ow, w)).collect();
    RgbImage::from_fn(ow, oh, |x, y| {
        let (y0, y1) = span(y, oh, h);
        let (x0, x1) = xs[x as usize];
        let mut best = *img.get_pixel(x0, y0);
        let mut best_rank = rank(best);
        for yy in y0..y1 {
            for xx in x0..x1 {
                let p = *img.get_pixel(xx, yy);
                let r = rank(p);
                if r > best_rank {
                    (best, best_rank) = (p, r);
                }
            }
        }
        best
    })
}

/// One series of a line plot.
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Colour of the line.
    pub colour: Rgb<u8>,
    /// (x, y) points; y in [0, 1].
    pub points: Vec<(f64, f64)>,
}

/// A line plot of series with y in [0, 1] shown as 0-100%, x ticks at the points' x values.
pub fn line_plot(
    title: &str,
    x_label: &str,
    series: &[Series],
    width: u32,
    height: u32,
) -> RgbImage {
    let white = Rgb([255, 255, 255]);
    let black = Rgb([0, 0, 0]);
    let grey = Rgb([215, 215, 215]);
    let mut img = RgbImage::from_pixel(width, height, white);
    let (l, r, t, b) = (
        70.0,
        f64::from(width) - 20.0,
        40.0,
        f64::from(height) - 60.0,
    );
    draw_text(&mut img, 10, 10, title, 2, black);
    let xs: Vec<f64> = {
        let mut v: Vec<f64> = series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0))
            .collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    };
    let (xmin, xmax) = (
        xs.first().copied().unwrap_or(0.0),
        xs.last().copied().unwrap_or(1.0),
    );
    let span = if xmax > xmin { xmax - xmin } else { 1.0 };
    let px = |x: f64| l + (x - xmin) / span * (r - l);
    let py = |y: f64| b - y.clamp(0.0, 1.0) * (b - t);
    for i in 0..=10 {
        let y = py(f64::from(i) / 10.0);
        line(&mut img, (l, y), (r, y), 1, grey);
        if i % 2 == 0 {
            let label = format!("{}%", i * 10);
            draw_text(
                &mut img,
                (l as i64) - 8 - i64::from(text_width(&label, 1)),
                y as i64 - 3,
                &label,
                1,
                black,
            );
        }
    }
    for &x in &xs {
        let label = format!("{x}");
        draw_text(
            &mut img,
            px(x) as i64 - i64::from(text_width(&label, 1)) / 2,
            b as i64 + 8,
            &label,
            1,
            black,
        );
    }
    line(&mut img, (l, t), (l, b), 2, black);
    line(&mut img, (l, b), (r, b), 2, black);
    draw_text(
        &mut img,
        ((l + r) / 2.0) as i64 - i64::from(text_width(x_label, 2)) / 2,
        b as i64 + 26,
        x_label,
        2,
        black,
    );
    for (k, s) in series.iter().enumerate() {
        for w in s.points.windows(2) {
            line(
                &mut img,
                (px(w[0].0), py(w[0].1)),
                (px(w[1].0), py(w[1].1)),
                3,
                s.colour,
            );
        }
        for &(x, y) in &s.points {
            fill(&mut img, px(x) as i64 - 3, py(y) as i64 - 3, 7, 7, s.colour);
        }
        let ly = t as i64 + 8 + 18 * k as i64;
        fill(&mut img, r as i64 - 170, ly, 20, 7, s.colour);
        draw_text(&mut img, r as i64 - 144, ly, &s.label, 1, black);
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_image_fills_the_box_and_keeps_what_ranks_high() {
        // Enlarged by a non-integer factor: 10x4 into 100x100 is 100x40, cells crisp.
        let mut small = RgbImage::from_pixel(10, 4, Rgb([255, 255, 255]));
        small.put_pixel(3, 1, Rgb([255, 0, 0]));
        let big = fit_image(&small, 100, 100, |_| 0);
        assert_eq!(big.dimensions(), (100, 40));
        let red: Vec<(u32, u32)> = big
            .enumerate_pixels()
            .filter(|p| p.2 .0 == [255, 0, 0])
            .map(|p| (p.0, p.1))
            .collect();
        assert_eq!(red.len(), 100, "one source pixel is a 10x10 block");
        assert!(red
            .iter()
            .all(|&(x, y)| (30..40).contains(&x) && (10..20).contains(&y)));
        // 7x3 into 20x20: zoom 20/7, not an integer; the picture spans the box's width exactly and every
        // source pixel gets its share, the last included: pixel x shows column x * 7 / 20, so column 6 is
        // x = 18, 19 and row 2 is y = 6, 7, 8 (of 9).
        let mut odd = RgbImage::from_pixel(7, 3, Rgb([255, 255, 255]));
        odd.put_pixel(6, 2, Rgb([0, 0, 255]));
        let fitted = fit_image(&odd, 20, 20, |_| 0);
        assert_eq!(fitted.dimensions(), (20, 9));
        let blue: Vec<(u32, u32)> = fitted
            .enumerate_pixels()
            .filter(|p| p.2 .0 == [0, 0, 255])
            .map(|p| (p.0, p.1))
            .collect();
        assert_eq!(blue.len(), 6, "{blue:?}");
        assert!(blue.iter().all(|&(x, y)| x >= 18 && y >= 6));
        // Shrunk 10x: a one-pixel line survives when it ranks high, is lost when it does not.
        let mut wide = RgbImage::from_pixel(1000, 50, Rgb([255, 255, 255]));
        for x in 0..1000 {
            wide.put_pixel(x, 23, Rgb([0, 0, 0]));
        }
        let dark = |p: Rgb<u8>| 255 - p.0[0];
        let kept = fit_image(&wide, 100, 100, dark);
        assert_eq!(kept.dimensions(), (100, 5));
        assert!((0..100).all(|x| kept.get_pixel(x, 2).0 == [0, 0, 0]));
        let plain = fit_image(&wide, 100, 100, |_| 0);
        assert!((0..100).all(|x| plain.get_pixel(x, 2).0 == [255, 255, 255]));
    }

    #[test]
    fn a_legend_wraps_and_sits_below_the_picture() {
        let img = RgbImage::from_pixel(120, 50, Rgb([1, 2, 3]));
        let entries = [
            ("FIRST ENTRY", Rgb([250, 0, 0])),
            ("SECOND ENTRY", Rgb([0, 250, 0])),
            ("THIRD ENTRY", Rgb([0, 0, 250])),
        ];
        // Each entry is 20 + 11 or 12 characters of 12 px + 18: three do not fit one 380-px row.
        assert_eq!(legend_rows(380, &entries), 2);
        let out = with_legend(&img, &entries);
        assert_eq!(out.width(), 400);
        assert_eq!(out.height(), 50 + 10 + 2 * LEGEND_ROW);
        assert_eq!(out.get_pixel(119, 49).0, [1, 2, 3], "the picture kept");
        for (_, c) in entries {
            let at = out
                .enumerate_pixels()
                .find(|p| *p.2 == c)
                .map(|p| p.1)
                .unwrap_or_else(|| panic!("no swatch {c:?}"));
            assert!(at >= 50, "swatch {c:?} drawn over the picture");
        }
    }

    #[test]
    fn crop_to_content_cuts_the_background_away() {
        let mut img = RgbImage::from_pixel(50, 40, Rgb([150, 150, 150]));
        img.put_pixel(10, 20, Rgb([0, 0, 0]));
        img.put_pixel(30, 25, Rgb([0, 0, 0]));
        let c = crop_to_content(&img, Rgb([150, 150, 150]), 2);
        assert_eq!(c.dimensions(), (25, 10));
        assert_eq!(c.get_pixel(2, 2).0, [0, 0, 0]);
        let blank = RgbImage::from_pixel(5, 5, Rgb([150, 150, 150]));
        assert_eq!(
            crop_to_content(&blank, Rgb([150, 150, 150]), 2).dimensions(),
            (5, 5)
        );
    }
}
