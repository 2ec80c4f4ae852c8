//! The OGM detector on the GPU: one fused pass over the raw map bytes per tile, the device-side scan of its
//! counts and the scatter into the final list, all in the tile's one submission (`shaders/ogm_corners.wgsl`,
//! `shaders/scan.wgsl`). The host reads back twice per call, whatever the number of tiles: the total, then
//! exactly that many 8-byte keypoints.

use super::scan::{scan_binds, ScanPlan, MAX_LEVELS, PARAM_ALIGN};
use super::*;
use crate::backend::fast::bitplanes::{ogm_sets, ValueSet};

/// Invocations of a `detect` workgroup side by side, each owning 32 pixels of a row.
const LANES: u32 = 64;
/// Rows a `detect` invocation walks down.
const STRIP: u32 = 16;
/// Pixels of one invocation's run.
pub(super) const RUN: u32 = tiles::ROW_ALIGN;
/// The most keypoints a workgroup can find (every pixel of its strip).
const MAX_SCRATCH: u32 = LANES * RUN * STRIP;
/// Bytes of a keypoint in the device list: x, then y << 8 | code.
const KEYPOINT_BYTES: u64 = 8;
/// Rows of one slab at most: keypoint rows are stored in 24 bits, so taller maps run slab by slab.
pub(super) const SLAB_ROWS: u32 = 1 << 24;
/// Bytes of the parameter blocks at the head of each staged band: the detector's, then one per scan level.
pub(super) const PARAMS_BYTES: u64 = PARAM_ALIGN * (MAX_LEVELS as u64 + 1);
/// Tiles whose kernels are timed per call at most (two timestamps each, within wgpu's query-set limit).
const MAX_TIMED_TILES: usize = 2048;

/// The detector's parameters, laid out as `struct Params` in ogm_corners.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct OgmParams {
    buf_w: u32,
    buf_h: u32,
    stride: u32,
    lanes_x: u32,
    groups_x: u32,
    core_x0: u32,
    core_y0: u32,
    core_x1: u32,
    core_y1: u32,
    x_base: u32,
    y_base: u32,
    interval: u32,
    free_lo: u32,
    free_span: u32,
    blk_lo: u32,
    blk_span: u32,
    min_bits: u32,
    scratch: u32,
    out_start: u32,
    out_end: u32,
    n_counts: u32,
    _pad: [u32; 3],
}

