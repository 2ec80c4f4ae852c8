//! Netpbm: PGM (P2, P5), PBM (P1, P4) and PPM (P3, P6), row by row.
//!
//! # Header
//!
//! The header is read as image 0.25.10 reads it, so that valid files decode identically: the
//! magic number, then width, height and (except for PBM) maxval as unsigned decimal numbers
//! (leading zeros allowed, no sign). Any run of whitespace (space, `\t`, `\r`, `\n`, `\x0b`,
//! `\x0c`) may stand between tokens, and comments may stand anywhere before the last token's
//! terminating byte: a comment runs from `#` through the next `\r` or `\n`, and is removed from
//! the byte stream entirely, that terminating byte included (so `20#x\n 20` is `20 20`, but
//! `2#x\n0` is `20`).
//!
//! # Where the raster starts (CRLF headers)
//!
//! The netpbm spec says exactly ONE whitespace byte follows the last header number (maxval, or
//! height for PBM), and the binary raster starts right after it. Files written on Windows often
//! end the header with `\r\n`, which under that rule makes the `\n` the first raster byte and
//! shifts the whole map by one pixel. So, when the byte after the last number is `\r`, the next is
//! `\n` and the input's total length is known: if exactly the raster follows the `\n`, the pair
//! `\r\n` is the separator; if exactly the raster follows the `\r`, the spec reading stands (the
//! `\n` is the first pixel); if more follows (data after the raster), both readings fit and either
//! could shift the map, so the file is refused rather than guessed. With the length unknown the spec
//! reading stands. ASCII rasters (P1, P2, P3) are unaffected: whitespace before their samples is
//! skipped anyway.
//!
//! # Raster
//!
//! Binary samples are 1 byte for maxval <= 255 and 2 bytes big-endian above. A sample above
//! maxval is an error naming value, maxval, row and column (counted from 0). ASCII samples are
//! decimal tokens separated by whitespace; a token that is not all digits, or whose value exceeds
//! 65535 (more than 5 significant digits), is an error; leading zeros are allowed, as in image
//! and netpbm. PBM rows are packed 8 pixels a byte, most significant bit first, padded to a whole
//! byte; 1 is black. Exactly the raster's bytes are read; for binary types anything after it is
//! only counted (when the input length is known) and reported by `finish`.

use std::io::BufRead;

use super::{
    check_size, grey16_to_grey8, io_error, rgb16_to_grey, rgb8_to_grey, trailing_warning, Header,
    ImageKind, Source,
};

#[derive(Clone, Copy, PartialEq, Eq)]
enum Family {
    Pbm,
    Pgm,
    Ppm,
}

impl Family {
    fn name(self) -> &'static str {
        match self {
            Family::Pbm => "PBM",
            Family::Pgm => "PGM",
            Family::Ppm => "PPM",
        }
    }
}

fn is_space(b: u8) -> bool {
    matches!(b, b'\t' | b'\n' | b'\x0b' | b'\x0c' | b'\r' | b' ')
}

/// Decoder state for one Netpbm image.
pub(crate) struct PnmDecoder<R> {
    src: Source<R>,
    family: Family,
    binary: bool,
    width: u32,
    height: u32,
    maxval: u32,
    /// Two bytes a sample (maxval > 255).
    wide: bool,
    /// Sample (0..=maxval) to the value image holds after its maxval scaling (8 or 16 bits).
    scaled: Vec<u16>,
    /// PGM only: sample to final grey.
    grey: Vec<u8>,
    len: Option<u64>,
    /// Raster bytes read by someone else ([`PnmDecoder::raster_read_elsewhere`]).
    raw_elsewhere: u64,
}

