//! One OGM detection call on the device: the tiles of each slab planned within the binding and tile
//! budgets, each tile's pixels placed (staged from the host, or bound where a device map lies), its
//! kernels, scan and scatter recorded in one submission, the passes over the list's windows, and the
//! keypoints read back. The kernels' parameters, pipelines and buffers are in `ogm.rs`.

use super::device_map::Source;
use super::ogm::{
    DetectForm, OgmParams, ENOUGH_GROUPS, KEYPOINT_BYTES, LANES, MAX_SCRATCH, MAX_TIMED_TILES,
    PARAMS_BYTES, RUN, SLAB_ROWS, STRIP,
};
use super::scan::{ScanPlan, PARAM_ALIGN};
use super::*;
use crate::backend::fast::bitplanes::{ogm_sets, ValueSet};

/// A value set's form in the kernel (see [`DetectForm`]) with its lo and span in every byte: at least lo
/// where the set reaches 255 (as the ROS thresholds' free set does), below lo where it starts at 0 (their
/// blocking set), else the general interval; `None` where only the table states it (the empty set too).
fn state_form(set: &ValueSet) -> Option<(u32, u32, u32)> {
    let every = |v: u32| v * 0x0101_0101;
    match *set {
        ValueSet::Interval { lo, span } => {
            let (lo, span) = (u32::from(lo), u32::from(span));
            Some(if lo + span == 255 {
                (1, every(lo), 0)
            } else if lo == 0 {
                (2, every(span + 1), 0)
            } else {
                (0, every(lo), every(span))
            })
        }
        ValueSet::Empty | ValueSet::Table(_) => None,
    }
}

/// Rows a detect invocation walks down in a tile of `core_rows` rows and `groups_x` workgroup columns:
/// [`STRIP`], the fewest halo rows read twice, where that gives [`ENOUGH_GROUPS`] workgroups; else 8 or 4
/// (rows read per row of the map: 18/16, 10/8, 6/4), within `max_groups` strips and `max_scratch`
/// workgroups' scratch regions.
fn strip_rows(groups_x: u32, core_rows: u32, max_groups: u32, max_scratch: u64) -> u32 {
    let groups = |s: u32| u64::from(groups_x) * u64::from(core_rows.div_ceil(s));
    let mut s = STRIP;
    while s > 4
        && groups(s) < ENOUGH_GROUPS
        && strip_fits(s / 2, groups_x, core_rows, max_groups, max_scratch)
    {
        s /= 2;
    }
    s
}

/// Whether strips of `s` rows keep a tile's strips within `max_groups` and their workgroups' scratch
/// regions within `max_scratch`.
fn strip_fits(s: u32, groups_x: u32, core_rows: u32, max_groups: u32, max_scratch: u64) -> bool {
    let strips = core_rows.div_ceil(s);
    strips <= max_groups && u64::from(groups_x) * u64::from(strips) <= max_scratch
}

/// The strip height `want` asks for, raised (up to [`STRIP`], which the plan fits) until the tile's
/// strips stay within `max_groups` and their scratch regions within `max_scratch`.
fn strip_within(
    want: u32,
    groups_x: u32,
    core_rows: u32,
    max_groups: u32,
    max_scratch: u64,
) -> u32 {
    (want.clamp(1, STRIP)..STRIP)
        .find(|&s| strip_fits(s, groups_x, core_rows, max_groups, max_scratch))
        .unwrap_or(STRIP)
}

/// What stays the same over a call: the classification (its form and each state's lo and span) and the
/// rules.
struct Call {
    form: DetectForm,
    free: (u32, u32),
    blk: (u32, u32),
    min_bits: u32,
}

impl Call {
    fn new(free: &ValueSet, blk: &ValueSet, min_bits: u32) -> Self {
        match (state_form(free), state_form(blk)) {
            (Some(f), Some(b)) => Call {
                form: DetectForm {
                    table: false,
                    free: f.0,
                    blk: b.0,
                },
                free: (f.1, f.2),
                blk: (b.1, b.2),
                min_bits,
            },
            _ => Call {
                form: DetectForm {
                    table: true,
                    free: 0,
                    blk: 0,
                },
                free: (0, 0),
                blk: (0, 0),
                min_bits,
            },
        }
    }
}

/// The head of a tile's parameter buffer: the detector's block, then one block per scan level.
fn params_head(p: &OgmParams, scan: &ScanPlan, max_groups: u32) -> Vec<u8> {
    let mut head = vec![0u8; PARAMS_BYTES as usize];
    head[..std::mem::size_of::<OgmParams>()].copy_from_slice(bytemuck::bytes_of(p));
    for (k, sp) in scan.params(max_groups).iter().enumerate() {
        let at = (k + 1) * PARAM_ALIGN as usize;
        head[at..at + 16].copy_from_slice(bytemuck::bytes_of(sp));
    }
    head
}

