//! The bodies of the fuzz targets, shared by `fuzz/fuzz_targets/*.rs` (libFuzzer, `scripts/fuzz.sh`) and
//! by `tests/house/fuzz_regressions.rs`, which replays the kept corpus and every crash ever found in the
//! ordinary test suite. Each body panics exactly when it finds a bug: a panic inside the library, or two
//! backends (or two paths that must agree) that disagree.
#![allow(dead_code)]

use ogm_corners::backend::fast::FastCpuBackend;
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::backend::Backend;
use ogm_corners::detect::output::{self, Format};
use ogm_corners::map::decode::{Decoder, ImageKind};
use ogm_corners::map::{
    decode_image, grid_image, GridThresholds, MapYaml, GRID_FREE, GRID_OCCUPIED, GRID_UNKNOWN,
};
use ogm_corners::measure::pairs::PairSet;
use ogm_corners::merge::compose::{Canvas, MAX_CANVAS_FACTOR};
use ogm_corners::merge::footprint::{check_alignable, footprint};
use ogm_corners::merge::pair::align::{
    align_prepared_with, Acceptance, Alignment, MergeOptions, Prepared,
};
use ogm_corners::merge::pair::hypotheses::Hypotheses;
use ogm_corners::merge::pair::{
    at_resolution_of, compose_pair, merge_pair, overlay_pair, PairMerge,
};
use ogm_corners::merge::Rigid;
use ogm_corners::support::memory::Budget;
use ogm_corners::{
    BaselineParams, CellState, ClassTable, DetectOptions, Detector, DetectorKind, GeoRef, MapImage,
    OccupancyMap, RuleSet, Thresholds,
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
                assert!(
                    ogm_corners::map::decode::decode_bytes(data, hint, MAX_DECODER_BYTES).is_err()
                );
                continue;
            }
        };
        assert!(header.width >= 1 && header.height >= 1);
        let pixels = u64::from(header.width) * u64::from(header.height);
        if pixels > MAX_DECODED_PIXELS {
            // A header may claim 4 Gpx in a few bytes; the loader's budget refuses those (tested apart).
            continue;
        }
        let whole = ogm_corners::map::decode::decode_bytes(data, hint, MAX_DECODER_BYTES);
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
    // What a folder search reads of any file's first bytes: never a panic.
    let _ = ogm_corners::support::marks::mark_in(data);
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = MapYaml::meant_image(text);
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
    let robust = ogm_corners::detect::robust::RobustParams {
        min_scale: u32::from(p0 % 4),
        max_scale: u32::from(p1 % 18),
        nms_radius: u32::from(p2 % 9),
        min_strength: u32::from(p3 % 5),
        convex: flags & 4 != 0,
        angle: (flags & 8 != 0).then_some(f64::from(*p0) - 128.0),
        // Anchors near the map, far off it, and past the farthest allowed (refused).
        anchor: match flags >> 6 {
            0 => ogm_corners::detect::robust::Anchor::World,
            1 => ogm_corners::detect::robust::Anchor::Centre,
            2 => ogm_corners::detect::robust::Anchor::Point(
                f64::from(*p1) / 3.0 - 20.0,
                f64::from(*p2),
            ),
            _ => ogm_corners::detect::robust::Anchor::Point(f64::from(*p3) * 8192.0 - 1e6, -3.5),
        },
        // Shares of 0 to 104 percent and gaps of 0 to 69: the out-of-range ones must be refused.
        cells: ogm_corners::backend::reference::coarsen::CellRule {
            occupied_pct: u32::from(*p1 % 105),
            free_pct: u32::from(*p2 % 105),
        },
        wall_gap: u32::from(*p3 % 70),
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
        let reference = Detector::with_backend(options, Box::new(ReferenceBackend)).detect(&map);
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

/// Reads fuzz bytes front to back; zeros once they run out, so every input means something.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }

    /// Any f64 bit pattern (NaN, infinities, subnormals included).
    fn raw_f64(&mut self) -> f64 {
        let mut b = [0u8; 8];
        for x in &mut b {
            *x = self.u8();
        }
        f64::from_le_bytes(b)
    }

    /// Mostly a value of `table` (what real files hold), sometimes any f64 bit pattern.
    fn number(&mut self, table: &[f64]) -> f64 {
        match table.get(usize::from(self.u8()) % (table.len() + 1)) {
            Some(&v) => v,
            None => self.raw_f64(),
        }
    }

    fn pick<T: Copy>(&mut self, table: &[T]) -> T {
        table[usize::from(self.u8()) % table.len()]
    }
}

