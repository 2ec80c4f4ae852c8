//! Maps already on the GPU: `GpuBackend::detect_device_map` on a map in a `wgpu::Buffer` returns exactly
//! the CPU reference's keypoints, at any offset and row pitch, band by band and slab by slab, and refuses a
//! map its buffer cannot hold with a clear error. Runs on whatever adapter wgpu finds (lavapipe in CI);
//! with CI=true a missing adapter fails.

use crate::common;
use ogm_corners::backend::gpu::{DeviceMap, GpuBackend, GpuOptions};
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::map::synthetic::Rng;
use ogm_corners::{Backend, ClassTable, MapImage, RuleSet, RuleTable};

const VARIANTS: [(RuleSet, bool); 4] = [
    (RuleSet::Paper, false),
    (RuleSet::Paper, true),
    (RuleSet::PaperMod2, false),
    (RuleSet::PaperMod2, true),
];

/// A buffer on `device` holding `img` from byte `offset`, rows `pitch` bytes apart; every other byte
/// (before, between rows, after) is random, so that a kernel reading outside the map shows.
fn device_buffer(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    img: &MapImage,
    offset: u64,
    pitch: u64,
) -> wgpu::Buffer {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let size = (offset as usize + h.max(1) * pitch as usize + 5).next_multiple_of(4);
    let mut rng = Rng::new(offset ^ pitch);
    let mut bytes: Vec<u8> = (0..size).map(|_| rng.next_u64() as u8).collect();
    for (y, row) in img.pixels().chunks_exact(w.max(1)).enumerate() {
        let at = offset as usize + y * pitch as usize;
        bytes[at..at + w].copy_from_slice(row);
    }
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("test map"),
        size: size as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    queue.write_buffer(&buffer, 0, &bytes);
    buffer
}

/// `img` as `device_buffer` holds it.
fn map_in<'a>(buffer: &'a wgpu::Buffer, img: &MapImage, offset: u64, pitch: u64) -> DeviceMap<'a> {
    DeviceMap {
        buffer,
        offset,
        width: img.width(),
        height: img.height(),
        bytes_per_row: pitch,
    }
}

/// Asserts the device map of `img` at `offset` and `pitch` gives the reference's keypoints for every
/// rule reading; returns the reference's count.
fn assert_same(gpu: &mut GpuBackend, img: &MapImage, offset: u64, pitch: u64) -> usize {
    let buffer = device_buffer(gpu.device(), gpu.queue(), img, offset, pitch);
    let map = map_in(&buffer, img, offset, pitch);
    let classes = ClassTable::default();
    let mut n = 0;
    for (set, uao) in VARIANTS {
        let rules = RuleTable::new(set);
        let want = ReferenceBackend.detect(img, &classes, &rules, uao).unwrap();
        let got = gpu.detect_device_map(&map, &classes, &rules, uao).unwrap();
        if got != want {
            let first = got.iter().zip(&want).position(|(a, b)| a != b);
            panic!(
                "{}x{} at offset {offset}, pitch {pitch} ({set}, unknown_as_occupied={uao}): GPU {} \
                 keypoints, CPU {}; first difference at {first:?}",
                img.width(),
                img.height(),
                got.len(),
                want.len()
            );
        }
        n += want.len();
    }
    n
}

/// Offsets and pitches for a map `w` wide: aligned runs (read 16 bytes at a time), a pitch of a whole
/// number of words, and bytes at any offset and pitch.
fn layouts(w: u32) -> [(u64, u64); 5] {
    let w = u64::from(w);
    [
        (0, w.next_multiple_of(32)),
        (256, w.next_multiple_of(16) + 16),
        (0, w),
        (3, w + 5),
        (263, w.next_multiple_of(4) + 4),
    ]
}

#[test]
fn maps_in_device_buffers_match_the_reference_at_any_offset_and_pitch() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let sizes = [
        (1, 1),
        (2, 9),
        (5, 3),
        (13, 17),
        (31, 29),
        (33, 7),
        (65, 65),
        (257, 3),
        (1023, 5),
        (250, 250),
    ];
    for (i, (w, h)) in sizes.into_iter().enumerate() {
        let img = common::random_map(w, h, i as u64);
        for (offset, pitch) in layouts(w) {
            assert_same(&mut gpu, &img, offset, pitch);
        }
    }
    let all = common::all_3x3_configurations();
    let w = u64::from(all.width());
    assert!(assert_same(&mut gpu, &all, 0, w.next_multiple_of(32)) > 1000);
    assert!(assert_same(&mut gpu, &all, 7, w + 3) > 1000);
}

