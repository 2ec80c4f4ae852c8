//! The transform-scoring kernel's GPU passes (`shaders/merge_score.wgsl`): the target uploaded in bands of
//! rows within the tile budget, the points in chunks within it, the transforms in batches of at most one
//! workgroup row each; every band's and chunk's dispatch adds into the batch's counters.

use super::params::kernel_params;
use super::*;
use crate::backend::reference::merge_score::{
    check_score_input, FixedRigid, ScoreTarget, SCORE_FRAC_BITS,
};

/// Invocations per workgroup of the scoring kernel.
const SCORE_GROUP: u32 = 256;

/// Points each invocation handles at least (when there are enough): fewer workgroups, so fewer flushes
/// of the workgroup counters into the global ones.
const POINTS_PER_INVOCATION: u64 = 8;

/// Bytes of one counts entry on the GPU: inside, near and deep as u32.
const COUNT_BYTES: u64 = 12;

kernel_params! {
    /// The kernel's parameters, laid out as `struct Params` in `shaders/merge_score.wgsl`.
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
    pub(super) struct SParams {
        width: u32,
        height: u32,
        stride: u32,
        band_y0: u32,
        band_h: u32,
        n_points: u32,
        groups_x: u32,
        frac_bits: u32,
    }
}

const _: () = assert!(
    std::mem::size_of::<SParams>() == 32,
    "matches shaders/merge_score.wgsl"
);

impl GpuBackend {
    /// Per transform, the counts of `points` landing on each flag of `target`, exactly as the CPU twin
    /// ([`crate::backend::reference::merge_score::score_transforms`]) computes them.
    pub(super) fn score_transforms_gpu(
        &mut self,
        target: &ScoreTarget,
        points: &[[u32; 2]],
        transforms: &[FixedRigid],
    ) -> Result<Vec<[u32; 3]>> {
        // The same checks as the twin, so both refuse the same input with the same message.
        check_score_input(target, points, transforms)?;
        self.check()?;
        self.stats = GpuStats::default();
        if points.is_empty() || transforms.is_empty() {
            return Ok(vec![[0; 3]; transforms.len()]);
        }
        let pipeline = self.kernel_pipeline("merge_score")?;
        let budget = self.max_binding.min(self.options.max_tile_bytes.max(1));
        let stride = target.width.div_ceil(4);
        let row_bytes = u64::from(stride) * 4;
        // A row is at most 8 KiB (sides below 2^15), within any device's binding limit; a smaller budget
        // still gets one row a band.
        let band_rows = (budget / row_bytes).clamp(1, u64::from(target.height)) as u32;
        let chunk_len = (budget / 4).clamp(1, u64::from(u32::MAX)) as usize;
        let batch_len = u64::from(self.max_groups)
            .min(self.max_binding / COUNT_BYTES)
            .min(self.max_binding / std::mem::size_of::<FixedRigid>() as u64)
            .max(1) as usize;
        // Points packed a word each (x low, y high: both below 2^15), uploaded once for every band.
        let chunks: Vec<(wgpu::Buffer, u32)> = points
            .chunks(chunk_len)
            .map(|c| {
                let words: Vec<u32> = c.iter().map(|p| p[0] | p[1] << 16).collect();
                let buf = upload(
                    &self.device,
                    "merge_score points",
                    bytemuck::cast_slice(&words),
                    wgpu::BufferUsages::STORAGE,
                );
                (buf, c.len() as u32)
            })
            .collect();
        let mut out = Vec::with_capacity(transforms.len());
        for batch in transforms.chunks(batch_len) {
            let tbuf = upload(
                &self.device,
                "merge_score transforms",
                bytemuck::cast_slice(batch),
                wgpu::BufferUsages::STORAGE,
            );
            let count_bytes = batch.len() as u64 * COUNT_BYTES;
            // wgpu zero-initialises new buffers: the counters start at 0.
            let counts = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("merge_score counts"),
                size: count_bytes.next_multiple_of(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let mut band_y0 = 0;
            while band_y0 < target.height {
                let band_h = band_rows.min(target.height - band_y0);
                let flags = self.score_band(target, band_y0, band_h, stride);
                let mut params = Vec::with_capacity(chunks.len());
                let mut groups = Vec::with_capacity(chunks.len());
                for (buf, n) in &chunks {
                    let gx = u64::from(*n)
                        .div_ceil(u64::from(SCORE_GROUP) * POINTS_PER_INVOCATION)
                        .clamp(1, u64::from(self.max_groups)) as u32;
                    let p = SParams {
                        width: target.width,
                        height: target.height,
                        stride,
                        band_y0,
                        band_h,
                        n_points: *n,
                        groups_x: gx,
                        frac_bits: SCORE_FRAC_BITS,
                    };
                    let uniform = upload(
                        &self.device,
                        "merge_score params",
                        bytemuck::bytes_of(&p),
                        wgpu::BufferUsages::UNIFORM,
                    );
                    groups.push(self.bind(
                        &pipeline,
                        &[
                            (0, &uniform),
                            (1, &flags),
                            (2, buf),
                            (3, &tbuf),
                            (4, &counts),
                        ],
                    ));
                    params.push(gx);
                    self.stats.tiles += 1;
                }
                let dispatches: Vec<_> = groups
                    .iter()
                    .zip(&params)
                    .map(|(g, &gx)| (&pipeline, g, (gx, batch.len() as u32)))
                    .collect();
                let encoder = self.encode(&dispatches);
                band_y0 += band_h;
                if band_y0 < target.height {
                    // One band on the device at a time, besides the points.
                    self.queue.submit([encoder.finish()]);
                    continue;
                }
                let bytes = self.submit_and_read(encoder, &counts, count_bytes, false)?;
                out.extend(bytes.chunks_exact(COUNT_BYTES as usize).map(|c| {
                    let word = |k: usize| {
                        u32::from_le_bytes(c[4 * k..4 * k + 4].try_into().expect("4 bytes"))
                    };
                    [word(0), word(1), word(2)]
                }));
            }
        }
        self.check()?;
        Ok(out)
    }

    /// Uploads rows `[y0, y0 + h)` of the target's flags, each row padded to `stride` words.
    fn score_band(&mut self, target: &ScoreTarget, y0: u32, h: u32, stride: u32) -> wgpu::Buffer {
        let (w, stride_bytes) = (target.width as usize, stride as usize * 4);
        let rows = &target.flags[y0 as usize * w..(y0 + h) as usize * w];
        let contents = if w == stride_bytes {
            rows
        } else {
            self.staging.clear();
            self.staging.resize(stride_bytes * h as usize, 0);
            for (dst, src) in self
                .staging
                .chunks_exact_mut(stride_bytes)
                .zip(rows.chunks_exact(w))
            {
                dst[..w].copy_from_slice(src);
            }
            &self.staging
        };
        upload(
            &self.device,
            "merge_score flags",
            contents,
            wgpu::BufferUsages::STORAGE,
        )
    }
}

/// A buffer holding `contents`.
fn upload(
    device: &wgpu::Device,
    label: &'static str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage,
    })
}