/// A pixel from a byte: most bytes become the three ROS values, the rest stay grey levels (which the
/// thresholds, and negate, decide).
fn shade(v: u8) -> u8 {
    match v {
        0..=191 => [254, 0, 205][usize::from(v % 3)],
        v => v,
    }
}

/// The biggest side of a map the merge target builds: milliseconds a merge, and every stage of the
/// aligner (coarse cells, crop margins, symmetry) still reached.
const MERGE_SIDE: u8 = 96;

/// What the merge target lets one input allocate (the maps, B at A's resolution and their preparations,
/// estimated as `merge A B` estimates them): B resampled to a few hundred pixels a side at most, so one
/// execution stays short.
const MERGE_BUDGET: u64 = 12 << 20;

/// A map yaml from the bytes: real values mostly, broken or extreme ones sometimes (resolution, origin,
/// yaw, negate, thresholds, mode), written as a person or `map_saver` would.
fn merge_yaml(b: &mut Bytes) -> String {
    let res = b.number(&[
        0.05,
        0.05,
        0.05,
        0.1,
        0.025,
        0.07,
        // Within and just past the aligner's tolerance for "the same resolution".
        0.05 * (1.0 + 1e-10),
        0.05 * (1.0 + 1e-6),
        0.2,
        0.0,
        -0.05,
    ]);
    let ox = b.number(&[0.0, -10.0, 3.25, -100.5, 1e6, -1e300]);
    let oy = b.number(&[0.0, -10.0, 3.25, -100.5, 1e6, 1e300]);
    let yaw = match b.u8() % 6 {
        0 => "0.0".to_string(),
        1 => "1.5707963".to_string(),
        2 => "-3.14".to_string(),
        3 => "nan".to_string(),
        4 => ".nan".to_string(),
        _ => format!("{:?}", b.raw_f64()),
    };
    let negate = b.pick(&[
        "",
        "negate: 0\n",
        "negate: 1\n",
        "negate: true\n",
        "negate: 2\n",
    ]);
    let mut thresh = |key: &str| match b.u8() % 8 {
        0 => String::new(),
        1 => format!("{key}: 0.65\n"),
        2 => format!("{key}: 0.196\n"),
        3 => format!("{key}: 0.5\n"),
        4 => format!("{key}: 0\n"),
        5 => format!("{key}: 1\n"),
        6 => format!("{key}: 1.5\n"),
        _ => format!("{key}: {:?}\n", b.raw_f64()),
    };
    let occupied = thresh("occupied_thresh");
    let free = thresh("free_thresh");
    let mode = b.pick(&[
        "",
        "mode: trinary\n",
        "mode: scale\n",
        "mode: raw\n",
        "mode: 3\n",
    ]);
    format!(
        "image: map.pgm\nresolution: {res:?}\norigin: [{ox:?}, {oy:?}, {yaw}]\n{negate}{occupied}{free}{mode}"
    )
}

