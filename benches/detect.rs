//! Detection throughput on a synthetic 4096 x 4096 office map, CPU and GPU. Criterion's "elem/s" are
//! pixels per second. The GPU group measures end to end (upload, kernels, read-back); kernel-only GPU
//! times come from timestamp queries in `ogm-corners bench`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use ogm_corners::cpu::{classify::classify, ogm_corners::ogm_corners, CpuBackend};
use ogm_corners::gpu::{GpuBackend, GpuOptions};
use ogm_corners::synth::office_map;
use ogm_corners::{Backend, ClassTable, OccupancyMap, RuleSet, RuleTable};

const SIZE: (u32, u32) = (4096, 4096);

fn bench(c: &mut Criterion) {
    let (w, h) = SIZE;
    let map = OccupancyMap::from_image(office_map(w, h, 1).expect("synthetic map"));
    let classes = ClassTable::new(&map.thresholds);
    let rules = RuleTable::new(RuleSet::Paper);
    let mut g = c.benchmark_group("cpu");
    g.throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
    g.sample_size(20);
    g.bench_function("detect_end_to_end/4096x4096", |b| {
        b.iter(|| {
            CpuBackend
                .detect(&map.image, &classes, &rules, false)
                .expect("detect")
                .len()
        })
    });
    g.bench_function("classify/4096x4096", |b| {
        b.iter(|| classify(&map.image, &classes).len())
    });
    let states = classify(&map.image, &classes);
    g.bench_function("ogm_corners/4096x4096", |b| {
        b.iter(|| ogm_corners(&states, w, h, &rules, false).len())
    });
    g.finish();

    match GpuBackend::new(GpuOptions::default()) {
        Ok(mut gpu) => {
            let mut g = c.benchmark_group(format!("gpu ({})", gpu.adapter().name));
            g.throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
            g.sample_size(10);
            g.bench_function("detect_end_to_end/4096x4096", |b| {
                b.iter(|| {
                    gpu.detect(&map.image, &classes, &rules, false)
                        .expect("detect")
                        .len()
                })
            });
            g.finish();
        }
        Err(e) => eprintln!("GPU benchmarks NOT run: {e}"),
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
