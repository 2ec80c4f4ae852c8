//! Strict, bounded-memory, header-first decoding of map images (Netpbm and PNG) into 8-bit grey.
//!
//! [`Decoder::new`] reads only the header; [`Decoder::read_row`] then yields one 8-bit grey row
//! at a time, top to bottom, reading only the bytes that row needs. For every valid input the
//! rows are bit for bit what `image` 0.25.10 gives through
//! `ImageReader::with_guessed_format()?.decode()?` followed by `to_luma8()` (or the raw
//! buffer for 8-bit grey):
//!
//! * 16-bit grey to 8 bits: `(v + 128) / 257` (integer division), that is round(v * 255 / 65535).
//! * Colour to grey: image's sRGB luminance in `f32`. Each channel is expanded to `f32` as
//!   `c as f32 * (1.0 / MAX as f32)` (MAX = 255 or 65535), then
//!   `y = ((0 + r * KR) + g * KG) + b * KB` with the coefficients moxcms derives for BT.709
//!   primaries and a D65 white point (KR = 0.21264784, KG = 0.7151792, KB = 0.07217304, exact
//!   `f32` bit patterns below), each step fused (`mul_add`) where image fuses it (x86 with the
//!   `fma` target feature, aarch64 with `neon`); the grey value is `(y * 255.0).round() as u8`.
//! * Alpha and tRNS transparency are dropped.
//! * PNG grey of 1, 2 or 4 bits is scaled by 255, 85 or 17 (png's EXPAND transformation).
//! * PNG palette images become the luminance (as above) of the palette entry's RGB.
//! * Netpbm samples for a maxval other than 255 (8-bit) or 65535 (16-bit) are first scaled as
//!   image's pnm decoder does: `(v as f32 * (T as f32 / maxval as f32)).round()` with T = 255
//!   for maxval <= 255 and T = 65535 above; 16-bit results then go to 8 bits as above.
//! * PBM bits: 1 (black) is 0, 0 (white) is 255.
//!
//! Where the project's old path silently accepted bad data, this decoder refuses it with a
//! one-line error: Netpbm samples above maxval, PNG palette indices past the palette's end, and
//! truncated rasters. Errors never contain a newline, and no byte string makes it panic.

mod pgm;
mod png;

use std::io::{self, BufRead, Read, Seek, SeekFrom};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// Which image format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageKind {
    /// Netpbm: PGM (P2, P5), and also PBM (P1, P4) and PPM (P3, P6), which the old path decoded
    /// as well. PAM (P7) is refused.
    Pgm,
    /// PNG, any colour type and bit depth, interlaced or not.
    Png,
}

/// What the header says, known before any pixel is read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Header {
    /// The format found from the content (or, without a magic number, from the hint).
    pub kind: ImageKind,
    /// Width in pixels (at least 1).
    pub width: u32,
    /// Height in pixels (at least 1).
    pub height: u32,
    /// Bytes the decoder itself allocates beyond the caller's 8-bit output (row buffers; a whole
    /// raw frame for interlaced PNG).
    ///
    /// For Netpbm this is the sample lookup table (at most 192 KiB); rows are converted straight
    /// from the reader's buffer. For PNG it is the raw row buffer, for Adam7 images a whole 8-bit
    /// grey frame (width * height) plus one grey row, plus an estimate of the png crate's own
    /// working set (a few raw rows and its inflate buffers).
    pub decoder_bytes: u64,
    /// Whether decoding holds the whole image (an interlaced PNG: its seven passes cover every row), so
    /// that it cannot be streamed in bounded memory.
    pub whole_image: bool,
}

/// Most pixels an image decoded into memory may have: 2^32, a 65536 x 65536 map ([`check_in_memory`]).
/// A map read row by row ([`crate::map::stream`]) has no such limit: only its width and height, each below
/// 2^32 (keypoint coordinates are `u32`), bound it.
pub const MAX_PIXELS: u64 = 1 << 32;

/// Refuses an image of more than [`MAX_PIXELS`] pixels, for paths that hold it whole in memory.
pub fn check_in_memory(width: u32, height: u32) -> Result<(), String> {
    if u64::from(width) * u64::from(height) > MAX_PIXELS {
        return Err(format!(
            "image of {width}x{height} exceeds {MAX_PIXELS} pixels (detect reads larger maps row by row)"
        ));
    }
    Ok(())
}

