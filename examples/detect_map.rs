//! Detects the corners of a ROS map (`map.yaml` beside its image) and prints the first few, in pixels and
//! in the map's world frame.
//!
//! ```sh
//! cargo run --release --example detect_map -- MAP.yaml [ogm|ogm-robust]
//! ```

use ogm_corners::{DetectOptions, Detector, DetectorKind, OccupancyMap};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .ok_or("usage: detect_map MAP.yaml [ogm|ogm-robust]")?;
    // The paper's detector is exact on clean maps; the robust one is made for real sensor maps.
    let detector = match args.next().as_deref() {
        None | Some("ogm") => DetectorKind::Ogm,
        Some("ogm-robust") => DetectorKind::OgmRobust,
        Some(other) => return Err(format!("unknown detector `{other}`: ogm or ogm-robust").into()),
    };
    let map = OccupancyMap::load(std::path::Path::new(&path))?;
    let (w, h) = (map.image.width(), map.image.height());
    let mut d = Detector::new(DetectOptions {
        detector,
        ..Default::default()
    });
    let found = d.detect(&map)?;
    println!("{} corners in {path} ({w}x{h})", found.keypoints.len());
    for k in found.keypoints.iter().take(10) {
        match map.georef {
            Some(g) => {
                let (x, y) = g.pixel_to_world(k.x, k.y, h);
                println!(
                    "  pixel ({}, {})  world ({x:.2}, {y:.2}) m  rule {}",
                    k.x, k.y, k.rule
                );
            }
            None => println!("  pixel ({}, {})  rule {}", k.x, k.y, k.rule),
        }
    }
    Ok(())
}