/// The OGM pipelines, built once per device.
pub(super) struct OgmPipelines {
    pub detect: wgpu::ComputePipeline,
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
        let corners = module(
            "ogm_corners.wgsl",
            include_str!("../../../shaders/ogm_corners.wgsl"),
        );
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
struct SlotBinds {
    detect: wgpu::BindGroup,
    scatter: wgpu::BindGroup,
    finish: wgpu::BindGroup,
    scan: Vec<wgpu::BindGroup>,
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
    fn binds(&mut self, device: &wgpu::Device, p: &OgmPipelines, slot: usize) -> SlotBinds {
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

/// A value set as the kernel's interval parameters, lo and span in every byte; `false` when only the
/// table states it (the empty set included).
fn interval(set: &ValueSet) -> (bool, u32, u32) {
    match set {
        ValueSet::Interval { lo, span } => (
            true,
            u32::from(*lo) * 0x0101_0101,
            u32::from(*span) * 0x0101_0101,
        ),
        ValueSet::Empty | ValueSet::Table(_) => (false, 0, 0),
    }
}

/// What stays the same over a call: the classification, the rules and the output window.
struct Call {
    free: (bool, u32, u32),
    blk: (bool, u32, u32),
    min_bits: u32,
}

impl GpuBackend {
    /// The OGM tiles of rows `y0..y1` of a `w` x `h` map: bands within the device's binding limit and the
    /// tile budget, each small enough for its dispatch and its scratch.
    pub(super) fn ogm_plan(&self, w: u32, h: u32, y0: u32, y1: u32) -> Result<Vec<tiles::Tile>> {
        let budget = self.max_binding.min(self.options.max_tile_bytes.max(1));
        let too_small = || {
            Error::Unavailable(format!(
                "{}'s buffer limit ({} bytes) is too small for any tile",
                self.adapter.name, budget
            ))
        };
        let forced = self.options.tile.unwrap_or((w, h));
        let max_rows = self.max_groups.saturating_mul(STRIP);
        let (tw, th) =
            tiles::tile_size(w, y1 - y0, budget, Some((forced.0, forced.1.min(max_rows))))
                .ok_or_else(too_small)?;
        // Workgroup columns cover the tile's buffer, its halo columns included.
        let groups_x = tw.saturating_add(2).min(w).div_ceil(RUN * LANES);
        if groups_x > self.max_groups {
            return Err(too_small());
        }
        // Scratch: two regions of `scratch` keypoints per workgroup, each within one binding.
        let groups_x = u64::from(groups_x);
        let per_strip = groups_x * u64::from(self.ogm_bufs.scratch) * KEYPOINT_BYTES;
        let strips = (self.max_binding / per_strip.max(1)).min(u64::from(self.max_groups));
        let th = th.min((strips * u64::from(STRIP)).min(u64::from(u32::MAX)) as u32);
        if th == 0 {
            return Err(too_small());
        }
        Ok(tiles::plan_rows(w, h, y0, y1, tw, th, 1))
    }

    /// Rows of one slab of a map `w` pixels wide: at most [`SLAB_ROWS`] (the keypoint's row field) and
    /// fewer than 2^32 pixels (list positions are 32-bit).
    pub(super) fn ogm_slab(&self, w: u32) -> u32 {
        self.options
            .slab_rows
            .clamp(1, SLAB_ROWS)
            .min((u32::MAX / w.max(1)).max(1))
    }

    /// Stages tile `t` (its parameter blocks, then its rows padded to whole 32-pixel runs) into the ring and
    /// records its copy, kernels, scan and scatter into a new encoder; returns the encoder and the staging
    /// buffer's index.
    fn encode_tile(
        &mut self,
        image: Rows,
        t: &tiles::Tile,
        slot: usize,
        p: OgmParams,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) -> Result<(wgpu::CommandEncoder, usize)> {
        let core_rows = t.core[3] - t.core[1];
        let n_counts = u64::from(core_rows) * u64::from(p.groups_x);
        let scan = ScanPlan::new(n_counts + 1).ok_or_else(|| {
            Error::Internal(format!("tile of {n_counts} counts is too large to scan"))
        })?;
        let mut head = vec![0u8; PARAMS_BYTES as usize];
        head[..std::mem::size_of::<OgmParams>()].copy_from_slice(bytemuck::bytes_of(&p));
        for (k, sp) in scan.params(self.max_groups).iter().enumerate() {
            let at = (k + 1) * PARAM_ALIGN as usize;
            head[at..at + 16].copy_from_slice(bytemuck::bytes_of(sp));
        }
        let (ring_i, staging, bytes) = self.ring.stage_band(
            &self.device,
            image,
            t,
            t.ogm_pitch() as usize,
            &head,
            PARAMS_BYTES as usize,
        )?;
        let strips = core_rows.div_ceil(STRIP);
        let b = &mut self.ogm_bufs;
        let cap = self.max_binding;
        let pixels = b.pixels[slot].get(&self.device, bytes, cap).clone();
        let counts = b.counts.get(&self.device, scan.entries * 4, cap).clone();
        let scratch_bytes =
            u64::from(p.groups_x) * u64::from(strips) * u64::from(p.scratch) * KEYPOINT_BYTES;
        b.found.get(&self.device, scratch_bytes, cap);
        b.ordered.get(&self.device, scratch_bytes, cap);
        let sb = b.binds(&self.device, &self.ogm, slot);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&staging, 0, &b.params[slot], 0, PARAMS_BYTES);
        encoder.copy_buffer_to_buffer(&staging, PARAMS_BYTES, &pixels, 0, bytes);
        // The entry after the counts is the scan's total once scanned; it must start at zero.
        encoder.clear_buffer(&counts, n_counts * 4, Some(4));
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("ogm tile"),
                timestamp_writes: timing.map(|(query_set, i)| wgpu::ComputePassTimestampWrites {
                    query_set,
                    beginning_of_pass_write_index: Some(2 * i),
                    end_of_pass_write_index: Some(2 * i + 1),
                }),
            });
            pass.set_pipeline(&self.ogm.detect);
            pass.set_bind_group(0, &sb.detect, &[]);
            pass.dispatch_workgroups(p.groups_x, strips, 1);
            self.stats.dispatches += 3 + scan.encode(
                &mut pass,
                &self.ogm.scan_blocks,
                &self.ogm.scan_add,
                &sb.scan,
                self.max_groups,
            );
            pass.set_pipeline(&self.ogm.scatter);
            pass.set_bind_group(0, &sb.scatter, &[]);
            pass.dispatch_workgroups(p.groups_x, strips, 1);
            pass.set_pipeline(&self.ogm.finish);
            pass.set_bind_group(0, &sb.finish, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        }
        self.ring.recycle(ring_i, &encoder);
        Ok((encoder, ring_i))
    }