/// A header-first, row-by-row decoder of one image.
pub struct Decoder<R: BufRead> {
    header: Header,
    inner: Inner<R>,
    rows_done: u32,
}

enum Inner<R: BufRead> {
    Pnm(pgm::PnmDecoder<R>),
    Png(Box<png::PngDecoder<R>>),
}

impl<R: BufRead> Decoder<R> {
    /// Reads the header only. `len`: total length of the input in bytes when known (a regular file's size); `hint`: the kind the file name suggests, used only when the content has no magic number. `max_decoder_bytes` bounds what the png crate may allocate (png::Limits).
    ///
    /// `max_decoder_bytes` also bounds this decoder's own buffers (see
    /// [`Header::decoder_bytes`]); an image that needs more is refused here, before any pixel is
    /// read. For PNG the header is everything up to the first image data chunk.
    pub fn new(
        reader: R,
        len: Option<u64>,
        hint: Option<ImageKind>,
        max_decoder_bytes: u64,
    ) -> Result<Self, String> {
        let (src, magic) = Source::new(reader)?;
        if magic.is_empty() {
            return Err("empty file".into());
        }
        let kind = if magic.starts_with(PNG_SIGNATURE) {
            ImageKind::Png
        } else if magic.len() >= 2 && magic[0] == b'P' && (b'1'..=b'7').contains(&magic[1]) {
            ImageKind::Pgm
        } else {
            match hint {
                Some(kind) => kind,
                None => return Err("unknown image format: expected PGM (P2/P5) or PNG".into()),
            }
        };
        let (inner, header) = match kind {
            ImageKind::Pgm => {
                let d = pgm::PnmDecoder::new(src, len, max_decoder_bytes)?;
                let h = d.header();
                (Inner::Pnm(d), h)
            }
            ImageKind::Png => {
                let d = png::PngDecoder::new(src, len, max_decoder_bytes)?;
                let h = d.header();
                (Inner::Png(Box::new(d)), h)
            }
        };
        Ok(Decoder {
            header,
            inner,
            rows_done: 0,
        })
    }

    /// What the header says.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Decodes the next row (top to bottom) as 8-bit grey into `out` (out.len() == width). Errors on truncation/corruption with a one-line message.
    ///
    /// Calling it again after the last row, or with a wrong-sized `out`, is an error.
    pub fn read_row(&mut self, out: &mut [u8]) -> Result<(), String> {
        if out.len() as u64 != u64::from(self.header.width) {
            return Err(format!(
                "row buffer of {} bytes for an image {} pixels wide",
                out.len(),
                self.header.width
            ));
        }
        if self.rows_done >= self.header.height {
            return Err(format!("all {} rows were already read", self.header.height));
        }
        let y = self.rows_done;
        match &mut self.inner {
            Inner::Pnm(d) => d.read_row(y, out)?,
            Inner::Png(d) => d.read_row(y, out)?,
        }
        self.rows_done += 1;
        Ok(())
    }

    /// Decodes the next rows (top to bottom, `out.len() / width` of them) into `out`, as
    /// [`Decoder::read_row`] does one by one. An 8-bit PGM whose samples are their own grey levels
    /// (maxval 255, the ROS maps) is read in one piece straight into `out`: one copy from the
    /// operating system, so a map streamed from disk is read at the disk's speed.
    pub fn read_rows(&mut self, out: &mut [u8]) -> Result<(), String> {
        let w = self.header.width as usize;
        let rows = out.len() / w.max(1);
        if rows * w != out.len() {
            return Err(format!(
                "row buffer of {} bytes for an image {} pixels wide",
                out.len(),
                self.header.width
            ));
        }
        if rows as u64 > u64::from(self.header.height - self.rows_done) {
            return Err(format!(
                "{rows} rows asked for, {} left",
                self.header.height - self.rows_done
            ));
        }
        if let Inner::Pnm(d) = &mut self.inner {
            if d.read_raw_rows(self.rows_done, out)? {
                self.rows_done += rows as u32;
                return Ok(());
            }
        }
        for row in out.chunks_exact_mut(w) {
            self.read_row(row)?;
        }
        Ok(())
    }

