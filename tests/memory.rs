//! Memory of the fast CPU path: beyond the map itself, detection allocates only a few rows of bit-planes
//! per thread and the keypoints. Counted by a global allocator, so the check is exact and not timing-bound.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use ogm_corners::fast::FastCpuBackend;
use ogm_corners::synth::office_map;
use ogm_corners::{Backend, Baseline, BaselineParams, ClassTable, RuleSet, RuleTable, Thresholds};

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: defers to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let now = LIVE.fetch_add(l.size(), Relaxed) + l.size();
        PEAK.fetch_max(now, Relaxed);
        System.alloc(l)
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        LIVE.fetch_sub(l.size(), Relaxed);
        System.dealloc(p, l)
    }
}

#[global_allocator]
static A: Counting = Counting;

/// Peak bytes allocated by `f` beyond what was live when it started.
fn peak_extra<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.load(Relaxed);
    PEAK.store(base, Relaxed);
    let r = f();
    (r, PEAK.load(Relaxed) - base)
}

#[test]
fn fast_paths_allocate_a_small_fraction_of_the_map() {
    // One test function: the counters are process-wide, so nothing else may run beside it.
    let img = office_map(4096, 4096, 1).unwrap();
    let map_bytes = img.len();
    let classes = ClassTable::new(&Thresholds::default());
    let rules = RuleTable::new(RuleSet::Paper);
    let (kps, extra) = peak_extra(|| {
        FastCpuBackend
            .detect(&img, &classes, &rules, false)
            .unwrap()
    });
    eprintln!(
        "ogm: {} keypoints, {extra} bytes beyond the {map_bytes}-byte map",
        kps.len()
    );
    assert!(!kps.is_empty());
    // The bound is 1.5x the map in all; the bit-plane path needs far less.
    assert!(
        extra < map_bytes / 20,
        "OGM fast path allocated {extra} bytes for a {map_bytes}-byte map"
    );
    for kind in [Baseline::Harris, Baseline::ShiTomasi, Baseline::Trajkovic] {
        let (kps, extra) = peak_extra(|| {
            FastCpuBackend
                .baseline_keypoints(kind, &img, &BaselineParams::default())
                .unwrap()
        });
        eprintln!(
            "{kind:?}: {} keypoints, {extra} bytes beyond the map",
            kps.len()
        );
        assert!(
            extra < map_bytes / 2,
            "{kind:?} fast path allocated {extra} bytes for a {map_bytes}-byte map"
        );
    }
}
