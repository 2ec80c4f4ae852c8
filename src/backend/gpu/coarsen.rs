//! The coarsening kernel's GPU passes (`shaders/coarsen.wgsl`): per scale, tiles of coarse cells, each
//! with the rectangle of map pixels its samples reach uploaded beside it.

use super::params::kernel_params;
use super::*;
use crate::backend::reference::coarsen::{CellRule, Mosaic, UNKNOWN};
use crate::map::grid::{RotatedGrid, FRAC_BITS};

/// Invocations per workgroup of the coarsening kernel.
const COARSEN_GROUP: u32 = 64;

kernel_params! {
    /// The kernel's parameters, laid out as `struct Params` in `shaders/coarsen.wgsl`.
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
    pub(super) struct CParams {
        cos: i32,
        sin: i32,
        ox: i32,
        oy: i32,
        map_w: u32,
        map_h: u32,
        band_x0: u32,
        band_y0: u32,
        band_w: u32,
        band_h: u32,
        band_stride: u32,
        scale: u32,
        cell_u0: u32,
        cell_v0: u32,
        tile_w: u32,
        tile_h: u32,
        out_stride: u32,
        occ_min: u32,
        free_min: u32,
        groups_x: u32,
        frac_bits: u32,
        cx: i32,
        cy: i32,
        mosaic_w: u32,
        mosaic_h: u32,
        _pad: [u32; 3],
    }
}

const _: () = assert!(
    std::mem::size_of::<CParams>() == 112,
    "matches shaders/coarsen.wgsl"
);

/// A tile of coarse cells, `[u0, u1) x [v0, v1)`.
#[derive(Clone, Copy, Debug)]
struct CellTile {
    u0: u32,
    v0: u32,
    u1: u32,
    v1: u32,
}

