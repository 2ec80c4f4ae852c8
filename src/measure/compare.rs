//! The paper's Table I with timings, as `compare` makes it: rows, their tables, and a contact sheet per map.

use std::io::{self, Write};

use image::RgbImage;

use crate::detect::detector::DetectorKind;
use crate::detect::output::{csv_field, md_cell, TableFormat};
use crate::map::states::ClassTable;
use crate::map::OccupancyMap;

/// One row of `compare`: a detector on a map.
#[derive(serde::Serialize, Debug)]
pub struct CompareRecord {
    /// The map's short name.
    pub map: String,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// The detector's name.
    pub detector: &'static str,
    /// Keypoints found (the same on every backend: checked).
    pub keypoints: usize,
    /// The fast CPU path, end to end.
    pub cpu_end_to_end_ms: Option<f64>,
    /// The single-threaded reference: its work before keypoint selection, and end to end.
    pub reference_kernel_ms: Option<f64>,
    /// The reference, end to end.
    pub reference_end_to_end_ms: Option<f64>,
    /// The GPU kernels (timestamp queries).
    pub gpu_kernel_ms: Option<f64>,
    /// The GPU, end to end.
    pub gpu_end_to_end_ms: Option<f64>,
}

/// Width of one contact-sheet panel, pixels; its height follows the map's shape (a third to one and a half
/// of the width).
pub const PANEL: u32 = 560;

/// Height of a sheet's title, legend and panel label, pixels.
const TITLE_H: u32 = 34;
const LEGEND_H: u32 = 26;
const LABEL_H: u32 = 22;

/// Bytes of one contact sheet of `compare` (RGB, five panels), for memory budgets.
pub const SHEET_BYTES: u64 = sheet_bytes(5);

/// Bytes of a sheet of `panels` panels, two a row (at their tallest).
pub const fn sheet_bytes(panels: u32) -> u64 {
    let rows = panels.div_ceil(2) as u64;
    let tallest = (PANEL as u64 * 3).div_ceil(2);
    3 * (2 * PANEL as u64 + 30)
        * ((TITLE_H + LEGEND_H) as u64 + rows * (tallest + LABEL_H as u64 + 10) + 20)
}

/// Colour of the rings around hand-marked points.
pub const MARK_COLOUR: image::Rgb<u8> = image::Rgb([0, 170, 0]);

/// Colour of a panel behind the map (not a grey a map can have, so the map's extent shows).
pub const PANEL_BACKING: image::Rgb<u8> = image::Rgb([222, 228, 240]);

/// The keypoint colours a sheet's legend lists ([`crate::detect::overlay::rule_colour`]).
pub fn rule_legend() -> Vec<(&'static str, image::Rgb<u8>)> {
    use crate::detect::overlay::rule_colour;
    vec![
        ("OGM RULE 4", rule_colour(4)),
        ("RULE 5", rule_colour(5)),
        ("RULE 6", rule_colour(6)),
        ("OTHER DETECTORS", rule_colour(0)),
    ]
}

/// One panel per detector of the map's explored part with the keypoints marked, labelled.
pub fn contact_sheet(
    name: &str,
    map: &OccupancyMap,
    found: &[(DetectorKind, Vec<crate::Keypoint>)],
) -> RgbImage {
    let panels: Vec<(String, &[crate::Keypoint])> = found
        .iter()
        .map(|(kind, kps)| {
            (
                format!("{}: {} KEYPOINTS", kind.name(), kps.len()),
                &kps[..],
            )
        })
        .collect();
    labelled_sheet(
        &format!(
            "{name}: {}X{}, CROPPED TO THE EXPLORED AREA",
            map.image.width(),
            map.image.height()
        ),
        map,
        &panels,
        &[],
    )
}

