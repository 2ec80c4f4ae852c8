//! Streamed detection ([`Detector::detect_streamed`]): the keypoints of a map read in windows of rows are
//! the reference's on the whole map, bit for bit and in the same order, for every streamed detector, on
//! every backend, for windows down to two rows; files of every format stream through the command line to
//! the same keypoint files as the in-memory path; and a map far larger than a memory cap streams under it.

use crate::common;
use std::path::Path;

use ogm_corners::backend::baselines::{cpu_scores, select, Baseline, BaselineParams};
use ogm_corners::backend::fast::FastCpuBackend;
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::detect::detector::strongest;
use ogm_corners::detect::output::{self, Format};
use ogm_corners::map::stream::{RowSource, SliceRows};
use ogm_corners::map::synthetic::{office_map, OfficeRows};
use ogm_corners::{
    Backend, ClassTable, DetectOptions, Detector, DetectorKind, Keypoint, MapImage, OccupancyMap,
    RuleSet, RuleTable, Thresholds,
};

const STREAMED: [DetectorKind; 4] = [
    DetectorKind::Ogm,
    DetectorKind::Baseline(Baseline::Harris),
    DetectorKind::Baseline(Baseline::ShiTomasi),
    DetectorKind::Baseline(Baseline::Trajkovic),
];

/// The oracle: the plain reference on the whole map (the OGM kernel, or the score map and the reference's
/// selection), then the cap.
fn oracle(image: &MapImage, o: &DetectOptions) -> Vec<Keypoint> {
    let classes = ClassTable::new(&Thresholds::default());
    let found = match o.detector {
        DetectorKind::Baseline(kind) => {
            let scores = cpu_scores(kind, image, &o.baseline.exact().unwrap());
            select(kind, &scores, image.width(), image.height(), &o.baseline)
                .into_iter()
                .map(|(x, y, v)| Keypoint::scored(x, y, v))
                .collect()
        }
        _ => ReferenceBackend
            .detect(
                image,
                &classes,
                &RuleTable::new(o.rules),
                o.unknown_as_occupied,
            )
            .unwrap(),
    };
    match o.max_corners {
        Some(n) => strongest(found, n, o.detector).unwrap(),
        None => found,
    }
}

/// The keypoints of `image` streamed through `backend` in windows of `window` bytes (None: the backend's
/// choice), and how many calls of the sink and windows it took.
fn streamed(
    backend: Box<dyn Backend>,
    o: &DetectOptions,
    image: &MapImage,
    window: Option<u64>,
) -> (Vec<Keypoint>, usize, usize) {
    let mut d = Detector::with_backend(*o, backend);
    d.set_window_bytes(window);
    let classes = ClassTable::new(&Thresholds::default());
    let (mut out, mut sinks, mut windows) = (Vec::new(), 0, 0);
    let mut src = SliceRows::new(image);
    let done = d
        .detect_streamed(
            &mut src,
            &classes,
            None,
            &mut |k| {
                sinks += 1;
                out.extend_from_slice(k);
                Ok(())
            },
            &mut |_, _| windows += 1,
        )
        .unwrap();
    assert_eq!(done.count, out.len() as u64);
    assert_eq!((done.width, done.height), (image.width(), image.height()));
    (out, sinks, windows)
}

fn options(detector: DetectorKind) -> Vec<DetectOptions> {
    let base = DetectOptions {
        detector,
        ..DetectOptions::default()
    };
    match detector {
        DetectorKind::Ogm => vec![
            base,
            DetectOptions {
                unknown_as_occupied: true,
                rules: RuleSet::PaperMod2,
                ..base
            },
        ],
        _ => vec![
            base,
            DetectOptions {
                max_corners: Some(40),
                baseline: BaselineParams {
                    quality: 0.002,
                    min_distance: 9.0,
                    ..BaselineParams::default()
                },
                ..base
            },
        ],
    }
}

/// Maps whose heights are odd and even, with corners right at window edges.
fn maps() -> Vec<(String, MapImage)> {
    vec![
        ("noise 61x97".into(), common::random_map(61, 97, 3)),
        ("noise 130x41".into(), common::random_map(130, 41, 6)),
        ("office 200x151".into(), office_map(200, 151, 4).unwrap()),
        (
            "cluttered 180x120".into(),
            common::cluttered_office(180, 120, 2),
        ),
        (
            "3x3 configurations".into(),
            common::all_3x3_configurations(),
        ),
        ("one row".into(), common::random_map(50, 1, 1)),
        ("two rows".into(), common::random_map(3, 2, 1)),
    ]
}

