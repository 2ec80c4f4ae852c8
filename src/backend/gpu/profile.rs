//! What `bench` measures on the GPU beside end-to-end detection: the upload as the OGM path does it, and
//! the transfer floor it is compared with.

use super::ogm::PARAMS_BYTES;
use super::*;

impl GpuBackend {
    /// The time to upload `image` alone, band by band as [`Backend::detect`] does (through the staging
    /// ring, one submission per band), and wait for it; the first slab only, on maps taller than one.
    pub fn upload_time(&mut self, image: &MapImage) -> Result<Duration> {
        self.check()?;
        let (w, h) = (image.width(), image.height());
        let plan = self.ogm_plan(w, h, 0, h.min(self.ogm_slab(w)))?;
        let start = std::time::Instant::now();
        for (i, t) in plan.iter().enumerate() {
            let (ring_i, staging, bytes) = self.ring.stage_band(
                &self.device,
                Rows::of(image),
                t,
                t.ogm_pitch() as usize,
                &[],
                PARAMS_BYTES as usize,
            )?;
            let pixels = self.ogm_bufs.pixels[i % 2]
                .get(&self.device, bytes, self.max_binding)
                .clone();
            let mut encoder = self.device.create_command_encoder(&Default::default());
            encoder.copy_buffer_to_buffer(&staging, PARAMS_BYTES, &pixels, 0, bytes);
            self.ring.recycle(ring_i, &encoder);
            let index = self.queue.submit([encoder.finish()]);
            self.ring.submitted(ring_i, index);
        }
        buffers::wait_idle(&self.device)?;
        self.check()?;
        Ok(start.elapsed())
    }

    /// The transfer floor: the same bands copied from staging buffers that are already filled (no host
    /// work at all), one submission per band, waited for.
    pub fn upload_ref_time(&mut self, image: &MapImage) -> Result<Duration> {
        self.check()?;
        let (w, h) = (image.width(), image.height());
        let plan = self.ogm_plan(w, h, 0, h.min(self.ogm_slab(w)))?;
        let largest = plan
            .iter()
            .map(|t| u64::from(t.ogm_pitch()) * u64::from(t.buf_h()))
            .max()
            .unwrap_or(16);
        let staging: Vec<wgpu::Buffer> = (0..2)
            .map(|_| {
                let b = self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("upload_ref staging"),
                    size: largest.next_multiple_of(16),
                    usage: wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: true,
                });
                b.unmap();
                b
            })
            .collect();
        let start = std::time::Instant::now();
        for (i, t) in plan.iter().enumerate() {
            let bytes = u64::from(t.ogm_pitch()) * u64::from(t.buf_h());
            let pixels = self.ogm_bufs.pixels[i % 2]
                .get(&self.device, bytes, self.max_binding)
                .clone();
            let mut encoder = self.device.create_command_encoder(&Default::default());
            encoder.copy_buffer_to_buffer(&staging[i % 2], 0, &pixels, 0, bytes);
            self.queue.submit([encoder.finish()]);
        }
        buffers::wait_idle(&self.device)?;
        self.check()?;
        Ok(start.elapsed())
    }
}