/// The explored part of a map (anything not unknown) with a margin of 8 pixels: (x0, y0, x1, y1), the
/// whole map when nothing is explored.
pub fn explored_box(map: &OccupancyMap) -> (u32, u32, u32, u32) {
    let classes = ClassTable::new(&map.thresholds);
    let (w, h) = (map.image.width(), map.image.height());
    crate::support::plot::bounding_box(w, h, 8, |x, y| {
        classes.state(map.image.get(x, y)) != crate::CellState::Unknown
    })
    .unwrap_or((0, 0, w, h))
}

/// `text` cut to at most `width` pixels at scale 2, with `...` when cut.
fn fit_label(text: &str, width: u32) -> String {
    let most = (width / 12) as usize;
    if text.chars().count() <= most {
        return text.to_string();
    }
    let mut s: String = text.chars().take(most.saturating_sub(3)).collect();
    s.push_str("...");
    s
}

/// Panels of the map's explored part, two a row, each with its label and keypoints, and `marks` (points
/// a person marked, pixel coordinates) ringed in [`MARK_COLOUR`] on every panel. Each panel is
/// [`PANEL`] wide and as tall as the crop's shape asks, and the crop fills it: shrunk (darkest of each
/// block, so walls stay) when larger, enlarged by any real factor (nearest neighbour, cells crisp) when
/// smaller.
pub fn labelled_sheet(
    title: &str,
    map: &OccupancyMap,
    found: &[(String, &[crate::Keypoint])],
    marks: &[(f64, f64)],
) -> RgbImage {
    use crate::detect::overlay::{fit_shrink, fit_zoom, OverlayCanvas};
    use crate::support::plot::{draw_text, fill};
    let (x0, y0, x1, y1) = explored_box(map);
    let (cw, ch) = (x1 - x0, y1 - y0);
    let px = (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .map(|(x, y)| map.image.get(x, y))
        .collect();
    let crop = crate::MapImage::new(cw, ch, px).expect("non-empty crop");
    let ph = ((f64::from(PANEL) * f64::from(ch) / f64::from(cw)).round() as u32)
        .clamp(PANEL / 3, PANEL * 3 / 2);
    let d = fit_shrink(cw, ch, PANEL, ph);
    let mut canvas = OverlayCanvas::with_shrink(cw, ch, d);
    canvas.add_rows(crate::map::stream::Rows::of(&crop), (0, ch as usize));
    let f = fit_zoom(cw.div_ceil(d), ch.div_ceil(d), PANEL, ph);
    let mut legend = rule_legend();
    if !marks.is_empty() {
        legend.push(("MARKED BY HAND", MARK_COLOUR));
    }
    let top = TITLE_H + LEGEND_H;
    let mut sheet = RgbImage::from_pixel(
        2 * PANEL + 30,
        top + (found.len() as u32).div_ceil(2).max(1) * (ph + LABEL_H + 10) + 20,
        image::Rgb([255, 255, 255]),
    );
    let black = image::Rgb([0, 0, 0]);
    draw_text(
        &mut sheet,
        10,
        8,
        &fit_label(title, 2 * PANEL + 10),
        2,
        black,
    );
    crate::support::plot::draw_legend(&mut sheet, 10, i64::from(TITLE_H), 2 * PANEL + 10, &legend);
    for (i, (label, kps)) in found.iter().enumerate() {
        let shifted: Vec<crate::Keypoint> = kps
            .iter()
            .filter(|k| k.x >= x0 && k.x < x1 && k.y >= y0 && k.y < y1)
            .map(|k| crate::Keypoint {
                x: k.x - x0,
                y: k.y - y0,
                ..*k
            })
            .collect();
        let mut panel = canvas.clone().render_fit(&shifted, PANEL, ph);
        let radius = ((3.0 * f + 3.0).round() as i64).clamp(6, 27);
        // The marked pixel's centre in doubled panel coordinates: the crop's pixel (mx - x0) spans
        // [mx - x0, mx - x0 + 1), a canvas cell d of them, a cell the panel's pixels over its cells.
        let (zx, zy) = (
            f64::from(panel.width()) / f64::from(cw.div_ceil(d)),
            f64::from(panel.height()) / f64::from(ch.div_ceil(d)),
        );
        for &(mx, my) in marks {
            let (px2, py2) = (
                2.0 * (mx - f64::from(x0)) + 1.0,
                2.0 * (my - f64::from(y0)) + 1.0,
            );
            if px2 < 0.0 || py2 < 0.0 {
                continue;
            }
            let (cx2, cy2) = (
                (px2 / f64::from(d) * zx).round() as i64,
                (py2 / f64::from(d) * zy).round() as i64,
            );
            crate::detect::overlay::ring(&mut panel, cx2, cy2, radius, MARK_COLOUR);
        }
        let (ox, oy) = (
            10 + (i as u32 % 2) * (PANEL + 10),
            top + (i as u32 / 2) * (ph + LABEL_H + 10),
        );
        draw_text(
            &mut sheet,
            i64::from(ox),
            i64::from(oy) + 4,
            &fit_label(label, PANEL),
            2,
            black,
        );
        fill(
            &mut sheet,
            i64::from(ox),
            i64::from(oy + LABEL_H),
            i64::from(PANEL),
            i64::from(ph),
            PANEL_BACKING,
        );
        image::imageops::overlay(&mut sheet, &panel, i64::from(ox), i64::from(oy + LABEL_H));
    }
    sheet
}

/// The rows as the Markdown table `compare.md` holds.
pub fn markdown(rows: &[CompareRecord]) -> String {
    let ms = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    let mut md = String::from("| map | size | detector | keypoints | CPU end-to-end ms | reference kernel ms | reference end-to-end ms | GPU kernel ms | GPU end-to-end ms |\n|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        md += &format!(
            "| {} | {}x{} | {} | {} | {} | {} | {} | {} | {} |\n",
            md_cell(&r.map),
            r.width,
            r.height,
            r.detector,
            r.keypoints,
            ms(r.cpu_end_to_end_ms),
            ms(r.reference_kernel_ms),
            ms(r.reference_end_to_end_ms),
            ms(r.gpu_kernel_ms),
            ms(r.gpu_end_to_end_ms)
        );
    }
    md
}