/// Pixels of a `w` x `h` map from the bytes: raw (one byte a pixel, [`shade`]d) or rooms (free rectangles
/// walled with occupied pixels, on unknown: what the aligner finds walls in).
fn merge_pixels(b: &mut Bytes, w: u32, h: u32, raw: bool) -> Vec<u8> {
    let n = (w * h) as usize;
    if raw {
        return (0..n).map(|_| shade(b.u8())).collect();
    }
    let mut px = vec![205u8; n];
    for _ in 0..b.u8() % 16 {
        let (x0, y0) = (u32::from(b.u8()) % w, u32::from(b.u8()) % h);
        let (x1, y1) = (
            (x0 + 2 + u32::from(b.u8()) % w).min(w - 1),
            (y0 + 2 + u32::from(b.u8()) % h).min(h - 1),
        );
        for y in y0..=y1 {
            for x in x0..=x1 {
                let wall = x == x0 || x == x1 || y == y0 || y == y1;
                px[(y * w + x) as usize] = if wall { 0 } else { 254 };
            }
        }
    }
    px
}

/// A few pixels changed: what tells two maps of one place apart.
fn merge_noise(b: &mut Bytes, w: u32, h: u32, px: &mut [u8]) {
    for _ in 0..b.u8() % 16 {
        let (x, y) = (u32::from(b.u8()) % w, u32::from(b.u8()) % h);
        px[(y * w + x) as usize] = shade(b.u8());
    }
}

/// B cut from A: a window of A (`cw` x `ch` at (x0, y0)) turned by `q` quarter turns.
fn cut(a: &MapImage, x0: u32, y0: u32, cw: u32, ch: u32, q: u8) -> (u32, u32, Vec<u8>) {
    let (x0, y0) = (x0 % a.width(), y0 % a.height());
    let (cw, ch) = (1 + cw % (a.width() - x0), 1 + ch % (a.height() - y0));
    let at = |x: u32, y: u32| a.get(x0 + x, y0 + y);
    let (w, h) = if q & 1 == 0 { (cw, ch) } else { (ch, cw) };
    let mut px = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            px.push(match q % 4 {
                0 => at(x, y),
                1 => at(y, ch - 1 - x),
                2 => at(cw - 1 - x, ch - 1 - y),
                _ => at(cw - 1 - y, x),
            });
        }
    }
    (w, h, px)
}

/// A map as the loader makes it from a yaml and an image (`yaml` None: an image alone): the yaml
/// parsed, its world coordinates checked against the size. None where the loader refuses it.
fn loaded_map(image: MapImage, yaml: Option<&str>) -> Option<OccupancyMap> {
    let Some(text) = yaml else {
        return Some(OccupancyMap::from_image(image));
    };
    let meta = match MapYaml::parse(text) {
        Ok(m) => m,
        Err(e) => {
            assert!(!e.contains('\n'), "a message of more than one line: {e:?}");
            return None;
        }
    };
    let georef = meta.georef();
    if let Err(e) = georef.check_finite(image.width(), image.height()) {
        assert!(!e.contains('\n'), "a message of more than one line: {e:?}");
        return None;
    }
    Some(OccupancyMap {
        thresholds: meta.thresholds,
        georef: Some(georef),
        ..OccupancyMap::from_image(image)
    })
}

/// The merge options from the bytes: the hypotheses' source and detector, the acceptance rule (the
/// calibrated one, one that accepts nearly anything, or any numbers), the symmetry check, the ranking.
fn merge_options(flags: u8, b: &mut Bytes) -> MergeOptions {
    let kinds = [
        DetectorKind::Ogm,
        DetectorKind::OgmRobust,
        DetectorKind::Baseline(ogm_corners::Baseline::Harris),
        DetectorKind::Baseline(ogm_corners::Baseline::ShiTomasi),
        DetectorKind::Baseline(ogm_corners::Baseline::Trajkovic),
    ];
    let h = b.u8();
    let kind = kinds[usize::from(h / 3) % kinds.len()];
    let hypotheses = match h % 3 {
        0 => Hypotheses::Dense,
        1 => Hypotheses::Corners(kind),
        _ => Hypotheses::Both(kind),
    };
    let d = Acceptance::default();
    let accept = match b.u8() % 4 {
        0 => d,
        // Accepts what no veto declines: the merged map and picture of nearly every pair.
        1 => Acceptance {
            threshold: -1e3,
            ..d
        },
        2 => Acceptance {
            threshold: d.threshold - f64::from(b.u8()) / 4.0,
            ..d
        },
        _ => Acceptance {
            w_coarse: b.raw_f64(),
            w_free_inside: b.raw_f64(),
            w_free_disagree: b.raw_f64(),
            threshold: b.raw_f64(),
        },
    };
    MergeOptions {
        accept,
        hypotheses,
        check_symmetry: flags & 0x20 == 0,
        always_verify: flags & 0x40 != 0,
        // The hypotheses' byte's bits above its 15 sources: no byte more read, so saved inputs replay.
        ranking: if (h / 15) & 1 == 0 {
            ogm_corners::merge::Ranking::Choice
        } else {
            ogm_corners::merge::Ranking::Evidence
        },
    }
}

