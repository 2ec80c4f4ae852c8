//! The OGM detector on the GPU: one fused pass over the raw map bytes per tile, the device-side scan of its
//! counts and the scatter into the final list, all in the tile's one submission (`shaders/ogm_corners.wgsl`,
//! `shaders/scan.wgsl`). The host reads back twice per call, whatever the number of tiles: the total, then
//! exactly that many 8-byte keypoints. This file holds the kernels' parameters, pipelines and buffers;
//! `ogm_call.rs` runs a call.

use super::scan::{scan_binds, MAX_LEVELS, PARAM_ALIGN};
use super::*;

/// Invocations of a `detect` workgroup side by side, each owning 32 pixels of a row.
pub(super) const LANES: u32 = 64;
/// Rows a `detect` invocation walks down.
pub(super) const STRIP: u32 = 16;
/// Pixels of one invocation's run.
pub(super) const RUN: u32 = tiles::ROW_ALIGN;
/// The most keypoints a workgroup can find (every pixel of its strip).
pub(super) const MAX_SCRATCH: u32 = LANES * RUN * STRIP;
/// Bytes of a keypoint in the device list: x, then y << 8 | code.
pub(super) const KEYPOINT_BYTES: u64 = 8;
/// Rows of one slab at most: keypoint rows are stored in 24 bits, so taller maps run slab by slab.
pub(super) const SLAB_ROWS: u32 = 1 << 24;
/// Bytes of the parameter blocks at the head of each staged band: the detector's, then one per scan level.
pub(super) const PARAMS_BYTES: u64 = PARAM_ALIGN * (MAX_LEVELS as u64 + 1);
/// Tiles whose kernels are timed per call at most (two timestamps each, within wgpu's query-set limit).
pub(super) const MAX_TIMED_TILES: usize = 2048;

/// The detector's parameters, laid out as `struct Params` in ogm_corners.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct OgmParams {
    pub(super) buf_w: u32,
    pub(super) buf_h: u32,
    pub(super) row_bytes: u32,
    pub(super) lanes_x: u32,
    pub(super) groups_x: u32,
    pub(super) core_x0: u32,
    pub(super) core_y0: u32,
    pub(super) core_x1: u32,
    pub(super) core_y1: u32,
    pub(super) x_base: u32,
    pub(super) y_base: u32,
    pub(super) interval: u32,
    pub(super) free_lo: u32,
    pub(super) free_span: u32,
    pub(super) blk_lo: u32,
    pub(super) blk_span: u32,
    pub(super) min_bits: u32,
    pub(super) scratch: u32,
    pub(super) out_start: u32,
    pub(super) out_end: u32,
    pub(super) n_counts: u32,
    pub(super) first_byte: u32,
    pub(super) _pad: [u32; 2],
}

/// The OGM pipelines, built once per device.
pub(super) struct OgmPipelines {
    /// Reads rows that start 16-byte aligned (shaders/lib/ogm_fetch_runs.wgsl).
    pub detect: wgpu::ComputePipeline,
    /// Reads a map at any offset and pitch (shaders/lib/ogm_fetch_bytes.wgsl); built on first use.
    pub detect_any: Option<wgpu::ComputePipeline>,
    pub scatter: wgpu::ComputePipeline,
    pub finish: wgpu::ComputePipeline,
    pub scan_blocks: wgpu::ComputePipeline,
    pub scan_add: wgpu::ComputePipeline,
}

impl OgmPipelines {
    pub fn new(device: &wgpu::Device) -> Self {
        let module = |label, src: &str| {
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            })
        };
        let corners = module("ogm_corners.wgsl", &super::ogm_shader_source(false));
        let scan = module("scan.wgsl", include_str!("../../../shaders/scan.wgsl"));
        let pipeline =
            |m: &wgpu::ShaderModule, entry: &str, layout: Option<&wgpu::PipelineLayout>| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout,
                    module: m,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
        // The scan's two entry points share one layout, so one bind group per level serves both.
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let scan_group = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scan"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Uniform),
                entry(1, wgpu::BufferBindingType::Storage { read_only: false }),
            ],
        });
        let scan_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scan"),
            bind_group_layouts: &[Some(&scan_group)],
            immediate_size: 0,
        });
        OgmPipelines {
            detect: pipeline(&corners, "detect", None),
            detect_any: None,
            scatter: pipeline(&corners, "scatter", None),
            finish: pipeline(&corners, "finish", None),
            scan_blocks: pipeline(&scan, "scan_blocks", Some(&scan_layout)),
            scan_add: pipeline(&scan, "scan_add", Some(&scan_layout)),
        }
    }
}

/// The device buffers of the OGM path: two slots (parameters and pixels) so that one band uploads while the
/// previous one runs, and the shared counts, scratch, status and list.
pub(super) struct OgmBuffers {
    pub params: [wgpu::Buffer; 2],
    pub pixels: [Slot; 2],
    pub tables: wgpu::Buffer,
    pub counts: Slot,
    pub found: Slot,
    pub ordered: Slot,
    pub status: wgpu::Buffer,
    pub status_read: wgpu::Buffer,
    pub keypoints: Slot,
    pub readback: Slot,
    /// Keypoints a workgroup's scratch holds; grows when a map needs more.
    pub scratch: u32,
    binds: Option<(Vec<u64>, [SlotBinds; 2])>,
}

