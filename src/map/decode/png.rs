//! PNG, row by row, through the png crate.
//!
//! Non-palette images are decoded with png's EXPAND transformation, as image does, and each
//! row is converted to grey as image's `to_luma8` would. Palette images are decoded without it:
//! the raw indices are unpacked here, each is checked against the palette's length (png would
//! turn an index past the end into black), and mapped to the luminance of the palette RGB.
//!
//! Non-interlaced images go through png's row API, one row per call. Adam7 images need all seven
//! passes before the first full row exists, so the first `read_row` decodes every pass, converting
//! each pass row to grey straight away into a width * height grey frame (one byte a pixel, not
//! the raw frame's up to eight).

use std::io::BufRead;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use png::{BitDepth, ColorType, Transformations};

use super::{
    check_size, grey16_to_grey8, one_line, rgb16_to_grey, rgb8_to_grey, trailing_warning, Header,
    ImageKind, Shared, Source,
};

/// How far past the image data `finish` looks for the end chunk, to report trailing bytes.
const END_SEARCH_BYTES: u64 = 1 << 20;

/// Rough working set of png itself: its unfiltering buffer and inflate state.
const PNG_WORKING_BYTES: u64 = 320 * 1024;

/// The layout of the rows png hands out.
#[derive(Clone, Copy)]
enum Layout {
    /// Grey (first of `ch` channels), 8 bits.
    Grey8 { ch: usize },
    /// Grey (first of `ch` channels), 16 bits big-endian.
    Grey16 { ch: usize },
    /// RGB (first three of `ch` channels), 8 bits.
    Rgb8 { ch: usize },
    /// RGB (first three of `ch` channels), 16 bits big-endian.
    Rgb16 { ch: usize },
    /// Palette indices of 1, 2, 4 or 8 bits, packed most significant first.
    Indexed { bits: u8 },
}

/// Decoder state for one PNG image.
pub(crate) struct PngDecoder<R: BufRead> {
    reader: png::Reader<Source<R>>,
    shared: Arc<Shared>,
    width: u32,
    height: u32,
    layout: Layout,
    /// Grey value of each palette entry.
    palette: Vec<u8>,
    /// One raw row as png outputs it.
    row: Vec<u8>,
    interlaced: bool,
    /// Adam7 only: the whole image in grey, filled by the first `read_row`.
    frame: Vec<u8>,
    len: Option<u64>,
    decoder_bytes: u64,
}

fn png_error(e: &png::DecodingError) -> String {
    one_line(&format!("cannot decode PNG: {e}"))
}

/// Allocates `n` zeroed bytes, failing instead of aborting.
fn alloc(n: usize, what: &str) -> Result<Vec<u8>, String> {
    let mut v = Vec::new();
    v.try_reserve_exact(n)
        .map_err(|_| format!("cannot allocate {n} bytes for {what}"))?;
    v.resize(n, 0);
    Ok(v)
}

