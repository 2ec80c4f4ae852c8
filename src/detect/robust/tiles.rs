//! The robust detector on a map of any size, in bounded memory, with the keypoints of the map in memory,
//! bit for bit.
//!
//! The detector resamples the map on a grid turned to its walls, so it cannot run down a stream of rows
//! as the other detectors do. Instead:
//! 1. the map's rows go once to a temporary file ([`Spill`]; a map read from a PNG cannot be read
//!    out of order), and the wall direction is measured from that file in two passes over its rows
//!    ([`orientation::dominant_angle_of`]: its subset of boundary pixels is bounded);
//! 2. the turned grid is cut into square tiles; each tile's cells are worked on in a [`Window`]: the tile,
//!    a ring of cells around it measured as exactly as the tile's own ([`TilePlan::ring`]: the suppression
//!    looks that far), and a halo that every measured cell's walls and neighbours fit in
//!    ([`TilePlan::halo`]: 64 cells of the largest scale, the longest wall arm). The window reads only the
//!    crop of the map under it;
//! 3. in each window the suppression decides exactly the corners whose stronger neighbours it all sees
//!    ([`super::suppress::fates`]), drops those it knows are suppressed, and places the others; every
//!    window's survivors then go through the whole map's suppression ([`super::finish`]). A corner another
//!    corner suppresses never suppresses anything itself, so dropping those early changes nothing.
//!
//! A map small enough for one tile is one window with every corner settled: the in-memory detection.

use std::fs::File;
use std::io::Write;
use std::os::unix::fs::FileExt;

use super::corners::MAX_ARM_CELLS;
use super::orientation::{self, RowReader};
use super::{detect_window, finish, RobustInfo, RobustParams, Span, Window};
use crate::backend::rules::RuleTable;
use crate::backend::MAX_SCALE;
use crate::backend::{Backend, Keypoint};
use crate::map::grid::RotatedGrid;
use crate::map::states::ClassTable;
use crate::map::stream::{RowSource, Rows};
use crate::map::MapImage;
use crate::support::error::{Error, Result};

/// Smallest tile side, samples: below it the halo is nearly all the work.
pub const MIN_TILE: u32 = 256;

/// How the turned grid is cut: tiles of `tile` x `tile` samples, each worked on in a window `ring + halo`
/// samples larger on every side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TilePlan {
    /// Tile side, samples.
    pub tile: u32,
    /// Samples around a tile whose cells are measured exactly, so that the suppression settles the
    /// tile's corners.
    pub ring: u32,
    /// Samples beyond the ring that the ring's cells read (their walls, up to [`MAX_ARM_CELLS`] cells).
    pub halo: u32,
    /// How far inside the measured cells a corner must lie to have all its neighbours in view.
    pub settle: u32,
    /// How far inside the measured cells a placed corner must lie to have all its placed neighbours in
    /// view.
    pub placed_settle: u32,
    /// Samples beyond the window its crop covers (the coarsening reads past a window's last cell).
    pub margin: u32,
    /// Coarse maps a window holds (the scales).
    scales: u32,
}

