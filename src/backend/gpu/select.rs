//! The baselines' selection on the device (`shaders/select_maxima.wgsl`): the scores stay on the GPU, the
//! local maxima are found and compacted there and the map's maximum reduced there; only the candidates and
//! one maximum per tile come back, and the host applies the thresholds
//! ([`crate::backend::baselines::select_candidates`]).

use super::params::kernel_params;
use super::scan::{scan_binds, ScanPlan, MAX_LEVELS, PARAM_ALIGN};
use super::*;

/// Candidates: x, y, score, in (y, x) order.
pub type Candidates = Vec<(u32, u32, i64)>;

/// Bytes of a candidate in the device list: x, y, the score's low and high words.
const CANDIDATE_BYTES: u64 = 16;

kernel_params! {
    /// The selection's parameters, laid out as `struct Params` in select_maxima.wgsl.
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
    pub(super) struct SelParams {
        region_x0: u32,
        region_y0: u32,
        region_w: u32,
        region_h: u32,
        core_x0: u32,
        core_y0: u32,
        core_w: u32,
        core_h: u32,
        map_w: u32,
        map_h: u32,
        groups_x: u32,
        n_items: u32,
        out_start: u32,
        out_end: u32,
        n_groups: u32,
        _pad: u32,
    }
}

/// Pipelines and buffers of the selection, made on first use.
pub(super) struct Select {
    count: wgpu::ComputePipeline,
    reduce_max: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    counts: Slot,
    maxes: Slot,
    out: Slot,
    small: wgpu::Buffer,
    read: Slot,
}

impl Select {
    fn new(device: &wgpu::Device) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("select_maxima.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                include_str!("../../../shaders/select_maxima.wgsl").into(),
            ),
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let copy = storage | wgpu::BufferUsages::COPY_SRC;
        Select {
            count: pipeline("count"),
            reduce_max: pipeline("reduce_max"),
            scatter: pipeline("scatter"),
            params: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("select params"),
                size: PARAM_ALIGN * (MAX_LEVELS as u64 + 1),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            counts: Slot::new("select counts", copy),
            maxes: Slot::new("select maxima", copy),
            out: Slot::new("candidates", copy),
            small: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("select totals"),
                size: 16,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            read: Slot::new(
                "candidate readback",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
        }
    }
}

impl GpuBackend {
    /// Every positive 3x3 local maximum of `kind`'s score map in (y, x) order, and the map's largest score:
    /// exactly [`crate::backend::reference::select_maxima::select_maxima`] of [`crate::backend::baselines::cpu_scores`].
    pub fn baseline_candidates(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        p: &ExactParams,
    ) -> Result<(Candidates, i64)> {
        let core = (0, image.height() as usize);
        self.baseline_candidates_rows(kind, Rows::of(image), core, p)
    }

    /// [`GpuBackend::baseline_candidates`] of rows `core` of a window of a map (which holds the rows
    /// around the core the map has, up to [`crate::map::stream::HALO`]): the candidates of those rows and their
    /// largest score.
    pub fn baseline_candidates_rows(
        &mut self,
        kind: Baseline,
        image: Rows,
        core: (usize, usize),
        p: &ExactParams,
    ) -> Result<(Candidates, i64)> {
        self.start_call()?;
        let plan = self.baseline_plan(image.width() as u32, image.height() as u32, core)?;
        self.stats.tiles = plan.len();
        let mut all = Vec::new();
        let mut max = i64::MIN;
        for t in &plan {
            let (m, found) = self.select_tile(kind, image, p, t)?;
            max = max.max(m);
            all.extend(found);
        }
        if plan
            .iter()
            .any(|t| ((t.core[2] - t.core[0]) as usize) < image.width())
        {
            all.sort_unstable_by_key(|&(x, y, _)| (y, x));
        }
        self.check()?;
        Ok((all, max))
    }

