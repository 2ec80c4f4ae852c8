//! Maps read as a stream of rows: every detector except the robust one (which works in tiles of its turned
//! grid, [`crate::detect::robust::tiles`]) looks at a few rows at a time, so a map of any size is detected in
//! windows of rows with a small halo above and below, holding only a few windows in memory.
//!
//! - [`Rows`] is a band of a map's rows in memory, addressed by the map's own row numbers.
//! - [`RowSource`] hands out a map's rows top to bottom: a decoder reading a file ([`crate::map::decode`]), the
//!   synthetic generator ([`crate::map::synthetic::OfficeRows`]), or an image in memory.
//! - [`for_each_window`] cuts a source into [`Window`]s: a core of rows whose results a detector reports, and
//!   [`HALO`] rows around it that only feed the core's neighbourhoods. A reader thread fills the next window
//!   while the caller works on the current one, so disk reads overlap the kernels.
//! - `write_pgm` writes a source's rows as a binary PGM.
//! - [`direct`] (`direct.rs`): a raw PGM raster read straight into page-aligned window buffers, with
//!   `O_DIRECT` where the page cache does not hold the window (`mincore` to ask), and never through a
//!   memory map.
//!
//! A map in memory is one window (no copy): the in-memory detection is the streamed one over a slice.

pub mod direct;

use std::sync::mpsc;

use crate::map::MapImage;
use crate::support::error::{Error, Result};
use direct::{AlignedBuf, RawFile, ALIGN};

/// Rows above and below a window's core that every detector's neighbourhood fits in: OGM reads 1, Harris
/// and Shi-Tomasi 3 for the score and 1 more for the local maximum, Trajkovic up to 4 for its
/// low-resolution rows and 1 for the local maximum. Even, so that windows start on even rows, where
/// Trajkovic's 2x2 low-resolution blocks start.
pub const HALO: usize = 8;

/// The halo the OGM detector needs (1 row), made even as every halo is.
pub const OGM_HALO: usize = 2;

/// A band of a map's rows held in memory, addressed by the map's row numbers.
#[derive(Clone, Copy, Debug)]
pub struct Rows<'a> {
    px: &'a [u8],
    width: usize,
    height: usize,
    first: usize,
}

impl<'a> Rows<'a> {
    /// Rows `first..first + px.len() / width` of a `width` x `height` map. Panics when `px` is not whole
    /// rows or runs past the map (a caller's bug, not input).
    pub fn new(px: &'a [u8], width: usize, height: usize, first: usize) -> Self {
        assert!(width > 0 && px.len().is_multiple_of(width), "whole rows");
        assert!(first + px.len() / width <= height, "rows inside the map");
        Rows {
            px,
            width,
            height,
            first,
        }
    }

    /// Every row of an image.
    pub fn of(image: &'a MapImage) -> Self {
        Rows::new(
            image.pixels(),
            image.width() as usize,
            image.height() as usize,
            0,
        )
    }

    /// The map's width.
    #[inline]
    pub fn width(&self) -> usize {
        self.width
    }

    /// The map's height (not the band's).
    #[inline]
    pub fn height(&self) -> usize {
        self.height
    }

    /// The first row held.
    #[inline]
    pub fn first(&self) -> usize {
        self.first
    }

    /// One past the last row held.
    #[inline]
    pub fn end(&self) -> usize {
        self.first + self.px.len() / self.width
    }

    /// Map row `y` (which must be held).
    #[inline(always)]
    pub fn row(&self, y: usize) -> &'a [u8] {
        let i = (y - self.first) * self.width;
        &self.px[i..i + self.width]
    }

    /// The rows held, row-major.
    pub fn pixels(&self) -> &'a [u8] {
        self.px
    }

    /// The rows held as an image of their own (a copy): for backends that detect in whole images.
    pub fn image(&self) -> Result<MapImage> {
        let h = u32::try_from(self.end() - self.first)
            .map_err(|_| Error::invalid("a window of rows taller than 2^32"))?;
        MapImage::new(self.width as u32, h, self.px.to_vec())
    }
}

/// A map's rows, top to bottom.
pub trait RowSource: Send {
    /// Width in pixels.
    fn width(&self) -> u32;
    /// Height in pixels.
    fn height(&self) -> u32;
    /// Fills `out` (whole rows) with the next rows.
    fn read_rows(&mut self, out: &mut [u8]) -> Result<()>;
    /// Called after the last row: warnings worth telling a user (such as trailing bytes ignored).
    fn finish(&mut self) -> Result<Vec<String>> {
        Ok(Vec::new())
    }
    /// The file that holds the rows as they are (one byte a pixel, row after row) and the byte offset
    /// of row 0, when it does and no row has been read: [`for_each_window`] then reads the windows
    /// straight from it ([`direct`]) and calls [`RowSource::raw_read`] instead of `read_rows`.
    fn raw_file(&self) -> Option<(std::path::PathBuf, u64)> {
        None
    }
    /// Every row was read from [`RowSource::raw_file`].
    fn raw_read(&mut self) {}
}