/// The two-map merge (`merge A B`, the Python `merge`): two small maps (rooms or raw pixels, B drawn
/// apart or cut from A and turned, a few pixels changed) with their yaml (resolution, origin, yaw,
/// negate, thresholds, mode) or none, checked against a memory budget as the CLI checks them, then
/// merged: B brought to A's resolution, aligned, the verdict, the merged map and the picture. A panic is
/// a bug; so is a verdict that contradicts itself, or a merged map and a picture on different canvases.
/// Transforms include non-finite ones and ones past any canvas: refused, never overflowed.
pub fn merge(data: &[u8]) {
    merge_with(data);
}

fn merge_with(data: &[u8]) {
    let mut b = Bytes(data);
    // Bits: 1 A without yaml, 2 B without yaml, 4 B cut from A, 8 raw pixels, 0x10 also on the
    // reference backend, 0x20 no symmetry check, 0x40 always verify, 0x80 composed with the bytes' own
    // transform too.
    let flags = b.u8();
    let options = merge_options(flags, &mut b);
    let (wa, ha) = (
        1 + u32::from(b.u8() % MERGE_SIDE),
        1 + u32::from(b.u8() % MERGE_SIDE),
    );
    let (yaml_a, yaml_b) = (merge_yaml(&mut b), merge_yaml(&mut b));
    let mut pa = merge_pixels(&mut b, wa, ha, flags & 8 != 0);
    merge_noise(&mut b, wa, ha, &mut pa);
    let image_a = MapImage::new(wa, ha, pa).expect("a well-sized image");
    let (wb, hb, mut pb) = if flags & 4 != 0 {
        let (x0, y0, cw, ch, q) = (b.u8(), b.u8(), b.u8(), b.u8(), b.u8());
        cut(&image_a, x0.into(), y0.into(), cw.into(), ch.into(), q)
    } else {
        let (wb, hb) = (
            1 + u32::from(b.u8() % MERGE_SIDE),
            1 + u32::from(b.u8() % MERGE_SIDE),
        );
        (wb, hb, merge_pixels(&mut b, wb, hb, flags & 8 != 0))
    };
    merge_noise(&mut b, wb, hb, &mut pb);
    let image_b = MapImage::new(wb, hb, pb).expect("a well-sized image");
    let Some(a) = loaded_map(image_a, (flags & 1 == 0).then_some(yaml_a.as_str())) else {
        return;
    };
    let Some(b_map) = loaded_map(image_b, (flags & 2 == 0).then_some(yaml_b.as_str())) else {
        return;
    };

    // What the merge holds (B at A's resolution, both preparations), estimated and checked as `merge A B`
    // checks it before loading anything more.
    let fa = footprint(&a, None).expect("a map kept as it is");
    let fb = match footprint(&b_map, a.georef.map(|g| g.resolution)) {
        Ok(f) => f,
        Err(e) => {
            // Past the largest map: resampling refuses it the same way, before allocating.
            let m = e.to_string();
            assert!(!m.contains('\n'), "a message of more than one line: {m:?}");
            let r = merge_pair(&a, &b_map, &options, &mut FastCpuBackend);
            assert!(r.is_err(), "B was resampled past the largest map: {m}");
            return;
        }
    };
    let budget = Budget::new(MERGE_BUDGET);
    if budget
        .check("the two maps", fa.bytes().saturating_add(fb.bytes()))
        .is_err()
        || check_alignable(&fa, &fb).is_err()
    {
        return;
    }

    // `merge_pair` prepares its maps without corners: with corner hypotheses, B is brought to A's
    // resolution and both are prepared with their corners, as `merge-eval` does.
    let run = |backend: &mut dyn Backend| -> ogm_corners::Result<(Alignment, Option<PairMerge>)> {
        match options.hypotheses.detector() {
            None => {
                merge_pair(&a, &b_map, &options, backend).map(|m| (m.alignment.clone(), Some(m)))
            }
            Some(d) => {
                let (b_res, _) = at_resolution_of(&a, &b_map)?;
                let (pa, pb) = (
                    Prepared::with_corners(&a, d)?,
                    Prepared::with_corners(&b_res, d)?,
                );
                align_prepared_with(&pa, &pb, &options, backend).map(|al| (al, None))
            }
        }
    };
    let (al, pair) = match run(&mut FastCpuBackend) {
        Ok(r) => r,
        Err(e) => {
            let m = e.to_string();
            assert!(!m.contains('\n'), "a message of more than one line: {m:?}");
            return;
        }
    };
    assert_eq!(al.accepted, al.reason.is_none(), "{al:?}");
    if let Some(r) = &al.reason {
        assert!(!r.contains('\n'), "a reason of more than one line: {r:?}");
    }
    if let Some(c) = al.candidates.first() {
        assert_eq!(
            format!("{:?}", c.transform),
            format!("{:?}", al.transform),
            "the chosen candidate is not the transform"
        );
    }
    assert!(!al.explain().contains('\n'));
    if let Some(merged) = &pair {
        assert!(merged.b_scale >= 0.0, "b_scale {}", merged.b_scale);
        assert_eq!(
            merged.world.is_some(),
            a.georef.is_some() && b_map.georef.is_some()
        );
        serde_json::to_string(&merged.verdict()).expect("a verdict serialises");
    }
    if flags & 0x10 != 0 {
        // Every backend scores the candidates with the same counts: the reference gives the same result.
        let (reference, _) = run(&mut ReferenceBackend).expect("aligned once already");
        assert_eq!(
            format!("{reference:?}"),
            format!("{al:?}"),
            "the reference backend aligns differently"
        );
    }

    let mut transforms = vec![al.transform];
    if flags & 0x80 != 0 {
        let table = [0.0, 90.0, -33.5, 1e3, 1e19, -1e300, f64::NAN, f64::INFINITY];
        transforms.push(Rigid {
            theta_deg: b.number(&table),
            tx: b.number(&table),
            ty: b.number(&table),
        });
    }
    // B at A's resolution: the transforms map its pixels.
    let (bw, bh) = (fb.width as u32, fb.height as u32);
    for t in transforms {
        // The canvas, known before anything is drawn on it: refused past a few times the two maps
        // (before allocating), else counted against the budget as `merge A B` counts it.
        let limit = (u64::from(wa * ha) + u64::from(bw) * u64::from(bh)) * MAX_CANVAS_FACTOR;
        let (cw, ch, refused) = match Canvas::of(wa, ha, bw, bh, &t) {
            Ok(c) => (c.width(), c.height(), c.pixels() > limit),
            Err(e) => {
                let e = e.to_string();
                assert!(!e.contains('\n'), "{e:?}");
                (0, 0, true)
            }
        };
        if !refused && budget.check("the canvas", cw * ch * 7).is_err() {
            continue;
        }
        // The merged map and the picture share that canvas: both made, or both refused.
        let composed = compose_pair(&a, &b_map, &t);
        let picture = overlay_pair(&a, &b_map, &t);
        match (&composed, &picture) {
            (Ok(m), Ok(p)) => {
                assert!(!refused, "{t:?}: a {cw}x{ch} canvas made");
                assert_eq!((m.image.width(), m.image.height()), p.dimensions());
                assert_eq!((u64::from(p.width()), u64::from(p.height())), (cw, ch));
                assert!(m.image.width() >= wa && m.image.height() >= ha);
                assert_eq!(m.georef.is_some(), a.georef.is_some());
                assert!(m.image.pixels().iter().all(|v| [0, 205, 254].contains(v)));
            }
            (Err(x), Err(y)) => {
                let (x, y) = (x.to_string(), y.to_string());
                assert!(!x.contains('\n') && !y.contains('\n'), "{x:?} / {y:?}");
                assert!(refused, "{t:?}: a {cw}x{ch} canvas refused: {x}");
            }
            _ => panic!(
                "{t:?}: merged map {:?} vs picture {:?}",
                composed.as_ref().err(),
                picture.as_ref().err()
            ),
        }
    }
}

