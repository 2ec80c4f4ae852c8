//! The decoder against image 0.25.10 (the project's old path), and each defect it fixes.

use std::io::Cursor;

use image::DynamicImage;
use ogm_corners::map::decode::{decode_bytes, Decoder, ImageKind};
use proptest::prelude::*;

pub(crate) const LIMIT: u64 = 1 << 32;

// ---------------------------------------------------------------- oracle and helpers

/// The project's old decoding path.
pub(crate) fn oracle(bytes: &[u8]) -> Result<(u32, u32, Vec<u8>), String> {
    let img = image::ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?
        .decode()
        .map_err(|e| e.to_string())?;
    let (w, h) = (img.width(), img.height());
    let grey = match img {
        DynamicImage::ImageLuma8(g) => g.into_raw(),
        other => other.to_luma8().into_raw(),
    };
    Ok((w, h, grey))
}

pub(crate) fn ours(bytes: &[u8]) -> Result<(u32, u32, Vec<u8>), String> {
    decode_bytes(bytes, None, LIMIT).map(|(w, h, p, _)| (w, h, p))
}

/// Both decoders succeed and agree pixel for pixel.
#[track_caller]
pub(crate) fn assert_same(bytes: &[u8], what: &str) {
    let want = oracle(bytes).unwrap_or_else(|e| panic!("{what}: image failed: {e}"));
    let got = ours(bytes).unwrap_or_else(|e| panic!("{what}: decoder failed: {e}"));
    assert_eq!((got.0, got.1), (want.0, want.1), "{what}: size");
    if got.2 != want.2 {
        let i = got.2.iter().zip(&want.2).position(|(a, b)| a != b).unwrap();
        panic!(
            "{what}: pixel {i} (x {}, y {}) is {} but image gives {}",
            i % want.0 as usize,
            i / want.0 as usize,
            got.2[i],
            want.2[i]
        );
    }
}

#[track_caller]
pub(crate) fn err_of(bytes: &[u8]) -> String {
    match decode_bytes(bytes, None, LIMIT) {
        Ok(_) => panic!("decoded, but an error was expected"),
        Err(e) => {
            assert!(
                !e.contains('\n') && !e.contains('\r'),
                "multi-line error: {e:?}"
            );
            e
        }
    }
}

/// Deterministic pseudo-random numbers.
pub(crate) struct Rng(pub(crate) u64);
impl Rng {
    pub(crate) fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    pub(crate) fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

// ---------------------------------------------------------------- a PNG writer

pub(crate) fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

pub(crate) fn adler32(data: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    for &x in data {
        a = (a + u32::from(x)) % 65521;
        b = (b + a) % 65521;
    }
    (b << 16) | a
}

/// zlib stream of stored (uncompressed) blocks.
pub(crate) fn zlib_stored(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0x78, 0x01];
    let mut blocks: Vec<&[u8]> = data.chunks(65535).collect();
    if blocks.is_empty() {
        blocks.push(&[]);
    }
    let last = blocks.len() - 1;
    for (i, b) in blocks.iter().enumerate() {
        out.push(u8::from(i == last));
        let n = b.len() as u16;
        out.extend_from_slice(&n.to_le_bytes());
        out.extend_from_slice(&(!n).to_le_bytes());
        out.extend_from_slice(b);
    }
    out.extend_from_slice(&adler32(data).to_be_bytes());
    out
}

pub(crate) fn chunk(out: &mut Vec<u8>, ty: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let start = out.len();
    out.extend_from_slice(ty);
    out.extend_from_slice(data);
    let crc = crc32(&out[start..]);
    out.extend_from_slice(&crc.to_be_bytes());
}

pub(crate) fn channels(color: u8) -> usize {
    match color {
        0 | 3 => 1,
        2 => 3,
        4 => 2,
        6 => 4,
        _ => unreachable!(),
    }
}

pub(crate) fn pack(samples: &[u16], depth: u8) -> Vec<u8> {
    match depth {
        16 => samples.iter().flat_map(|s| s.to_be_bytes()).collect(),
        8 => samples.iter().map(|&s| s as u8).collect(),
        d => {
            let per = 8 / d as usize;
            samples
                .chunks(per)
                .map(|c| {
                    let mut b = 0u8;
                    for (i, &s) in c.iter().enumerate() {
                        b |= (s as u8) << (8 - d as usize * (i + 1));
                    }
                    b
                })
                .collect()
        }
    }
}

