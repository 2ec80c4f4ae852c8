//! The baselines' GPU passes over one tile: blur, structure tensor and score (Harris, Shi-Tomasi), or
//! Trajkovic's two resolutions, each score exact in integers.

use super::params::kernel_params;
use super::*;

kernel_params! {
    /// The baseline kernels' parameters, laid out as `struct BParams` in `shaders/lib/baseline_common.wgsl`.
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
    pub(super) struct BParams {
        map_w: u32,
        map_h: u32,
        origin_x: u32,
        origin_y: u32,
        buf_w: u32,
        buf_h: u32,
        stride: u32,
        core_x0: u32,
        core_y0: u32,
        core_w: u32,
        core_h: u32,
        k_side: u32,
        k_centre: u32,
        kn: u32,
        kd: u32,
        t1: u32,
        t2: u32,
        groups_x: u32,
        n_items: u32,
        _pad: u32,
    }
}

/// One baseline pass: pipeline, uniform, input, output, and the dispatch's workgroups.
pub(super) struct BaselinePass(
    wgpu::ComputePipeline,
    wgpu::Buffer,
    wgpu::Buffer,
    wgpu::Buffer,
    (u32, u32),
);

/// Halo of the baseline tiles: scores are computed over the core grown by one pixel (the selection's 3x3
/// window needs them), and from there blur, Sobel and the 3x3 window reach 3 pixels, Trajkovic's
/// low-resolution neighbours 4. Even, so tile origins stay on the low-resolution grid.
pub(super) const BASELINE_HALO: u32 = 6;
/// Bytes per buffer pixel of the largest baseline buffer (the structure tensor, 4 x i32).
pub(super) const BASELINE_BYTES_PER_PX: u64 = 16;

impl GpuBackend {
    /// Whether the baseline kernels use native 64-bit integers (else the exact emulation).
    pub fn native_int64(&self) -> bool {
        self.native_int64
    }