    /// The byte offset in the input where the raster starts, when its bytes are the image's rows as they
    /// are (a binary PGM with maxval 255, the ROS maps) and no row has been read: a caller may then read
    /// them straight from the file ([`crate::map::stream`] does, into its windows) and call
    /// [`Decoder::raster_read_elsewhere`].
    pub fn raw_raster(&self) -> Option<u64> {
        match &self.inner {
            Inner::Pnm(d) if self.rows_done == 0 => d.raw_raster(),
            _ => None,
        }
    }

    /// Every row was read from the file by the caller ([`Decoder::raw_raster`]): [`Decoder::finish`]
    /// then checks what follows the raster as if this decoder had read it.
    pub fn raster_read_elsewhere(&mut self) {
        if let Inner::Pnm(d) = &mut self.inner {
            d.raster_read_elsewhere();
            self.rows_done = self.header.height;
        }
    }

    /// Call after the last row: warnings (e.g. trailing bytes ignored).
    ///
    /// Fails when rows are left unread, or when the end of the PNG image data is damaged (the old
    /// path refused those too). Trailing data after the raster (Netpbm, binary types) or after
    /// the PNG end chunk is counted when the input length is known, never read.
    pub fn finish(self) -> Result<Vec<String>, String> {
        if self.rows_done < self.header.height {
            return Err(format!(
                "finished after {} of {} rows",
                self.rows_done, self.header.height
            ));
        }
        match self.inner {
            Inner::Pnm(d) => d.finish(),
            Inner::Png(d) => d.finish(),
        }
    }
}

/// Convenience: whole image into one Vec (w*h bytes), for inputs in memory.
///
/// Returns width, height, the row-major pixels (row 0 at the top) and the warnings of
/// [`Decoder::finish`].
pub fn decode_bytes(
    bytes: &[u8],
    hint: Option<ImageKind>,
    max_decoder_bytes: u64,
) -> Result<(u32, u32, Vec<u8>, Vec<String>), String> {
    let mut dec = Decoder::new(bytes, Some(bytes.len() as u64), hint, max_decoder_bytes)?;
    let (w, h) = (dec.header().width, dec.header().height);
    check_in_memory(w, h)?;
    let n = usize::try_from(u64::from(w) * u64::from(h))
        .map_err(|_| format!("image of {w}x{h} does not fit in memory here"))?;
    let mut pixels = Vec::new();
    pixels
        .try_reserve_exact(n)
        .map_err(|_| format!("cannot allocate {n} bytes for a {w}x{h} image"))?;
    pixels.resize(n, 0);
    if n > 0 {
        dec.read_rows(&mut pixels)?;
    }
    let warnings = dec.finish()?;
    Ok((w, h, pixels, warnings))
}

const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

/// Checks the size rules shared by both formats (the pixel count is [`check_in_memory`]'s, for the
/// paths that need it).
fn check_size(width: u32, height: u32) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("zero-size image ({width}x{height})"));
    }
    Ok(())
}

/// Makes any message one line: errors from png and io may embed newlines.
fn one_line(s: &str) -> String {
    s.split(['\n', '\r'])
        .filter(|p| !p.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

/// The warning for bytes left after the image, when the input length is known.
fn trailing_warning(len: Option<u64>, pos: u64) -> Option<String> {
    match len {
        Some(len) if len > pos => {
            let n = len - pos;
            let unit = if n == 1 { "byte" } else { "bytes" };
            Some(format!("{n} {unit} after the image data ignored"))
        }
        _ => None,
    }
}

// --- Conversions, each matching image 0.25.10 exactly (see the module doc). ---

/// moxcms' BT.709 / D65 luminance row, the coefficients image uses for sRGB images.
const KR: f32 = f32::from_bits(0x3e59_c05b);
const KG: f32 = f32::from_bits(0x3f37_15fc);
const KB: f32 = f32::from_bits(0x3d93_cf75);

/// image's `multiply_accumulate`: fused where image compiles it fused.
#[cfg(any(
    all(
        any(target_arch = "x86", target_arch = "x86_64"),
        target_feature = "fma"
    ),
    all(target_arch = "aarch64", target_feature = "neon")
))]
#[inline(always)]
fn mac(acc: f32, a: f32, b: f32) -> f32 {
    a.mul_add(b, acc)
}