#[test]
fn device_maps_run_band_by_band_and_slab_by_slab() {
    let classes = ClassTable::default();
    let rules = RuleTable::new(RuleSet::Paper);
    let img = common::random_map(301, 431, 7);
    let want = ReferenceBackend
        .detect(&img, &classes, &rules, false)
        .unwrap();
    for options in [
        GpuOptions {
            tile: Some((64, 37)), // full-width bands of 37 rows; the width is not split
            ..GpuOptions::default()
        },
        GpuOptions {
            slab_rows: 50,
            initial_keypoint_capacity: 1,
            initial_workgroup_scratch: 1,
            ..GpuOptions::default()
        },
    ] {
        let Some(mut gpu) = common::gpu_backend(options) else {
            return;
        };
        for (offset, pitch) in layouts(img.width()) {
            let buffer = device_buffer(gpu.device(), gpu.queue(), &img, offset, pitch);
            let map = map_in(&buffer, &img, offset, pitch);
            let got = gpu
                .detect_device_map(&map, &classes, &rules, false)
                .unwrap();
            assert_eq!(got, want, "{options:?} offset {offset} pitch {pitch}");
            let s = gpu.stats();
            assert!(s.tiles > 1 || options.slab_rows < img.height(), "{s:?}");
        }
    }
}

#[test]
fn a_backend_made_from_the_callers_device_detects_its_maps() {
    // The caller's own instance, adapter and device, as a mapping pipeline holds them.
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()));
    let Ok(adapter) = adapter else {
        assert!(
            !std::env::var("CI").is_ok_and(|v| v == "true"),
            "CI=true requires a GPU adapter (lavapipe will do)"
        );
        eprintln!("SKIPPED: no wgpu adapter; the device-map test did NOT run");
        return;
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&Default::default())).unwrap();
    let img = common::random_map(200, 150, 3);
    let buffer = device_buffer(&device, &queue, &img, 5, 203);
    let mut gpu = GpuBackend::from_device(&adapter, device, queue, GpuOptions::default()).unwrap();
    let map = DeviceMap {
        buffer: &buffer,
        offset: 5,
        width: 200,
        height: 150,
        bytes_per_row: 203,
    };
    let (classes, rules) = (ClassTable::default(), RuleTable::new(RuleSet::Paper));
    let want = ReferenceBackend
        .detect(&img, &classes, &rules, false)
        .unwrap();
    assert!(want.len() > 10);
    assert_eq!(
        gpu.detect_device_map(&map, &classes, &rules, false)
            .unwrap(),
        want
    );
    // The same backend still detects maps in host memory.
    assert_eq!(gpu.detect(&img, &classes, &rules, false).unwrap(), want);
}

#[test]
fn a_map_its_buffer_cannot_hold_is_refused_with_a_clear_error() {
    let Some(mut gpu) = common::gpu_backend(GpuOptions::default()) else {
        return;
    };
    let (classes, rules) = (ClassTable::default(), RuleTable::new(RuleSet::Paper));
    let buffer = |size, usage| {
        gpu.device().create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size,
            usage,
            mapped_at_creation: false,
        })
    };
    let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
    let big = buffer(1000, storage);
    let odd = buffer(10, storage);
    let unreadable = buffer(1000, wgpu::BufferUsages::COPY_DST);
    let map = |buffer, offset, width, height, bytes_per_row| DeviceMap {
        buffer,
        offset,
        width,
        height,
        bytes_per_row,
    };
    for (m, says) in [
        (map(&big, 0, 20, 10, 19), "less than the width"),
        (map(&big, 0, 20, 51, 20), "run past the buffer"),
        (map(&big, 990, 20, 1, 20), "run past the buffer"),
        (map(&big, u64::MAX - 3, 20, 2, 20), "run past the buffer"),
        (map(&big, 0, 1, 2, 1 << 33), "over 2^32"),
        (map(&odd, 0, 10, 1, 10), "partial 4-byte word"),
        (map(&unreadable, 0, 20, 10, 20), "STORAGE"),
    ] {
        let e = gpu
            .detect_device_map(&m, &classes, &rules, false)
            .expect_err(says)
            .to_string();
        assert!(e.contains(says), "{m:?}: {e}");
        assert!(!e.contains('\n'), "{e}");
    }
    // An empty map has no keypoints; the backend is still usable after the refusals.
    assert!(gpu
        .detect_device_map(&map(&big, 0, 0, 10, 0), &classes, &rules, false)
        .unwrap()
        .is_empty());
    let img = common::random_map(20, 10, 1);
    let want = ReferenceBackend
        .detect(&img, &classes, &rules, false)
        .unwrap();
    assert_eq!(gpu.detect(&img, &classes, &rules, false).unwrap(), want);
}
