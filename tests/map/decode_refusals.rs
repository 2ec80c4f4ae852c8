//! Each defect of the old decoding path the decoder fixes (reading only what the image needs, samples
//! above maxval, palette indices past the palette, CRLF headers) and its other refusals (truncated
//! rasters, bad headers, misuse of the row API, buffers within the limit).

use super::decode::*;
use std::io::{BufReader, Read};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use ogm_corners::map::decode::{decode_bytes, Decoder, ImageKind};

// ---------------------------------------------------------------- defect 1: read only what the image needs

/// Serves `data`, then junk forever, counting what it served.
struct Endless {
    data: Vec<u8>,
    pos: usize,
    served: Arc<AtomicU64>,
}

impl Read for Endless {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        let n = out.len();
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.data.get(self.pos + i).copied().unwrap_or(0xA5);
        }
        self.pos += n;
        self.served.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
}

const CAP: usize = 4096;

/// Decodes `data` followed by endless junk; returns pixels, warnings and bytes read.
fn decode_endless(data: &[u8], len: Option<u64>) -> (Vec<u8>, Vec<String>, u64) {
    let served = Arc::new(AtomicU64::new(0));
    let src = Endless {
        data: data.to_vec(),
        pos: 0,
        served: Arc::clone(&served),
    };
    let mut d = Decoder::new(BufReader::with_capacity(CAP, src), len, None, LIMIT).unwrap();
    let (w, h) = (d.header().width as usize, d.header().height as usize);
    let mut pixels = vec![0; w * h];
    for row in pixels.chunks_exact_mut(w) {
        d.read_row(row).unwrap();
    }
    let warnings = d.finish().unwrap();
    (pixels, warnings, served.load(Ordering::Relaxed))
}

#[test]
fn trailing_junk_is_not_read() {
    let mut rng = Rng(3);
    let s = samples_to(&mut rng, 400, 255);
    let pgm = pnm_binary("P5", 20, 20, 255, &s, 0);
    // "5 GB of junk": the length says so, the reader never ends.
    let junk = 5_000_000_000u64;
    let (pixels, warnings, served) = decode_endless(&pgm, Some(pgm.len() as u64 + junk));
    assert_eq!(pixels, ours(&pgm).unwrap().2);
    assert!(served <= (pgm.len() + CAP) as u64, "read {served} bytes");
    assert_eq!(
        warnings,
        vec![format!("{junk} bytes after the image data ignored")]
    );
    // Unknown length: no warning, still bounded.
    let (_, warnings, served) = decode_endless(&pgm, None);
    assert!(warnings.is_empty());
    assert!(served <= (pgm.len() + CAP) as u64);

    // The same for a PNG, interlaced or not, and for P2.
    for interlace in [false, true] {
        let samples = png_samples(&mut rng, 50, 40, 0, 8, 0);
        let png_bytes = make_png(&PngSpec {
            w: 50,
            h: 40,
            color: 0,
            depth: 8,
            interlace,
            samples: &samples,
            palette: None,
            trns: None,
        });
        let (pixels, warnings, served) =
            decode_endless(&png_bytes, Some(png_bytes.len() as u64 + 12345));
        assert_eq!(pixels, oracle(&png_bytes).unwrap().2);
        assert!(served <= (png_bytes.len() + CAP) as u64, "read {served}");
        assert_eq!(
            warnings,
            vec!["12345 bytes after the image data ignored".to_string()]
        );
    }
    let p2 = pnm_ascii("P2", 20, 20, 255, &s, 0, &mut rng);
    let (pixels, _, served) = decode_endless(&p2, None);
    assert_eq!(pixels, ours(&pgm).unwrap().2);
    assert!(served <= (p2.len() + CAP) as u64);
}

#[test]
fn trailing_bytes_in_memory_are_reported() {
    let mut pgm = pnm_binary("P5", 3, 2, 255, &[1, 2, 3, 4, 5, 6], 0);
    pgm.extend_from_slice(&[9; 12345]);
    let (_, _, p, warnings) = decode_bytes(&pgm, None, LIMIT).unwrap();
    assert_eq!(p, [1, 2, 3, 4, 5, 6]);
    assert_eq!(warnings, ["12345 bytes after the image data ignored"]);
    let clean = pnm_binary("P5", 3, 2, 255, &[1, 2, 3, 4, 5, 6], 0);
    assert!(decode_bytes(&clean, None, LIMIT).unwrap().3.is_empty());
}