/// A map's rows in memory as a source.
pub struct SliceRows<'a> {
    rows: Rows<'a>,
    next: usize,
}

impl<'a> SliceRows<'a> {
    /// The rows of `image`.
    pub fn new(image: &'a MapImage) -> Self {
        SliceRows {
            rows: Rows::of(image),
            next: 0,
        }
    }
}

impl RowSource for SliceRows<'_> {
    fn width(&self) -> u32 {
        self.rows.width as u32
    }
    fn height(&self) -> u32 {
        self.rows.height as u32
    }
    fn read_rows(&mut self, out: &mut [u8]) -> Result<()> {
        let start = self.next * self.rows.width;
        let src = self
            .rows
            .px
            .get(start..start + out.len())
            .ok_or_else(|| Error::Internal("read past the last row".into()))?;
        out.copy_from_slice(src);
        self.next += out.len() / self.rows.width;
        Ok(())
    }
}

impl RowSource for crate::map::DecoderRows {
    fn width(&self) -> u32 {
        crate::map::DecoderRows::width(self)
    }
    fn height(&self) -> u32 {
        crate::map::DecoderRows::height(self)
    }
    fn read_rows(&mut self, out: &mut [u8]) -> Result<()> {
        crate::map::DecoderRows::read_rows(self, out)
    }
    fn finish(&mut self) -> Result<Vec<String>> {
        crate::map::DecoderRows::finish(self)
    }
    fn raw_file(&self) -> Option<(std::path::PathBuf, u64)> {
        crate::map::DecoderRows::raw_file(self)
    }
    fn raw_read(&mut self) {
        crate::map::DecoderRows::raw_read(self)
    }
}

impl RowSource for crate::map::synthetic::OfficeRows {
    fn width(&self) -> u32 {
        crate::map::synthetic::OfficeRows::width(self)
    }
    fn height(&self) -> u32 {
        crate::map::synthetic::OfficeRows::height(self)
    }
    fn read_rows(&mut self, out: &mut [u8]) -> Result<()> {
        let w = self.width() as usize;
        out.chunks_exact_mut(w)
            .try_for_each(|row| self.next_row(row))
    }
}

/// Writes the rows of `source` as a binary PGM (P5, maxval 255) to `path`, atomically
/// ([`crate::support::files::AtomicFile`]), holding about a megabyte of rows at a time.
pub fn write_pgm(path: &std::path::Path, source: &mut dyn RowSource) -> Result<()> {
    use std::io::Write;
    let (w, h) = (source.width(), source.height());
    let mut file = crate::support::files::AtomicFile::create(path)?;
    let io = |e: std::io::Error| Error::write(path, e);
    crate::map::write_pgm_header(&mut file, w, h).map_err(io)?;
    // Whole rows a megabyte or so at a time: few calls, bounded memory.
    let rows = (((1usize << 20) / w as usize).max(1)).min(h as usize);
    let mut buf = vec![0u8; rows * w as usize];
    let mut y = 0usize;
    while y < h as usize {
        let n = rows.min(h as usize - y);
        let chunk = &mut buf[..n * w as usize];
        source.read_rows(chunk)?;
        file.write_all(chunk).map_err(io)?;
        y += n;
    }
    file.flush().map_err(io)?;
    file.commit()
}

/// Rows of a map the caller looks at: `rows` holds `core` and up to the plan's halo rows around it (fewer at the
/// map's top and bottom).
#[derive(Clone, Copy, Debug)]
pub struct Window<'a> {
    /// The rows held.
    pub rows: Rows<'a>,
    /// The rows this window reports, half-open.
    pub core: (usize, usize),
}

/// How a source is cut into windows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WindowPlan {
    /// Core rows per window (even, at least 2).
    pub core_rows: usize,
    /// Rows held above and below each core (even): [`HALO`], or less for a detector that reads less.
    pub halo: usize,
}

/// Windows in flight at once: one being read, one waiting, one being worked on.
pub const WINDOWS_IN_FLIGHT: u64 = 3;