#[cfg(not(any(
    all(
        any(target_arch = "x86", target_arch = "x86_64"),
        target_feature = "fma"
    ),
    all(target_arch = "aarch64", target_feature = "neon")
)))]
#[inline(always)]
fn mac(acc: f32, a: f32, b: f32) -> f32 {
    acc + a * b
}

#[inline]
fn luma_f32(r: f32, g: f32, b: f32) -> u8 {
    let mut y = 0.0f32;
    y = mac(y, r, KR);
    y = mac(y, g, KG);
    y = mac(y, b, KB);
    // Saturating float-to-int cast does the clamp, as in image.
    (y * 255.0).round() as u8
}

/// 8-bit RGB to grey as image's `to_luma8` does it.
#[inline]
pub(crate) fn rgb8_to_grey(r: u8, g: u8, b: u8) -> u8 {
    const S: f32 = 1.0 / 255.0;
    luma_f32(r as f32 * S, g as f32 * S, b as f32 * S)
}

/// 16-bit RGB to 8-bit grey as image's `to_luma8` does it.
#[inline]
pub(crate) fn rgb16_to_grey(r: u16, g: u16, b: u16) -> u8 {
    const S: f32 = 1.0 / 65535.0;
    luma_f32(r as f32 * S, g as f32 * S, b as f32 * S)
}

/// 16-bit grey to 8 bits, image's `FromPrimitive<u16> for u8`.
#[inline]
pub(crate) fn grey16_to_grey8(v: u16) -> u8 {
    ((u32::from(v) + 128) / 257) as u8
}

// --- The byte source shared by both decoders. ---

/// Position bookkeeping shared with the png crate's reader, which hides its inner reader.
#[derive(Default)]
struct Shared {
    /// Bytes consumed so far.
    pos: AtomicU64,
    /// Reads stop (report end of input) at this position.
    limit: AtomicU64,
    /// Set when a read was cut short by `limit`.
    hit_limit: AtomicBool,
}

/// A `BufRead` that first replays the magic bytes read for format detection, counts what is
/// consumed, and can be capped at a position. Its `Seek` only reports the position: png needs
/// the bound but never seeks.
pub(crate) struct Source<R> {
    inner: R,
    prefix: [u8; 8],
    pre_start: usize,
    pre_end: usize,
    shared: Arc<Shared>,
}

impl<R: BufRead> Source<R> {
    /// Wraps `inner` and reads up to 8 bytes of magic (returned, and replayed later).
    fn new(mut inner: R) -> Result<(Self, Vec<u8>), String> {
        let mut prefix = [0u8; 8];
        let mut n = 0;
        while n < prefix.len() {
            let buf = match inner.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(io_error(&e)),
            };
            if buf.is_empty() {
                break;
            }
            let k = buf.len().min(prefix.len() - n);
            prefix[n..n + k].copy_from_slice(&buf[..k]);
            inner.consume(k);
            n += k;
        }
        let shared = Shared {
            limit: AtomicU64::new(u64::MAX),
            ..Shared::default()
        };
        let src = Source {
            inner,
            prefix,
            pre_start: 0,
            pre_end: n,
            shared: Arc::new(shared),
        };
        Ok((src, prefix[..n].to_vec()))
    }

    /// Bytes consumed so far.
    pub(crate) fn pos(&self) -> u64 {
        self.shared.pos.load(Ordering::Relaxed)
    }

    fn handle(&self) -> Arc<Shared> {
        Arc::clone(&self.shared)
    }

    /// Fills as much of `out` as the input holds (up to the cap), returning how much: the buffered bytes
    /// first, then reads straight into `out` (a `BufReader` hands a large read to the file directly).
    pub(crate) fn read_bulk(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let mut n = 0;
        while n < out.len() {
            let pos = self.shared.pos.load(Ordering::Relaxed);
            let limit = self.shared.limit.load(Ordering::Relaxed);
            let room = usize::try_from(limit.saturating_sub(pos)).unwrap_or(usize::MAX);
            if room == 0 {
                self.shared.hit_limit.store(true, Ordering::Relaxed);
                break;
            }
            let end = out.len().min(n.saturating_add(room));
            let k = if self.pre_start < self.pre_end {
                let k = (self.pre_end - self.pre_start).min(end - n);
                out[n..n + k].copy_from_slice(&self.prefix[self.pre_start..self.pre_start + k]);
                self.pre_start += k;
                k
            } else {
                match self.inner.read(&mut out[n..end]) {
                    Ok(0) => break,
                    Ok(k) => k,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(e) => return Err(e),
                }
            };
            self.shared.pos.fetch_add(k as u64, Ordering::Relaxed);
            n += k;
        }
        Ok(n)
    }

    /// The next byte, consumed; `None` at the end of input.
    pub(crate) fn next_byte(&mut self) -> Result<Option<u8>, String> {
        let b = self.peek_byte()?;
        if b.is_some() {
            self.consume(1);
        }
        Ok(b)
    }

    /// The next byte, not consumed.
    pub(crate) fn peek_byte(&mut self) -> Result<Option<u8>, String> {
        let buf = self.fill_buf().map_err(|e| io_error(&e))?;
        Ok(buf.first().copied())
    }
}