    /// One pass over the tiles of a slab (rows `y0..y1`), writing list positions `window` into the
    /// keypoint buffer; returns the slab's total and the largest workgroup count that overflowed its
    /// scratch (0 when none did).
    fn ogm_pass(
        &mut self,
        image: Rows,
        plan: &[tiles::Tile],
        slab_y0: u32,
        call: &Call,
        window: (u32, u32),
    ) -> Result<(u32, u32)> {
        let timed = self.timestamps.is_some() && plan.len() <= MAX_TIMED_TILES;
        if !timed {
            // A partial sum would read as a kernel time; report none.
            self.stats.kernel_time = None;
        }
        let queries = timed.then(|| {
            self.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("ogm tile timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * plan.len() as u32,
            })
        });
        let window_len = u64::from(window.1 - window.0);
        self.ogm_bufs
            .keypoints
            .get(&self.device, window_len * KEYPOINT_BYTES, self.max_binding);
        let mut first = self.device.create_command_encoder(&Default::default());
        first.clear_buffer(&self.ogm_bufs.status, 0, None);
        self.queue.submit([first.finish()]);
        for (i, t) in plan.iter().enumerate() {
            let stride = t.ogm_pitch() / 4;
            let lanes_x = stride / 8;
            let groups_x = lanes_x.div_ceil(LANES);
            let p = OgmParams {
                buf_w: t.buf_w(),
                buf_h: t.buf_h(),
                stride,
                lanes_x,
                groups_x,
                core_x0: t.core[0] - t.buf[0],
                core_y0: t.core[1] - t.buf[1],
                core_x1: t.core[2] - t.buf[0],
                core_y1: t.core[3] - t.buf[1],
                x_base: t.buf[0],
                y_base: t.buf[1].wrapping_sub(slab_y0),
                interval: u32::from(call.free.0 && call.blk.0),
                free_lo: call.free.1,
                free_span: call.free.2,
                blk_lo: call.blk.1,
                blk_span: call.blk.2,
                min_bits: call.min_bits,
                scratch: self.ogm_bufs.scratch,
                out_start: window.0,
                out_end: window.1,
                n_counts: (t.core[3] - t.core[1]) * groups_x,
                _pad: [0; 3],
            };
            let slot = i % 2;
            let (encoder, ring_i) =
                self.encode_tile(image, t, slot, p, queries.as_ref().map(|q| (q, i as u32)))?;
            let index = self.queue.submit([encoder.finish()]);
            self.ring.submitted(ring_i, index);
        }
        let mut last = self.device.create_command_encoder(&Default::default());
        last.copy_buffer_to_buffer(&self.ogm_bufs.status, 0, &self.ogm_bufs.status_read, 0, 16);
        let resolve = queries.as_ref().map(|q| {
            let size = 16 * plan.len() as u64;
            let resolve = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp readback"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            last.resolve_query_set(q, 0..2 * plan.len() as u32, &resolve, 0);
            last.copy_buffer_to_buffer(&resolve, 0, &read, 0, size);
            (read, size)
        });
        self.queue.submit([last.finish()]);
        let status = buffers::map_read(&self.device, &self.ogm_bufs.status_read, 16)?;
        self.check()?;
        if let Some((read, size)) = resolve {
            let ts = buffers::map_read(&self.device, &read, size)?;
            let ticks: &[u64] = bytemuck::cast_slice(&ts);
            let total: u64 = ticks
                .chunks_exact(2)
                .map(|t| t[1].saturating_sub(t[0]))
                .sum();
            let ns = total as f64 * f64::from(self.queue.get_timestamp_period());
            if let Some(prev) = self.stats.kernel_time {
                self.stats.kernel_time = Some(prev + Duration::from_nanos(ns as u64));
            }
        }
        let word =
            |i: usize| u32::from_le_bytes(status[4 * i..4 * i + 4].try_into().expect("4 bytes"));
        Ok((word(0), word(1)))
    }

    /// Every keypoint of rows `core` of the map rows `image` (which hold a row above and below the core
    /// where the map has them), in (y, x) order: slab by slab, each slab's tiles in passes over a window
    /// of the list (one pass unless the list outgrows the keypoint buffer), rerun with more scratch when a
    /// workgroup overflowed its own.
    pub(super) fn ogm_detect(
        &mut self,
        image: Rows,
        core: (usize, usize),
        classes: &ClassTable,
        rules: &RuleTable,
        unknown_as_occupied: bool,
    ) -> Result<Vec<Keypoint>> {
        let (w, h) = (image.width() as u32, image.height() as u32);
        let Some(min_bits) = rules.min_accepted_bits() else {
            return Ok(Vec::new());
        };
        let (core0, core1) = (core.0 as u32, core.1 as u32);
        if w == 0 || core1 <= core0 {
            return Ok(Vec::new());
        }
        let (free_set, blk_set) = ogm_sets(classes, unknown_as_occupied);
        // The table the kernel falls back to: bit 0 free, bit 1 blocking.
        let mut tables = [0u32; 512];
        for v in 0..=255u8 {
            tables[v as usize] =
                u32::from(free_set.contains(v)) | (u32::from(blk_set.contains(v)) << 1);
        }
        for (c, &r) in rules.as_bytes().iter().enumerate() {
            tables[256 + c] = u32::from(r);
        }
        self.queue
            .write_buffer(&self.ogm_bufs.tables, 0, bytemuck::cast_slice(&tables));
        let call = Call {
            free: interval(&free_set),
            blk: interval(&blk_set),
            min_bits,
        };
        let per_pass = (self.max_binding / KEYPOINT_BYTES)
            .min(
                self.options
                    .max_keypoints_per_pass
                    .map_or(u64::MAX, u64::from),
            )
            .clamp(1, u64::from(u32::MAX)) as u32;
        let mut out = Vec::new();
        let mut side_by_side = false;
        let slab = self.ogm_slab(w);
        for slab_y0 in (core0..core1).step_by(slab as usize) {
            let slab_y1 = slab_y0.saturating_add(slab).min(core1);
            let mut start = 0u32;
            loop {
                let plan = self.ogm_plan(w, h, slab_y0, slab_y1)?;
                self.stats.tiles = self.stats.tiles.max(plan.len());
                side_by_side |= plan.iter().any(|t| t.core[2] - t.core[0] < w);
                let have = (self.ogm_bufs.keypoints.size / KEYPOINT_BYTES) as u32;
                let want = have
                    .max(self.options.initial_keypoint_capacity)
                    .clamp(1, per_pass);
                let window = (start, start.saturating_add(want));
                let (total, overflow) = self.ogm_pass(image, &plan, slab_y0, &call, window)?;
                self.stats.write_passes += 1;
                if overflow > self.ogm_bufs.scratch {
                    // A workgroup found more than its scratch holds: rerun with room for it.
                    self.ogm_bufs.scratch = overflow.next_power_of_two().min(MAX_SCRATCH);
                    self.stats.scratch_reruns += 1;
                    continue;
                }
                let got = total.min(window.1) - start.min(total);
                if got > 0 {
                    out.extend(self.read_keypoints(got, slab_y0, rules)?);
                }
                if total <= window.1 {
                    break;
                }
                // The list outgrew the buffer: grow it to the whole list (within the pass limit), so the
                // next call on a map like this one writes it in one pass, and write the next window.
                start = window.1;
                self.ogm_bufs.keypoints.get(
                    &self.device,
                    u64::from(total.min(per_pass)) * KEYPOINT_BYTES,
                    u64::from(per_pass) * KEYPOINT_BYTES,
                );
            }
        }
        self.stats.keypoint_capacity = self.ogm_bufs.keypoints.size / KEYPOINT_BYTES;
        if side_by_side {
            // Tiles side by side interleave rows; restore (y, x) order.
            out.sort_unstable();
        }
        Ok(out)
    }

    /// The first `n` entries of the keypoint buffer, decoded.
    fn read_keypoints(&mut self, n: u32, slab_y0: u32, rules: &RuleTable) -> Result<Vec<Keypoint>> {
        let size = u64::from(n) * KEYPOINT_BYTES;
        let read = self
            .ogm_bufs
            .readback
            .get(&self.device, size, u64::MAX)
            .clone();
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(
            self.ogm_bufs.keypoints.get(&self.device, size, u64::MAX),
            0,
            &read,
            0,
            size,
        );
        self.queue.submit([encoder.finish()]);
        let raw = buffers::map_read(&self.device, &read, size)?;
        self.check()?;
        let table = rules.as_bytes();
        Ok(raw[..size as usize]
            .chunks_exact(8)
            .map(|c| {
                let x = u32::from_le_bytes(c[0..4].try_into().expect("4 bytes"));
                let v = u32::from_le_bytes(c[4..8].try_into().expect("4 bytes"));
                let code = (v & 0xff) as u8;
                Keypoint::ogm(x, slab_y0 + (v >> 8), table[code as usize], code)
            })
            .collect())
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