#[test]
fn endless_junk_is_refused_at_once() {
    let served = Arc::new(AtomicU64::new(0));
    let src = Endless {
        data: Vec::new(),
        pos: 0,
        served: Arc::clone(&served),
    };
    let e = Decoder::new(BufReader::with_capacity(CAP, src), None, None, LIMIT)
        .err()
        .unwrap();
    assert_eq!(e, "unknown image format: expected PGM (P2/P5) or PNG");
    assert!(served.load(Ordering::Relaxed) <= CAP as u64);
}

#[test]
fn header_is_known_before_any_pixel() {
    // A PGM header with no raster behind it yet (unknown length): the header still reads.
    let d = Decoder::new(&b"P5\n640 480\n65535\n"[..], None, None, LIMIT).unwrap();
    let h = d.header();
    assert_eq!((h.kind, h.width, h.height), (ImageKind::Pgm, 640, 480));
    assert!(h.decoder_bytes <= 200 * 1024);
    // With the length known, a missing raster is refused up front.
    let bytes = b"P5\n640 480\n255\n";
    let e = Decoder::new(&bytes[..], Some(bytes.len() as u64), None, LIMIT)
        .err()
        .unwrap();
    assert!(e.contains("truncated PGM"), "{e}");

    let samples = vec![0u16; 30 * 20 * 4];
    let spec = |interlace| PngSpec {
        w: 30,
        h: 20,
        color: 6,
        depth: 16,
        interlace,
        samples: &samples,
        palette: None,
        trns: None,
    };
    let d = decode_header(&make_png(&spec(false)));
    assert_eq!((d.kind, d.width, d.height), (ImageKind::Png, 30, 20));
    let plain = d.decoder_bytes;
    let d = decode_header(&make_png(&spec(true)));
    // The interlaced frame is counted: one grey byte a pixel.
    assert!(
        d.decoder_bytes >= plain + 30 * 20,
        "{} vs {plain}",
        d.decoder_bytes
    );
}

fn decode_header(bytes: &[u8]) -> ogm_corners::map::decode::Header {
    Decoder::new(bytes, Some(bytes.len() as u64), None, LIMIT)
        .unwrap()
        .header()
        .clone()
}

// ---------------------------------------------------------------- defect 2: samples above maxval

#[test]
fn samples_above_maxval_are_refused() {
    // Unknown (205) in a maxval-100 map: the old path made it free space.
    let mut s = vec![50u32; 12];
    s[7] = 205;
    let p5 = pnm_binary("P5", 4, 3, 100, &s, 0);
    assert!(oracle(&p5).is_ok(), "the old path accepted it");
    let e = err_of(&p5);
    assert_eq!(e, "PGM sample 205 at row 1, column 3 exceeds maxval 100");
    let p2 = pnm_ascii("P2", 4, 3, 100, &s, 0, &mut Rng(1));
    assert_eq!(err_of(&p2), e);
    // 16-bit.
    let mut s = vec![0u32; 6];
    s[5] = 1001;
    let e = err_of(&pnm_binary("P5", 3, 2, 1000, &s, 0));
    assert_eq!(e, "PGM sample 1001 at row 1, column 2 exceeds maxval 1000");
    // PPM names the channel.
    let e = err_of(&pnm_binary("P6", 1, 1, 10, &[1, 11, 2], 0));
    assert!(e.contains("11 (green)") && e.contains("maxval 10"), "{e}");
    // ASCII tokens: too large, not numeric.
    let e = err_of(b"P2 2 1 65535\n1 65536\n");
    assert!(e.contains("above 65535"), "{e}");
    let e = err_of(b"P2 2 1 65535\n1 12a\n");
    assert!(e.contains("not a number"), "{e}");
    let e = err_of(b"P2 2 1 255\n1 #c\n 2\n");
    assert!(e.contains("not a number"), "{e}");
}