impl<R: BufRead> PnmDecoder<R> {
    /// Reads the magic number and header; leaves the source at the first raster byte.
    pub(crate) fn new(
        mut src: Source<R>,
        len: Option<u64>,
        max_decoder_bytes: u64,
    ) -> Result<Self, String> {
        let m0 = src.next_byte()?;
        let m1 = src.next_byte()?;
        let (family, binary) = match (m0, m1) {
            (Some(b'P'), Some(b'1')) => (Family::Pbm, false),
            (Some(b'P'), Some(b'2')) => (Family::Pgm, false),
            (Some(b'P'), Some(b'3')) => (Family::Ppm, false),
            (Some(b'P'), Some(b'4')) => (Family::Pbm, true),
            (Some(b'P'), Some(b'5')) => (Family::Pgm, true),
            (Some(b'P'), Some(b'6')) => (Family::Ppm, true),
            (Some(b'P'), Some(b'7')) => {
                return Err("unsupported PNM type P7 (PAM): expected PGM (P2 or P5) or PNG".into())
            }
            _ => return Err("not a PGM file: no P2/P5 magic number".into()),
        };
        let name = family.name();
        let width = read_header_u32(&mut src, name, "width")?.0;
        let (height, mut last) = read_header_u32(&mut src, name, "height")?;
        let maxval = if family == Family::Pbm {
            1
        } else {
            let (m, t) = read_header_u32(&mut src, name, "maxval")?;
            last = t;
            m
        };
        if maxval == 0 {
            return Err(format!("{name} maxval is 0"));
        }
        if maxval > 0xFFFF {
            return Err(format!("{name} maxval {maxval} exceeds 65535"));
        }
        check_size(width, height)?;
        let wide = maxval > 0xFF;

        if binary {
            let raster = raster_bytes(family, width, height, wide);
            if last == Some(b'\r') && src.peek_byte()? == Some(b'\n') {
                if let Some(len) = len {
                    // Exactly one of the two readings fits the file's length: take it. With data after
                    // the raster both fit, and either could shift the map by a pixel: refuse.
                    let after_cr = len.saturating_sub(src.pos());
                    if after_cr == raster + 1 {
                        src.next_byte()?;
                    } else if after_cr > raster + 1 {
                        return Err(format!(
                            "{name} header ends with CR LF and data follows the raster: cannot tell whether the LF is the first pixel; rewrite the header with one LF"
                        ));
                    }
                }
            }
            if let Some(len) = len {
                let have = len.saturating_sub(src.pos());
                if have < raster {
                    return Err(format!(
                        "truncated {name}: the {width}x{height} raster needs {raster} bytes, the file has {have} after the header"
                    ));
                }
            }
        }

        let lut_bytes = (u64::from(maxval) + 1) * if family == Family::Pgm { 3 } else { 2 };
        if lut_bytes > max_decoder_bytes {
            return Err(format!(
                "{name} decoding needs {lut_bytes} bytes of tables, above the limit of {max_decoder_bytes}"
            ));
        }
        let scaled = scale_table(maxval);
        let grey = if family == Family::Pgm {
            scaled
                .iter()
                .map(|&v| if wide { grey16_to_grey8(v) } else { v as u8 })
                .collect()
        } else {
            Vec::new()
        };
        Ok(PnmDecoder {
            src,
            family,
            binary,
            width,
            height,
            maxval,
            wide,
            scaled,
            grey,
            len,
            raw_elsewhere: 0,
        })
    }

    pub(crate) fn header(&self) -> Header {
        Header {
            kind: ImageKind::Pgm,
            width: self.width,
            height: self.height,
            decoder_bytes: (self.scaled.len() * 2 + self.grey.len()) as u64,
            whole_image: false,
        }
    }

    /// Reads rows `y..` into `out` in one piece when the raster is those rows' bytes as they are (binary
    /// PGM, maxval 255: every byte is a valid sample and its own grey level); `false` (nothing read)
    /// otherwise.
    pub(crate) fn read_raw_rows(&mut self, y: u32, out: &mut [u8]) -> Result<bool, String> {
        if !(self.family == Family::Pgm && self.binary && self.maxval == 255) {
            return Ok(false);
        }
        let n = self.src.read_bulk(out).map_err(|e| io_error(&e))?;
        if n < out.len() {
            let w = self.width as usize;
            return Err(format!(
                "truncated PGM: the raster ends at row {}, column {} of a {}x{} image",
                y as usize + n / w,
                n % w,
                self.width,
                self.height
            ));
        }
        Ok(true)
    }

