//! Criterion: every detector (ogm, harris, shi-tomasi, trajkovic) on every backend (`cpu`, the fast path;
//! `reference`, the single-threaded oracle; `gpu`, when an adapter opens) end to end, image in memory to
//! keypoints in memory, on synthetic office maps of 1024^2, 4096^2 and 16384^2 and on every shared real map.
//! Throughput is in elements = pixels, so criterion's "elem/s" are pixels per second.
//!
//! Benchmark ids are `MAP-WxH/DETECTOR/BACKEND`, e.g. `synthetic-4096x4096/harris/cpu`; a filter runs a
//! subset: `cargo bench -p ogm-corners-benches -- synthetic-1024x1024`.
//!
//! - The real maps come from `$OGM_MAPS_DIR`, else `../shared/maps` beside the project; a line says so when
//!   the folder is missing.
//! - Without a GPU adapter the GPU rows are left out, with a line saying why.
//! - The reference and software GPU adapters (lavapipe, WARP) on the baselines at 16384^2 take minutes per
//!   benchmark, so they are skipped unless `OGM_BENCH_FULL=1` (a line lists what was skipped).
//!
//! Kernel-only and upload-only GPU times and peak memory come from `ogm-corners bench`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use criterion::{
    criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode, Throughput,
};
use ogm_corners::backend::fast::FastCpuBackend;
use ogm_corners::backend::gpu::{GpuBackend, GpuOptions};
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::map::synthetic::office_map;
use ogm_corners::{
    Backend, Baseline, BaselineParams, ClassTable, DetectorKind, OccupancyMap, RuleSet, RuleTable,
};

#[path = "../tests/common/maps.rs"]
mod maps;

const SIZES: [u32; 3] = [1024, 4096, 16384];

const DETECTORS: [DetectorKind; 5] = [
    DetectorKind::Ogm,
    DetectorKind::OgmRobust,
    DetectorKind::Baseline(Baseline::Harris),
    DetectorKind::Baseline(Baseline::ShiTomasi),
    DetectorKind::Baseline(Baseline::Trajkovic),
];

/// Above this many pixels the reference and software adapters take minutes per baseline benchmark (the
/// same limit as `ogm-corners bench --backend all`).
const SLOW_PIXELS: u64 = 32 << 20;

/// One backend with its name in the benchmark ids; `slow` for the reference and software adapters.
struct Engine {
    name: &'static str,
    backend: Box<dyn Backend>,
    slow: bool,
}

fn engines() -> Vec<Engine> {
    let mut v = vec![
        Engine {
            name: "cpu",
            backend: Box::new(FastCpuBackend),
            slow: false,
        },
        Engine {
            name: "reference",
            backend: Box::new(ReferenceBackend),
            slow: true,
        },
    ];
    match GpuBackend::new(GpuOptions::default()) {
        Ok(g) => {
            let a = g.adapter();
            println!(
                "detect bench: gpu = {} ({}, {})",
                a.name, a.backend, a.device_type
            );
            let slow = a.device_type == "Cpu";
            v.push(Engine {
                name: "gpu",
                backend: Box::new(g),
                slow,
            });
        }
        Err(e) => println!("detect bench: NO GPU ROWS: no adapter opened: {e}"),
    }
    v
}

/// The shared real maps as (label, path), or none with a line saying why.
fn shared_maps() -> Vec<(String, PathBuf)> {
    let dir = std::env::var_os("OGM_MAPS_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/maps"));
    if !dir.is_dir() {
        println!(
            "detect bench: NO REAL-MAP ROWS: the shared maps folder {} is missing (set OGM_MAPS_DIR)",
            dir.display()
        );
        return Vec::new();
    }
    let mut seen = std::collections::HashMap::new();
    maps::real_maps(&dir)
        .into_iter()
        .map(|p| {
            // ROS's usual map.yaml is named after its folder.
            let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or("map");
            let base = match p
                .parent()
                .and_then(|d| d.file_name())
                .and_then(|d| d.to_str())
            {
                Some(dir) if stem == "map" => dir.to_string(),
                _ => stem.to_string(),
            };
            let n: &mut u32 = seen.entry(base.clone()).or_default();
            *n += 1;
            let label = if *n == 1 { base } else { format!("{base}-{n}") };
            (label, p)
        })
        .collect()
}

/// Every detector on every engine for one map, as the benchmark group `label-WxH`.
fn bench_map(
    c: &mut Criterion,
    label: &str,
    map: &OccupancyMap,
    engines: &mut [Engine],
    full: bool,
) {
    let image = &map.image;
    let (w, h) = (image.width(), image.height());
    let pixels = u64::from(w) * u64::from(h);
    let classes = ClassTable::new(&map.thresholds);
    let rules = RuleTable::new(RuleSet::Paper);
    let params = BaselineParams::default();
    let mut g = c.benchmark_group(format!("{label}-{w}x{h}"));
    g.throughput(Throughput::Elements(pixels));
    // Ten samples (criterion's minimum) of equal size: one iteration of a large map takes long enough.
    g.sample_size(10).sampling_mode(SamplingMode::Flat);
    let (warm, measure) = match pixels {
        0..=4_000_000 => (0.3, 0.7),
        4_000_001..=20_000_000 => (1.0, 3.0),
        _ => (1.0, 5.0),
    };
    g.warm_up_time(Duration::from_secs_f64(warm))
        .measurement_time(Duration::from_secs_f64(measure));
    let mut skipped = Vec::new();
    for kind in DETECTORS {
        for e in engines.iter_mut() {
            if e.slow && !full && kind != DetectorKind::Ogm && pixels > SLOW_PIXELS {
                skipped.push(format!("{}/{}", kind.name(), e.name));
                continue;
            }
            let backend = &mut e.backend;
            g.bench_function(BenchmarkId::new(kind.name(), e.name), |b| {
                b.iter(|| {
                    match kind {
                        DetectorKind::Ogm => backend.detect(image, &classes, &rules, false),
                        DetectorKind::OgmRobust => ogm_corners::detect::robust::detect(
                            &mut **backend,
                            image,
                            &classes,
                            &rules,
                            &Default::default(),
                        )
                        .map(|r| r.0),
                        DetectorKind::Baseline(k) => backend.baseline_keypoints(k, image, &params),
                    }
                    .expect("detection")
                    .len()
                })
            });
        }
    }
    g.finish();
    if !skipped.is_empty() {
        println!(
            "detect bench: {label}-{w}x{h}: SKIPPED {} (minutes each on the reference or a software \
             adapter); OGM_BENCH_FULL=1 runs them",
            skipped.join(", ")
        );
    }
}

fn bench(c: &mut Criterion) {
    let full = std::env::var("OGM_BENCH_FULL").is_ok_and(|v| v == "1");
    let mut engines = engines();
    // One map in memory at a time: 16384^2 is 268 MB.
    for side in SIZES {
        let map = OccupancyMap::from_image(office_map(side, side, 1).expect("synthetic map"));
        bench_map(c, "synthetic", &map, &mut engines, full);
    }
    for (label, path) in shared_maps() {
        let map = OccupancyMap::load(&path).expect("shared map loads");
        bench_map(c, &label, &map, &mut engines, full);
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
