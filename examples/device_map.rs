//! Detects the corners of a map held in a GPU buffer, where a GPU mapping pipeline keeps its grid: the
//! kernels read the buffer where it lies, and only the corners come back. Here the buffer is filled from a
//! ROS map with a row pitch of its own, and the corners are checked against the CPU's.
//!
//! ```sh
//! cargo run --release --example device_map -- MAP.yaml
//! ```

use ogm_corners::backend::gpu::{DeviceMap, GpuBackend, GpuOptions};
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::{Backend, ClassTable, OccupancyMap, RuleSet, RuleTable};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: device_map MAP.yaml")?;
    let map = OccupancyMap::load(std::path::Path::new(&path))?;
    let (w, h) = (map.image.width(), map.image.height());
    // A mapping pipeline opens its own device and hands it over with GpuBackend::from_device; this
    // example lets the backend open one (any adapter, software ones included).
    let mut gpu = GpuBackend::new(GpuOptions::default())?;
    // The grid as the pipeline keeps it: one byte a cell, rows 64-byte aligned.
    let pitch = u64::from(w).next_multiple_of(64);
    let mut cells = vec![0u8; (pitch * u64::from(h)) as usize];
    for (row, src) in cells
        .chunks_exact_mut(pitch as usize)
        .zip(map.image.pixels().chunks_exact(w as usize))
    {
        row[..w as usize].copy_from_slice(src);
    }
    let buffer = gpu.device().create_buffer(&wgpu::BufferDescriptor {
        label: Some("occupancy grid"),
        size: cells.len() as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    gpu.queue().write_buffer(&buffer, 0, &cells);
    let grid = DeviceMap {
        buffer: &buffer,
        offset: 0,
        width: w,
        height: h,
        bytes_per_row: pitch,
    };
    let classes = ClassTable::new(&map.thresholds);
    let rules = RuleTable::new(RuleSet::Paper);
    let corners = gpu.detect_device_map(&grid, &classes, &rules, false)?;
    println!(
        "{} corners in {path} ({w}x{h}) on {}",
        corners.len(),
        gpu.adapter().name
    );
    // The same corners as the map in memory on the CPU reference.
    let cpu = ReferenceBackend.detect(&map.image, &classes, &rules, false)?;
    if cpu != corners {
        return Err(format!(
            "the CPU found {} corners, the GPU {}",
            cpu.len(),
            corners.len()
        )
        .into());
    }
    Ok(())
}
