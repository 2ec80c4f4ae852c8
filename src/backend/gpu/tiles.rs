//! Splitting a map into tiles that fit the device's buffer limits, each with a one-pixel halo.

/// One tile: the rectangle of map pixels it reports keypoints for (its core) and the rectangle it uploads
/// (the core plus a one-pixel halo wherever the map extends).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    /// Core rectangle, map coordinates, half-open: [x0, x1) x [y0, y1).
    pub core: [u32; 4],
    /// Uploaded rectangle, map coordinates, half-open.
    pub buf: [u32; 4],
}

impl Tile {
    /// Width of the uploaded rectangle.
    pub fn buf_w(&self) -> u32 {
        self.buf[2] - self.buf[0]
    }

    /// Height of the uploaded rectangle.
    pub fn buf_h(&self) -> u32 {
        self.buf[3] - self.buf[1]
    }

    /// Words per uploaded row (four pixels a word).
    pub fn stride(&self) -> u32 {
        self.buf_w().div_ceil(4)
    }

    /// Bytes of an uploaded row for the OGM kernel: the row padded to whole runs of [`ROW_ALIGN`] pixels.
    pub fn ogm_pitch(&self) -> u32 {
        self.buf_w().div_ceil(ROW_ALIGN) * ROW_ALIGN
    }

    /// Bytes of the uploaded, word-padded rectangle.
    pub fn bytes(&self) -> u64 {
        u64::from(self.stride()) * 4 * u64::from(self.buf_h())
    }
}

/// Pixels the OGM kernel's rows are padded to: one invocation's run (`RUN` in src/backend/gpu/ogm.rs).
pub const ROW_ALIGN: u32 = 32;

/// Bytes one OGM tile's padded upload needs for a core of `w` x `h` (halo included, worst case).
pub fn tile_bytes(w: u32, h: u32) -> u64 {
    u64::from((w + 2).div_ceil(ROW_ALIGN)) * u64::from(ROW_ALIGN) * u64::from(h + 2)
}

/// The core size to use for a `width` x `height` map when one tile's upload may take `max_bytes`:
/// whole rows when they fit (so tiles are horizontal bands and the output needs no sort), else square-ish
/// tiles. `forced` (for tests) caps the core size further.
pub fn tile_size(
    width: u32,
    height: u32,
    max_bytes: u64,
    forced: Option<(u32, u32)>,
) -> Option<(u32, u32)> {
    let (mut tw, mut th) = forced.unwrap_or((width, height));
    tw = tw.clamp(1, width);
    th = th.clamp(1, height);
    if tile_bytes(tw, th) <= max_bytes {
        return Some((tw, th));
    }
    // Full-width bands of as many rows as fit, if at least a few rows fit.
    let row = u64::from((tw + 2).div_ceil(ROW_ALIGN)) * u64::from(ROW_ALIGN);
    let rows = (max_bytes / row).saturating_sub(2);
    if rows >= 16 {
        return Some((tw, rows.min(u64::from(th)) as u32));
    }
    // Otherwise square tiles: side s with (s + 2)^2 (padded) <= max_bytes.
    let mut s = ((max_bytes as f64).sqrt() as u32).saturating_sub(6);
    while s > 0 && tile_bytes(s, s) > max_bytes {
        s -= 1;
    }
    if s == 0 {
        return None;
    }
    Some((tw.min(s), th.min(s)))
}