    /// Decodes row `y` into `out` (width bytes).
    pub(crate) fn read_row(&mut self, y: u32, out: &mut [u8]) -> Result<(), String> {
        match (self.family, self.binary) {
            (Family::Pbm, true) => self.read_pbm_binary(y, out),
            (Family::Pbm, false) => self.read_pbm_ascii(y, out),
            (_, true) => self.read_binary(y, out),
            (_, false) => self.read_ascii(y, out),
        }
    }

    /// Where the raster starts in the input, when its bytes are the rows as they are (binary PGM, maxval
    /// 255) and none has been read: for a reader that reads them itself ([`super::Decoder::raw_raster`]).
    pub(crate) fn raw_raster(&self) -> Option<u64> {
        (self.family == Family::Pgm && self.binary && self.maxval == 255 && self.raw_elsewhere == 0)
            .then(|| self.src.pos())
    }

    /// The raster was read by someone else ([`PnmDecoder::raw_raster`]): `finish` counts what follows
    /// it as if this decoder had read it.
    pub(crate) fn raster_read_elsewhere(&mut self) {
        self.raw_elsewhere = u64::from(self.width) * u64::from(self.height);
    }

    /// Warnings: trailing bytes after a binary raster, when the length is known.
    pub(crate) fn finish(self) -> Result<Vec<String>, String> {
        if !self.binary {
            return Ok(Vec::new());
        }
        Ok(
            trailing_warning(self.len, self.src.pos() + self.raw_elsewhere)
                .into_iter()
                .collect(),
        )
    }

    fn truncated(&self, y: u32, x: usize) -> String {
        format!(
            "truncated {}: the raster ends at row {y}, column {x} of a {}x{} image",
            self.family.name(),
            self.width,
            self.height
        )
    }

    fn read_binary(&mut self, y: u32, out: &mut [u8]) -> Result<(), String> {
        let spp = if self.family == Family::Ppm { 3 } else { 1 };
        let bps = if self.wide { 2 } else { 1 };
        let psize = spp * bps;
        let conv = Conv {
            family: self.family,
            wide: self.wide,
            maxval: self.maxval,
            scaled: &self.scaled,
            grey: &self.grey,
            y,
        };
        if self.family == Family::Pgm && !self.wide {
            return self.read_p5_8bit(y, out);
        }
        // A pixel split across two reader buffers is assembled here.
        let mut carry = [0u8; 6];
        let mut carry_len = 0;
        let mut x = 0;
        let w = out.len();
        while x < w {
            let buf = match self.src.fill_buf() {
                Ok(b) => b,
                Err(e) => return Err(io_error(&e)),
            };
            if buf.is_empty() {
                let msg = format!(
                    "truncated {}: the raster ends at row {y}, column {x} of a {}x{} image",
                    self.family.name(),
                    self.width,
                    self.height
                );
                return Err(msg);
            }
            let need = (w - x) * psize - carry_len;
            let n = buf.len().min(need);
            let mut data = &buf[..n];
            if carry_len > 0 {
                let k = (psize - carry_len).min(data.len());
                carry[carry_len..carry_len + k].copy_from_slice(&data[..k]);
                carry_len += k;
                data = &data[k..];
                if carry_len == psize {
                    out[x] = conv.pixel(&carry[..psize], x)?;
                    x += 1;
                    carry_len = 0;
                }
            }
            let mut px = data.chunks_exact(psize);
            for p in &mut px {
                out[x] = conv.pixel(p, x)?;
                x += 1;
            }
            let rest = px.remainder();
            carry[carry_len..carry_len + rest.len()].copy_from_slice(rest);
            carry_len += rest.len();
            self.src.consume(n);
        }
        Ok(())
    }