pub(crate) struct PngSpec<'a> {
    pub(crate) w: u32,
    pub(crate) h: u32,
    pub(crate) color: u8,
    pub(crate) depth: u8,
    pub(crate) interlace: bool,
    /// w * h * channels samples.
    pub(crate) samples: &'a [u16],
    pub(crate) palette: Option<&'a [u8]>,
    pub(crate) trns: Option<&'a [u8]>,
}

/// A PNG written by hand: any colour type and depth, Adam7 or not, filter 0, stored deflate,
/// image data split over several IDAT chunks.
pub(crate) fn make_png(s: &PngSpec) -> Vec<u8> {
    let ch = channels(s.color);
    let px = |x: u32, y: u32| {
        let i = (y as usize * s.w as usize + x as usize) * ch;
        &s.samples[i..i + ch]
    };
    let mut raw = Vec::new();
    let push_row = |xs: &[u32], y: u32, raw: &mut Vec<u8>| {
        let row: Vec<u16> = xs.iter().flat_map(|&x| px(x, y).to_vec()).collect();
        raw.push(0);
        raw.extend(pack(&row, s.depth));
    };
    if s.interlace {
        for (dx, x0, dy, y0) in [
            (8, 0, 8, 0),
            (8, 4, 8, 0),
            (4, 0, 8, 4),
            (4, 2, 4, 0),
            (2, 0, 4, 2),
            (2, 1, 2, 0),
            (1, 0, 2, 1),
        ] {
            let xs: Vec<u32> = (x0..s.w).step_by(dx).collect();
            if xs.is_empty() {
                continue;
            }
            for y in (y0..s.h).step_by(dy) {
                push_row(&xs, y, &mut raw);
            }
        }
    } else {
        let xs: Vec<u32> = (0..s.w).collect();
        for y in 0..s.h {
            push_row(&xs, y, &mut raw);
        }
    }
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&s.w.to_be_bytes());
    ihdr.extend_from_slice(&s.h.to_be_bytes());
    ihdr.extend_from_slice(&[s.depth, s.color, 0, 0, u8::from(s.interlace)]);
    chunk(&mut out, b"IHDR", &ihdr);
    if let Some(p) = s.palette {
        chunk(&mut out, b"PLTE", p);
    }
    if let Some(t) = s.trns {
        chunk(&mut out, b"tRNS", t);
    }
    let z = zlib_stored(&raw);
    for part in z.chunks(1000) {
        chunk(&mut out, b"IDAT", part);
    }
    chunk(&mut out, b"IEND", &[]);
    out
}

/// Random samples for a PNG of the given type, palette indices below `pal_len`.
pub(crate) fn png_samples(
    rng: &mut Rng,
    w: u32,
    h: u32,
    color: u8,
    depth: u8,
    pal_len: usize,
) -> Vec<u16> {
    let n = w as usize * h as usize * channels(color);
    let max = if color == 3 {
        pal_len as u64
    } else {
        1u64 << depth
    };
    // Mix in the extremes, which exercise rounding at both ends.
    (0..n)
        .map(|_| match rng.below(8) {
            0 => 0,
            1 => (max - 1) as u16,
            _ => rng.below(max) as u16,
        })
        .collect()
}

pub(crate) fn random_palette(rng: &mut Rng, n: usize) -> Vec<u8> {
    (0..n * 3).map(|_| rng.below(256) as u8).collect()
}

pub(crate) fn trns_for(color: u8, depth: u8, pal_len: usize, rng: &mut Rng) -> Vec<u8> {
    let v = |rng: &mut Rng| ((rng.below(1 << depth)) as u16).to_be_bytes();
    match color {
        0 => v(rng).to_vec(),
        2 => [v(rng), v(rng), v(rng)].concat(),
        3 => (0..pal_len.min(200))
            .map(|_| rng.below(256) as u8)
            .collect(),
        _ => unreachable!(),
    }
}

// ---------------------------------------------------------------- PGM writers

/// Header styles: the oracle must read all of them as we do.
pub(crate) const STYLES: usize = 7;

