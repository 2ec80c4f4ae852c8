//! The device-side exclusive scan (`shaders/scan.wgsl`): per-workgroup counts become list positions in the
//! same submission as the kernels that produced them, so no count crosses to the host.

use super::params::kernel_params;
use super::*;

/// Entries one `scan_blocks` workgroup scans.
const BLOCK: u64 = 1024;
/// Levels of the scan at most: 1024^4 entries are more than any tile has.
pub(super) const MAX_LEVELS: usize = 4;
/// Bytes between the levels' parameter blocks (the uniform offset alignment WebGPU guarantees).
pub(super) const PARAM_ALIGN: u64 = 256;

kernel_params! {
    /// One level's parameters, laid out as `struct Params` in scan.wgsl.
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
    pub(super) struct ScanParams {
        n: u32,
        off: u32,
        next: u32,
        groups_x: u32,
    }
}

/// The levels of a scan of `n` entries at offset 0 of the counts buffer: each level's blocks' totals are
/// the next level, each level starting on a 64-entry boundary.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct ScanPlan {
    pub levels: Vec<(u32, u32, u32)>,
    /// Entries of the counts buffer the scan uses, levels included.
    pub entries: u64,
}

impl ScanPlan {
    /// The plan for `n` entries (at least one), or `None` when it needs more than [`MAX_LEVELS`].
    pub fn new(n: u64) -> Option<Self> {
        let mut levels = Vec::new();
        let (mut len, mut off) = (n.max(1), 0u64);
        loop {
            let next = (off + len).next_multiple_of(64);
            levels.push((len as u32, off as u32, next as u32));
            let blocks = len.div_ceil(BLOCK);
            if len <= BLOCK {
                return (levels.len() <= MAX_LEVELS && next + 64 < u64::from(u32::MAX)).then_some(
                    ScanPlan {
                        levels,
                        entries: next + 64,
                    },
                );
            }
            off = next;
            len = blocks;
        }
    }

    /// The parameter blocks, one per level, [`PARAM_ALIGN`] bytes apart, with the dispatch shape for
    /// `max_groups` workgroups per dimension.
    pub fn params(&self, max_groups: u32) -> Vec<ScanParams> {
        self.levels
            .iter()
            .map(|&(n, off, next)| {
                let groups = u64::from(n).div_ceil(BLOCK) as u32;
                ScanParams {
                    n,
                    off,
                    next,
                    groups_x: groups.clamp(1, max_groups),
                }
            })
            .collect()
    }

    /// Records the scan's dispatches into `pass`: every level's blocks from the first, then the adds back
    /// down. `binds[k]` binds level k's parameters.
    pub fn encode(
        &self,
        pass: &mut wgpu::ComputePass,
        blocks: &wgpu::ComputePipeline,
        add: &wgpu::ComputePipeline,
        binds: &[wgpu::BindGroup],
        max_groups: u32,
    ) -> usize {
        let shape = |n: u32| {
            let groups = (u64::from(n).div_ceil(BLOCK) as u32).max(1);
            let gx = groups.min(max_groups);
            (gx, groups.div_ceil(gx))
        };
        pass.set_pipeline(blocks);
        for (k, &(n, _, _)) in self.levels.iter().enumerate() {
            let (gx, gy) = shape(n);
            pass.set_bind_group(0, &binds[k], &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        pass.set_pipeline(add);
        for k in (0..self.levels.len().saturating_sub(1)).rev() {
            let (gx, gy) = shape(self.levels[k].0);
            pass.set_bind_group(0, &binds[k], &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        2 * self.levels.len() - 1
    }
}

/// The scan's bind groups: level k's parameters at `base + (k + 1) * PARAM_ALIGN` of `params`, and the
/// counts buffer.
pub(super) fn scan_binds(
    device: &wgpu::Device,
    pipeline: &wgpu::ComputePipeline,
    params: &wgpu::Buffer,
    counts: &wgpu::Buffer,
) -> Vec<wgpu::BindGroup> {
    (0..MAX_LEVELS)
        .map(|k| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("scan"),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: params,
                            offset: (k as u64 + 1) * PARAM_ALIGN,
                            size: wgpu::BufferSize::new(std::mem::size_of::<ScanParams>() as u64),
                        }),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: counts.as_entire_binding(),
                    },
                ],
            })
        })
        .collect()
}

impl GpuBackend {
    /// The device scan of `counts` (exclusive prefix sums, then the total), as the OGM pipeline runs it;
    /// for the conformance tests against [`crate::backend::reference::scan::exclusive_scan`].
    pub fn scan(&mut self, counts: &[u32]) -> Result<(Vec<u32>, u32)> {
        self.check()?;
        let n = counts.len() as u64;
        let plan = ScanPlan::new(n + 1)
            .ok_or_else(|| Error::invalid(format!("{n} entries are too many to scan")))?;
        if plan.entries * 4 > self.max_binding {
            return Err(Error::invalid(format!(
                "{n} entries exceed the device's binding limit"
            )));
        }
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC;
        let data = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("scan test data"),
            size: plan.entries * 4,
            usage,
            mapped_at_creation: false,
        });
        let mut init = counts.to_vec();
        init.push(0);
        self.queue
            .write_buffer(&data, 0, bytemuck::cast_slice(&init));
        let params = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("scan test params"),
            size: PARAM_ALIGN * (MAX_LEVELS as u64 + 1),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        for (k, p) in plan.params(self.max_groups).iter().enumerate() {
            self.queue
                .write_buffer(&params, (k as u64 + 1) * PARAM_ALIGN, bytemuck::bytes_of(p));
        }
        let binds = scan_binds(&self.device, &self.ogm.scan_blocks, &params, &data);
        let read = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("scan test readback"),
            size: (n + 1) * 4,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            let _ = plan.encode(
                &mut pass,
                &self.ogm.scan_blocks,
                &self.ogm.scan_add,
                &binds,
                self.max_groups,
            );
        }
        encoder.copy_buffer_to_buffer(&data, 0, &read, 0, (n + 1) * 4);
        self.queue.submit([encoder.finish()]);
        let raw = buffers::map_read(&self.device, &read, (n + 1) * 4)?;
        self.check()?;
        let words: Vec<u32> = bytemuck::cast_slice(&raw[..(n as usize + 1) * 4]).to_vec();
        Ok((words[..n as usize].to_vec(), words[n as usize]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_shrink_by_the_block_size() {
        let p = ScanPlan::new(1).unwrap();
        assert_eq!(p.levels, vec![(1, 0, 64)]);
        let p = ScanPlan::new(1025).unwrap();
        assert_eq!(p.levels, vec![(1025, 0, 1088), (2, 1088, 1152)]);
        let p = ScanPlan::new(3 << 20).unwrap();
        assert_eq!(p.levels.len(), 3);
        assert!(ScanPlan::new(1 << 41).is_none());
    }
}