    /// The common case, one byte a pixel, without the general loop's pixel assembly.
    fn read_p5_8bit(&mut self, y: u32, out: &mut [u8]) -> Result<(), String> {
        let mut x = 0;
        while x < out.len() {
            let buf = self.src.fill_buf().map_err(|e| io_error(&e))?;
            if buf.is_empty() {
                return Err(format!(
                    "truncated PGM: the raster ends at row {y}, column {x} of a {}x{} image",
                    self.width, self.height
                ));
            }
            let n = buf.len().min(out.len() - x);
            for (i, (o, &v)) in out[x..x + n].iter_mut().zip(&buf[..n]).enumerate() {
                if u32::from(v) > self.maxval {
                    return Err(format!(
                        "PGM sample {v} at row {y}, column {} exceeds maxval {}",
                        x + i,
                        self.maxval
                    ));
                }
                *o = self.grey[v as usize];
            }
            self.src.consume(n);
            x += n;
        }
        Ok(())
    }

    fn read_pbm_binary(&mut self, y: u32, out: &mut [u8]) -> Result<(), String> {
        let w = out.len();
        for (k, chunk) in out.chunks_mut(8).enumerate() {
            let byte = match self.src.next_byte()? {
                Some(b) => b,
                None => return Err(self.truncated(y, k * 8)),
            };
            for (i, o) in chunk.iter_mut().enumerate() {
                *o = if (byte >> (7 - i)) & 1 == 1 { 0 } else { 255 };
            }
        }
        debug_assert_eq!(w, self.width as usize);
        Ok(())
    }

    fn read_pbm_ascii(&mut self, y: u32, out: &mut [u8]) -> Result<(), String> {
        for (x, o) in out.iter_mut().enumerate() {
            *o = loop {
                match self.src.next_byte()? {
                    None => return Err(self.truncated(y, x)),
                    Some(b) if is_space(b) => continue,
                    Some(b'0') => break 255,
                    Some(b'1') => break 0,
                    Some(b) => {
                        return Err(format!(
                            "PBM raster has unexpected byte {b:#04x} at row {y}, column {x} (expected 0 or 1)"
                        ))
                    }
                }
            };
        }
        Ok(())
    }

    fn read_ascii(&mut self, y: u32, out: &mut [u8]) -> Result<(), String> {
        let spp = if self.family == Family::Ppm { 3 } else { 1 };
        let mut s = [0u16; 3];
        for (x, o) in out.iter_mut().enumerate() {
            for v in s.iter_mut().take(spp) {
                *v = self.read_ascii_sample(y, x)?;
            }
            let conv = Conv {
                family: self.family,
                wide: self.wide,
                maxval: self.maxval,
                scaled: &self.scaled,
                grey: &self.grey,
                y,
            };
            *o = conv.samples(&s[..spp], x)?;
        }
        Ok(())
    }

    /// One decimal token, as image's `read_separated_ascii` reads it (the terminating whitespace
    /// byte is consumed), but bounded: the value may not pass 65535.
    fn read_ascii_sample(&mut self, y: u32, x: usize) -> Result<u16, String> {
        let name = self.family.name();
        let mut b = loop {
            match self.src.next_byte()? {
                None => return Err(self.truncated(y, x)),
                Some(b) if is_space(b) => continue,
                Some(b) => break b,
            }
        };
        let mut v: u32 = 0;
        loop {
            if !b.is_ascii_digit() {
                return Err(format!(
                    "{name} sample at row {y}, column {x} is not a number (byte {b:#04x})"
                ));
            }
            v = v * 10 + u32::from(b - b'0');
            if v > 0xFFFF {
                return Err(format!(
                    "{name} sample at row {y}, column {x} is above 65535"
                ));
            }
            match self.src.next_byte()? {
                None => break,
                Some(c) if is_space(c) => break,
                Some(c) => b = c,
            }
        }
        Ok(v as u16)
    }
}

/// What converting a pixel needs, borrowed apart from the source.
struct Conv<'a> {
    family: Family,
    wide: bool,
    maxval: u32,
    scaled: &'a [u16],
    grey: &'a [u8],
    y: u32,
}