/// The anchor of map `name`'s contact sheet on the `--html` page: letters and digits kept, any other
/// character as its code in hex between `-`s, so different names never share an anchor.
pub fn sheet_anchor(name: &str) -> String {
    let mut a = String::from("sheet-");
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            a.push(c);
        } else {
            a.push_str(&format!("-{:x}-", u32::from(c)));
        }
    }
    a
}

/// The rows as the `--html` page's table (`id="compare"`), each map linked to its contact sheet.
pub fn html_table(rows: &[CompareRecord]) -> crate::support::report::Table {
    use crate::support::report::{Cell, Table};
    let mut t = Table::new(
        "compare",
        "Keypoints and median times (ms) per map and detector; the same keypoints on every backend (checked)",
        &[
            ("map", false),
            ("size", true),
            ("detector", false),
            ("keypoints", true),
            ("CPU end-to-end", true),
            ("reference kernel", true),
            ("reference end-to-end", true),
            ("GPU kernel", true),
            ("GPU end-to-end", true),
        ],
    );
    for r in rows {
        // Sorted by pixels.
        let mpx = f64::from(r.width) * f64::from(r.height) / 1e6;
        t.row(vec![
            Cell::text(&r.map).link(format!("#{}", sheet_anchor(&r.map))),
            Cell::keyed(format!("{}x{}", r.width, r.height), mpx),
            Cell::text(r.detector),
            Cell::int(r.keypoints as i128),
            Cell::opt(r.cpu_end_to_end_ms, 2),
            Cell::opt(r.reference_kernel_ms, 2),
            Cell::opt(r.reference_end_to_end_ms, 2),
            Cell::opt(r.gpu_kernel_ms, 2),
            Cell::opt(r.gpu_end_to_end_ms, 2),
        ]);
    }
    t
}

/// The picture of map `i` named `name` on the `--html` page.
pub fn sheet_file(i: usize, name: &str) -> String {
    crate::support::report::file_name(i, name, "-contact-sheet")
}

