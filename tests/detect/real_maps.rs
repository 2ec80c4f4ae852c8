//! Every real map under `../shared/maps` loads and detects; the CLI, CSV and overlay run on one of them.
//! Says clearly when the folder is missing, and fails then under CI=true.

use crate::common;
use std::process::Command;

use ogm_corners::{DetectOptions, Detector, OccupancyMap, RuleSet};

#[test]
fn every_real_map_loads_and_detects() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let maps = common::maps::real_maps(&dir);
    assert!(
        maps.len() >= 20,
        "expected the shared maps, found {}",
        maps.len()
    );
    let mut detectors: Vec<Detector> = [
        (RuleSet::Paper, false),
        (RuleSet::PaperMod2, false),
        (RuleSet::Paper, true),
    ]
    .map(|(rules, unknown_as_occupied)| {
        Detector::new(DetectOptions {
            rules,
            unknown_as_occupied,
            ..DetectOptions::default()
        })
    })
    .into();
    let mut total = 0;
    for p in &maps {
        let map = OccupancyMap::load(p).unwrap_or_else(|e| panic!("{e}"));
        let counts: Vec<usize> = detectors
            .iter_mut()
            .map(|d| {
                let det = d.detect(&map).unwrap();
                assert!(det
                    .keypoints
                    .windows(2)
                    .all(|w| (w[0].y, w[0].x) < (w[1].y, w[1].x)));
                det.keypoints.len()
            })
            .collect();
        eprintln!(
            "{:>5} {:>5} {:>5}  {}",
            counts[0],
            counts[1],
            counts[2],
            p.strip_prefix(&dir).unwrap().display()
        );
        total += counts[0];
    }
    assert!(total > 500, "real maps have many corners: {total}");
}

#[test]
fn cli_csv_and_overlay_on_a_real_map() {
    let Some(dir) = common::shared_maps() else {
        return;
    };
    let yaml = dir.join("mas_domestic_robotics/mdr_environments/brsu-c069/map.yaml");
    let out = std::env::temp_dir().join(format!("ogm-real-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let csv = out.join("k.csv");
    let png = out.join("o.png");
    let o = Command::new(env!("CARGO_BIN_EXE_ogm-corners"))
        .args([
            "detect",
            yaml.to_str().unwrap(),
            "-o",
            csv.to_str().unwrap(),
            "--overlay",
            png.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,rule,code,world_x,world_y"));
    let map = OccupancyMap::load(&yaml).unwrap();
    let det = Detector::new(DetectOptions::default())
        .detect(&map)
        .unwrap();
    assert_eq!(lines.clone().count(), det.keypoints.len());
    assert!(det.keypoints.len() > 20);
    // Each row matches the library's keypoint and lies inside the map's world extent.
    let g = map.georef.unwrap();
    for (line, k) in lines.zip(&det.keypoints) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(
            (f[0].parse::<u32>().unwrap(), f[1].parse::<u32>().unwrap()),
            (k.x, k.y)
        );
        let wx: f64 = f[4].parse().unwrap();
        let wy: f64 = f[5].parse().unwrap();
        assert!(wx > g.origin[0] && wx < g.origin[0] + 576.0 * 0.05, "{wx}");
        assert!(wy > g.origin[1] && wy < g.origin[1] + 544.0 * 0.05, "{wy}");
    }
    let img = image::open(&png).unwrap().to_rgb8();
    let s = ogm_corners::detect::overlay::overlay_scale(576, 544);
    assert_eq!(s, 2, "a 576 px map is shown at twice its size");
    assert_eq!((img.width(), img.height()), (576 * s, 544 * s));
    let red = img.pixels().filter(|p| p[0] > 200 && p[1] < 60).count();
    assert!(red > det.keypoints.len(), "markers drawn: {red}");
}