impl TilePlan {
    /// Tiles whose windows need about `bytes` of working memory ([`TilePlan::bytes`]), at least
    /// [`MIN_TILE`] a side.
    pub fn with_bytes(params: &RobustParams, bytes: u64) -> Result<Self> {
        let mut plan = TilePlan::with_tile(params, MIN_TILE)?;
        let (mut lo, mut hi) = (MIN_TILE, 1u32 << 20);
        // The largest tile whose window fits.
        while lo < hi {
            let mid = lo + (hi - lo).div_ceil(2);
            plan.tile = mid;
            if plan.bytes() <= bytes {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        plan.tile = lo;
        Ok(plan)
    }

    /// Tiles of `tile` samples a side (at least 1), the ring and halo that `params` need.
    pub fn with_tile(params: &RobustParams, tile: u32) -> Result<Self> {
        let scales = params.scales()?;
        let top = scales.iter().copied().max().unwrap_or(1).min(MAX_SCALE);
        let r = params.nms_radius;
        // A corner lies within `top` samples of its cell's first sample, and at most 3 `top` outside the
        // map (its cell holds a sample of the map), where its pixel is clamped to the map's edge; rounding
        // to pixels and the fixed-point turn move it by under 2 more. A corner `settle` inside the measured
        // cells has none unseen within the radius.
        let settle = top + r + 2 * (3 * top + 2) + 3;
        // Placing moves a corner at most 3 `top` + 2 from its cell's middle (itself within `top` of the
        // cell's first sample), then twice by at most 15 at the canonical scale. Placed corners are settled
        // only away from the map's edges (where clamping moves them), so no clamping slack here.
        let drift = 4 * top + 32;
        let placed_settle = drift + r + 5;
        // Every tile's corner settled, placed or not, and chains of suppression a few radii long decided
        // in view.
        let ring = (settle + top).max(placed_settle + drift) + 2 * r + 8;
        // A cell's walls run up to MAX_ARM_CELLS cells, one cell off its side, and its box `top` further.
        let halo = (MAX_ARM_CELLS as u32 + 2) * top + 4;
        Ok(TilePlan {
            tile: tile.max(1),
            ring,
            halo,
            settle,
            placed_settle,
            margin: 3 * top + 4,
            scales: scales.len() as u32,
        })
    }

    /// Side of a tile's window, samples.
    pub fn window_side(&self) -> u64 {
        u64::from(self.tile) + 2 * u64::from(self.ring + self.halo)
    }

    /// Working memory of one window: its coarse maps and the coarsening's planes (as
    /// [`crate::backend::robust_params::robust_working_bytes`] counts a grid), and its crop of the map
    /// (at most twice the window's area, at 45 degrees).
    pub fn bytes(&self) -> u64 {
        let side = self.window_side() + 2 * u64::from(self.margin);
        let samples = side.saturating_mul(side);
        samples
            .saturating_mul(u64::from(self.scales) + 4)
            .saturating_add(samples.saturating_mul(2))
    }
}

/// A map the tiled detector reads: its rows in passes, and crops of it.
pub trait MapReader: RowReader {
    /// The pixels of columns `x0..x0 + w`, rows `y0..y0 + h` (inside the map) as an image.
    fn crop(&mut self, x0: u32, y0: u32, w: u32, h: u32) -> Result<MapImage>;
}

/// A map in memory as a [`MapReader`] (crops are copies): the tiled path over a map that would fit whole,
/// to check it against the in-memory one.
pub struct ImageReader<'a>(pub orientation::ImageRows<'a>);

impl<'a> ImageReader<'a> {
    /// Reads `image`.
    pub fn new(image: &'a MapImage) -> Self {
        ImageReader(orientation::ImageRows(image))
    }
}

impl RowReader for ImageReader<'_> {
    fn width(&self) -> usize {
        self.0.width()
    }
    fn height(&self) -> usize {
        self.0.height()
    }
    fn row(&mut self, y: usize) -> Result<&[u8]> {
        self.0.row(y)
    }
    fn rewind(&mut self) -> Result<()> {
        Ok(())
    }
}

impl MapReader for ImageReader<'_> {
    fn crop(&mut self, x0: u32, y0: u32, w: u32, h: u32) -> Result<MapImage> {
        let image = self.0 .0;
        let stride = image.width() as usize;
        let mut px = Vec::with_capacity(w as usize * h as usize);
        for y in y0..y0 + h {
            let start = y as usize * stride + x0 as usize;
            px.extend_from_slice(&image.pixels()[start..start + w as usize]);
        }
        MapImage::new(w, h, px)
    }
}

/// A map's rows in an unnamed temporary file (removed when closed): a map read once from a stream, then
/// in passes and crops.
pub struct Spill {
    file: File,
    width: u32,
    height: u32,
    /// Rows `first..first + buf.len() / width` of the last pass's read.
    buf: Vec<u8>,
    first: usize,
}

/// Bytes of rows a [`Spill`] reads or writes at a time.
const SPILL_CHUNK: usize = 4 << 20;

impl Spill {
    /// Bytes a [`Spill`] holds in memory for a map `width` wide: a chunk of rows.
    pub fn bytes(width: u32) -> u64 {
        SPILL_CHUNK.max(width as usize) as u64
    }

    /// Reads every row of `source` into a temporary file (in the system's temporary folder, `TMPDIR`),
    /// showing each chunk of rows to `on_rows` (with its rows as the core); returns the source's warnings.
    pub fn from_source(
        source: &mut dyn RowSource,
        on_rows: &mut dyn FnMut(Rows, (usize, usize)),
    ) -> Result<(Self, Vec<String>)> {
        let (w, h) = (source.width(), source.height());
        let dir = std::env::temp_dir();
        let io = |e: std::io::Error| {
            Error::Unavailable(format!(
                "the robust detector keeps a map too large for memory in a temporary file ({} bytes) in {}: {e}",
                u64::from(w) * u64::from(h),
                dir.display()
            ))
        };
        let mut file = tempfile::tempfile_in(&dir).map_err(io)?;
        let rows = (SPILL_CHUNK / (w as usize).max(1)).max(1);
        let mut buf = vec![0u8; rows * w as usize];
        let mut y = 0usize;
        while y < h as usize {
            crate::support::stop::check()?;
            let n = rows.min(h as usize - y);
            let chunk = &mut buf[..n * w as usize];
            source.read_rows(chunk)?;
            file.write_all(chunk).map_err(io)?;
            on_rows(Rows::new(chunk, w as usize, h as usize, y), (y, y + n));
            y += n;
        }
        file.flush().map_err(io)?;
        let warnings = source.finish()?;
        buf.clear();
        Ok((
            Spill {
                file,
                width: w,
                height: h,
                buf,
                first: 0,
            },
            warnings,
        ))
    }

    fn read_at(&self, out: &mut [u8], offset: u64) -> Result<()> {
        self.file.read_exact_at(out, offset).map_err(|e| {
            Error::Unavailable(format!("reading back the map's temporary file failed: {e}"))
        })
    }
}