fn io_error(e: &io::Error) -> String {
    one_line(&format!("cannot read: {e}"))
}

impl<R: BufRead> BufRead for Source<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        let pos = self.shared.pos.load(Ordering::Relaxed);
        let limit = self.shared.limit.load(Ordering::Relaxed);
        let room = usize::try_from(limit.saturating_sub(pos)).unwrap_or(usize::MAX);
        if room == 0 {
            self.shared.hit_limit.store(true, Ordering::Relaxed);
            return Ok(&[]);
        }
        if self.pre_start < self.pre_end {
            let end = self.pre_end.min(self.pre_start.saturating_add(room));
            return Ok(&self.prefix[self.pre_start..end]);
        }
        // Retry interrupted reads here so callers (png included) never see them. Two calls
        // because a borrow returned from inside the loop would outlive it.
        loop {
            match self.inner.fill_buf() {
                Ok(_) => break,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            }
        }
        let buf = self.inner.fill_buf()?;
        Ok(&buf[..buf.len().min(room)])
    }

    fn consume(&mut self, amt: usize) {
        if self.pre_start < self.pre_end {
            debug_assert!(amt <= self.pre_end - self.pre_start);
            self.pre_start += amt.min(self.pre_end - self.pre_start);
        } else {
            self.inner.consume(amt);
        }
        self.shared.pos.fetch_add(amt as u64, Ordering::Relaxed);
    }
}

impl<R: BufRead> Read for Source<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let buf = self.fill_buf()?;
        let n = buf.len().min(out.len());
        out[..n].copy_from_slice(&buf[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> Seek for Source<R> {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        match pos {
            SeekFrom::Current(0) => Ok(self.pos()),
            _ => Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "the image source cannot seek",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_strips_newlines() {
        assert_eq!(one_line("a\nb\r\nc"), "a b c");
    }

    #[test]
    fn grey16_matches_rounding() {
        for v in 0..=u16::MAX {
            let want = (f64::from(v) * 255.0 / 65535.0).round() as u8;
            assert_eq!(grey16_to_grey8(v), want, "{v}");
        }
    }

    #[test]
    fn source_replays_prefix_and_caps() {
        let data: &[u8] = b"0123456789abcdef";
        let (mut src, magic) = Source::new(data).unwrap();
        assert_eq!(magic, b"01234567");
        let mut all = Vec::new();
        src.read_to_end(&mut all).unwrap();
        assert_eq!(all, data);
        assert_eq!(src.pos(), 16);

        let (mut src, _) = Source::new(data).unwrap();
        src.shared.limit.store(10, Ordering::Relaxed);
        let mut all = Vec::new();
        src.read_to_end(&mut all).unwrap();
        assert_eq!(all, &data[..10]);
        assert!(src.shared.hit_limit.load(Ordering::Relaxed));
    }
}