pub(crate) fn pnm_header(
    magic: &str,
    w: u32,
    h: u32,
    maxval: Option<u32>,
    style: usize,
) -> Vec<u8> {
    let m = maxval.map(|m| m.to_string());
    let s = match style {
        0 => match &m {
            Some(m) => format!("{magic}\n{w} {h}\n{m}\n"),
            None => format!("{magic}\n{w} {h}\n"),
        },
        1 => match &m {
            Some(m) => format!("{magic} {w} {h} {m} "),
            None => format!("{magic} {w} {h} "),
        },
        2 => match &m {
            Some(m) => format!("{magic}\n# a comment\n{w}\t{h}\n# another\r{m}\n"),
            None => format!("{magic}\n# a comment\n{w}\t{h}\n"),
        },
        3 => match &m {
            Some(m) => format!("{magic}\x0b{w}\x0c{h}\r\n\n  {m}\t"),
            None => format!("{magic}\x0b{w}\x0c\x0c{h}\t"),
        },
        4 => match &m {
            Some(m) => format!("{magic}#c\u{e9}\u{20ac}\n0{w} 00{h} # x\n 0{m}\n"),
            None => format!("{magic}#c\u{e9}\n0{w} 00{h}\n"),
        },
        5 => match &m {
            // No whitespace after the magic: image and netpbm's libraries accept that.
            Some(m) => format!("{magic}{w}\n{h}#comment right after a token\n\t{m}\r"),
            None => format!("{magic}{w}\n{h}\r"),
        },
        _ => match &m {
            Some(m) => format!("{magic}\r\n#crlf comment\r\n{w} {h}\r\n\r\n{m}\n"),
            None => format!("{magic}\r\n#crlf comment\r\n{w} {h}\n"),
        },
    };
    s.into_bytes()
}

pub(crate) fn pnm_binary(
    magic: &str,
    w: u32,
    h: u32,
    maxval: u32,
    samples: &[u32],
    style: usize,
) -> Vec<u8> {
    let mut out = pnm_header(magic, w, h, Some(maxval), style);
    for &s in samples {
        if maxval > 255 {
            out.extend_from_slice(&(s as u16).to_be_bytes());
        } else {
            out.push(s as u8);
        }
    }
    out
}

pub(crate) fn pnm_ascii(
    magic: &str,
    w: u32,
    h: u32,
    maxval: u32,
    samples: &[u32],
    style: usize,
    rng: &mut Rng,
) -> Vec<u8> {
    let mut out = pnm_header(magic, w, h, Some(maxval), style);
    let seps = [" ", "\t", "\n", "  ", "\r\n", "\x0b", "\x0c"];
    for &s in samples {
        if rng.below(6) == 0 {
            out.extend_from_slice(format!("00{s}").as_bytes());
        } else {
            out.extend_from_slice(s.to_string().as_bytes());
        }
        out.extend_from_slice(seps[rng.below(seps.len() as u64) as usize].as_bytes());
    }
    out
}

pub(crate) fn samples_to(rng: &mut Rng, n: usize, maxval: u32) -> Vec<u32> {
    (0..n)
        .map(|_| match rng.below(8) {
            0 => 0,
            1 => maxval,
            _ => rng.below(u64::from(maxval) + 1) as u32,
        })
        .collect()
}

pub(crate) const SIZES: [(u32, u32); 4] = [(1, 1), (7, 3), (65, 33), (3, 9)];
pub(crate) const MAXVALS: [u32; 9] = [1, 7, 100, 254, 255, 256, 1000, 65534, 65535];

// ---------------------------------------------------------------- differential: PNG