impl RowReader for Spill {
    fn width(&self) -> usize {
        self.width as usize
    }
    fn height(&self) -> usize {
        self.height as usize
    }
    fn row(&mut self, y: usize) -> Result<&[u8]> {
        let w = self.width as usize;
        let held = self.buf.len() / w.max(1);
        if !(self.first..self.first + held).contains(&y) {
            let n = (SPILL_CHUNK / w.max(1))
                .max(1)
                .min(self.height as usize - y);
            let mut buf = std::mem::take(&mut self.buf);
            buf.resize(n * w, 0);
            self.read_at(&mut buf, y as u64 * w as u64)?;
            self.buf = buf;
            self.first = y;
        }
        let i = (y - self.first) * w;
        Ok(&self.buf[i..i + w])
    }
    fn rewind(&mut self) -> Result<()> {
        self.buf.clear();
        self.first = 0;
        Ok(())
    }
}

impl MapReader for Spill {
    fn crop(&mut self, x0: u32, y0: u32, w: u32, h: u32) -> Result<MapImage> {
        let stride = u64::from(self.width);
        let mut px = vec![0u8; w as usize * h as usize];
        for (j, row) in px.chunks_exact_mut(w.max(1) as usize).enumerate() {
            let y = u64::from(y0) + j as u64;
            self.read_at(row, y * stride + u64::from(x0))?;
        }
        MapImage::new(w, h, px)
    }
}

/// The robust detector over `map` in the tiles of `plan`: the keypoints of [`super::detect`] on the whole
/// map, bit for bit, holding one window's memory at a time (and the corners no window could rule out).
pub fn detect_tiled(
    backend: &mut dyn Backend,
    map: &mut dyn MapReader,
    classes: &ClassTable,
    rules: &RuleTable,
    params: &RobustParams,
    plan: &TilePlan,
) -> Result<(Vec<Keypoint>, RobustInfo)> {
    params.scales()?;
    let (w, h) = (map.width() as u32, map.height() as u32);
    let anchor2 = params.anchor2(w, h);
    let angle = match params.angle {
        Some(a) => a,
        None => orientation::dominant_angle_of(map, classes, anchor2)?,
    };
    let grid = RotatedGrid::anchored(w, h, angle, anchor2)?;
    let t = i64::from(plan.tile);
    let (gw, gh) = (i64::from(grid.width), i64::from(grid.height));
    let (nx, ny) = ((gw + t - 1) / t, (gh + t - 1) / t);
    // Owned cells: the tile's samples, open beyond the first and last tiles (cells start up to a scale
    // before the grid's first sample).
    let span = |i: i64, n: i64| {
        (
            if i == 0 { i64::MIN } else { i * t },
            if i + 1 == n { i64::MAX } else { (i + 1) * t },
        )
    };
    let reach = i64::from(plan.ring + plan.halo);
    // Each window's corners in a list of their own (no reallocation of one growing list), joined at the end.
    let mut lists: Vec<Vec<super::Found>> = Vec::new();
    let mut candidates = 0;
    for j in 0..ny {
        for i in 0..nx {
            crate::support::stop::check()?;
            let owned = Span {
                p: span(i, nx),
                q: span(j, ny),
            };
            let trusted = owned.grown(i64::from(plan.ring));
            let settled = trusted.grown(-i64::from(plan.settle));
            let placed_settled = trusted.grown(-i64::from(plan.placed_settle));
            // The window, clipped to the grid (beyond it every sample is outside the map).
            let (p0, p1) = ((i * t - reach).max(0), ((i + 1) * t + reach).min(gw));
            let (q0, q1) = ((j * t - reach).max(0), ((j + 1) * t + reach).min(gh));
            let m = i64::from(plan.margin);
            let c = |v: i64| v as i32;
            let (cp0, cp1, cq0, cq1) = (c(p0 - m), c(p1 + m), c(q0 - m), c(q1 + m));
            let (Some((x0, x1)), Some((y0, y1))) = (
                grid.source_cols(cp0, cp1, cq0, cq1),
                grid.source_rows(cp0, cp1, cq0, cq1),
            ) else {
                // No sample of the window reads the map: no cell of it is free or occupied.
                continue;
            };
            let crop = map.crop(x0, y0, x1 - x0, y1 - y0)?;
            let window = Window {
                image: &crop,
                grid: grid.window(
                    (c(p0), c(q0)),
                    (p1 - p0) as u32,
                    (q1 - q0) as u32,
                    (x0, y0, x1 - x0, y1 - y0),
                ),
                offset: (c(p0), c(q0)),
                owned,
                trusted,
                settled,
                placed_settled,
            };
            let (f, n) = detect_window(backend, &window, classes, rules, params)?;
            lists.push(f);
            candidates += n;
        }
    }
    let mut found = Vec::with_capacity(lists.iter().map(Vec::len).sum());
    for list in lists {
        found.extend(list);
    }
    Ok((
        finish(found, params.nms_radius, &grid),
        RobustInfo {
            angle: grid.degrees(),
            anchor: grid.anchor(),
            candidates,
        },
    ))
}