// ---------------------------------------------------------------- defect 3: palette indices

#[test]
fn palette_index_past_the_end_is_refused() {
    for interlace in [false, true] {
        let (w, h) = (9u32, 6u32);
        let mut samples = vec![1u16; (w * h) as usize];
        samples[(4 * w + 5) as usize] = 17;
        let palette = [10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110, 120];
        let bytes = make_png(&PngSpec {
            w,
            h,
            color: 3,
            depth: 8,
            interlace,
            samples: &samples,
            palette: Some(&palette),
            trns: None,
        });
        let old = oracle(&bytes).expect("the old path accepted it");
        assert_eq!(old.2[(4 * w + 5) as usize], 0, "as black");
        assert_eq!(
            err_of(&bytes),
            "PNG palette index 17 at row 4, column 5 is past the end of the 4-entry palette"
        );
    }
    // A 2-bit image with a 3-entry palette and index 3.
    let mut samples = vec![0u16; 10];
    samples[9] = 3;
    let palette = [1, 2, 3, 4, 5, 6, 7, 8, 9];
    let bytes = make_png(&PngSpec {
        w: 5,
        h: 2,
        color: 3,
        depth: 2,
        interlace: false,
        samples: &samples,
        palette: Some(&palette),
        trns: None,
    });
    assert_eq!(
        err_of(&bytes),
        "PNG palette index 3 at row 1, column 4 is past the end of the 3-entry palette"
    );
}

// ---------------------------------------------------------------- defect 4: CRLF headers

#[test]
fn crlf_header_reads_the_same_pixels_as_lf() {
    let mut rng = Rng(77);
    for maxval in [255, 100, 65535] {
        for extra in [0usize, 1, 1000] {
            let s = samples_to(&mut rng, 400, maxval);
            let lf = pnm_binary("P5", 20, 20, maxval, &s, 0);
            let crlf_header = format!("P5\r\n20 20\r\n{maxval}\r\n").into_bytes();
            let mut crlf = crlf_header.clone();
            crlf.extend_from_slice(&lf[format!("P5\n20 20\n{maxval}\n").len()..]);
            let mut lf_t = lf.clone();
            lf_t.extend(std::iter::repeat_n(7u8, extra));
            crlf.extend(std::iter::repeat_n(7u8, extra));
            if extra > 0 {
                // Data after the raster: both readings fit, so the file is refused, never shifted.
                let e = decode_bytes(&crlf, None, LIMIT).unwrap_err();
                assert!(e.contains("CR LF and data follows"), "{e}");
                continue;
            }
            let (w, h, p, _) = decode_bytes(&crlf, None, LIMIT).unwrap();
            let want = decode_bytes(&lf_t, None, LIMIT).unwrap();
            assert_eq!(
                (w, h, &p),
                (want.0, want.1, &want.2),
                "maxval {maxval} extra {extra}"
            );
            if extra == 0 && maxval == 255 {
                // The old path shifted the map by one pixel: '\n' became pixel 0.
                let old = oracle(&crlf).unwrap().2;
                assert_eq!(old[0], b'\n');
                assert_eq!(old[1..], p[..p.len() - 1]);
            }
        }
    }
    // Comments ending in CRLF inside the header are fine either way.
    let s = samples_to(&mut rng, 6, 255);
    let bytes = pnm_binary("P5", 3, 2, 255, &s, 6);
    assert_same(&bytes, "CRLF comments");
}

#[test]
fn crlf_keeps_the_spec_reading_when_it_must() {
    // Exactly the raster after the '\r': the '\n' is pixel 0, as the spec says.
    let bytes = b"P5\r\n2 1\r\n255\r\n\x07";
    assert_same(bytes, "LF as first pixel");
    assert_eq!(ours(bytes).unwrap().2, [10, 7]);
    // Length unknown: the spec reading (and the old path's pixels).
    let mut crlf = b"P5\r\n2 1\r\n255\r\n".to_vec();
    crlf.extend_from_slice(&[1, 2, 3]);
    let mut d = Decoder::new(&crlf[..], None, None, LIMIT).unwrap();
    let mut row = [0; 2];
    d.read_row(&mut row).unwrap();
    assert_eq!(row, [10, 1]);
    // Length known, one byte more than either reading needs: ambiguous, refused.
    assert!(decode_bytes(&crlf, None, LIMIT).is_err());
    // Length known, exactly the raster after the LF: CRLF.
    let (_, _, p, _) = decode_bytes(&crlf[..crlf.len() - 1], None, LIMIT).unwrap();
    assert_eq!(p, [1, 2]);
}

