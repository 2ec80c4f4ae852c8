//! Harris and Shi-Tomasi agree with OpenCV on every real map: at least 99% of our keypoints lie within 1 px
//! (8-neighbourhood) of an OpenCV keypoint, and the reverse; and our Gaussian blur equals OpenCV's bit for
//! bit. OpenCV runs through `scripts/opencv_keypoints.py` in the virtual environment that the test command
//! sets up (`target/opencv-venv`, or `$OGM_OPENCV_PYTHON`).

use crate::common;
use std::collections::HashSet;
use std::path::PathBuf;
use std::process::Command;

use ogm_corners::backend::reference::gaussian_blur::{gaussian_blur, gaussian_kernel};
use ogm_corners::{Baseline, DetectOptions, Detector, DetectorKind, OccupancyMap};

fn python() -> Option<PathBuf> {
    let p = std::env::var_os("OGM_OPENCV_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/opencv-venv/bin/python")
        });
    if p.is_file() {
        return Some(p);
    }
    let msg = format!("no Python with OpenCV at {}: the OpenCV agreement checks did NOT run (scripts/test.sh sets it up)", p.display());
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("{msg}");
    }
    eprintln!("SKIPPED: {msg}");
    None
}

fn read_points(path: &std::path::Path) -> Vec<(i64, i64)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let (x, y) = l.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

/// Fraction of `a` with a point of `b` within one pixel (8-neighbourhood); 1 when `a` is empty.
fn within_1px(a: &[(i64, i64)], b: &[(i64, i64)]) -> f64 {
    if a.is_empty() {
        return 1.0;
    }
    let set: HashSet<_> = b.iter().copied().collect();
    let near = a
        .iter()
        .filter(|&&(x, y)| (-1..=1).any(|dy| (-1..=1).any(|dx| set.contains(&(x + dx, y + dy)))))
        .count();
    near as f64 / a.len() as f64
}

#[test]
fn harris_and_shi_tomasi_agree_with_opencv_on_real_maps() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let Some(py) = python() else { return };
    let tmp = std::env::temp_dir().join(format!("ogm-opencv-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let maps = common::maps::real_maps(&dir);
    let mut inputs = Vec::new();
    let mut loaded = Vec::new();
    for (i, p) in maps.iter().enumerate() {
        let map = OccupancyMap::load(p).unwrap();
        // The grey image exactly as the detectors see it.
        let pgm = tmp.join(format!("map{i:02}.pgm"));
        map.image.write_pgm(&pgm).unwrap();
        inputs.push(pgm);
        loaded.push(map);
    }
    let out = tmp.join("out");
    let status = Command::new(&py)
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scripts/opencv_keypoints.py"
        ))
        .arg(&out)
        .args(&inputs)
        .status()
        .unwrap();
    assert!(status.success(), "opencv_keypoints.py failed");
    let mut worst: f64 = 1.0;
    eprintln!(
        "{:>32} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}",
        "map", "H ours", "H cv", "H o->c", "H c->o", "ST ours", "ST cv", "ST o->c", "ST c->o"
    );
    for (i, (p, map)) in maps.iter().zip(&loaded).enumerate() {
        let stem = out.join(format!("map{i:02}"));
        // The blur is OpenCV's, bit for bit.
        let cv_blur = OccupancyMap::load(stem.with_extension("blur.pgm")).unwrap();
        assert_eq!(
            cv_blur.image.pixels(),
            gaussian_blur(&map.image, gaussian_kernel(1.0)).as_slice(),
            "{}: blur differs from OpenCV",
            p.display()
        );
        let mut row = Vec::new();
        for (kind, file) in [
            (Baseline::Harris, "harris.csv"),
            (Baseline::ShiTomasi, "shi_tomasi.csv"),
        ] {
            let opts = DetectOptions {
                detector: DetectorKind::Baseline(kind),
                ..DetectOptions::default()
            };
            let ours: Vec<(i64, i64)> = Detector::new(opts)
                .detect(map)
                .unwrap()
                .keypoints
                .iter()
                .map(|k| (i64::from(k.x), i64::from(k.y)))
                .collect();
            let theirs = read_points(&stem.with_extension(file));
            let (a, b) = (within_1px(&ours, &theirs), within_1px(&theirs, &ours));
            assert!(
                a >= 0.99 && b >= 0.99,
                "{} {kind:?}: ours {} vs OpenCV {}; {:.4} of ours near OpenCV's, {:.4} of OpenCV's near ours",
                p.display(),
                ours.len(),
                theirs.len(),
                a,
                b
            );
            worst = worst.min(a).min(b);
            row.extend([ours.len() as f64, theirs.len() as f64, a, b]);
        }
        let name = p.strip_prefix(&dir).unwrap().display().to_string();
        let name = if name.len() > 32 {
            name[name.len() - 32..].to_string()
        } else {
            name
        };
        eprintln!(
            "{name:>32} {:>7} {:>7} {:>7.4} {:>7.4} {:>7} {:>7} {:>7.4} {:>7.4}",
            row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7]
        );
    }
    eprintln!("worst agreement: {worst:.4}");
}