#[test]
fn streamed_keypoints_are_the_whole_maps_on_the_fast_path() {
    for (name, image) in maps() {
        let w = u64::from(image.width());
        for detector in STREAMED {
            for o in options(detector) {
                let want = oracle(&image, &o);
                // Cores of 2 rows (the smallest), 6, 30, and the backend's own (one window here).
                for window in [Some(w), Some(22 * w), Some(46 * w), None] {
                    let (got, sinks, windows) =
                        streamed(Box::new(FastCpuBackend), &o, &image, window);
                    assert!(
                        got == want,
                        "{name}, {}, window {window:?}: {} keypoints streamed, {} in the reference",
                        detector.name(),
                        got.len(),
                        want.len()
                    );
                    let h = image.height() as usize;
                    if window == Some(w) {
                        assert_eq!(windows, h.div_ceil(2), "{name}");
                    }
                    // The OGM keypoints are handed over window by window; the baselines' (and capped
                    // lists) at the end, none when there are none.
                    let streams = detector == DetectorKind::Ogm && o.max_corners.is_none();
                    let at_end = usize::from(!got.is_empty());
                    assert_eq!(sinks, if streams { windows } else { at_end }, "{name}");
                }
            }
        }
    }
}

#[test]
fn streamed_keypoints_are_the_whole_maps_on_the_reference() {
    // The reference detects each window as an image of its own (the backends' default route).
    for (name, image) in maps().into_iter().take(4) {
        let w = u64::from(image.width());
        for detector in STREAMED {
            for o in options(detector) {
                let want = oracle(&image, &o);
                for window in [Some(w), Some(30 * w)] {
                    let (got, _, _) = streamed(Box::new(ReferenceBackend), &o, &image, window);
                    assert!(got == want, "{name}, {}, {window:?}", detector.name());
                }
            }
        }
    }
}

#[test]
fn streamed_keypoints_are_the_whole_maps_on_the_gpu() {
    let Some(_) = common::gpu_backend(Default::default()) else {
        return;
    };
    for (name, image) in maps().into_iter().take(5) {
        let w = u64::from(image.width());
        for detector in STREAMED {
            let o = DetectOptions {
                detector,
                ..DetectOptions::default()
            };
            let want = oracle(&image, &o);
            for window in [Some(w), Some(40 * w)] {
                let gpu = common::gpu_backend(Default::default()).unwrap();
                let (got, _, _) = streamed(Box::new(gpu), &o, &image, window);
                assert!(got == want, "{name}, {}, {window:?}", detector.name());
            }
        }
    }
}

/// The robust detector streams too: the rows once into a temporary file, then tiles of its turned grid,
/// with the keypoints (and the angle, and the strongest N) of the map in memory.
#[test]
fn the_robust_detector_streams_in_tiles_to_its_in_memory_keypoints() {
    let image = common::floor_plan(1100, 800, 7);
    let thresholds = Thresholds::default();
    let classes = ClassTable::new(&thresholds);
    for max_corners in [None, Some(12)] {
        let options = DetectOptions {
            detector: DetectorKind::OgmRobust,
            max_corners,
            ..DetectOptions::default()
        };
        let want = Detector::new(options)
            .detect_image(&image, &thresholds)
            .unwrap();
        let mut d = Detector::new(options);
        // The smallest tiles: a dozen of them over this map.
        d.set_window_bytes(Some(1));
        let plan = d.tile_plan().unwrap();
        assert!(plan.tile * 4 <= image.width(), "{plan:?}");
        let (mut got, mut rows) = (Vec::new(), 0);
        let done = d
            .detect_streamed(
                &mut SliceRows::new(&image),
                &classes,
                None,
                &mut |k| {
                    got.extend_from_slice(k);
                    Ok(())
                },
                &mut |_, core| rows += core.1 - core.0,
            )
            .unwrap();
        assert!(want.keypoints.len() >= 12, "{}", want.keypoints.len());
        assert_eq!(got, want.keypoints, "max_corners {max_corners:?}");
        assert_eq!(done.robust, want.robust);
        assert_eq!((done.count as usize, rows), (got.len(), 800));
    }
}