/// A `compare --html` page being written: each map's contact sheet written as the map is done.
pub struct ComparePage {
    report: crate::support::report::Report,
    figures: Vec<crate::support::report::Figure>,
}

impl ComparePage {
    /// A page written into `dir` (made now, so that a bad folder is found before the measurements).
    pub fn create(dir: &std::path::Path) -> crate::support::error::Result<Self> {
        Ok(ComparePage {
            report: crate::support::report::Report::create(dir, "ogm-corners compare")?,
            figures: Vec::new(),
        })
    }

    /// Adds map `i`'s contact sheet ([`sheet_file`]), anchored where its rows link ([`sheet_anchor`]).
    pub fn add_sheet(
        &mut self,
        i: usize,
        name: &str,
        path: &std::path::Path,
        sheet: &RgbImage,
    ) -> crate::support::error::Result<()> {
        let caption = vec![name.to_string(), path.display().to_string()];
        let mut figure = self.report.picture(&sheet_file(i, name), sheet, caption)?;
        figure.id = Some(sheet_anchor(name));
        self.figures.push(figure);
        Ok(())
    }

    /// Writes the page (`about`: a line on the run) and returns its path.
    pub fn finish(
        mut self,
        rows: &[CompareRecord],
        about: &str,
    ) -> crate::support::error::Result<std::path::PathBuf> {
        let r = &mut self.report;
        r.text(format!("{about} Click a column to sort."));
        r.table(html_table(rows));
        r.heading("Contact sheets: each detector's keypoints on the explored part of each map");
        r.legend(&rule_legend());
        r.figures_at(self.figures, 900);
        self.report.finish()
    }
}

