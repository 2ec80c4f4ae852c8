//! The paper's Table I with timings, as `compare` makes it: rows, their tables, and a contact sheet per map.

use std::io::{self, Write};

use image::RgbImage;

use crate::detector::DetectorKind;
use crate::map::OccupancyMap;
use crate::output::{csv_field, md_cell, TableFormat};
use crate::states::ClassTable;

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

/// Side of one contact-sheet panel, pixels.
pub const PANEL: u32 = 560;

/// Bytes of one contact sheet of `compare` (RGB, five panels), for memory budgets.
pub const SHEET_BYTES: u64 = sheet_bytes(5);

/// Bytes of a sheet of `panels` panels, two a row.
pub const fn sheet_bytes(panels: u32) -> u64 {
    let rows = panels.div_ceil(2) as u64;
    3 * (2 * PANEL as u64 + 30) * (34 + rows * (PANEL as u64 + 32) + 20)
}

/// Colour of the rings around hand-marked points.
pub const MARK_COLOUR: image::Rgb<u8> = image::Rgb([0, 170, 0]);

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

/// Panels of the map's explored part, two a row, each with its label and keypoints, and `marks` (points
/// a person marked, pixel coordinates) ringed in [`MARK_COLOUR`] on every panel.
pub fn labelled_sheet(
    title: &str,
    map: &OccupancyMap,
    found: &[(String, &[crate::Keypoint])],
    marks: &[(f64, f64)],
) -> RgbImage {
    use crate::plot::{draw_text, fill};
    // Crop to what the robot saw (anything not unknown), with a margin: the rest is empty grey.
    let classes = ClassTable::new(&map.thresholds);
    let (w, h) = (map.image.width(), map.image.height());
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for y in 0..h {
        for x in 0..w {
            if classes.state(map.image.get(x, y)) != crate::CellState::Unknown {
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
            }
        }
    }
    if x1 <= x0 {
        (x0, y0, x1, y1) = (0, 0, w, h);
    }
    let m = 8;
    let (x0, y0, x1, y1) = (
        x0.saturating_sub(m),
        y0.saturating_sub(m),
        (x1 + m).min(w),
        (y1 + m).min(h),
    );
    let (cw, ch) = (x1 - x0, y1 - y0);
    let px = (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .map(|(x, y)| map.image.get(x, y))
        .collect();
    let crop = crate::MapImage::new(cw, ch, px).expect("non-empty crop");
    let side = cw.max(ch);
    let (zoom, shrink) = if side <= PANEL {
        ((PANEL / side).clamp(1, 8), 1)
    } else {
        (1, side.div_ceil(PANEL))
    };
    let (label_h, title_h) = (22u32, 34u32);
    let mut sheet = RgbImage::from_pixel(
        2 * PANEL + 30,
        title_h + (found.len() as u32).div_ceil(2).max(1) * (PANEL + label_h + 10) + 20,
        image::Rgb([255, 255, 255]),
    );
    let black = image::Rgb([0, 0, 0]);
    draw_text(&mut sheet, 10, 8, title, 2, black);
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
        let mut panel = crate::overlay::render_overlay_at(&crop, &shifted, zoom, shrink);
        for &(mx, my) in marks {
            // The mark's pixel centre in the panel, in doubled coordinates.
            let (px, py) = (
                (mx - f64::from(x0)) / f64::from(shrink),
                (my - f64::from(y0)) / f64::from(shrink),
            );
            if px < -0.5 || py < -0.5 {
                continue;
            }
            let z = f64::from(zoom);
            let (cx2, cy2) = (
                (2.0 * px * z + z).round() as i64,
                (2.0 * py * z + z).round() as i64,
            );
            crate::overlay::ring(&mut panel, cx2, cy2, i64::from(3 * zoom + 3), MARK_COLOUR);
        }
        let (ox, oy) = (
            10 + (i as u32 % 2) * (PANEL + 10),
            title_h + (i as u32 / 2) * (PANEL + label_h + 10),
        );
        draw_text(
            &mut sheet,
            i64::from(ox),
            i64::from(oy) + 4,
            label,
            2,
            black,
        );
        fill(
            &mut sheet,
            i64::from(ox),
            i64::from(oy + label_h),
            i64::from(PANEL),
            i64::from(PANEL),
            image::Rgb([205, 205, 205]),
        );
        image::imageops::overlay(&mut sheet, &panel, i64::from(ox), i64::from(oy + label_h));
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