impl<R: BufRead> PngDecoder<R> {
    /// Reads the signature and every chunk before the image data.
    pub(crate) fn new(
        src: Source<R>,
        len: Option<u64>,
        max_decoder_bytes: u64,
    ) -> Result<Self, String> {
        let shared = src.handle();
        let limits = png::Limits {
            bytes: usize::try_from(max_decoder_bytes).unwrap_or(usize::MAX),
        };
        let mut dec = png::Decoder::new_with_limits(src, limits);
        // Metadata the map does not use is skipped, not decompressed: a compressed colour profile (iCCP)
        // or text chunk can hold a gigabyte in a megabyte (a bomb in a 20 x 10 map).
        dec.set_ignore_text_chunk(true);
        dec.set_ignore_iccp_chunk(true);
        let info = dec.read_header_info().map_err(|e| png_error(&e))?;
        let (width, height) = (info.width, info.height);
        check_size(width, height)?;
        let indexed = info.color_type == ColorType::Indexed;
        dec.set_transformations(if indexed {
            Transformations::IDENTITY
        } else {
            Transformations::EXPAND
        });
        let reader = dec.read_info().map_err(|e| png_error(&e))?;
        let info = reader.info();
        if let Some(fc) = info.frame_control {
            // png checks this too; the row API would otherwise yield a smaller frame.
            if (fc.width, fc.height, fc.x_offset, fc.y_offset) != (width, height, 0, 0) {
                return Err(
                    "cannot decode PNG: the APNG default frame does not cover the image".into(),
                );
            }
        }
        let interlaced = info.interlaced;
        let (color, depth) = reader.output_color_type();
        let ch = color.samples();
        let layout = match (color, depth) {
            (
                ColorType::Indexed,
                d @ (BitDepth::One | BitDepth::Two | BitDepth::Four | BitDepth::Eight),
            ) => Layout::Indexed { bits: d as u8 },
            (ColorType::Grayscale | ColorType::GrayscaleAlpha, BitDepth::Eight) => {
                Layout::Grey8 { ch }
            }
            (ColorType::Grayscale | ColorType::GrayscaleAlpha, BitDepth::Sixteen) => {
                Layout::Grey16 { ch }
            }
            (ColorType::Rgb | ColorType::Rgba, BitDepth::Eight) => Layout::Rgb8 { ch },
            (ColorType::Rgb | ColorType::Rgba, BitDepth::Sixteen) => Layout::Rgb16 { ch },
            (c, d) => {
                return Err(format!(
                    "cannot decode PNG: unexpected output {c:?} at {} bits",
                    d as u8
                ))
            }
        };
        let palette = if indexed {
            match info.palette.as_deref() {
                Some(p) => p
                    .chunks_exact(3)
                    .map(|c| rgb8_to_grey(c[0], c[1], c[2]))
                    .collect(),
                None => return Err("cannot decode PNG: palette image without a PLTE chunk".into()),
            }
        } else {
            Vec::new()
        };

        let row_len = reader
            .output_line_size(width)
            .ok_or_else(|| format!("PNG rows of {width} pixels do not fit in memory here"))?;
        let frame_len = if interlaced {
            // The grey frame plus one grey pass row.
            u64::from(width) * u64::from(height) + u64::from(width)
        } else {
            0
        };
        let own = row_len as u64 + frame_len + palette.len() as u64;
        if own > max_decoder_bytes {
            return Err(format!(
                "decoding this {}PNG needs {own} bytes of buffers, above the limit of {max_decoder_bytes}",
                if interlaced { "interlaced " } else { "" }
            ));
        }
        let row = alloc(row_len, "a PNG row")?;
        let decoder_bytes = own + 6 * row_len as u64 + PNG_WORKING_BYTES;
        Ok(PngDecoder {
            reader,
            shared,
            width,
            height,
            layout,
            palette,
            row,
            interlaced,
            frame: Vec::new(),
            len,
            decoder_bytes,
        })
    }

    pub(crate) fn header(&self) -> Header {
        Header {
            kind: ImageKind::Png,
            width: self.width,
            height: self.height,
            decoder_bytes: self.decoder_bytes,
            whole_image: self.interlaced,
        }
    }

    fn palette_error(&self, index: u8, x: u64, y: u64) -> String {
        format!(
            "PNG palette index {index} at row {y}, column {x} is past the end of the {}-entry palette",
            self.palette.len()
        )
    }

    /// Decodes row `y` into `out` (width bytes).
    pub(crate) fn read_row(&mut self, y: u32, out: &mut [u8]) -> Result<(), String> {
        if self.interlaced {
            if y == 0 {
                self.decode_adam7()?;
            }
            let w = self.width as usize;
            let start = y as usize * w;
            out.copy_from_slice(&self.frame[start..start + w]);
            return Ok(());
        }
        match self.reader.read_row(&mut self.row) {
            Ok(Some(_)) => {}
            Ok(None) => {
                return Err(format!(
                    "cannot decode PNG: the image data ends after {y} of {} rows",
                    self.height
                ))
            }
            Err(e) => return Err(png_error(&e)),
        }
        let n = out.len();
        convert(self.layout, &self.row, out, &self.palette, n)
            .map_err(|(i, idx)| self.palette_error(idx, i as u64, u64::from(y)))
    }