impl GpuBackend {
    /// The coarse maps of `image` on `grid` (every phase, [`Mosaic`]), one per scale, exactly as the CPU
    /// twin computes them.
    pub(super) fn coarsen_maps(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        grid: &RotatedGrid,
        scales: &[u32],
        rule: CellRule,
    ) -> Result<Vec<MapImage>> {
        self.check()?;
        self.stats = GpuStats::default();
        let pipeline = self.kernel_pipeline("coarsen")?;
        let class_words: Vec<u32> = classes.states().iter().map(|&s| s as u32).collect();
        let class_buf = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("coarsen class table"),
                contents: bytemuck::cast_slice(&class_words),
                usage: wgpu::BufferUsages::STORAGE,
            });
        let budget = self.max_binding.min(self.options.max_tile_bytes.max(1));
        let mut out = Vec::with_capacity(scales.len());
        for &scale in scales {
            let mosaic = Mosaic::new(grid, scale);
            let (cw, ch) = mosaic.size();
            let mut cells = vec![UNKNOWN; cw as usize * ch as usize];
            let mut todo = vec![CellTile {
                u0: 0,
                v0: 0,
                u1: cw,
                v1: ch,
            }];
            while let Some(t) = todo.pop() {
                let (p0, p1) = mosaic.sample_span(t.u0, t.u1, mosaic.tile_w);
                let (q0, q1) = mosaic.sample_span(t.v0, t.v1, mosaic.tile_h);
                let (Some(rows), Some(cols)) = (
                    grid.source_rows(p0, p1, q0, q1),
                    grid.source_cols(p0, p1, q0, q1),
                ) else {
                    continue; // no sample on the map: every cell stays unknown
                };
                let band_w = cols.1 - cols.0;
                let stride = u64::from(band_w.div_ceil(4));
                let band_bytes = stride * 4 * u64::from(rows.1 - rows.0);
                let (tw, th) = (t.u1 - t.u0, t.v1 - t.v0);
                let out_stride = tw.div_ceil(4);
                let out_bytes = u64::from(out_stride) * u64::from(th) * 4;
                let groups = (u64::from(out_stride) * u64::from(th)).div_ceil(COARSEN_GROUP.into());
                let (_, gy) = self.dispatch_shape_groups(groups.min(u64::from(u32::MAX)) as u32);
                if band_bytes > budget || out_bytes > self.max_binding || gy > self.max_groups {
                    if tw == 1 && th == 1 {
                        return Err(Error::Unavailable(format!(
                            "{}'s buffer limit ({budget} bytes) is too small for one coarse cell",
                            self.adapter.name
                        )));
                    }
                    // Split the longer side in two.
                    if tw >= th {
                        let m = t.u0 + tw / 2;
                        todo.push(CellTile { u1: m, ..t });
                        todo.push(CellTile { u0: m, ..t });
                    } else {
                        let m = t.v0 + th / 2;
                        todo.push(CellTile { v1: m, ..t });
                        todo.push(CellTile { v0: m, ..t });
                    }
                    continue;
                }
                self.stats.tiles += 1;
                let (occ_min, free_min) = rule.thresholds(scale);
                let (gx, gy) = self.dispatch_shape_groups(groups as u32);
                let params = CParams {
                    cos: grid.cos,
                    sin: grid.sin,
                    ox: grid.ox,
                    oy: grid.oy,
                    map_w: grid.map_width,
                    map_h: grid.map_height,
                    band_x0: cols.0,
                    band_y0: rows.0,
                    band_w,
                    band_h: rows.1 - rows.0,
                    band_stride: stride as u32,
                    scale,
                    cell_u0: t.u0,
                    cell_v0: t.v0,
                    tile_w: tw,
                    tile_h: th,
                    out_stride,
                    occ_min,
                    free_min,
                    groups_x: gx,
                    frac_bits: FRAC_BITS,
                    cx: grid.cx,
                    cy: grid.cy,
                    mosaic_w: mosaic.tile_w,
                    mosaic_h: mosaic.tile_h,
                    _pad: [0; 3],
                };
                let words = self.coarsen_tile(image, &pipeline, &class_buf, &params, (gx, gy))?;
                for (r, row) in words.chunks_exact(out_stride as usize * 4).enumerate() {
                    let start = (t.v0 as usize + r) * cw as usize + t.u0 as usize;
                    cells[start..start + tw as usize].copy_from_slice(&row[..tw as usize]);
                }
            }
            out.push(MapImage::new(cw, ch, cells)?);
        }
        self.check()?;
        Ok(out)
    }

    /// Uploads the band `params` names, runs one tile and returns its output bytes, row by row.
    fn coarsen_tile(
        &mut self,
        image: &MapImage,
        pipeline: &wgpu::ComputePipeline,
        class_buf: &wgpu::Buffer,
        params: &CParams,
        shape: (u32, u32),
    ) -> Result<Vec<u8>> {
        let stride_bytes = params.band_stride as usize * 4;
        self.staging.clear();
        self.staging
            .resize((stride_bytes * params.band_h as usize).max(4), 0);
        let iw = image.width() as usize;
        for r in 0..params.band_h as usize {
            let src = (params.band_y0 as usize + r) * iw + params.band_x0 as usize;
            self.staging[r * stride_bytes..r * stride_bytes + params.band_w as usize]
                .copy_from_slice(&image.pixels()[src..src + params.band_w as usize]);
        }
        let init = |label, contents: &[u8], usage| {
            self.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                })
        };
        let pixels = init("coarsen pixels", &self.staging, wgpu::BufferUsages::STORAGE);
        let uniform = init(
            "coarsen params",
            bytemuck::bytes_of(params),
            wgpu::BufferUsages::UNIFORM,
        );
        let out_bytes = u64::from(params.out_stride) * u64::from(params.tile_h) * 4;
        let cells = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("coarse cells"),
            size: out_bytes.max(16),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let group = self.bind(
            pipeline,
            &[(0, &uniform), (1, class_buf), (2, &pixels), (3, &cells)],
        );
        let encoder = self.encode(&[(pipeline, &group, shape)]);
        self.submit_and_read(encoder, &cells, out_bytes, false)
    }
}