impl GpuBackend {
    /// The OGM tiles of rows `y0..y1` of a `w` x `h` map staged from the host: bands within the device's
    /// binding limit and the tile budget, each small enough for its dispatch and its scratch.
    pub(super) fn ogm_plan(&self, w: u32, h: u32, y0: u32, y1: u32) -> Result<Vec<tiles::Tile>> {
        let budget = self.max_binding.min(self.options.max_tile_bytes.max(1));
        self.ogm_plan_within(w, h, y0, y1, budget, self.options.tile.unwrap_or((w, h)))
    }

    /// The OGM tiles of rows `y0..y1` of `src`: a host map's as [`Self::ogm_plan`]; a device map's in
    /// full-width bands, each bound where it lies within the binding limit.
    fn ogm_plan_for(&self, src: Source, y0: u32, y1: u32) -> Result<Vec<tiles::Tile>> {
        let (w, h) = src.size();
        let Source::Device(map) = src else {
            return self.ogm_plan(w, h, y0, y1);
        };
        // A band of r buffer rows binds at most r rows of the map plus the offset's alignment slack;
        // the tile budget counts rows padded to whole runs.
        let bindable = self.max_binding.min(u64::from(u32::MAX) - 64);
        let rows = bindable.saturating_sub(self.storage_align() + 16) / map.bytes_per_row.max(1);
        let padded_row = u64::from((w + 2).div_ceil(RUN) * RUN);
        // Bands of as many rows as bind, however few (the tile planner would square tiles below 16).
        let bindable_rows = rows.saturating_sub(2).clamp(1, u64::from(h)) as u32;
        let forced = (w, self.options.tile.map_or(h, |t| t.1).min(bindable_rows));
        let plan = self.ogm_plan_within(w, h, y0, y1, rows * padded_row, forced)?;
        if plan.iter().any(|t| t.core[2] - t.core[0] < w) {
            return Err(Error::Unavailable(format!(
                "rows of {} bytes are too wide for {}'s storage binding limit ({} bytes)",
                map.bytes_per_row, self.adapter.name, self.max_binding
            )));
        }
        Ok(plan)
    }