#[derive(Clone)]
pub(super) struct SlotBinds {
    pub detect: wgpu::BindGroup,
    pub scatter: wgpu::BindGroup,
    pub finish: wgpu::BindGroup,
    pub scan: Vec<wgpu::BindGroup>,
}

impl OgmBuffers {
    pub fn new(device: &wgpu::Device, scratch: u32) -> Self {
        let buffer = |label, size, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let uniform = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        OgmBuffers {
            params: [
                buffer("ogm params", PARAMS_BYTES, uniform),
                buffer("ogm params", PARAMS_BYTES, uniform),
            ],
            pixels: [Slot::new("pixels", storage), Slot::new("pixels", storage)],
            tables: buffer("ogm tables", 2048, storage),
            counts: Slot::new("counts", storage),
            found: Slot::new("found", wgpu::BufferUsages::STORAGE),
            ordered: Slot::new("ordered", wgpu::BufferUsages::STORAGE),
            status: buffer("status", 16, storage | wgpu::BufferUsages::COPY_SRC),
            status_read: buffer(
                "status readback",
                16,
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            keypoints: Slot::new("keypoints", storage | wgpu::BufferUsages::COPY_SRC),
            readback: Slot::new(
                "keypoint readback",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            scratch: scratch.clamp(1, MAX_SCRATCH),
            binds: None,
        }
    }

    /// The bind groups of both slots, rebuilt only when a buffer they bind was replaced.
    pub(super) fn binds(
        &mut self,
        device: &wgpu::Device,
        p: &OgmPipelines,
        slot: usize,
    ) -> SlotBinds {
        let key = vec![
            self.pixels[0].generation,
            self.pixels[1].generation,
            self.counts.generation,
            self.found.generation,
            self.ordered.generation,
            self.keypoints.generation,
        ];
        if self.binds.as_ref().is_none_or(|(k, _)| *k != key) {
            let mut make = |s: usize| {
                let params = &self.params[s];
                let pixels = self.pixels[s].get(device, 16, u64::MAX).clone();
                let counts = self.counts.get(device, 16, u64::MAX).clone();
                let found = self.found.get(device, 16, u64::MAX).clone();
                let ordered = self.ordered.get(device, 16, u64::MAX).clone();
                let keypoints = self.keypoints.get(device, 16, u64::MAX).clone();
                SlotBinds {
                    detect: buffers::bind_group(
                        device,
                        &p.detect,
                        &[
                            (0, params),
                            (1, &self.tables),
                            (2, &pixels),
                            (3, &counts),
                            (4, &found),
                            (5, &ordered),
                            (6, &self.status),
                        ],
                    ),
                    scatter: buffers::bind_group(
                        device,
                        &p.scatter,
                        &[
                            (0, params),
                            (3, &counts),
                            (5, &ordered),
                            (6, &self.status),
                            (7, &keypoints),
                        ],
                    ),
                    finish: buffers::bind_group(
                        device,
                        &p.finish,
                        &[(0, params), (3, &counts), (6, &self.status)],
                    ),
                    scan: scan_binds(device, &p.scan_blocks, params, &counts),
                }
            };
            let built = [make(0), make(1)];
            self.binds = Some((key, built));
        }
        self.binds.as_ref().expect("bind groups were just built").1[slot].clone()
    }
}

#[cfg(test)]
mod tests {
    /// The kernel's `in_interval`, line for line.
    fn in_interval(p: u32, lo4: u32, span4: u32) -> u32 {
        const H: u32 = 0x8080_8080;
        let d = ((p | H).wrapping_sub(lo4 & !H)) ^ ((p ^ !lo4) & H);
        let t = (span4 | H).wrapping_sub(d & !H);
        let m = (((span4 & !d) | (!(span4 ^ d) & t)) & H) >> 7;
        (m | (m >> 7) | (m >> 14) | (m >> 21)) & 0xf
    }

    #[test]
    fn the_bytewise_interval_compare_is_exact() {
        // Every lo, span and value, at a varying byte of a word whose other bytes vary too.
        let mut x = 12345u64;
        for lo in 0..256u32 {
            for span in 0..256u32 {
                for v in 0..256u32 {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    let k = (x % 4) as u32;
                    let p = ((x >> 8) as u32 & !(0xff << (8 * k))) | (v << (8 * k));
                    let want: u32 = (0..4)
                        .map(|i| {
                            let b = (p >> (8 * i)) & 0xff;
                            u32::from(b.wrapping_sub(lo) & 0xff <= span) << i
                        })
                        .sum();
                    assert_eq!(
                        in_interval(p, lo * 0x0101_0101, span * 0x0101_0101),
                        want,
                        "lo {lo} span {span} word {p:#x}"
                    );
                }
            }
        }
    }
}
