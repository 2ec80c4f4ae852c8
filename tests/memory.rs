//! Memory of the fast CPU path: beyond the map itself, detection allocates only a few rows of bit-planes
//! per thread and the keypoints. Counted by a global allocator, so the check is exact and not timing-bound;
//! a binary of its own, as a counting allocator counts the whole binary.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use ogm_corners::backend::fast::FastCpuBackend;
use ogm_corners::map::synthetic::office_map;
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
    loading_takes_about_one_map();
}

/// Loading decodes row by row into the one output buffer: about 1x the 8-bit map, whatever the file's
/// format (a 16-bit or colour image used to take 2-3x: the file, the decoded image, the grey copy).
fn loading_takes_about_one_map() {
    let dir = tempfile::tempdir().unwrap();
    let img = office_map(2048, 1536, 7).unwrap();
    let out_bytes = img.len();
    let pgm = dir.path().join("m.pgm");
    img.write_pgm(&pgm).unwrap();
    let write_png = |name: &str,
                     color: png::ColorType,
                     depth: png::BitDepth,
                     expand: &dyn Fn(u8) -> Vec<u8>| {
        let p = dir.path().join(name);
        let mut enc = png::Encoder::new(std::fs::File::create(&p).unwrap(), 2048, 1536);
        enc.set_color(color);
        enc.set_depth(depth);
        let data: Vec<u8> = img.pixels().iter().flat_map(|&v| expand(v)).collect();
        enc.write_header().unwrap().write_image_data(&data).unwrap();
        p
    };
    let files = [
        pgm,
        write_png(
            "g16.png",
            png::ColorType::Grayscale,
            png::BitDepth::Sixteen,
            &|v| vec![v, v],
        ),
        write_png(
            "rgba.png",
            png::ColorType::Rgba,
            png::BitDepth::Eight,
            &|v| vec![v, v, v, 255],
        ),
    ];
    for f in &files {
        let (map, extra) = peak_extra(|| ogm_corners::OccupancyMap::load(f).unwrap());
        assert_eq!(map.image.pixels(), img.pixels(), "{}", f.display());
        eprintln!(
            "load {}: {extra} bytes for a {out_bytes}-byte map",
            f.display()
        );
        assert!(
            extra < out_bytes + out_bytes / 20 + (1 << 20),
            "{}: loading allocated {extra} bytes for a {out_bytes}-byte map",
            f.display()
        );
    }
}