#[test]
fn real_maps_stream_to_their_keypoints() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let maps = common::maps::real_maps(&dir);
    assert!(maps.len() >= 10, "{} maps", maps.len());
    for path in maps {
        let map = OccupancyMap::load(&path).unwrap();
        let classes = ClassTable::new(&map.thresholds);
        for detector in STREAMED {
            let o = DetectOptions {
                detector,
                ..DetectOptions::default()
            };
            let mut whole = Detector::new(o);
            let want = whole.detect(&map).unwrap().keypoints;
            // Windows of 8 core rows: many windows on every map.
            let mut d = Detector::new(o);
            d.set_window_bytes(Some(24 * u64::from(map.image.width())));
            let mut got = Vec::new();
            d.detect_streamed(
                &mut SliceRows::new(&map.image),
                &classes,
                map.georef.as_ref(),
                &mut |k| {
                    got.extend_from_slice(k);
                    Ok(())
                },
                &mut |_, _| {},
            )
            .unwrap();
            assert!(got == want, "{}, {}", path.display(), detector.name());
        }
    }
}

/// Runs the tool, asserting success.
fn tool(dir: &Path, command: &str, args: &[&str]) -> String {
    let out = common::tool_in(dir, command, args);
    assert!(
        out.status.success(),
        "{command} {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// The keypoint file the in-memory path writes for the map at `path`.
fn in_memory_file(path: &Path, o: &DetectOptions, format: Format) -> String {
    let map = OccupancyMap::load(path).unwrap();
    let mut d = Detector::new(*o);
    let det = d.detect(&map).unwrap();
    let mut text = Vec::new();
    output::write_keypoints(&mut text, format, &map, &det, o, &d.backend_name()).unwrap();
    String::from_utf8(text).unwrap()
}

#[test]
fn files_of_every_format_stream_to_the_in_memory_files() {
    let dir = tempfile::tempdir().unwrap();
    let image = office_map(300, 211, 9).unwrap();
    let (w, h) = (image.width(), image.height());
    let pgm = dir.path().join("map.pgm");
    image.write_pgm(&pgm).unwrap();
    // ASCII PGM.
    let mut p2 = format!("P2\n# ascii\n{w} {h}\n255\n");
    for row in image.pixels().chunks(w as usize) {
        let line: Vec<String> = row.iter().map(|v| v.to_string()).collect();
        p2 += &line.join(" ");
        p2 += "\n";
    }
    std::fs::write(dir.path().join("ascii.pgm"), p2).unwrap();
    let grey = image::GrayImage::from_raw(w, h, image.pixels().to_vec()).unwrap();
    grey.save(dir.path().join("map.png")).unwrap();
    std::fs::write(
        dir.path().join("map.yaml"),
        "image: map.pgm\nresolution: 0.05\norigin: [-3.0, 2.5, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    )
    .unwrap();
    for name in ["map.pgm", "ascii.pgm", "map.png", "map.yaml"] {
        let path = dir.path().join(name);
        for detector in STREAMED {
            let o = DetectOptions {
                detector,
                ..DetectOptions::default()
            };
            for (format, flag) in [(Format::Csv, "csv"), (Format::Json, "json")] {
                let want = in_memory_file(&path, &o, format);
                let got = tool(
                    dir.path(),
                    "detect",
                    &[name, "--detector", detector.name(), "--format", flag],
                );
                // The map's name is the path as given (relative here, absolute in the in-memory file).
                let want = want.replace(&path.display().to_string(), name);
                assert!(got == want, "{name} {} {flag}", detector.name());
            }
        }
    }
}

#[test]
fn an_overlay_is_drawn_while_streaming() {
    let dir = tempfile::tempdir().unwrap();
    let image = office_map(400, 300, 2).unwrap();
    image.write_pgm(&dir.path().join("map.pgm")).unwrap();
    tool(
        dir.path(),
        "detect",
        &["map.pgm", "-o", "k.csv", "--overlay", "o.png"],
    );
    let got = image::open(dir.path().join("o.png")).unwrap().to_rgb8();
    let map = OccupancyMap::load(dir.path().join("map.pgm")).unwrap();
    let det = Detector::new(DetectOptions::default())
        .detect(&map)
        .unwrap();
    let want = ogm_corners::detect::overlay::render_overlay(&map.image, &det.keypoints);
    assert!(
        got == want,
        "the streamed overlay differs from the in-memory one"
    );
}

/// `detect --detector ogm-robust` on a map whose whole-map detection does not fit the memory limit works
/// in tiles from a temporary copy of its rows, under a cap on its data memory, and writes the file the
/// in-memory run writes (angle included).
#[test]
fn the_robust_detector_streams_a_map_over_the_memory_limit_to_the_in_memory_file() {
    let dir = tempfile::tempdir().unwrap();
    common::floor_plan(3000, 2800, 11)
        .write_pgm(&dir.path().join("map.pgm"))
        .unwrap();
    let args = [
        "detect",
        "map.pgm",
        "--detector",
        "ogm-robust",
        "--backend",
        "cpu",
    ];
    let run = |extra: &[&str], cap: Option<u64>| {
        let mut c = match cap {
            Some(cap) => {
                let mut c = std::process::Command::new("prlimit");
                c.arg(format!("--data={cap}"))
                    .arg(env!("CARGO_BIN_EXE_ogm-corners"));
                c
            }
            None => std::process::Command::new(env!("CARGO_BIN_EXE_ogm-corners")),
        };
        let out = c
            .args(args)
            .args(extra)
            .current_dir(dir.path())
            .output()
            .expect("the tool (and prlimit, util-linux) run");
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(out.status.success(), "{extra:?}: {err}");
        err
    };
    run(&["--format", "json", "-o", "whole.json"], None);
    // The whole-map detection needs about 190 MB here; 150M streams it, under a 230 MB data cap.
    run(
        &[
            "--format",
            "json",
            "-o",
            "tiled.json",
            "--max-memory",
            "150M",
        ],
        Some(230_000_000),
    );
    let read = |n: &str| std::fs::read_to_string(dir.path().join(n)).unwrap();
    let (whole, tiled) = (read("whole.json"), read("tiled.json"));
    assert!(whole.contains("\"angle_deg\": "), "{}", &whole[..400]);
    assert!(whole.matches("\"x\":").count() >= 50);
    assert!(
        whole == tiled,
        "the tiled file differs from the whole-map one"
    );
    // Below what one tile needs: a one-line refusal, before anything is read.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_ogm-corners"))
        .args(args)
        .args(["--max-memory", "20M", "-o", "no.csv"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("over the limit"), "{err}");
    assert!(!dir.path().join("no.csv").exists());
}

/// A 20000 x 20000 map (400 MB) written by the tool row by row, then detected by the tool from the file
/// under a cap on its data memory of 160 MB (and `--max-memory 64M`, which makes its windows smaller):
/// the keypoints are the in-memory path's.
#[test]
fn a_map_far_larger_than_a_memory_cap_streams_under_it() {
    let dir = tempfile::tempdir().unwrap();
    let side = 20_000u32;
    tool(
        dir.path(),
        "bench",
        &[
            "--size",
            "20000x20000",
            "--seed",
            "3",
            "--write-map",
            "big.pgm",
        ],
    );
    let size = std::fs::metadata(dir.path().join("big.pgm")).unwrap().len();
    assert!(size > 400_000_000, "{size}");
    let cap = 160_000_000u64;
    for detector in ["ogm", "harris"] {
        let out = std::process::Command::new("prlimit")
            .arg(format!("--data={cap}"))
            .arg(env!("CARGO_BIN_EXE_ogm-corners"))
            .args([
                "detect",
                "big.pgm",
                "--detector",
                detector,
                "--max-memory",
                "64M",
            ])
            .args(["--backend", "cpu", "-o", "k.csv"])
            .current_dir(dir.path())
            .output()
            .expect("prlimit (util-linux) runs");
        assert!(
            out.status.success(),
            "{detector} under a {cap}-byte cap: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let got = std::fs::read_to_string(dir.path().join("k.csv")).unwrap();
        // The same map, made in memory here (the generator is deterministic), through the in-memory path.
        let mut rows = OfficeRows::new(side, side, 3).unwrap();
        let mut px = vec![0u8; (side * side) as usize];
        rows.read_rows(&mut px).unwrap();
        let image = MapImage::new(side, side, px).unwrap();
        let kind = match detector {
            "ogm" => DetectorKind::Ogm,
            _ => DetectorKind::Baseline(Baseline::Harris),
        };
        let o = DetectOptions {
            detector: kind,
            ..DetectOptions::default()
        };
        let map = OccupancyMap::from_image(image);
        let det = Detector::new(o).detect(&map).unwrap();
        assert!(det.keypoints.len() > 1000, "{}", det.keypoints.len());
        let mut text = Vec::new();
        output::write_keypoints(&mut text, Format::Csv, &map, &det, &o, "cpu").unwrap();
        assert!(got == String::from_utf8(text).unwrap(), "{detector}");
    }
}

/// Refusals of the streamed path name the right cause: a 16-bit PGM whose lookup tables exceed a tiny
/// limit is not called an interlaced PNG; a map too large to hold whole is refused up front by the commands
/// that hold maps whole.
#[test]
fn streamed_refusals_name_their_cause() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (200u32, 150u32);
    let mut pgm = format!("P5\n{w} {h}\n65535\n").into_bytes();
    pgm.extend(std::iter::repeat_n([0xff, 0xff], (w * h) as usize).flatten());
    std::fs::write(dir.path().join("s16.pgm"), pgm).unwrap();
    let out = common::tool_in(
        dir.path(),
        "detect",
        &["s16.pgm", "--backend", "cpu", "--max-memory", "200K"],
    );
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(e.contains("streaming a 200x150 map needs about"), "{e}");
    assert!(!e.contains("interlaced"), "{e}");
    // A sparse 70000 x 70000 map (4.9 GB of holes) beside a small one: `eval` refuses it before it starts.
    office_map(64, 64, 1)
        .unwrap()
        .write_pgm(&dir.path().join("a.pgm"))
        .unwrap();
    let header = b"P5\n70000 70000\n255\n";
    let f = std::fs::File::create(dir.path().join("huge.pgm")).unwrap();
    use std::io::Write;
    (&f).write_all(header).unwrap();
    f.set_len(header.len() as u64 + 70000 * 70000).unwrap();
    let out = common::tool_in(
        dir.path(),
        "eval",
        &[
            "a.pgm",
            "huge.pgm",
            "--trials",
            "1",
            "--max-memory",
            "2000G",
        ],
    );
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(
        e.contains("huge.pgm") && e.contains("exceeds 4294967296 pixels"),
        "{e}"
    );
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

/// The synthetic generator holds its strip and one office per thread, never more offices than the strip
/// has: a map of one office costs the same on 16 threads as on one.
#[test]
fn the_generator_counts_the_offices_it_draws() {
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    let bytes = |n| pool(n).install(|| OfficeRows::new(8192, 8192, 1).unwrap().bytes());
    assert_eq!(bytes(16), bytes(1));
    assert_eq!(bytes(1), 2 * 8192 * 8192);
}

/// A binary PGM is read straight from the file into the windows (around the page cache where it can, in
/// aligned pieces): many small windows, an odd width (rows straddle every alignment), trailing bytes after
/// the raster, direct reads on and off: the in-memory keypoints and the trailing-bytes warning each time.
#[test]
fn raw_pgm_windows_read_from_the_file_are_the_in_memory_keypoints() {
    let dir = tempfile::tempdir().unwrap();
    let image = office_map(2999, 1601, 4).unwrap();
    let pgm = dir.path().join("map.pgm");
    image.write_pgm(&pgm).unwrap();
    let mut bytes = std::fs::read(&pgm).unwrap();
    bytes.extend_from_slice(&[7u8; 5000]);
    std::fs::write(&pgm, &bytes).unwrap();
    let o = DetectOptions::default();
    let want = in_memory_file(&pgm, &o, Format::Csv).replace(&pgm.display().to_string(), "map.pgm");
    for direct in ["1", "0"] {
        // Out of the page cache (where the system lets us), so that direct reads are what runs.
        #[cfg(unix)]
        {
            let f = std::fs::File::open(&pgm).unwrap();
            f.sync_all().unwrap();
            let _ = rustix::fs::fadvise(&f, 0, None, rustix::fs::Advice::DontNeed);
        }
        // 8 MB makes windows of about a megabyte: five of them over this 4.8 MB map.
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_ogm-corners"))
            .args(["detect", "map.pgm", "--max-memory", "8M"])
            .env("OGM_CORNERS_DIRECT_IO", direct)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "direct {direct}: {err}");
        assert!(
            String::from_utf8_lossy(&out.stdout) == want,
            "direct {direct}"
        );
        assert!(
            err.contains("5000 bytes after the image data ignored"),
            "direct {direct}: {err}"
        );
    }
}
