//! The shared real maps' files, for the tests and the criterion benchmarks (benches/detect.rs includes
//! this file alone: it needs nothing but the library).

use std::path::PathBuf;

use ogm_corners::OccupancyMap;

/// Every map under `dir`: each yaml, and each image that no yaml names.
pub fn real_maps(dir: &std::path::Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                files.push(p);
            }
        }
    }
    files.sort();
    let ext = |p: &PathBuf| {
        p.extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_string()
    };
    let yamls: Vec<PathBuf> = files.iter().filter(|p| ext(p) == "yaml").cloned().collect();
    let named: Vec<PathBuf> = yamls
        .iter()
        .filter_map(|y| OccupancyMap::load(y).ok().and_then(|m| m.image_path))
        .map(|p| p.canonicalize().unwrap())
        .collect();
    let mut maps = yamls;
    for p in files {
        if matches!(ext(&p).as_str(), "pgm" | "png") && !named.contains(&p.canonicalize().unwrap())
        {
            maps.push(p);
        }
    }
    maps
}