impl WindowPlan {
    /// Windows of about `bytes` of pixels each (cores of at least 2 rows) for a map `width` wide, with
    /// `halo` rows (rounded up to even) above and below.
    pub fn with_bytes(width: u32, bytes: u64, halo: usize) -> Self {
        let halo = halo + halo % 2;
        let rows = (bytes / u64::from(width.max(1))).saturating_sub(2 * halo as u64);
        let rows = usize::try_from(rows).unwrap_or(usize::MAX / 2).max(2);
        WindowPlan {
            core_rows: rows + rows % 2,
            halo,
        }
    }

    /// Bytes the windows of a `width` x `height` map hold at most: [`WINDOWS_IN_FLIGHT`] windows and the
    /// rows carried from one to the next.
    pub fn bytes(&self, width: u32, height: u32) -> u64 {
        let h = u64::from(height);
        let rows = (self.core_rows as u64 + 2 * self.halo as u64).min(h);
        let carry = (2 * self.halo as u64).min(h);
        (WINDOWS_IN_FLIGHT * rows + carry).saturating_mul(u64::from(width))
    }
}

/// Whether [`for_each_window`] reads raw rasters with `O_DIRECT` where it can: on, unless
/// `OGM_CORNERS_DIRECT_IO=0` (to compare, or for a file system that misbehaves with it).
fn direct_io_wanted() -> bool {
    std::env::var_os("OGM_CORNERS_DIRECT_IO").is_none_or(|v| v != "0")
}

/// Where a window's rows come from: the source's `read_rows`, or its raw file read straight into the
/// window ([`direct`]).
enum Fill<'a> {
    Rows(&'a mut dyn RowSource),
    Raw(RawFile, u64),
}

impl Fill<'_> {
    /// Fills `buf` with map rows `first..end` of a map `w` wide, whose first `kept.len()` bytes are
    /// `kept` (rows the last window held); returns where in `buf` the rows start.
    fn window(
        &mut self,
        buf: &mut AlignedBuf,
        kept: &[u8],
        (first, end): (usize, usize),
        w: usize,
    ) -> Result<usize> {
        let len = (end - first) * w;
        match self {
            Fill::Rows(source) => {
                buf.reserve(len)?;
                let out = &mut buf.bytes_mut()[..len];
                out[..kept.len()].copy_from_slice(kept);
                source.read_rows(&mut out[kept.len()..])?;
                Ok(0)
            }
            Fill::Raw(file, offset) => {
                // The rows start where their file offset's alignment puts them, so that the aligned
                // stretches of the file land on aligned memory; the kept rows are copied in before them.
                let start = *offset + (first * w) as u64;
                // One aligned block ahead of the rows' alignment: room for a direct read to start at the
                // aligned offset below the first byte it needs.
                let at = (start % ALIGN as u64) as usize + ALIGN;
                buf.reserve((at + len).next_multiple_of(ALIGN))?;
                buf.bytes_mut()[at..at + kept.len()].copy_from_slice(kept);
                let from = start + kept.len() as u64;
                if kept.len() < len {
                    file.read(buf, at + kept.len(), from, start + len as u64)?;
                }
                Ok(at)
            }
        }
    }
}

