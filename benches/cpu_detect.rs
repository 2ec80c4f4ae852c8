//! CPU detection throughput on a synthetic 4096 x 4096 office map. Criterion's "elem/s" are pixels/s.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use ogm_corners::cpu::{classify::classify, ogm_corners::ogm_corners};
use ogm_corners::synth::office_map;
use ogm_corners::{ClassTable, DetectOptions, Detector, OccupancyMap, RuleSet, RuleTable};

fn bench(c: &mut Criterion) {
    let (w, h) = (4096, 4096);
    let map = OccupancyMap::from_image(office_map(w, h, 1).expect("synthetic map"));
    let mut g = c.benchmark_group("cpu");
    g.throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
    g.sample_size(20);
    let mut det = Detector::new(DetectOptions::default());
    g.bench_function("detect_end_to_end/4096x4096", |b| {
        b.iter(|| det.detect(&map).expect("detect").keypoints.len())
    });
    let classes = ClassTable::new(&map.thresholds);
    g.bench_function("classify/4096x4096", |b| {
        b.iter(|| classify(&map.image, &classes).len())
    });
    let states = classify(&map.image, &classes);
    let rules = RuleTable::new(RuleSet::Paper);
    g.bench_function("ogm_corners/4096x4096", |b| {
        b.iter(|| ogm_corners(&states, w, h, &rules, false).len())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