    pub(super) fn kernel_pipeline(&mut self, name: &'static str) -> Result<wgpu::ComputePipeline> {
        if let Some(p) = self.kernel_pipelines.get(name) {
            return Ok(p.clone());
        }
        let src = shader_source(name, self.native_int64)
            .ok_or_else(|| Error::Internal(format!("no kernel {name}")))?;
        let module = self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            });
        let p = self
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(name),
                layout: None,
                module: &module,
                entry_point: Some(name),
                compilation_options: Default::default(),
                cache: None,
            });
        self.check()?;
        self.kernel_pipelines.insert(name, p.clone());
        Ok(p)
    }

    /// Uploads the tile's rectangle, rows padded to whole words, through the staging ring; the copy is
    /// submitted at once and runs before the passes submitted after it.
    fn upload_band(&mut self, image: Rows, t: &tiles::Tile) -> Result<wgpu::Buffer> {
        let (i, staging, _) =
            self.ring
                .stage_band(&self.device, image, t, t.stride() as usize * 4, &[], 0)?;
        let buf = self
            .base_pixels
            .get(&self.device, t.bytes(), self.max_binding)
            .clone();
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&staging, 0, &buf, 0, t.bytes());
        self.ring.recycle(i, &encoder);
        let index = self.queue.submit([encoder.finish()]);
        self.ring.submitted(i, index);
        Ok(buf)
    }

    /// The score region of tile `t`: its core grown by one pixel within the map, map coordinates.
    pub(super) fn score_region(image: Rows, t: &tiles::Tile) -> [u32; 4] {
        [
            t.core[0].saturating_sub(1),
            t.core[1].saturating_sub(1),
            (t.core[2] + 1).min(image.width() as u32),
            (t.core[3] + 1).min(image.height() as u32),
        ]
    }

    /// Uploads tile `t` and records its score passes; the scores of [`Self::score_region`] end up in the
    /// returned buffer, row-major, 8 bytes each.
    pub(super) fn encode_scores(
        &mut self,
        kind: Baseline,
        image: Rows,
        p: &ExactParams,
        t: &tiles::Tile,
    ) -> Result<(wgpu::CommandEncoder, wgpu::Buffer)> {
        let region = Self::score_region(image, t);
        let (bw, bh) = (t.buf_w(), t.buf_h());
        let (cw, ch) = (region[2] - region[0], region[3] - region[1]);
        let buf_px = u64::from(bw) * u64::from(bh);
        let core_px = u64::from(cw) * u64::from(ch);
        let (bgx, bgy) = self.dispatch_shape_groups(buf_px.div_ceil(u64::from(WORKGROUP)) as u32);
        let (cgx, cgy) = self.dispatch_shape_groups(core_px.div_ceil(u64::from(WORKGROUP)) as u32);
        if bgy > self.max_groups || cgy > self.max_groups {
            return Err(Error::Internal(
                "baseline tile needs too many workgroups".into(),
            ));
        }
        let base = BParams {
            map_w: image.width() as u32,
            map_h: image.height() as u32,
            origin_x: t.buf[0],
            origin_y: t.buf[1],
            buf_w: bw,
            buf_h: bh,
            stride: t.stride(),
            core_x0: region[0],
            core_y0: region[1],
            core_w: cw,
            core_h: ch,
            k_side: p.blur[0],
            k_centre: p.blur[1],
            kn: p.kn,
            kd: p.kd,
            t1: p.t1,
            t2: p.t2,
            ..BParams::default()
        };
        let on_buf = BParams {
            groups_x: bgx,
            n_items: buf_px as u32,
            ..base
        };
        let on_core = BParams {
            groups_x: cgx,
            n_items: core_px as u32,
            ..base
        };
        self.queue
            .write_buffer(&self.bp_buf, 0, bytemuck::bytes_of(&on_buf));
        self.queue
            .write_buffer(&self.bp_core, 0, bytemuck::bytes_of(&on_core));
        let raw = self.upload_band(image, t)?;
        let scores = self
            .scores
            .get(&self.device, core_px * 8, self.max_binding)
            .clone();

        let mut passes: Vec<BaselinePass> = Vec::new();
        match kind {
            Baseline::Harris | Baseline::ShiTomasi => {
                let blurred = self
                    .blurred
                    .get(&self.device, buf_px * 4, self.max_binding)
                    .clone();
                let tensor = self
                    .tensor
                    .get(&self.device, buf_px * 16, self.max_binding)
                    .clone();
                let score_kernel = if kind == Baseline::Harris {
                    "harris"
                } else {
                    "shi_tomasi"
                };
                passes.push(BaselinePass(
                    self.kernel_pipeline("gaussian_blur")?,
                    self.bp_buf.clone(),
                    raw,
                    blurred.clone(),
                    (bgx, bgy),
                ));
                passes.push(BaselinePass(
                    self.kernel_pipeline("structure_tensor")?,
                    self.bp_buf.clone(),
                    blurred,
                    tensor.clone(),
                    (bgx, bgy),
                ));
                passes.push(BaselinePass(
                    self.kernel_pipeline(score_kernel)?,
                    self.bp_core.clone(),
                    tensor,
                    scores.clone(),
                    (cgx, cgy),
                ));
            }
            Baseline::Trajkovic => passes.push(BaselinePass(
                self.kernel_pipeline("trajkovic")?,
                self.bp_core.clone(),
                raw,
                scores.clone(),
                (cgx, cgy),
            )),
        }
        let groups: Vec<wgpu::BindGroup> = passes
            .iter()
            .map(|BaselinePass(pl, u, i, o, _)| self.bind(pl, &[(0, u), (1, i), (2, o)]))
            .collect();
        let dispatches: Vec<_> = passes
            .iter()
            .zip(&groups)
            .map(|(BaselinePass(pl, _, _, _, shape), bg)| (pl, bg, *shape))
            .collect();
        Ok((self.encode(&dispatches), scores))
    }

    /// Runs one baseline tile and writes its core's scores into `out` (the whole map's score map).
    pub(super) fn run_baseline_tile(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        p: &ExactParams,
        t: &tiles::Tile,
        out: &mut [i64],
    ) -> Result<()> {
        let region = Self::score_region(Rows::of(image), t);
        let rw = (region[2] - region[0]) as usize;
        let rh = (region[3] - region[1]) as usize;
        let (encoder, scores) = self.encode_scores(kind, Rows::of(image), p, t)?;
        let raw_scores = self.submit_and_read(encoder, &scores, (rw * rh) as u64 * 8, true)?;
        let w = image.width() as usize;
        let (cx0, cw) = (t.core[0] as usize, (t.core[2] - t.core[0]) as usize);
        for y in t.core[1] as usize..t.core[3] as usize {
            let src = ((y - region[1] as usize) * rw + (cx0 - region[0] as usize)) * 8;
            let row = &raw_scores[src..src + cw * 8];
            for (dst, b) in out[y * w + cx0..y * w + cx0 + cw]
                .iter_mut()
                .zip(row.chunks_exact(8))
            {
                *dst = i64::from_le_bytes(b.try_into().expect("8 bytes"));
            }
        }
        Ok(())
    }
}