impl Conv<'_> {
    /// One binary pixel (1 or 3 samples of 1 or 2 bytes).
    #[inline]
    fn pixel(&self, p: &[u8], x: usize) -> Result<u8, String> {
        let mut s = [0u16; 3];
        let n = if self.wide {
            for (v, b) in s.iter_mut().zip(p.chunks_exact(2)) {
                *v = u16::from_be_bytes([b[0], b[1]]);
            }
            p.len() / 2
        } else {
            for (v, &b) in s.iter_mut().zip(p) {
                *v = u16::from(b);
            }
            p.len()
        };
        self.samples(&s[..n], x)
    }

    #[inline]
    fn samples(&self, s: &[u16], x: usize) -> Result<u8, String> {
        for (i, &v) in s.iter().enumerate() {
            if u32::from(v) > self.maxval {
                let what = if self.family == Family::Ppm {
                    [" (red)", " (green)", " (blue)"][i]
                } else {
                    ""
                };
                return Err(format!(
                    "{} sample {v}{what} at row {}, column {x} exceeds maxval {}",
                    self.family.name(),
                    self.y,
                    self.maxval
                ));
            }
        }
        Ok(match self.family {
            Family::Ppm => {
                let (r, g, b) = (
                    self.scaled[s[0] as usize],
                    self.scaled[s[1] as usize],
                    self.scaled[s[2] as usize],
                );
                if self.wide {
                    rgb16_to_grey(r, g, b)
                } else {
                    rgb8_to_grey(r as u8, g as u8, b as u8)
                }
            }
            _ => self.grey[s[0] as usize],
        })
    }
}

/// image's maxval scaling: to 255 (maxval <= 255) or 65535, by an `f32` factor, rounded.
fn scale_table(maxval: u32) -> Vec<u16> {
    let target: u32 = if maxval > 0xFF { 0xFFFF } else { 0xFF };
    let factor = target as f32 / maxval as f32;
    (0..=maxval)
        .map(|v| {
            if maxval == target {
                v as u16
            } else if target == 0xFF {
                (v as f32 * factor).round() as u8 as u16
            } else {
                (v as f32 * factor).round() as u16
            }
        })
        .collect()
}

/// Bytes of a binary raster; `u64::MAX` when they do not fit (no file is that long: it reads as truncated).
fn raster_bytes(family: Family, width: u32, height: u32, wide: bool) -> u64 {
    let (w, h) = (u64::from(width), u64::from(height));
    let per_px = match family {
        Family::Pbm => return w.div_ceil(8).saturating_mul(h),
        Family::Pgm => 1 + u64::from(wide),
        Family::Ppm => 3 * (1 + u64::from(wide)),
    };
    w.saturating_mul(h).saturating_mul(per_px)
}

/// Most bytes a header (comments included) may take.
const MAX_HEADER_BYTES: u64 = 1 << 20;

/// One header number as image's `read_next_u32` reads it (see the module doc), returning the
/// value and the byte that ended it (`None` at end of input), which is consumed.
fn read_header_u32<R: BufRead>(
    src: &mut Source<R>,
    name: &str,
    what: &str,
) -> Result<(u32, Option<u8>), String> {
    let mut in_comment = false;
    let mut value: u32 = 0;
    let mut found = false;
    while let Some(b) = src.next_byte()? {
        // A header is a few dozen bytes: a huge comment or run of blanks is no map (and would be read
        // byte by byte to its end).
        if src.pos() > MAX_HEADER_BYTES {
            return Err(format!(
                "{name} header: over {MAX_HEADER_BYTES} bytes before the {what}"
            ));
        }
        if in_comment || b == b'#' {
            in_comment = !(b == b'\r' || b == b'\n');
            continue;
        }
        match b {
            b if is_space(b) => {
                if found {
                    return Ok((value, Some(b)));
                }
            }
            b'0'..=b'9' => {
                value = value
                    .checked_mul(10)
                    .and_then(|v| v.checked_add(u32::from(b - b'0')))
                    .ok_or_else(|| format!("{name} header: {what} is too large"))?;
                found = true;
            }
            b if !b.is_ascii() => {
                return Err(format!(
                    "{name} header: non-ASCII byte {b:#04x} where the {what} should be"
                ))
            }
            b => {
                return Err(format!(
                    "{name} header: unexpected character {:?} where the {what} should be",
                    b as char
                ))
            }
        }
    }
    if !found {
        return Err(format!("{name} header ends before the {what}"));
    }
    Ok((value, None))
}