/// Calls `f` on every window of `source`, top to bottom, each core following the last. A reader thread
/// reads the next window while `f` runs; the first error (the source's or `f`'s) stops both and is
/// returned. Returns the source's warnings.
///
/// A source whose file holds the rows as they are ([`RowSource::raw_file`]: a binary 8-bit PGM) is read
/// straight into the windows' aligned buffers ([`direct`]: around the page cache where it does not hold
/// them, no decoder in between).
pub fn for_each_window(
    source: &mut dyn RowSource,
    plan: WindowPlan,
    f: &mut dyn FnMut(Window) -> Result<()>,
) -> Result<Vec<String>> {
    let (w, h) = (source.width() as usize, source.height() as usize);
    if w == 0 || h == 0 {
        return source.finish();
    }
    let raw = match source.raw_file() {
        Some((path, offset)) => Some((RawFile::open(&path, direct_io_wanted())?, offset)),
        None => None,
    };
    type Filled = Result<(AlignedBuf, usize, usize, (usize, usize))>;
    let (tx, rx) = mpsc::sync_channel::<Filled>(1);
    let (back_tx, back_rx) = mpsc::channel::<AlignedBuf>();
    std::thread::scope(|s| {
        let reader = s.spawn(move || -> Result<Vec<String>> {
            let raw_read = raw.is_some();
            let mut fill = match raw {
                Some((file, offset)) => Fill::Raw(file, offset),
                None => Fill::Rows(&mut *source),
            };
            // The rows start under two blocks in (their alignment, and one block for a direct read's
            // aligned start), and a direct read ends at the next block: three blocks of room.
            let largest = (plan.core_rows + 2 * plan.halo).min(h) * w + 3 * ALIGN;
            // Rows already read that the next window starts with: [carry_first, carry_first + carry / w).
            let mut carry: Vec<u8> = Vec::new();
            let mut carry_first = 0usize;
            let mut core0 = 0usize;
            while core0 < h {
                let core1 = (core0 + plan.core_rows).min(h);
                let (first, end) = (core0.saturating_sub(plan.halo), (core1 + plan.halo).min(h));
                // A returned buffer is reused as it is: every byte of the window is written below.
                let mut buf = back_rx.try_recv().unwrap_or_default();
                // Every window's size up front (the largest a window of the plan takes, with room for
                // its alignment): a recycled buffer never grows, so none is reallocated and zeroed again.
                if let Err(e) = buf.reserve(largest) {
                    let _ = tx.send(Err(e));
                    return Ok(Vec::new());
                }
                let kept = &carry[(first - carry_first) * w..];
                let at = match fill.window(&mut buf, kept, (first, end), w) {
                    Ok(at) => at,
                    Err(e) => {
                        let _ = tx.send(Err(e));
                        return Ok(Vec::new());
                    }
                };
                let next_first = core1.saturating_sub(plan.halo);
                carry.clear();
                carry.extend_from_slice(
                    &buf.bytes()[at + (next_first - first) * w..at + (end - first) * w],
                );
                carry_first = next_first;
                if tx.send(Ok((buf, at, first, (core0, core1)))).is_err() {
                    // The caller stopped (its own error): nothing more to read.
                    return Ok(Vec::new());
                }
                core0 = core1;
            }
            drop(tx);
            drop(fill);
            if raw_read {
                source.raw_read();
            }
            source.finish()
        });
        let mut outcome = Ok(());
        while let Ok(filled) = rx.recv() {
            let step = filled.and_then(|(buf, at, first, core)| {
                let end = (core.1 + plan.halo).min(h);
                let rows = Rows::new(&buf.bytes()[at..at + (end - first) * w], w, h, first);
                f(Window { rows, core })?;
                let _ = back_tx.send(buf);
                Ok(())
            });
            if let Err(e) = step {
                outcome = Err(e);
                break;
            }
        }
        drop(rx);
        let warnings = reader
            .join()
            .map_err(|_| Error::Internal("the row reader panicked".into()))?;
        outcome.and(warnings)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every window holds its core and the halo the map has around it, with the right pixels, and the
    /// cores tile the map once, for plans down to the smallest core.
    #[test]
    fn windows_tile_the_map_with_their_halos() {
        let (w, h) = (5u32, 41u32);
        let px: Vec<u8> = (0..w * h).map(|i| (i / w) as u8).collect();
        let image = MapImage::new(w, h, px).unwrap();
        for (core_rows, halo) in [2, 4, 6, 10, 16, 40, 64]
            .into_iter()
            .flat_map(|c| [(c, HALO), (c, OGM_HALO)])
        {
            let mut next = 0;
            let mut src = SliceRows::new(&image);
            for_each_window(&mut src, WindowPlan { core_rows, halo }, &mut |win| {
                assert_eq!(win.core.0, next);
                assert_eq!(win.rows.first(), win.core.0.saturating_sub(halo));
                assert_eq!(win.rows.end(), (win.core.1 + halo).min(h as usize));
                assert_eq!(win.rows.first() % 2, 0);
                for y in win.rows.first()..win.rows.end() {
                    assert!(win.rows.row(y).iter().all(|&v| v as usize == y));
                }
                next = win.core.1;
                Ok(())
            })
            .unwrap();
            assert_eq!(next, h as usize, "core_rows {core_rows}");
        }
    }

    /// An error of the caller stops the reader, and an error of the source reaches the caller.
    #[test]
    fn errors_stop_the_stream() {
        let image = MapImage::filled(4, 100, 7).unwrap();
        let mut calls = 0;
        let e = for_each_window(
            &mut SliceRows::new(&image),
            WindowPlan {
                core_rows: 2,
                halo: HALO,
            },
            &mut |_| {
                calls += 1;
                Err(Error::invalid("stop"))
            },
        )
        .unwrap_err();
        assert_eq!((e.to_string(), calls), ("stop".to_string(), 1));

        struct Broken;
        impl RowSource for Broken {
            fn width(&self) -> u32 {
                3
            }
            fn height(&self) -> u32 {
                50
            }
            fn read_rows(&mut self, _: &mut [u8]) -> Result<()> {
                Err(Error::invalid("truncated"))
            }
        }
        let e = for_each_window(
            &mut Broken,
            WindowPlan {
                core_rows: 2,
                halo: HALO,
            },
            &mut |_| Ok(()),
        );
        assert_eq!(e.unwrap_err().to_string(), "truncated");
    }
}
