//! The OGM detector on the GPU: one fused pass over the raw map bytes per tile, the device-side scan of its
//! counts and the scatter into the final list, all in the tile's one submission (`shaders/ogm_corners.wgsl`,
//! `shaders/scan.wgsl`). The host reads back twice per call, whatever the number of tiles: the total, then
//! exactly that many 8-byte keypoints. This file holds the kernels' parameters, pipelines and buffers;
//! `ogm_call.rs` runs a call.

use super::params::kernel_params;
use super::scan::{scan_binds, MAX_LEVELS, PARAM_ALIGN};
use super::*;

/// Invocations of a `detect` workgroup side by side, each owning 32 pixels of a row.
pub(super) const LANES: u32 = 64;
/// Rows a `detect` invocation walks down at most (its strip; fewer where a small map would leave the device
/// short of workgroups).
pub(super) const STRIP: u32 = 16;
/// Workgroups a map's dispatch should have for a large GPU to be full: 524,288 invocations, about twice
/// what the largest (132 multiprocessors of 2,048 threads) hold at once. Not yet tuned on a real GPU.
pub(super) const ENOUGH_GROUPS: u64 = 8192;
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

kernel_params! {
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
        pub(super) strip: u32,
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
}

/// How the detect kernel classifies a call's values, fixed when its pipeline is built (the override
/// constants of ogm_corners.wgsl): every value through the class table, or each state in its form (0: the
/// general interval, 1: at least lo, 2: below lo).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) struct DetectForm {
    pub table: bool,
    pub free: u32,
    pub blk: u32,
}

/// The OGM pipelines: `scatter`, `finish` and the scan built once per device; `detect` per form and
/// pixel reader on first use, all on one layout, so one bind group serves every variant.
pub(super) struct OgmPipelines {
    /// The kernel with each pixel reader: 16-byte runs (shaders/lib/ogm_fetch_runs.wgsl) and any
    /// offset and pitch (ogm_fetch_bytes.wgsl, made on first use).
    modules: [Option<wgpu::ShaderModule>; 2],
    detect_layout: wgpu::PipelineLayout,
    /// The detect kernel's bind group layout.
    pub detect_group: wgpu::BindGroupLayout,
    detect: std::collections::HashMap<(bool, DetectForm), wgpu::ComputePipeline>,
    pub scatter: wgpu::ComputePipeline,
    pub finish: wgpu::ComputePipeline,
    pub scan_blocks: wgpu::ComputePipeline,
    pub scan_add: wgpu::ComputePipeline,
}

fn module(device: &wgpu::Device, any_alignment: bool) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("ogm_corners.wgsl"),
        source: wgpu::ShaderSource::Wgsl(super::ogm_shader_source(any_alignment).into()),
    })
}

fn layout_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl OgmPipelines {
    pub fn new(device: &wgpu::Device) -> Self {
        let corners = module(device, false);
        let scan = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("scan.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../../../shaders/scan.wgsl").into()),
        });
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
        let uniform = wgpu::BufferBindingType::Uniform;
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let write = wgpu::BufferBindingType::Storage { read_only: false };
        // The scan's two entry points share one layout, so one bind group per level serves both.
        let scan_group = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scan"),
            entries: &[layout_entry(0, uniform), layout_entry(1, write)],
        });
        let scan_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scan"),
            bind_group_layouts: &[Some(&scan_group)],
            immediate_size: 0,
        });
        let detect_group = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("ogm detect"),
            entries: &[
                layout_entry(0, uniform),
                layout_entry(1, read),
                layout_entry(2, read),
                layout_entry(3, write),
                layout_entry(4, write),
                layout_entry(5, write),
                layout_entry(6, write),
            ],
        });
        let detect_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("ogm detect"),
            bind_group_layouts: &[Some(&detect_group)],
            immediate_size: 0,
        });
        OgmPipelines {
            scatter: pipeline(&corners, "scatter", None),
            finish: pipeline(&corners, "finish", None),
            scan_blocks: pipeline(&scan, "scan_blocks", Some(&scan_layout)),
            scan_add: pipeline(&scan, "scan_add", Some(&scan_layout)),
            modules: [Some(corners), None],
            detect_layout,
            detect_group,
            detect: Default::default(),
        }
    }

    /// The detect pipeline classifying in `form`, reading 16-byte runs or, with `any_alignment`, any
    /// offset and pitch; built on first use.
    pub fn detect(
        &mut self,
        device: &wgpu::Device,
        any_alignment: bool,
        form: DetectForm,
    ) -> wgpu::ComputePipeline {
        if let Some(p) = self.detect.get(&(any_alignment, form)) {
            return p.clone();
        }
        let m = self.modules[usize::from(any_alignment)]
            .get_or_insert_with(|| module(device, any_alignment));
        let constants = [
            ("TABLE", f64::from(u8::from(form.table))),
            ("FREE_FORM", f64::from(form.free)),
            ("BLK_FORM", f64::from(form.blk)),
        ];
        let p = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("detect"),
            layout: Some(&self.detect_layout),
            module: m,
            entry_point: Some("detect"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                // The kernel writes every workgroup variable before it reads it.
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        });
        self.detect.insert((any_alignment, form), p.clone());
        p
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
                    detect: buffers::bind_group_with(
                        device,
                        &p.detect_group,
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