// ---------------------------------------------------------------- truncation and other refusals

#[test]
fn truncated_rasters_are_errors() {
    let mut rng = Rng(8);
    let s = samples_to(&mut rng, 20 * 20, 1000);
    let full = [
        pnm_binary("P5", 20, 20, 1000, &s, 0),
        pnm_ascii("P2", 20, 20, 1000, &s, 0, &mut rng),
        pnm_binary(
            "P5",
            20,
            20,
            255,
            &s.iter().map(|v| v / 4).collect::<Vec<_>>(),
            0,
        ),
    ];
    for bytes in &full {
        // Whole P2 tokens must go: a cut inside the last one leaves a valid smaller value.
        let last = if bytes.starts_with(b"P2") {
            bytes.len() / 2
        } else {
            bytes.len() - 1
        };
        for cut in [last, bytes.len() / 2, 20, 3] {
            let e = err_of(&bytes[..cut]);
            assert!(
                oracle(&bytes[..cut]).is_err(),
                "old path accepted cut {cut}"
            );
            assert!(!e.is_empty());
        }
    }
    let e = err_of(&full[0][..full[0].len() - 1]);
    assert!(e.starts_with("truncated PGM"), "{e}");
    // Streaming with an unknown length: the error comes at the row that runs out.
    let cut = &full[0][..full[0].len() - 3];
    let mut d = Decoder::new(cut, None, None, LIMIT).unwrap();
    let mut row = [0; 20];
    for _ in 0..19 {
        d.read_row(&mut row).unwrap();
    }
    let e = d.read_row(&mut row).unwrap_err();
    assert_eq!(
        e,
        "truncated PGM: the raster ends at row 19, column 18 of a 20x20 image"
    );

    for interlace in [false, true] {
        let samples = png_samples(&mut rng, 30, 20, 2, 8, 0);
        let bytes = make_png(&PngSpec {
            w: 30,
            h: 20,
            color: 2,
            depth: 8,
            interlace,
            samples: &samples,
            palette: None,
            trns: None,
        });
        // Cut inside the image data (the IEND and last IDAT chunk are 12 + 1000 bytes).
        for cut in [bytes.len() - 30, bytes.len() / 2, 60, 9] {
            err_of(&bytes[..cut]);
            assert!(oracle(&bytes[..cut]).is_err());
        }
    }
}