#[test]
fn png_every_type_depth_and_interlace_matches_image() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let types: [(u8, &[u8]); 5] = [
        (0, &[1, 2, 4, 8, 16]),
        (2, &[8, 16]),
        (3, &[1, 2, 4, 8]),
        (4, &[8, 16]),
        (6, &[8, 16]),
    ];
    let mut count = 0;
    for (color, depths) in types {
        for &depth in depths {
            for interlace in [false, true] {
                for (w, h) in SIZES {
                    let trns_options: &[bool] = if matches!(color, 0 | 2 | 3) {
                        &[false, true]
                    } else {
                        &[false]
                    };
                    for &with_trns in trns_options {
                        // Full and short palettes.
                        let pal_lens: Vec<usize> = if color == 3 {
                            let full = 1usize << depth;
                            vec![full, full / 2 + 1, 1]
                        } else {
                            vec![0]
                        };
                        for pal_len in pal_lens {
                            let samples = png_samples(&mut rng, w, h, color, depth, pal_len);
                            let palette = random_palette(&mut rng, pal_len);
                            let trns = if with_trns {
                                trns_for(color, depth, pal_len, &mut rng)
                            } else {
                                Vec::new()
                            };
                            let bytes = make_png(&PngSpec {
                                w,
                                h,
                                color,
                                depth,
                                interlace,
                                samples: &samples,
                                palette: (color == 3).then_some(&palette[..]),
                                trns: with_trns.then_some(&trns[..]),
                            });
                            let what = format!(
                                "PNG colour {color} depth {depth} interlace {interlace} {w}x{h} tRNS {with_trns} palette {pal_len}"
                            );
                            assert_same(&bytes, &what);
                            count += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(count > 150, "{count}");
}

#[test]
fn png_from_the_png_encoder_matches_image() {
    // Real deflate compression and png's own filter choices.
    let mut rng = Rng(7);
    let cases = [
        (png::ColorType::Grayscale, png::BitDepth::Eight),
        (png::ColorType::Grayscale, png::BitDepth::Sixteen),
        (png::ColorType::Grayscale, png::BitDepth::Two),
        (png::ColorType::Rgb, png::BitDepth::Eight),
        (png::ColorType::Rgba, png::BitDepth::Sixteen),
        (png::ColorType::GrayscaleAlpha, png::BitDepth::Eight),
        (png::ColorType::Indexed, png::BitDepth::Four),
    ];
    for (ct, bd) in cases {
        for (w, h) in [(1, 1), (65, 33), (300, 17)] {
            let color = ct as u8;
            let depth = bd as u8;
            let samples = png_samples(&mut rng, w, h, color, depth, 16);
            let row_bytes: Vec<u8> = samples
                .chunks(w as usize * channels(color))
                .flat_map(|r| pack(r, depth))
                .collect();
            let mut bytes = Vec::new();
            {
                let mut enc = png::Encoder::new(&mut bytes, w, h);
                enc.set_color(ct);
                enc.set_depth(bd);
                if ct == png::ColorType::Indexed {
                    enc.set_palette(random_palette(&mut rng, 16));
                }
                let mut wr = enc.write_header().unwrap();
                wr.write_image_data(&row_bytes).unwrap();
            }
            assert_same(&bytes, &format!("png encoder {ct:?} {depth} {w}x{h}"));
        }
    }
}

#[test]
fn png_images_written_by_image_match() {
    // What the project writes (overlays, plots) and reads back.
    let mut rng = Rng(11);
    let rgb = image::RgbImage::from_fn(37, 21, |_, _| {
        image::Rgb([
            rng.below(256) as u8,
            rng.below(256) as u8,
            rng.below(256) as u8,
        ])
    });
    let mut bytes = Vec::new();
    DynamicImage::ImageRgb8(rgb)
        .write_to(&mut Cursor::new(&mut bytes), image::ImageFormat::Png)
        .unwrap();
    assert_same(&bytes, "image-written RGB PNG");
    let grey = image::GrayImage::from_fn(40, 30, |x, y| image::Luma([(x * 7 + y * 3) as u8]));
    let mut bytes = Vec::new();
    DynamicImage::ImageLuma8(grey)
        .write_to(&mut Cursor::new(&mut bytes), image::ImageFormat::Png)
        .unwrap();
    assert_same(&bytes, "image-written grey PNG");
}

// ---------------------------------------------------------------- differential: Netpbm

#[test]
fn pgm_p5_and_p2_every_maxval_and_style_match_image() {
    let mut rng = Rng(42);
    let mut count = 0;
    for maxval in MAXVALS {
        for (w, h) in SIZES {
            for style in 0..STYLES {
                let s = samples_to(&mut rng, (w * h) as usize, maxval);
                let p5 = pnm_binary("P5", w, h, maxval, &s, style);
                assert_same(&p5, &format!("P5 maxval {maxval} {w}x{h} style {style}"));
                let p2 = pnm_ascii("P2", w, h, maxval, &s, style, &mut rng);
                assert_same(&p2, &format!("P2 maxval {maxval} {w}x{h} style {style}"));
                // Both encodings of the same samples give the same map.
                assert_eq!(ours(&p5).unwrap(), ours(&p2).unwrap());
                count += 2;
            }
        }
    }
    assert_eq!(count, MAXVALS.len() * SIZES.len() * STYLES * 2);
}

#[test]
fn ppm_and_pbm_match_image() {
    let mut rng = Rng(5);
    for maxval in [1, 100, 255, 256, 1000, 65535] {
        for (w, h) in SIZES {
            for style in [0, 2, 3, 4] {
                let s = samples_to(&mut rng, (w * h * 3) as usize, maxval);
                let p6 = pnm_binary("P6", w, h, maxval, &s, style);
                assert_same(&p6, &format!("P6 maxval {maxval} {w}x{h} style {style}"));
                let p3 = pnm_ascii("P3", w, h, maxval, &s, style, &mut rng);
                assert_same(&p3, &format!("P3 maxval {maxval} {w}x{h} style {style}"));
            }
        }
    }
    for (w, h) in [(1, 1), (7, 3), (8, 2), (9, 5), (65, 33)] {
        for style in [0, 1, 2, 3, 4, 6] {
            let bits: Vec<u8> = (0..w * h).map(|_| rng.below(2) as u8).collect();
            // P4: rows padded to whole bytes, with junk in the padding bits.
            let mut p4 = pnm_header("P4", w, h, None, style);
            for row in bits.chunks(w as usize) {
                for c in row.chunks(8) {
                    let mut b = 0u8;
                    for (i, &bit) in c.iter().enumerate() {
                        b |= bit << (7 - i);
                    }
                    if c.len() < 8 {
                        b |= 0xFF >> c.len();
                    }
                    p4.push(b);
                }
            }
            assert_same(&p4, &format!("P4 {w}x{h} style {style}"));
            let mut p1 = pnm_header("P1", w, h, None, style);
            for (i, &bit) in bits.iter().enumerate() {
                p1.push(b'0' + bit);
                if i % 3 == 0 {
                    p1.push(b' ');
                }
                if (i + 1) % w as usize == 0 {
                    p1.push(b'\n');
                }
            }
            assert_same(&p1, &format!("P1 {w}x{h} style {style}"));
        }
    }
}

#[test]
fn every_rgb8_colour_converts_as_image_does() {
    // All 2^24 colours in one 4096 x 4096 PPM.
    let mut p6 = b"P6 4096 4096 255\n".to_vec();
    p6.reserve(3 << 24);
    for c in 0u32..1 << 24 {
        p6.extend_from_slice(&[(c >> 16) as u8, (c >> 8) as u8, c as u8]);
    }
    assert_same(&p6, "all RGB8 colours");
}

#[test]
fn rgb16_and_grey16_samples_convert_as_image_does() {
    // Every 16-bit grey value, and a million random 16-bit colours.
    let mut p5 = b"P5 256 256 65535\n".to_vec();
    for v in 0u32..65536 {
        p5.extend_from_slice(&(v as u16).to_be_bytes());
    }
    assert_same(&p5, "all grey16 values");
    let mut rng = Rng(99);
    let mut p6 = b"P6 1000 1000 65535\n".to_vec();
    for _ in 0..3_000_000 {
        p6.extend_from_slice(&(rng.next() as u16).to_be_bytes());
    }
    assert_same(&p6, "random RGB16");
}

// ---------------------------------------------------------------- proptest: random images

pub(crate) fn maxval_strategy() -> impl Strategy<Value = u32> {
    prop_oneof![
        prop::sample::select(MAXVALS.to_vec()),
        1u32..=255,
        256u32..=65535
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn random_pgm_matches_image(
        w in 1u32..40, h in 1u32..40, maxval in maxval_strategy(),
        style in 0..STYLES, ascii in any::<bool>(), seed in any::<u64>(),
    ) {
        let mut rng = Rng(seed | 1);
        let s = samples_to(&mut rng, (w * h) as usize, maxval);
        let bytes = if ascii {
            pnm_ascii("P2", w, h, maxval, &s, style, &mut rng)
        } else {
            pnm_binary("P5", w, h, maxval, &s, style)
        };
        prop_assert_eq!(ours(&bytes), oracle(&bytes));
    }

    #[test]
    fn random_png_matches_image(
        w in 1u32..40, h in 1u32..40, kind in 0usize..15, interlace in any::<bool>(),
        with_trns in any::<bool>(), pal_len in 1usize..=256, seed in any::<u64>(),
    ) {
        let (color, depth) = [
            (0, 1), (0, 2), (0, 4), (0, 8), (0, 16), (2, 8), (2, 16),
            (3, 1), (3, 2), (3, 4), (3, 8), (4, 8), (4, 16), (6, 8), (6, 16),
        ][kind];
        let pal_len = if color == 3 { pal_len.min(1 << depth) } else { 0 };
        let mut rng = Rng(seed | 1);
        let samples = png_samples(&mut rng, w, h, color, depth, pal_len);
        let palette = random_palette(&mut rng, pal_len);
        let trns = if matches!(color, 0 | 2 | 3) && with_trns {
            Some(trns_for(color, depth, pal_len, &mut rng))
        } else {
            None
        };
        let bytes = make_png(&PngSpec {
            w, h, color, depth, interlace, samples: &samples,
            palette: (color == 3).then_some(&palette[..]),
            trns: trns.as_deref(),
        });
        prop_assert_eq!(ours(&bytes), oracle(&bytes));
    }

    #[test]
    fn mutated_images_agree_whenever_both_decode(
        seed in any::<u64>(), flips in prop::collection::vec((any::<u32>(), any::<u8>()), 1..6),
        which in 0usize..4,
    ) {
        let mut rng = Rng(seed | 1);
        let mut bytes = match which {
            0 => pnm_binary("P5", 9, 7, 200, &samples_to(&mut rng, 63, 200), 2),
            1 => pnm_ascii("P2", 9, 7, 1000, &samples_to(&mut rng, 63, 1000), 0, &mut rng),
            2 => {
                let s = png_samples(&mut rng, 9, 7, 3, 4, 12);
                let p = random_palette(&mut rng, 12);
                make_png(&PngSpec { w: 9, h: 7, color: 3, depth: 4, interlace: true,
                    samples: &s, palette: Some(&p), trns: None })
            }
            _ => {
                let s = png_samples(&mut rng, 9, 7, 2, 16, 0);
                make_png(&PngSpec { w: 9, h: 7, color: 2, depth: 16, interlace: false,
                    samples: &s, palette: None, trns: None })
            }
        };
        for (at, v) in flips {
            let i = at as usize % bytes.len();
            bytes[i] = v;
        }
        if let (Ok(a), Ok(b)) = (ours(&bytes), oracle(&bytes)) {
            prop_assert_eq!(a, b);
        }
    }
}

// ---------------------------------------------------------------- proptest: never panic

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(
        prefix in prop::sample::select(vec![
            &b""[..], b"P5\n", b"P2\n", b"P5 3 2 255\n", b"P2 3 2 65535\n", b"P6 2 2 300\n",
            b"P4 9 2\n", b"P1 3 3\n", b"P3 1 1 7 ", b"P7\n", b"\x89PNG\r\n\x1a\n",
        ]),
        body in prop::collection::vec(any::<u8>(), 0..300),
        hint in prop::sample::select(vec![None, Some(ImageKind::Pgm), Some(ImageKind::Png)]),
        limit in prop::sample::select(vec![0u64, 100, 1 << 20, u64::MAX]),
    ) {
        let mut bytes = prefix.to_vec();
        bytes.extend(body);
        if let Err(e) = decode_bytes(&bytes, hint, limit) {
            prop_assert!(!e.contains('\n') && !e.contains('\r'), "{:?}", e);
        }
        // The streaming API with an unknown length too.
        if let Ok(mut d) = Decoder::new(&bytes[..], None, hint, limit) {
            let mut row = vec![0; d.header().width.min(1 << 16) as usize];
            if row.len() == d.header().width as usize {
                for _ in 0..d.header().height.min(64) {
                    if d.read_row(&mut row).is_err() {
                        break;
                    }
                }
            }
        }
    }

    #[test]
    fn png_chunk_soup_never_panics(
        chunks in prop::collection::vec(
            (prop::sample::select(vec![*b"IHDR", *b"PLTE", *b"tRNS", *b"IDAT", *b"IEND",
                                       *b"tEXt", *b"zTXt", *b"iCCP", *b"acTL", *b"fcTL"]),
             prop::collection::vec(any::<u8>(), 0..40)),
            0..8),
        ihdr in prop::collection::vec(any::<u8>(), 13),
    ) {
        let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
        chunk(&mut bytes, b"IHDR", &ihdr);
        for (ty, data) in chunks {
            chunk(&mut bytes, &ty, &data);
        }
        let _ = decode_bytes(&bytes, None, 1 << 24);
    }
}