    /// One tile: scores, then count, scan, maximum and scatter in the same submission; the tile's
    /// candidates come back in windows of what the list buffer holds.
    fn select_tile(
        &mut self,
        kind: Baseline,
        image: Rows,
        p: &ExactParams,
        t: &tiles::Tile,
    ) -> Result<(i64, Candidates)> {
        let region = Self::score_region(image, t);
        let (mut encoder, scores) = self.encode_scores(kind, image, p, t)?;
        let (cw, ch) = (t.core[2] - t.core[0], t.core[3] - t.core[1]);
        let n = u64::from(cw) * u64::from(ch);
        let groups = n.div_ceil(u64::from(WORKGROUP));
        let (gx, gy) = self.dispatch_shape_groups(groups as u32);
        let scan = ScanPlan::new(groups + 1)
            .ok_or_else(|| Error::Internal("baseline tile too large to scan".into()))?;
        let per_pass = (self.max_binding / CANDIDATE_BYTES).min(u64::from(u32::MAX)) as u32;
        let device = self.device.clone();
        let st = self.select.get_or_insert_with(|| Select::new(&device));
        let cap = self.max_binding;
        let counts = st.counts.get(&device, scan.entries * 4, cap).clone();
        let maxes = st.maxes.get(&device, (groups + 1) * 8, cap).clone();
        let out = st.out.get(&device, 1 << 16, cap).clone();
        let mut params = SelParams {
            region_x0: region[0],
            region_y0: region[1],
            region_w: region[2] - region[0],
            region_h: region[3] - region[1],
            core_x0: t.core[0],
            core_y0: t.core[1],
            core_w: cw,
            core_h: ch,
            map_w: image.width() as u32,
            map_h: image.height() as u32,
            groups_x: gx,
            n_items: n as u32,
            out_start: 0,
            out_end: ((st.out.size / CANDIDATE_BYTES) as u32).min(per_pass),
            n_groups: groups as u32,
            _pad: 0,
        };
        self.queue
            .write_buffer(&st.params, 0, bytemuck::bytes_of(&params));
        for (k, sp) in scan.params(self.max_groups).iter().enumerate() {
            self.queue.write_buffer(
                &st.params,
                (k as u64 + 1) * PARAM_ALIGN,
                bytemuck::bytes_of(sp),
            );
        }
        let bg_count = buffers::bind_group(
            &device,
            &st.count,
            &[(0, &st.params), (1, &scores), (2, &counts), (3, &maxes)],
        );
        let bg_max = buffers::bind_group(&device, &st.reduce_max, &[(0, &st.params), (3, &maxes)]);
        let bg_scatter = buffers::bind_group(
            &device,
            &st.scatter,
            &[(0, &st.params), (1, &scores), (2, &counts), (4, &out)],
        );
        let bg_scan = scan_binds(&device, &self.ogm.scan_blocks, &st.params, &counts);
        encoder.clear_buffer(&counts, groups * 4, Some(4));
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&st.count);
            pass.set_bind_group(0, &bg_count, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
            self.stats.write_passes += 1;
            self.stats.dispatches += 3 + scan.encode(
                &mut pass,
                &self.ogm.scan_blocks,
                &self.ogm.scan_add,
                &bg_scan,
                self.max_groups,
            );
            pass.set_pipeline(&st.reduce_max);
            pass.set_bind_group(0, &bg_max, &[]);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(&st.scatter);
            pass.set_bind_group(0, &bg_scatter, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        encoder.copy_buffer_to_buffer(&counts, groups * 4, &st.small, 0, 4);
        encoder.copy_buffer_to_buffer(&maxes, groups * 8, &st.small, 8, 8);
        let small_buf = st.small.clone();
        self.resolve_timestamps(&mut encoder);
        self.queue.submit([encoder.finish()]);
        let small = buffers::map_read(&device, &small_buf, 16)?;
        // The kernel time covers the score passes (the selection's passes are not timed).
        self.add_kernel_time()?;
        let total = u32::from_le_bytes(small[0..4].try_into().expect("4 bytes"));
        let max = i64::from_le_bytes(small[8..16].try_into().expect("8 bytes"));
        let mut found = Vec::with_capacity(total as usize);
        let mut start = 0u32;
        while start < total {
            if start > 0 || total > params.out_end {
                let window = (start, total);
                self.scatter_window(&mut params, window, per_pass, &scores, &counts, (gx, gy));
            }
            let st = self.select.as_mut().expect("made above");
            let len = total.min(params.out_end) - start;
            let bytes = u64::from(len) * CANDIDATE_BYTES;
            let read = st.read.get(&device, bytes, u64::MAX).clone();
            let mut encoder = device.create_command_encoder(&Default::default());
            encoder.copy_buffer_to_buffer(st.out.get(&device, bytes, cap), 0, &read, 0, bytes);
            self.queue.submit([encoder.finish()]);
            let raw = buffers::map_read(&device, &read, bytes)?;
            found.extend(raw[..bytes as usize].chunks_exact(16).map(|c| {
                let w =
                    |i: usize| u32::from_le_bytes(c[4 * i..4 * i + 4].try_into().expect("4 bytes"));
                (w(0), w(1), (i64::from(w(3) as i32) << 32) | i64::from(w(2)))
            }));
            start += len;
        }
        self.check()?;
        Ok((max, found))
    }

    /// The list outgrew the buffer: grows it to the whole list (`window.1` candidates, within `per_pass`;
    /// the next tile or call writes it in one pass) and scatters the window from `window.0` again (the
    /// scores and the scanned counts are still on the device).
    fn scatter_window(
        &mut self,
        params: &mut SelParams,
        (start, total): (u32, u32),
        per_pass: u32,
        scores: &wgpu::Buffer,
        counts: &wgpu::Buffer,
        (gx, gy): (u32, u32),
    ) {
        let device = self.device.clone();
        let st = self.select.as_mut().expect("made by select_tile");
        let want = u64::from(total.min(per_pass)) * CANDIDATE_BYTES;
        let out = st
            .out
            .get(&device, want, u64::from(per_pass) * CANDIDATE_BYTES)
            .clone();
        params.out_start = start;
        params.out_end =
            start.saturating_add(((st.out.size / CANDIDATE_BYTES) as u32).min(per_pass));
        self.queue
            .write_buffer(&st.params, 0, bytemuck::bytes_of(&*params));
        let bg = buffers::bind_group(
            &device,
            &st.scatter,
            &[(0, &st.params), (1, scores), (2, counts), (4, &out)],
        );
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&st.scatter);
            pass.set_bind_group(0, &bg, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        self.queue.submit([encoder.finish()]);
        self.stats.write_passes += 1;
        self.stats.dispatches += 1;
    }
}