/// The core size for the baseline kernels: whole tiles of at most `max_px` buffer pixels with a `halo` on
/// each side, core sides even (so that tile origins stay on the 2x2 grid of Trajkovic's low resolution).
pub fn tile_size_halo(
    width: u32,
    height: u32,
    max_px: u64,
    halo: u32,
    forced: Option<(u32, u32)>,
) -> Option<(u32, u32)> {
    let even = |v: u32, full: u32| {
        if v >= full {
            full
        } else {
            (v & !1).max(2).min(full)
        }
    };
    let (fw, fh) = forced.unwrap_or((width, height));
    let (mut tw, mut th) = (even(fw.max(1), width), even(fh.max(1), height));
    let area = |w: u32, h: u32| u64::from(w + 2 * halo) * u64::from(h + 2 * halo);
    if area(tw, th) <= max_px {
        return Some((tw, th));
    }
    let rows = (max_px / u64::from(tw + 2 * halo)).saturating_sub(u64::from(2 * halo));
    if rows >= 16 {
        return Some((tw, even(rows.min(u64::from(th)) as u32, height)));
    }
    let mut s = ((max_px as f64).sqrt() as u32).saturating_sub(2 * halo + 2) & !1;
    while s > 0 && area(s, s) > max_px {
        s -= 2;
    }
    if s == 0 {
        return None;
    }
    tw = tw.min(s);
    th = th.min(s);
    Some((even(tw, width), even(th, height)))
}

/// The tiles covering a `width` x `height` map with cores of `tw` x `th`, row by row, each buffer holding
/// `halo` more pixels on every side where the map extends.
pub fn plan(width: u32, height: u32, tw: u32, th: u32, halo: u32) -> Vec<Tile> {
    plan_rows(width, height, 0, height, tw, th, halo)
}

/// [`plan`] for the cores of rows `row0..row1` only (halos still reach into the rows around them).
pub fn plan_rows(
    width: u32,
    height: u32,
    row0: u32,
    row1: u32,
    tw: u32,
    th: u32,
    halo: u32,
) -> Vec<Tile> {
    let mut tiles = Vec::new();
    for y0 in (row0..row1).step_by(th as usize) {
        let y1 = y0.saturating_add(th).min(row1);
        for x0 in (0..width).step_by(tw as usize) {
            let x1 = x0.saturating_add(tw).min(width);
            tiles.push(Tile {
                core: [x0, y0, x1, y1],
                buf: [
                    x0.saturating_sub(halo),
                    y0.saturating_sub(halo),
                    x1.saturating_add(halo).min(width),
                    y1.saturating_add(halo).min(height),
                ],
            });
        }
    }
    tiles
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_map_once_with_halos() {
        for (w, h, tw, th) in [(10, 7, 3, 2), (1, 1, 1, 1), (5, 1, 2, 5), (9, 9, 9, 9)] {
            let tiles = plan(w, h, tw, th, 1);
            let mut seen = vec![0u8; (w * h) as usize];
            for t in &tiles {
                for y in t.core[1]..t.core[3] {
                    for x in t.core[0]..t.core[2] {
                        seen[(y * w + x) as usize] += 1;
                    }
                }
                assert_eq!(t.buf[0], t.core[0].saturating_sub(1));
                assert_eq!(t.buf[2], (t.core[2] + 1).min(w));
                assert!(t.buf_w() <= tw + 2 && t.buf_h() <= th + 2);
            }
            assert!(seen.iter().all(|&s| s == 1));
        }
    }

    #[test]
    fn sizes_respect_the_limit() {
        // Fits whole.
        assert_eq!(tile_size(100, 100, 1 << 20, None), Some((100, 100)));
        // Bands of full rows.
        let (tw, th) = tile_size(20_000, 20_000, 128 << 20, None).unwrap();
        assert_eq!(tw, 20_000);
        assert!(tile_bytes(tw, th) <= 128 << 20 && th > 6000);
        // Too wide for bands: square tiles.
        let (tw, th) = tile_size(1 << 30, 4, 4096, None).unwrap();
        assert!(tile_bytes(tw, th) <= 4096 && tw < 64, "{tw} {th}");
        // Forced small tiles.
        assert_eq!(tile_size(100, 50, 1 << 20, Some((7, 5))), Some((7, 5)));
        assert_eq!(tile_size(3, 2, 1 << 20, Some((7, 5))), Some((3, 2)));
        assert_eq!(tile_size(100, 100, 8, None), None);
    }
}
