//! The bodies of the fuzz targets, shared by `fuzz/fuzz_targets/*.rs` (libFuzzer, `scripts/fuzz.sh`) and
//! by `tests/fuzz_regressions.rs`, which replays the kept corpus and every crash ever found in the
//! ordinary test suite. Each body panics exactly when it finds a bug: a panic inside the library, or two
//! backends that disagree.
#![allow(dead_code)]

use ogm_corners::cpu::CpuBackend;
use ogm_corners::decode::{Decoder, ImageKind};
use ogm_corners::map::{decode_image, MapYaml};
use ogm_corners::output::{self, Format};
use ogm_corners::{
    BaselineParams, ClassTable, DetectOptions, Detector, DetectorKind, OccupancyMap, RuleSet,
    Thresholds,
};

/// Bounds what one input may make the decoder allocate, so the fuzzer explores rather than swaps.
const MAX_DECODER_BYTES: u64 = 64 << 20;

/// Images decoded whole by the decode target: larger headers are only parsed (their memory is the
/// loader's budget's business, tested apart), so the fuzzer spends its time on the decoders' logic.
const MAX_DECODED_PIXELS: u64 = 1 << 18;

/// Image decoding and classification: any bytes, as PGM or PNG (content sniffed, or each hint), must decode
/// or fail with a one-line message; a decoded image is classified without a panic, and the row decoder
/// and the whole-image decoder agree.
pub fn decode(data: &[u8]) {
    for hint in [None, Some(ImageKind::Pgm), Some(ImageKind::Png)] {
        let open = || {
            Decoder::new(
                std::io::Cursor::new(data),
                Some(data.len() as u64),
                hint,
                MAX_DECODER_BYTES,
            )
        };
        let header = match open() {
            Ok(d) => d.header().clone(),
            Err(m) => {
                assert!(!m.contains('\n'), "a message of more than one line: {m:?}");
                // The whole-image path reads the same header, so it fails too.
                assert!(ogm_corners::decode::decode_bytes(data, hint, MAX_DECODER_BYTES).is_err());
                continue;
            }
        };
        assert!(header.width >= 1 && header.height >= 1);
        let pixels = u64::from(header.width) * u64::from(header.height);
        if pixels > MAX_DECODED_PIXELS {
            // A header may claim 4 Gpx in a few bytes; the loader's budget refuses those (tested apart).
            continue;
        }
        let whole = ogm_corners::decode::decode_bytes(data, hint, MAX_DECODER_BYTES);
        // The row by row path over a reader gives the same result.
        let rows = open().and_then(|mut d| {
            let mut px = vec![0u8; pixels as usize];
            for row in px.chunks_exact_mut(header.width as usize) {
                d.read_row(row)?;
            }
            d.finish().map(|_| px)
        });
        match (&whole, &rows) {
            (Ok((w, h, px, _)), Ok(rows)) => {
                assert_eq!((*w, *h), (header.width, header.height));
                assert_eq!(px, rows, "{w}x{h}: rows differ from the whole image");
                let classes = ClassTable::new(&Thresholds::default());
                let free = px
                    .iter()
                    .filter(|&&v| classes.state(v) == ogm_corners::CellState::Free)
                    .count();
                assert!(free <= px.len());
            }
            (Err(a), Err(b)) => {
                assert!(!a.contains('\n') && !b.contains('\n'), "{a:?} / {b:?}");
            }
            _ => panic!(
                "whole {:?} vs rows {:?}",
                whole.as_ref().err(),
                rows.as_ref().err()
            ),
        }
        let _ = decode_image(data, hint);
    }
}

/// The map yaml loader: any text parses or fails with a one-line message; what parses is valid.
pub fn yaml(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match MapYaml::parse(text) {
        Ok(m) => {
            assert!(m.resolution.is_finite() && m.resolution > 0.0);
            assert!(m.origin[0].is_finite() && m.origin[1].is_finite());
            assert!(m.thresholds.validate().is_ok());
            assert!(!m.image.is_empty());
        }
        Err(e) => assert!(!e.contains('\n'), "a message of more than one line: {e:?}"),
    }
}

/// The whole detection path on a small map: the bytes make a PGM (first bytes: options, width, height;
/// the rest: pixels), which is decoded and given to every detector on the fast CPU backend and on the
/// reference. Any difference between the two is a bug; so is a panic while writing the outputs.
pub fn detect(data: &[u8]) {
    let [flags, w, h, p0, p1, p2, p3, rest @ ..] = data else {
        return;
    };
    // Up to 32 x 32: large enough for every window and band edge, small enough for thousands of runs a second.
    let (w, h) = (u32::from(*w % 32) + 1, u32::from(*h % 32) + 1);
    let n = (w * h) as usize;
    // Three-state-heavy pixels: most bytes map to the ROS values, some stay grey.
    let px: Vec<u8> = (0..n)
        .map(|i| match rest.get(i).copied().unwrap_or(0) {
            v @ 0..=191 => [254, 0, 205][usize::from(v % 3)],
            v => v,
        })
        .collect();
    let mut pgm = format!("P5\n{w} {h}\n255\n").into_bytes();
    pgm.extend_from_slice(&px);
    let image = decode_image(&pgm, None).expect("a valid PGM decodes");
    assert_eq!(image.pixels(), &px[..]);
    let baseline = BaselineParams {
        sigma: 0.3 + f64::from(*p0) / 64.0,
        harris_k: f64::from(p1 % 200) / 1000.0,
        quality: f64::from(*p2) / 255.0,
        min_distance: f64::from(p3 % 12),
        max_corners: (flags & 0x10 != 0).then_some(usize::from(*p3 % 7)),
        t1: u32::from(*p1) * 200,
        t2: u32::from(*p2) * 300,
    };
    let map = OccupancyMap::from_image(image);
    let robust = ogm_corners::robust::RobustParams {
        min_scale: u32::from(p0 % 4),
        max_scale: u32::from(p1 % 18),
        nms_radius: u32::from(p2 % 9),
        min_strength: u32::from(p3 % 5),
        convex: flags & 4 != 0,
        angle: (flags & 8 != 0).then_some(f64::from(*p0) - 128.0),
    };
    for detector in [
        DetectorKind::Ogm,
        DetectorKind::OgmRobust,
        DetectorKind::Baseline(ogm_corners::Baseline::Harris),
        DetectorKind::Baseline(ogm_corners::Baseline::ShiTomasi),
        DetectorKind::Baseline(ogm_corners::Baseline::Trajkovic),
    ] {
        let options = DetectOptions {
            detector,
            baseline,
            rules: if flags & 1 == 0 {
                RuleSet::Paper
            } else {
                RuleSet::PaperMod2
            },
            unknown_as_occupied: flags & 2 != 0,
            robust,
            max_corners: (flags & 0x20 != 0).then_some(usize::from(*p2 % 9)),
        };
        let fast = Detector::new(options).detect(&map);
        let reference = Detector::with_backend(options, Box::new(CpuBackend)).detect(&map);
        match (&fast, &reference) {
            (Ok(a), Ok(b)) => assert_eq!(a, b, "{detector:?} {options:?}: fast CPU != reference"),
            (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string()),
            _ => panic!("{detector:?}: fast {fast:?} vs reference {reference:?}"),
        }
        if let Ok(det) = fast {
            for format in [Format::Csv, Format::Json] {
                let mut out = Vec::new();
                output::write_keypoints(&mut out, format, &map, &det, &options, "cpu").unwrap();
                assert!(std::str::from_utf8(&out).is_ok());
            }
        }
    }
}