    /// Decodes all seven passes into the grey frame.
    fn decode_adam7(&mut self) -> Result<(), String> {
        let (w, h) = (self.width, self.height);
        self.frame = alloc(w as usize * h as usize, "the interlaced PNG frame")?;
        let mut grey = alloc(w as usize, "a PNG pass row")?;
        // (x step, x offset, y step, y offset) of Adam7 passes 1 to 7.
        const PASSES: [(u32, u32, u32, u32); 7] = [
            (8, 0, 8, 0),
            (8, 4, 8, 0),
            (4, 0, 8, 4),
            (4, 2, 4, 0),
            (2, 0, 4, 2),
            (2, 1, 2, 0),
            (1, 0, 2, 1),
        ];
        for (p, &(dx, x0, dy, y0)) in PASSES.iter().enumerate() {
            let samples = w.saturating_sub(x0).div_ceil(dx);
            let lines = h.saturating_sub(y0).div_ceil(dy);
            if samples == 0 {
                continue;
            }
            for line in 0..lines {
                match self.reader.read_row(&mut self.row) {
                    Ok(Some(png::InterlaceInfo::Adam7(info)))
                        if info == png::Adam7Info::new(p as u8 + 1, line, w) => {}
                    Ok(Some(_)) => {
                        return Err("cannot decode PNG: unexpected interlace pass order".into())
                    }
                    Ok(None) => {
                        return Err(format!(
                            "cannot decode PNG: the image data ends in interlace pass {}",
                            p + 1
                        ))
                    }
                    Err(e) => return Err(png_error(&e)),
                }
                let n = samples as usize;
                let yy = y0 + line * dy;
                if let Err((i, idx)) =
                    convert(self.layout, &self.row, &mut grey[..n], &self.palette, n)
                {
                    let x = u64::from(x0) + i as u64 * u64::from(dx);
                    return Err(self.palette_error(idx, x, u64::from(yy)));
                }
                let base = yy as usize * w as usize;
                for (i, &g) in grey[..n].iter().enumerate() {
                    self.frame[base + x0 as usize + i * dx as usize] = g;
                }
            }
        }
        Ok(())
    }

    /// Ends the image data as image does (an error there was an error before too), then looks a
    /// bounded distance for the end chunk to count trailing bytes; trouble there only warns.
    pub(crate) fn finish(mut self) -> Result<Vec<String>, String> {
        match self.reader.read_row(&mut self.row) {
            Ok(None) => {}
            Ok(Some(_)) => {
                return Err("cannot decode PNG: more image rows than the header says".into())
            }
            Err(e) => return Err(png_error(&e)),
        }
        let pos = self.shared.pos.load(Ordering::Relaxed);
        self.shared
            .limit
            .store(pos.saturating_add(END_SEARCH_BYTES), Ordering::Relaxed);
        let mut warnings = Vec::new();
        match self.reader.finish() {
            Ok(()) => {
                let end = self.shared.pos.load(Ordering::Relaxed);
                warnings.extend(trailing_warning(self.len, end));
            }
            Err(_) if self.shared.hit_limit.load(Ordering::Relaxed) => warnings.push(format!(
                "PNG end chunk not found within {END_SEARCH_BYTES} bytes after the image data; the rest was not read"
            )),
            Err(e) => warnings.push(one_line(&format!(
                "damaged PNG data after the image ignored: {e}"
            ))),
        }
        Ok(warnings)
    }
}

/// Converts the first `n` pixels of a raw row to grey. Err((pixel, index)) for a palette index
/// past the palette's end.
fn convert(
    layout: Layout,
    row: &[u8],
    out: &mut [u8],
    palette: &[u8],
    n: usize,
) -> Result<(), (usize, u8)> {
    let out = &mut out[..n];
    match layout {
        Layout::Grey8 { ch } => {
            for (o, p) in out.iter_mut().zip(row.chunks_exact(ch)) {
                *o = p[0];
            }
        }
        Layout::Grey16 { ch } => {
            for (o, p) in out.iter_mut().zip(row.chunks_exact(2 * ch)) {
                *o = grey16_to_grey8(u16::from_be_bytes([p[0], p[1]]));
            }
        }
        Layout::Rgb8 { ch } => {
            for (o, p) in out.iter_mut().zip(row.chunks_exact(ch)) {
                *o = rgb8_to_grey(p[0], p[1], p[2]);
            }
        }
        Layout::Rgb16 { ch } => {
            for (o, p) in out.iter_mut().zip(row.chunks_exact(2 * ch)) {
                let c = |i: usize| u16::from_be_bytes([p[2 * i], p[2 * i + 1]]);
                *o = rgb16_to_grey(c(0), c(1), c(2));
            }
        }
        Layout::Indexed { bits } => {
            let per_byte = 8 / bits as usize;
            let mask = ((1u16 << bits) - 1) as u8;
            for (i, o) in out.iter_mut().enumerate() {
                let byte = row[i / per_byte];
                let shift = 8 - bits as usize * (i % per_byte + 1);
                let idx = (byte >> shift) & mask;
                *o = *palette.get(idx as usize).ok_or((i, idx))?;
            }
        }
    }
    Ok(())
}