/// Writes the rows as Markdown, CSV or JSON.
pub fn write_table(
    out: &mut dyn Write,
    format: TableFormat,
    rows: &[CompareRecord],
) -> io::Result<()> {
    match format {
        TableFormat::Md => write!(out, "{}", markdown(rows))?,
        TableFormat::Json => {
            serde_json::to_writer_pretty(&mut *out, &rows)?;
            writeln!(out)?;
        }
        TableFormat::Csv => {
            writeln!(out, "map,width,height,detector,keypoints,cpu_end_to_end_ms,reference_kernel_ms,reference_end_to_end_ms,gpu_kernel_ms,gpu_end_to_end_ms")?;
            for r in rows {
                let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.3}"));
                writeln!(
                    out,
                    "{},{},{},{},{},{},{},{},{},{}",
                    csv_field(&r.map),
                    r.width,
                    r.height,
                    r.detector,
                    r.keypoints,
                    f(r.cpu_end_to_end_ms),
                    f(r.reference_kernel_ms),
                    f(r.reference_end_to_end_ms),
                    f(r.gpu_kernel_ms),
                    f(r.gpu_end_to_end_ms)
                )?;
            }
        }
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::states::{FREE, OCCUPIED, UNKNOWN};
    use crate::map::MapImage;

    /// A room of `w` x `h` free pixels walled in, at (40, 30) in a larger unknown map.
    fn room(w: u32, h: u32) -> OccupancyMap {
        let mut img = MapImage::filled(w + 100, h + 80, UNKNOWN).unwrap();
        let stride = (w + 100) as usize;
        for y in 30..30 + h {
            for x in 40..40 + w {
                let wall = x == 40 || y == 30 || x == 39 + w || y == 29 + h;
                img.pixels_mut()[y as usize * stride + x as usize] =
                    if wall { OCCUPIED } else { FREE };
            }
        }
        OccupancyMap::from_image(img)
    }

    /// The box of a panel's pixels that are not the backing, in panel coordinates.
    fn drawn_box(sheet: &RgbImage, ox: u32, oy: u32, pw: u32, ph: u32) -> (u32, u32, u32, u32) {
        let (mut x0, mut y0, mut x1, mut y1) = (pw, ph, 0, 0);
        for y in 0..ph {
            for x in 0..pw {
                if *sheet.get_pixel(ox + x, oy + y) != PANEL_BACKING {
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
                }
            }
        }
        (x0, y0, x1, y1)
    }

    #[test]
    fn sheet_anchors_differ_for_different_names() {
        assert_eq!(sheet_anchor("a_b"), "sheet-a-5f-b");
        assert_ne!(sheet_anchor("a b"), sheet_anchor("a_b"));
        assert_ne!(sheet_anchor("a-1"), sheet_anchor("a\u{2d1}"));
    }

    /// Golden geometry: whatever the map's size and shape, the crop fills its panel edge to edge along the
    /// panel's width and height (non-integer zoom), labels and the legend are drawn.
    #[test]
    fn panels_are_filled_and_labelled() {
        // Small and wide (an integer zoom would fill 316 of 560 px), large (shrunk), tall, tiny.
        for (w, h) in [(300, 70), (2000, 700), (120, 400), (20, 20)] {
            let map = room(w, h);
            let kps = [crate::Keypoint::scored(41, 31, 0)];
            let found = [
                ("FIRST PANEL".to_string(), &kps[..]),
                ("SECOND".to_string(), &kps[..]),
            ];
            let sheet = labelled_sheet("TITLE", &map, &found, &[(41.0, 31.0)]);
            let (cw, ch) = (w + 16, h + 16); // the explored box with its margin
            let ph = ((f64::from(PANEL) * f64::from(ch) / f64::from(cw)).round() as u32)
                .clamp(PANEL / 3, PANEL * 3 / 2);
            let top = TITLE_H + LEGEND_H;
            for i in 0..2u32 {
                let (ox, oy) = (10 + i * (PANEL + 10), top + LABEL_H);
                let (x0, y0, x1, y1) = drawn_box(&sheet, ox, oy, PANEL, ph);
                let aspect = f64::from(ch) / f64::from(cw);
                let clamped = !(1.0 / 3.0..=1.5).contains(&aspect);
                // Along the axis that limits the zoom the crop spans the panel to the pixel; along the
                // other it does too unless the shape was clamped.
                let (fw, fh) = (x1 - x0, y1 - y0);
                assert_eq!((x0, y0), (0, 0), "{w}x{h}");
                assert!(
                    fw >= PANEL - 1 || fh >= ph - 1,
                    "{w}x{h}: {fw}x{fh} in {PANEL}x{ph}"
                );
                if !clamped {
                    assert!(
                        fw >= PANEL - 2 && fh >= ph - 2,
                        "{w}x{h}: {fw}x{fh} in {PANEL}x{ph}"
                    );
                }
                // The label: dark text in the strip above the panel, within the panel's width.
                let label_dark = (top..top + LABEL_H)
                    .flat_map(|y| (ox..ox + PANEL).map(move |x| (x, y)))
                    .filter(|&(x, y)| sheet.get_pixel(x, y).0 == [0, 0, 0])
                    .count();
                assert!(label_dark > 30, "{w}x{h}: label pixels {label_dark}");
                // The keypoint's rule colour and the hand mark's ring are in the panel.
                let has = |c: image::Rgb<u8>| {
                    (0..ph).any(|y| (0..PANEL).any(|x| *sheet.get_pixel(ox + x, oy + y) == c))
                };
                assert!(
                    has(crate::detect::overlay::rule_colour(0)) && has(MARK_COLOUR),
                    "{w}x{h}"
                );
            }
            // The legend: every swatch colour in its strip, and the title's text above it.
            for (_, c) in rule_legend().into_iter().chain([("", MARK_COLOUR)]) {
                let found = (TITLE_H..TITLE_H + LEGEND_H)
                    .any(|y| (0..sheet.width()).any(|x| *sheet.get_pixel(x, y) == c));
                assert!(found, "legend colour {c:?}");
            }
            assert!((8..22).any(|y| (10..80).any(|x| sheet.get_pixel(x, y).0 == [0, 0, 0])));
        }
    }
}