/// The pair-file loader (`merge-eval --pairs`): any bytes, as a file, load or fail with a one-line
/// message; what loads is what the loader promises (finite numbers, as many points in both maps, at
/// least one) and what plain JSON parsing of the format gives; the success test runs on every pair.
pub fn pairs(data: &[u8]) {
    use std::sync::atomic::{AtomicU64, Ordering};
    // The loader reads files only; one name a call, so replays on several threads do not collide.
    static CALLS: AtomicU64 = AtomicU64::new(0);
    let path = std::env::temp_dir().join(format!(
        "ogm-corners-fuzz-pairs-{}-{}.json",
        std::process::id(),
        CALLS.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&path, data).expect("a temporary file");
    let loaded = PairSet::load(&path);
    let _ = std::fs::remove_file(&path);
    // The format without the loader's checks.
    let parsed = std::str::from_utf8(data)
        .ok()
        .and_then(|t| serde_json::from_str::<PairSet>(t).ok());
    let set = match loaded {
        Ok(set) => set,
        Err(e) => {
            let m = e.to_string();
            assert!(!m.contains('\n'), "a message of more than one line: {m:?}");
            return;
        }
    };
    let parsed = parsed.expect("what the loader reads, plain parsing reads");
    assert_eq!(parsed.pairs.len(), set.pairs.len());
    assert_eq!(parsed.negatives.len(), set.negatives.len());
    let estimates = [
        Rigid::IDENTITY,
        Rigid {
            theta_deg: 185.0,
            tx: -3.0,
            ty: 1e3,
        },
    ];
    for p in &set.pairs {
        assert!(!p.src_points.is_empty() && p.src_points.len() == p.dst_points.len());
        let numbers = [p.theta_deg, p.tx, p.ty, p.rms_limit_px, p.rot_limit_deg];
        assert!(numbers
            .iter()
            .chain(p.src_points.iter().chain(&p.dst_points).flatten())
            .all(|v| v.is_finite()));
        for t in estimates.iter().copied().chain([p.truth()]) {
            let (rot, rms) = p.errors(&t);
            // NaN only where the numbers overflow (a difference of two numbers near f64::MAX).
            assert!(
                rot.is_nan() || (0.0..=180.0).contains(&rot),
                "rotation error {rot}"
            );
            assert!(rms.is_nan() || rms >= 0.0, "RMS error {rms}");
            let _ = p.accurate(&t);
        }
        let (rot, _) = p.errors(&p.truth());
        assert!(
            rot == 0.0 || rot.is_nan(),
            "the truth is {rot} deg off itself"
        );
        // Where merge-eval looks for the maps, whatever the names.
        for name in [&p.src, &p.dst] {
            let _ = ogm_corners::measure::merging::map_path(
                std::path::Path::new("fuzz-no-such-dir"),
                name,
            );
        }
    }
}

/// Grid sizes beyond any cell count the fuzzer makes: refused from the size alone.
const GRID_SIZES: [u32; 6] = [0, 1, 65535, 65536, 1 << 31, u32::MAX];

/// The ROS `nav_msgs/OccupancyGrid` conversion (`OccupancyMap::from_occupancy_grid`, `grid_image`,
/// `to_occupancy_grid`): any cells, size, resolution, origin and thresholds give a map exactly when
/// they are valid, drawn as `map_saver` draws it (rows flipped, three values), which converts back to the
/// cells' states; detecting in the cells in place finds what detecting in the drawn map finds; and any map
/// with any thresholds converts to cells and back to its own states.
pub fn grid(data: &[u8]) {
    let mut b = Bytes(data);
    // Bits: 1-2 how the size relates to the cells, 4 detect in the cells (small grids), 8 the baselines
    // too, 0x10 raw cells (else mostly -1, 0 and 100).
    let flags = b.u8();
    let (w, h) = (b.u8(), b.u8());
    let resolution = b.number(&[
        0.05,
        0.05,
        1.0,
        0.0,
        -0.05,
        5e-324,
        1e300,
        f64::MAX,
        f64::NAN,
        f64::INFINITY,
    ]);
    let coordinates = [0.0, -12.5, 1e6, 1e308, -1e308, f64::NAN, f64::INFINITY];
    let origin = [
        b.number(&coordinates),
        b.number(&coordinates),
        b.number(&[
            0.0,
            std::f64::consts::FRAC_PI_2,
            -3.0,
            f64::NAN,
            f64::INFINITY,
        ]),
    ];
    let thresholds_table = [0.65, 0.25, 0.196, 0.0, 1.0, 0.5, -0.01, 1.01, f64::NAN];
    let t = GridThresholds {
        occupied_thresh: b.number(&thresholds_table),
        free_thresh: b.number(&thresholds_table),
    };
    let image_thresholds = Thresholds {
        negate: b.u8() & 1 != 0,
        occupied_thresh: b.number(&thresholds_table),
        free_thresh: b.number(&thresholds_table),
    };
    let rest = b.0;
    let cell = |v: u8| {
        if flags & 0x10 != 0 {
            v
        } else {
            match v {
                0..=191 => [GRID_UNKNOWN, GRID_FREE, GRID_OCCUPIED][usize::from(v % 3)] as u8,
                v => v & 0x7f,
            }
        }
    };
    let (width, height, cells): (u32, u32, Vec<u8>) = match flags & 3 {
        // As many cells as the size says, up to 64 x 64.
        0 | 1 => {
            let (w, h) = (1 + u32::from(w % 64), 1 + u32::from(h % 64));
            let cells = (0..(w * h) as usize)
                .map(|i| cell(rest.get(i).copied().unwrap_or(0)))
                .collect();
            (w, h, cells)
        }
        // The cells as they are, the width from the bytes: the height fits when the width divides them.
        2 => {
            let cells: Vec<u8> = rest.iter().map(|&v| cell(v)).collect();
            let w = 1 + u32::from(w);
            (w, cells.len() as u32 / w, cells)
        }
        // Sizes no cell count here matches.
        _ => (
            GRID_SIZES[usize::from(w) % GRID_SIZES.len()],
            GRID_SIZES[usize::from(h) % GRID_SIZES.len()],
            rest.iter().map(|&v| cell(v)).collect(),
        ),
    };
    let result = OccupancyMap::from_occupancy_grid(&cells, width, height, resolution, origin, &t);
    let georef_ok = GeoRef::checked(resolution, origin)
        .is_ok_and(|g| g.check_finite(width.max(1), height.max(1)).is_ok());
    let valid = width > 0
        && height > 0
        && u64::from(width) * u64::from(height) == cells.len() as u64
        && georef_ok
        && t.cell_values().is_ok();
    let map = match result {
        Ok(map) => map,
        Err(e) => {
            let m = e.to_string();
            assert!(!m.contains('\n'), "a message of more than one line: {m:?}");
            assert!(!valid, "a valid grid refused: {m}");
            return;
        }
    };
    assert!(valid, "an invalid grid accepted");
    let (w, h) = (width as usize, height as usize);
    assert_eq!((map.image.width(), map.image.height()), (width, height));
    let g = map.georef.expect("a grid is georeferenced");
    assert_eq!(g.resolution.to_bits(), resolution.to_bits());
    assert!(g
        .origin
        .iter()
        .zip(origin)
        .all(|(x, y)| x.to_bits() == y.to_bits()));
    assert_eq!(map.thresholds, Thresholds::default());
    let classes = t.class_table().expect("valid thresholds");
    let (free, occupied) = t.cell_values().expect("valid thresholds");
    assert!(free <= occupied);
    // Image row y is grid row h - 1 - y, drawn with map_server's values; back to cells, each the value
    // of its state.
    let back = map.to_occupancy_grid();
    for y in 0..h {
        for x in 0..w {
            let state = classes.state(cells[(h - 1 - y) * w + x]);
            assert_eq!(map.image.pixels()[y * w + x], state.map_server_value());
            let value = match state {
                CellState::Free => GRID_FREE,
                CellState::Occupied => GRID_OCCUPIED,
                CellState::Unknown => GRID_UNKNOWN,
            };
            assert_eq!(back[(h - 1 - y) * w + x], value);
        }
    }
    assert_eq!(
        grid_image(&cells, width, height, &t).expect("valid grid"),
        map.image
    );
    // The published cells, read back with the defaults, draw the same map.
    let back_bytes: Vec<u8> = back.iter().map(|&c| c as u8).collect();
    let again = OccupancyMap::from_occupancy_grid(
        &back_bytes,
        width,
        height,
        resolution,
        origin,
        &GridThresholds::default(),
    )
    .expect("the same grid, published");
    assert_eq!(again.image, map.image);

    if flags & 4 != 0 && w * h <= 32 * 32 {
        // Detecting in the cells in place (rows flipped into image order, as a node hands them over)
        // finds what detecting in map_saver's image finds.
        let mut flipped = Vec::with_capacity(cells.len());
        for row in cells.chunks_exact(w).rev() {
            flipped.extend_from_slice(row);
        }
        let in_place = MapImage::new(width, height, flipped).expect("a well-sized image");
        let mut kinds = vec![DetectorKind::Ogm, DetectorKind::OgmRobust];
        if flags & 8 != 0 {
            kinds.push(DetectorKind::Baseline(ogm_corners::Baseline::Harris));
            kinds.push(DetectorKind::Baseline(ogm_corners::Baseline::Trajkovic));
        }
        for detector in kinds {
            let mut d = Detector::new(DetectOptions {
                detector,
                ..DetectOptions::default()
            });
            let from_cells = d.detect_classified(&in_place, &classes);
            let from_image = d.detect_image(&map.image, &Thresholds::default());
            match (&from_cells, &from_image) {
                (Ok(x), Ok(y)) => assert_eq!(x, y, "{detector:?}: cells != image"),
                (Err(x), Err(y)) => assert_eq!(x.to_string(), y.to_string()),
                _ => panic!("{detector:?}: cells {from_cells:?} vs image {from_image:?}"),
            }
        }
    }

    // Any map, read with any valid thresholds, publishes cells of its own states.
    if image_thresholds.validate().is_ok() {
        let grey = OccupancyMap {
            thresholds: image_thresholds,
            ..OccupancyMap::from_image(MapImage::new(width, height, cells.clone()).expect("sized"))
        };
        let published = grey.to_occupancy_grid();
        let read = ClassTable::new(&image_thresholds);
        let bytes: Vec<u8> = published.iter().map(|&c| c as u8).collect();
        let drawn = grid_image(&bytes, width, height, &GridThresholds::default()).expect("valid");
        for y in 0..h {
            for x in 0..w {
                let state = read.state(cells[y * w + x]);
                assert_eq!(drawn.pixels()[y * w + x], state.map_server_value());
            }
        }
    }
}
