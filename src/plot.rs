//! Small raster drawing for the pictures the tool writes: a 5x7 bitmap font and line plots.
//!
//! Hand-rolled to keep the dependency list short: the pictures need only labels and a few lines.

use image::{Rgb, RgbImage};

/// 5x7 glyphs, one string of 7 rows of 5 pixels each ('#' set). Unknown characters draw as a box.
fn glyph(c: char) -> [&'static str; 7] {
    match c.to_ascii_uppercase() {
        'A' => [
            " ### ", "#   #", "#   #", "#####", "#   #", "#   #", "#   #",
        ],
        'B' => [
            "#### ", "#   #", "#   #", "#### ", "#   #", "#   #", "#### ",
        ],
        'C' => [
            " ### ", "#   #", "#    ", "#    ", "#    ", "#   #", " ### ",
        ],
        'D' => [
            "#### ", "#   #", "#   #", "#   #", "#   #", "#   #", "#### ",
        ],
        'E' => [
            "#####", "#    ", "#    ", "#### ", "#    ", "#    ", "#####",
        ],
        'F' => [
            "#####", "#    ", "#    ", "#### ", "#    ", "#    ", "#    ",
        ],
        'G' => [
            " ### ", "#   #", "#    ", "# ###", "#   #", "#   #", " ####",
        ],
        'H' => [
            "#   #", "#   #", "#   #", "#####", "#   #", "#   #", "#   #",
        ],
        'I' => [
            " ### ", "  #  ", "  #  ", "  #  ", "  #  ", "  #  ", " ### ",
        ],
        'J' => [
            "  ###", "   # ", "   # ", "   # ", "   # ", "#  # ", " ##  ",
        ],
        'K' => [
            "#   #", "#  # ", "# #  ", "##   ", "# #  ", "#  # ", "#   #",
        ],
        'L' => [
            "#    ", "#    ", "#    ", "#    ", "#    ", "#    ", "#####",
        ],
        'M' => [
            "#   #", "## ##", "# # #", "# # #", "#   #", "#   #", "#   #",
        ],
        'N' => [
            "#   #", "##  #", "# # #", "#  ##", "#   #", "#   #", "#   #",
        ],
        'O' => [
            " ### ", "#   #", "#   #", "#   #", "#   #", "#   #", " ### ",
        ],
        'P' => [
            "#### ", "#   #", "#   #", "#### ", "#    ", "#    ", "#    ",
        ],
        'Q' => [
            " ### ", "#   #", "#   #", "#   #", "# # #", "#  # ", " ## #",
        ],
        'R' => [
            "#### ", "#   #", "#   #", "#### ", "# #  ", "#  # ", "#   #",
        ],
        'S' => [
            " ####", "#    ", "#    ", " ### ", "    #", "    #", "#### ",
        ],
        'T' => [
            "#####", "  #  ", "  #  ", "  #  ", "  #  ", "  #  ", "  #  ",
        ],
        'U' => [
            "#   #", "#   #", "#   #", "#   #", "#   #", "#   #", " ### ",
        ],
        'V' => [
            "#   #", "#   #", "#   #", "#   #", "#   #", " # # ", "  #  ",
        ],
        'W' => [
            "#   #", "#   #", "#   #", "# # #", "# # #", "## ##", "#   #",
        ],
        'X' => [
            "#   #", "#   #", " # # ", "  #  ", " # # ", "#   #", "#   #",
        ],
        'Y' => [
            "#   #", "#   #", " # # ", "  #  ", "  #  ", "  #  ", "  #  ",
        ],
        'Z' => [
            "#####", "    #", "   # ", "  #  ", " #   ", "#    ", "#####",
        ],
        '0' => [
            " ### ", "#   #", "#  ##", "# # #", "##  #", "#   #", " ### ",
        ],
        '1' => [
            "  #  ", " ##  ", "  #  ", "  #  ", "  #  ", "  #  ", " ### ",
        ],
        '2' => [
            " ### ", "#   #", "    #", "   # ", "  #  ", " #   ", "#####",
        ],
        '3' => [
            "#####", "   # ", "  #  ", "   # ", "    #", "#   #", " ### ",
        ],
        '4' => [
            "   # ", "  ## ", " # # ", "#  # ", "#####", "   # ", "   # ",
        ],
        '5' => [
            "#####", "#    ", "#### ", "    #", "    #", "#   #", " ### ",
        ],
        '6' => [
            "  ## ", " #   ", "#    ", "#### ", "#   #", "#   #", " ### ",
        ],
        '7' => [
            "#####", "    #", "   # ", "  #  ", " #   ", " #   ", " #   ",
        ],
        '8' => [
            " ### ", "#   #", "#   #", " ### ", "#   #", "#   #", " ### ",
        ],
        '9' => [
            " ### ", "#   #", "#   #", " ####", "    #", "   # ", " ##  ",
        ],
        '-' => [
            "     ", "     ", "     ", "#####", "     ", "     ", "     ",
        ],
        '.' => [
            "     ", "     ", "     ", "     ", "     ", " ##  ", " ##  ",
        ],
        ',' => [
            "     ", "     ", "     ", "     ", " ##  ", "  #  ", " #   ",
        ],
        ':' => [
            "     ", " ##  ", " ##  ", "     ", " ##  ", " ##  ", "     ",
        ],
        '%' => [
            "##   ", "##  #", "   # ", "  #  ", " #   ", "#  ##", "   ##",
        ],
        '(' => [
            "   # ", "  #  ", " #   ", " #   ", " #   ", "  #  ", "   # ",
        ],
        ')' => [
            " #   ", "  #  ", "   # ", "   # ", "   # ", "  #  ", " #   ",
        ],
        '/' => [
            "     ", "    #", "   # ", "  #  ", " #   ", "#    ", "     ",
        ],
        '_' => [
            "     ", "     ", "     ", "     ", "     ", "     ", "#####",
        ],
        ' ' => ["     "; 7],
        _ => [
            "#####", "#   #", "#   #", "#   #", "#   #", "#   #", "#####",
        ],
    }
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