    /// The tiles of rows `y0..y1` whose padded uploads take at most `budget` bytes, cores capped at
    /// `forced`.
    fn ogm_plan_within(
        &self,
        w: u32,
        h: u32,
        y0: u32,
        y1: u32,
        budget: u64,
        forced: (u32, u32),
    ) -> Result<Vec<tiles::Tile>> {
        // Byte positions within a band are 32-bit in the kernel.
        let budget = budget.min(u64::from(u32::MAX) - 64);
        let too_small = || {
            Error::Unavailable(format!(
                "{}'s buffer limit ({} bytes) is too small for any tile",
                self.adapter.name, budget
            ))
        };
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

    /// Rows a detect invocation walks down in a tile of `core_rows` rows and `groups_x` workgroup
    /// columns ([`strip_rows`]); a software adapter, whose few threads are full anyway, keeps [`STRIP`].
    fn strip_rows(&self, groups_x: u32, core_rows: u32) -> u32 {
        let per_group = u64::from(self.ogm_bufs.scratch) * KEYPOINT_BYTES;
        let max_scratch = self.max_binding / per_group.max(1);
        if let Some(s) = self.options.strip_rows {
            return strip_within(s, groups_x, core_rows, self.max_groups, max_scratch);
        }
        if self.adapter.device_type == "Cpu" {
            return STRIP;
        }
        strip_rows(groups_x, core_rows, self.max_groups, max_scratch)
    }

    /// Rows of one slab of a map `w` pixels wide: at most [`SLAB_ROWS`] (the keypoint's row field) and
    /// fewer than 2^32 pixels (list positions are 32-bit).
    pub(super) fn ogm_slab(&self, w: u32) -> u32 {
        self.options
            .slab_rows
            .clamp(1, SLAB_ROWS)
            .min((u32::MAX / w.max(1)).max(1))
    }

    /// Where tile `t`'s kernel finds its pixels in its binding: bytes from a row to the next, and the
    /// byte of its first pixel.
    fn pixel_layout(&self, src: Source, t: &tiles::Tile) -> (u32, u32) {
        match src {
            Source::Host(_) if self.reads_staging() => {
                (t.ogm_pitch(), (PARAMS_BYTES % self.storage_align) as u32)
            }
            Source::Host(_) => (t.ogm_pitch(), 0),
            Source::Device(map) => (
                map.bytes_per_row as u32,
                map.window(t, self.storage_align()).first_byte,
            ),
        }
    }

    /// Puts tile `t`'s parameter blocks `head` and its pixels where its kernels read them: a host tile's
    /// parameters and rows (padded to whole 32-pixel runs) staged into the ring, the parameters copied by
    /// `encoder` and the rows read by the kernel in the staging buffer itself where the device allows
    /// ([`GpuBackend::reads_staging`]), else copied too; a device map's parameters written to the queue,
    /// its pixels left where they are. Returns the detect
    /// kernel's pipeline (classifying in `form`) and bind group, and the staging buffer's index.
    fn place_pixels(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        src: Source,
        t: &tiles::Tile,
        slot: usize,
        head: &[u8],
        form: DetectForm,
    ) -> Result<(wgpu::ComputePipeline, wgpu::BindGroup, Option<usize>)> {
        match src {
            Source::Host(image) => {
                let (ring_i, staging, bytes) = self.ring.stage_band(
                    &self.device,
                    image,
                    t,
                    t.ogm_pitch() as usize,
                    head,
                    PARAMS_BYTES as usize,
                )?;
                let pipeline = self.ogm.detect(&self.device, false, form);
                let params = &self.ogm_bufs.params[slot];
                encoder.copy_buffer_to_buffer(&staging, 0, params, 0, PARAMS_BYTES);
                if self.reads_staging() {
                    let offset = PARAMS_BYTES / self.storage_align * self.storage_align;
                    let size = PARAMS_BYTES - offset + bytes;
                    let bind = self.bind_pixels_at(slot, &staging, offset, size);
                    return Ok((pipeline, bind, Some(ring_i)));
                }
                let b = &mut self.ogm_bufs;
                let pixels = b.pixels[slot]
                    .get(&self.device, bytes, self.max_binding)
                    .clone();
                encoder.copy_buffer_to_buffer(&staging, PARAMS_BYTES, &pixels, 0, bytes);
                self.stats.pixel_copies += 1;
                let sb = b.binds(&self.device, &self.ogm, slot);
                Ok((pipeline, sb.detect, Some(ring_i)))
            }
            Source::Device(map) => {
                let win = map.window(t, self.storage_align());
                self.queue
                    .write_buffer(&self.ogm_bufs.params[slot], 0, head);
                let pipeline = self.ogm.detect(&self.device, !win.runs, form);
                let bind = self.bind_pixels_at(slot, map.buffer, win.offset, win.size);
                Ok((pipeline, bind, None))
            }
        }
    }

    /// The detect kernel's bind group for slot `slot` with its pixels bound at bytes `offset..offset +
    /// size` of `buffer` (a staging buffer, or a caller's map).
    fn bind_pixels_at(
        &mut self,
        slot: usize,
        buffer: &wgpu::Buffer,
        offset: u64,
        size: u64,
    ) -> wgpu::BindGroup {
        fn whole(binding: u32, buffer: &wgpu::Buffer) -> (u32, wgpu::BufferBinding<'_>) {
            (binding, buffer.as_entire_buffer_binding())
        }
        let b = &mut self.ogm_bufs;
        let counts = b.counts.get(&self.device, 16, u64::MAX).clone();
        let found = b.found.get(&self.device, 16, u64::MAX).clone();
        let ordered = b.ordered.get(&self.device, 16, u64::MAX).clone();
        let entries = [
            whole(0, &b.params[slot]),
            whole(1, &b.tables),
            (
                2,
                wgpu::BufferBinding {
                    buffer,
                    offset,
                    size: wgpu::BufferSize::new(size),
                },
            ),
            whole(3, &counts),
            whole(4, &found),
            whole(5, &ordered),
            whole(6, &b.status),
        ];
        let entries: Vec<wgpu::BindGroupEntry> = entries
            .into_iter()
            .map(|(binding, b)| wgpu::BindGroupEntry {
                binding,
                resource: wgpu::BindingResource::Buffer(b),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ogm pixels in place"),
            layout: &self.ogm.detect_group,
            entries: &entries,
        })
    }

    /// Records tile `t`'s pixels (staged or bound where they lie), kernels, scan and scatter into a new
    /// encoder; returns the encoder and the staging buffer's index, if it used one.
    fn encode_tile(
        &mut self,
        src: Source,
        t: &tiles::Tile,
        slot: usize,
        mut p: OgmParams,
        form: DetectForm,
        timing: Option<(&wgpu::QuerySet, u32)>,
    ) -> Result<(wgpu::CommandEncoder, Option<usize>)> {
        let core_rows = t.core[3] - t.core[1];
        let n_counts = u64::from(core_rows) * u64::from(p.groups_x);
        let scan = ScanPlan::new(n_counts + 1).ok_or_else(|| {
            Error::Internal(format!("tile of {n_counts} counts is too large to scan"))
        })?;
        let strips = core_rows.div_ceil(p.strip);
        let cap = self.max_binding;
        let b = &mut self.ogm_bufs;
        let counts = b.counts.get(&self.device, scan.entries * 4, cap).clone();
        let scratch_bytes =
            u64::from(p.groups_x) * u64::from(strips) * u64::from(p.scratch) * KEYPOINT_BYTES;
        b.found.get(&self.device, scratch_bytes, cap);
        b.ordered.get(&self.device, scratch_bytes, cap);
        (p.row_bytes, p.first_byte) = self.pixel_layout(src, t);
        let head = params_head(&p, &scan, self.max_groups);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let (detect, detect_bind, ring_i) =
            self.place_pixels(&mut encoder, src, t, slot, &head, form)?;
        let sb = self.ogm_bufs.binds(&self.device, &self.ogm, slot);
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
            pass.set_pipeline(&detect);
            pass.set_bind_group(0, &detect_bind, &[]);
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
        if let Some(i) = ring_i {
            self.ring.recycle(i, &encoder);
        }
        Ok((encoder, ring_i))
    }

    /// One pass over the tiles of a slab (rows `y0..y1`), writing list positions `window` into the
    /// keypoint buffer; returns the slab's total and the largest workgroup count that overflowed its
    /// scratch (0 when none did).
    fn ogm_pass(
        &mut self,
        src: Source,
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
            let lanes_x = t.buf_w().div_ceil(RUN);
            let groups_x = lanes_x.div_ceil(LANES);
            let p = OgmParams {
                buf_w: t.buf_w(),
                buf_h: t.buf_h(),
                row_bytes: 0, // set where the pixels are placed
                lanes_x,
                groups_x,
                core_x0: t.core[0] - t.buf[0],
                core_y0: t.core[1] - t.buf[1],
                core_x1: t.core[2] - t.buf[0],
                core_y1: t.core[3] - t.buf[1],
                x_base: t.buf[0],
                y_base: t.buf[1].wrapping_sub(slab_y0),
                strip: self.strip_rows(groups_x, t.core[3] - t.core[1]),
                free_lo: call.free.0,
                free_span: call.free.1,
                blk_lo: call.blk.0,
                blk_span: call.blk.1,
                min_bits: call.min_bits,
                scratch: self.ogm_bufs.scratch,
                out_start: window.0,
                out_end: window.1,
                n_counts: (t.core[3] - t.core[1]) * groups_x,
                first_byte: 0,
                _pad: [0; 2],
            };
            let slot = i % 2;
            let (encoder, ring_i) = self.encode_tile(
                src,
                t,
                slot,
                p,
                call.form,
                queries.as_ref().map(|q| (q, i as u32)),
            )?;
            let index = self.queue.submit([encoder.finish()]);
            if let Some(ring_i) = ring_i {
                self.ring.submitted(ring_i, index);
            }
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
        src: Source,
        core: (usize, usize),
        classes: &ClassTable,
        rules: &RuleTable,
        unknown_as_occupied: bool,
    ) -> Result<Vec<Keypoint>> {
        let (w, _) = src.size();
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
        let call = Call::new(&free_set, &blk_set, min_bits);
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
                let plan = self.ogm_plan_for(src, slab_y0, slab_y1)?;
                self.stats.tiles = self.stats.tiles.max(plan.len());
                side_by_side |= plan.iter().any(|t| t.core[2] - t.core[0] < w);
                let have = (self.ogm_bufs.keypoints.size / KEYPOINT_BYTES) as u32;
                let want = have
                    .max(self.options.initial_keypoint_capacity)
                    .clamp(1, per_pass);
                let window = (start, start.saturating_add(want));
                let (total, overflow) = self.ogm_pass(src, &plan, slab_y0, &call, window)?;
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

    /// One detection call: [`Self::ogm_detect`] between the call's start (a device error left from
    /// before fails it, the statistics cleared) and its end (a device error from it fails it).
    pub(super) fn ogm_call(
        &mut self,
        src: Source,
        core: (usize, usize),
        classes: &ClassTable,
        rules: &RuleTable,
        unknown_as_occupied: bool,
    ) -> Result<Vec<Keypoint>> {
        self.start_call()?;
        let out = self.ogm_detect(src, core, classes, rules, unknown_as_occupied)?;
        self.check()?;
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
    use super::{state_form, strip_rows, strip_within};
    use crate::backend::fast::bitplanes::ValueSet;

    const H: u32 = 0x8080_8080;

    /// The kernel's `in_interval`, `bytes_at_least`, `in_state` and `pack4`, line for line.
    fn in_interval(p: u32, lo4: u32, span4: u32) -> u32 {
        let d = ((p | H).wrapping_sub(lo4 & !H)) ^ ((p ^ !lo4) & H);
        let t = (span4 | H).wrapping_sub(d & !H);
        ((span4 & !d) | (!(span4 ^ d) & t)) & H
    }

    fn bytes_at_least(p: u32, y4: u32) -> u32 {
        let d = (p | H).wrapping_sub(y4 & !H);
        ((p & !y4) | (!(p ^ y4) & d)) & H
    }

    fn in_state(p: u32, form: u32, lo4: u32, span4: u32) -> u32 {
        match form {
            1 => bytes_at_least(p, lo4),
            2 => bytes_at_least(p, lo4) ^ H,
            _ => in_interval(p, lo4, span4),
        }
    }

    fn pack4(m: u32) -> u32 {
        m.wrapping_mul(0x0020_4081) >> 28
    }

    #[test]
    fn small_maps_take_shorter_strips_to_fill_the_device() {
        // 4096^2: 2 workgroup columns; 256 strips of 16 would be 512 workgroups, so strips of 4.
        assert_eq!(strip_rows(2, 4096, 65535, u64::MAX), 4);
        // 16384^2: 8 columns of 1024 strips of 16 are enough.
        assert_eq!(strip_rows(8, 16384, 65535, u64::MAX), 16);
        assert_eq!(strip_rows(2, 65536, 65535, u64::MAX), 16);
        // 8192^2: 4 columns, 512 strips of 16 (2048 workgroups), 1024 of 8, 2048 of 4.
        assert_eq!(strip_rows(4, 8192, 65535, u64::MAX), 4);
        // Within the dispatch limit and the scratch regions there is room for.
        assert_eq!(strip_rows(2, 4096, 300, u64::MAX), 16);
        assert_eq!(strip_rows(2, 4096, 65535, 1100), 8);
        assert_eq!(strip_rows(1, 10, 65535, u64::MAX), 4);
        // A height asked for is kept where it fits, raised where it would not.
        assert_eq!(strip_within(1, 2, 4096, 65535, u64::MAX), 1);
        assert_eq!(strip_within(1, 1, 100_000, 65535, u64::MAX), 2);
        assert_eq!(strip_within(3, 2, 4096, 65535, 1100), 8);
        assert_eq!(strip_within(40, 2, 4096, 65535, u64::MAX), 16);
        assert_eq!(strip_within(1, 2, 4096, 10, 10), 16);
    }

    #[test]
    fn every_interval_is_classified_exactly_in_the_form_the_host_picks() {
        // Every lo and span (wrapping intervals included), every value at a varying byte of a word
        // whose other bytes vary too; the forms the host picks for them (one-sided where the interval
        // reaches 0 or 255, as the ROS thresholds' do) and the general form for each.
        let mut x = 12345u64;
        let mut forms = [0usize; 3];
        for lo in 0..=255u8 {
            for span in 0..=255u8 {
                let set = ValueSet::Interval { lo, span };
                let (form, lo4, span4) = state_form(&set).expect("an interval has a form");
                forms[form as usize] += 1;
                let general = (
                    0,
                    u32::from(lo) * 0x0101_0101,
                    u32::from(span) * 0x0101_0101,
                );
                for v in 0..256u32 {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    let k = (x % 4) as u32;
                    let p = ((x >> 8) as u32 & !(0xff << (8 * k))) | (v << (8 * k));
                    let want: u32 = (0..4)
                        .map(|i| u32::from(set.contains(((p >> (8 * i)) & 0xff) as u8)) << i)
                        .sum();
                    for (f, l, s) in [(form, lo4, span4), general] {
                        assert_eq!(
                            pack4(in_state(p, f, l, s)),
                            want,
                            "lo {lo} span {span} form {f} word {p:#x}"
                        );
                    }
                }
            }
        }
        // 256 intervals reach 255, 255 more start at 0 (the whole range counted once).
        assert_eq!(forms, [65536 - 511, 256, 255]);
    }
}