#[test]
fn bad_headers_are_refused() {
    assert_eq!(err_of(b""), "empty file");
    assert_eq!(
        err_of(b"hello world"),
        "unknown image format: expected PGM (P2/P5) or PNG"
    );
    assert_eq!(
        err_of(b"P7\nWIDTH 1\nHEIGHT 1\nDEPTH 1\nMAXVAL 255\nENDHDR\n\0"),
        "unsupported PNM type P7 (PAM): expected PGM (P2 or P5) or PNG"
    );
    assert_eq!(err_of(b"P5 0 5 255\n"), "zero-size image (0x5)");
    assert_eq!(err_of(b"P2 5 0 255\n"), "zero-size image (5x0)");
    // Over 2^32 pixels is no header error (maps are streamed row by row); here the raster is missing.
    assert_eq!(
        err_of(b"P5 65537 65536 255\n"),
        "truncated PGM: the 65537x65536 raster needs 4295032832 bytes, the file has 0 after the header"
    );
    // Holding such an image whole in memory is refused.
    assert_eq!(
        ogm_corners::map::decode::check_in_memory(65537, 65536).unwrap_err(),
        "image of 65537x65536 exceeds 4294967296 pixels (detect reads larger maps row by row)"
    );
    assert!(ogm_corners::map::decode::check_in_memory(65536, 65536).is_ok());
    // Rasters whose byte count overflows 64 bits read as truncated, never as an overflow.
    for header in [
        &b"P5 4294967295 4294967295 65535\n"[..],
        b"P6 4294967295 4294967295 65535\n",
        b"P4 4294967295 4294967295\n",
    ] {
        let e = err_of(header);
        assert!(e.starts_with("truncated"), "{e}");
    }
    assert_eq!(err_of(b"P5 2 2 0\n"), "PGM maxval is 0");
    assert_eq!(err_of(b"P5 2 2 65536\n"), "PGM maxval 65536 exceeds 65535");
    assert!(err_of(b"P5 2 2 99999999999\n").contains("too large"));
    assert!(err_of(b"P5 2 -2 255\n").contains("unexpected character '-'"));
    assert!(err_of(b"P5 2 2").contains("ends before the maxval"));
    // A hint does not make content without a magic number decodable.
    for hint in [ImageKind::Pgm, ImageKind::Png] {
        let e = decode_bytes(b"no magic here", Some(hint), LIMIT).unwrap_err();
        assert!(!e.contains('\n'), "{e}");
    }
    // A PNG whose header claims a huge size cannot make png allocate past the limit.
    let samples = [0u16; 4];
    let mut bytes = make_png(&PngSpec {
        w: 1,
        h: 1,
        color: 6,
        depth: 16,
        interlace: false,
        samples: &samples,
        palette: None,
        trns: None,
    });
    // Patch IHDR to 2^30 x 4 pixels of RGBA16 and fix its CRC.
    bytes[16..20].copy_from_slice(&(1u32 << 30).to_be_bytes());
    bytes[20..24].copy_from_slice(&4u32.to_be_bytes());
    let crc = crc32(&bytes[12..29]);
    bytes[29..33].copy_from_slice(&crc.to_be_bytes());
    let e = decode_bytes(&bytes, None, 1 << 20).unwrap_err();
    assert!(e.contains("limit") || e.contains("Limit"), "{e}");
}

#[test]
fn row_api_misuse_is_an_error() {
    let bytes = pnm_binary("P5", 3, 2, 255, &[1, 2, 3, 4, 5, 6], 0);
    let mut d = Decoder::new(&bytes[..], Some(bytes.len() as u64), None, LIMIT).unwrap();
    assert!(d.read_row(&mut [0; 2]).is_err());
    let mut row = [0; 3];
    d.read_row(&mut row).unwrap();
    assert_eq!(row, [1, 2, 3]);
    d.read_row(&mut row).unwrap();
    assert_eq!(row, [4, 5, 6]);
    assert!(d.read_row(&mut row).is_err());
    assert!(d.finish().unwrap().is_empty());
    let d = Decoder::new(&bytes[..], None, None, LIMIT).unwrap();
    assert_eq!(d.finish().unwrap_err(), "finished after 0 of 2 rows");
}

#[test]
fn decoder_is_send() {
    fn send<T: Send>() {}
    send::<Decoder<&[u8]>>();
    send::<Decoder<BufReader<std::fs::File>>>();
}

#[test]
fn own_buffers_respect_the_limit() {
    // An interlaced PNG needs a width * height grey frame: refused under a smaller limit, before
    // any pixel is read.
    let samples = vec![0u16; 300 * 200];
    let spec = |interlace| PngSpec {
        w: 300,
        h: 200,
        color: 0,
        depth: 8,
        interlace,
        samples: &samples,
        palette: None,
        trns: None,
    };
    let e = decode_bytes(&make_png(&spec(true)), None, 50_000).unwrap_err();
    assert!(
        e.contains("interlaced PNG needs") && e.contains("limit of 50000"),
        "{e}"
    );
    assert!(decode_bytes(&make_png(&spec(false)), None, 50_000).is_ok());
}

#[test]
fn leading_zeros_in_ascii_samples_are_fine() {
    // image and netpbm accept them; only the value is bounded (at most 65535).
    let bytes = b"P2 2 1 255\n0000007 000000000000000000255\n";
    assert_same(bytes, "leading zeros");
    assert_eq!(ours(bytes).unwrap().2, [7, 255]);
}
