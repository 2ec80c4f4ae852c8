//! What `bench` measures on the GPU beside end-to-end detection: the upload as the OGM path does it, the
//! transfer floor it is compared with, and a map put in a device buffer for the device-map stage.

use super::ogm::PARAMS_BYTES;
use super::*;

impl GpuBackend {
    /// The time to upload `image` alone, band by band as [`Backend::detect`] does (through the staging
    /// ring, one submission per band; copied on into device memory only where the kernel cannot read the
    /// staging buffer, [`GpuBackend::reads_staging`]), and wait for it; the first slab only, on maps
    /// taller than one.
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
            let mut encoder = self.device.create_command_encoder(&Default::default());
            if !self.reads_staging() {
                let pixels = self.ogm_bufs.pixels[i % 2]
                    .get(&self.device, bytes, self.max_binding)
                    .clone();
                encoder.copy_buffer_to_buffer(&staging, PARAMS_BYTES, &pixels, 0, bytes);
            }
            self.ring.recycle(ring_i, &encoder);
            let index = self.queue.submit([encoder.finish()]);
            self.ring.submitted(ring_i, index);
        }
        buffers::wait_idle(&self.device)?;
        self.check()?;
        Ok(start.elapsed())
    }

    /// The same bands copied from staging buffers that are already filled (no host work at all), one
    /// submission per band, waited for. Not a bus transfer on a discrete GPU with a resizable BAR: its
    /// mappable staging memory is then device memory (wgpu's allocator prefers host-visible device-local
    /// memory for buffers the host writes), so this times a copy within the device.
    pub fn upload_ref_time(&mut self, image: &MapImage) -> Result<Duration> {
        let usage = wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC;
        self.copy_bands_time(image, usage, "upload_ref staging")
    }

    /// The transfer floor: the same bands copied by the device from buffers in host memory to its own
    /// (buffers the host only reads back are placed in host-cached system memory, and the copy moves
    /// them across the bus by DMA), one submission per band, waited for; no host work. An error where
    /// the device cannot copy from such buffers ([`GpuBackend::copies_from_host`]).
    pub fn transfer_floor_time(&mut self, image: &MapImage) -> Result<Duration> {
        if !self.copies_from_host() {
            return Err(Error::Unavailable(format!(
                "{} cannot copy from buffers in host memory",
                self.adapter.name
            )));
        }
        let usage = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_SRC;
        self.copy_bands_time(image, usage, "transfer floor host buffer")
    }

    /// `image` in a new buffer on the device, rows `width` bytes apart from byte 0 (as a mapping
    /// pipeline would keep its grid), written in pieces of at most 64 MiB and waited for; an error where
    /// the device has no buffer that large.
    pub fn device_map_buffer(&mut self, image: &MapImage) -> Result<wgpu::Buffer> {
        self.check()?;
        let px = image.pixels();
        let size = (px.len() as u64).max(4).next_multiple_of(4);
        if size > self.device.limits().max_buffer_size {
            return Err(Error::Unavailable(format!(
                "{} has no buffer of {size} bytes",
                self.adapter.name
            )));
        }
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("device map"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        const PIECE: usize = 64 << 20;
        for (i, piece) in px.chunks(PIECE).enumerate() {
            let at = (i * PIECE) as u64;
            if piece.len().is_multiple_of(4) {
                self.queue.write_buffer(&buffer, at, piece);
            } else {
                // The last piece, padded to whole words.
                let mut padded = piece.to_vec();
                padded.resize(piece.len().next_multiple_of(4), 0);
                self.queue.write_buffer(&buffer, at, &padded);
            }
            self.queue.submit([]);
        }
        buffers::wait_idle(&self.device)?;
        self.check()?;
        Ok(buffer)
    }

    /// Whether the device copies from buffers in host memory (`MAPPABLE_PRIMARY_BUFFERS`), which
    /// [`GpuBackend::transfer_floor_time`] needs.
    pub fn copies_from_host(&self) -> bool {
        self.host_copies
    }

    /// The time to copy the first slab's bands from two source buffers of `usage` into the device's
    /// pixel buffers, as the OGM path lays them out.
    fn copy_bands_time(
        &mut self,
        image: &MapImage,
        usage: wgpu::BufferUsages,
        label: &str,
    ) -> Result<Duration> {
        self.check()?;
        let (w, h) = (image.width(), image.height());
        let plan = self.ogm_plan(w, h, 0, h.min(self.ogm_slab(w)))?;
        let largest = plan
            .iter()
            .map(|t| u64::from(t.ogm_pitch()) * u64::from(t.buf_h()))
            .max()
            .unwrap_or(16);
        let sources: Vec<wgpu::Buffer> = (0..2)
            .map(|_| {
                let b = self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: largest.next_multiple_of(16),
                    usage,
                    mapped_at_creation: true,
                });
                b.unmap();
                b
            })
            .collect();
        // Filled before the clock starts: a buffer the host cannot write is filled by a copy wgpu queues
        // at unmap, which would otherwise run in the first timed submission.
        self.queue.submit([]);
        buffers::wait_idle(&self.device)?;
        let start = std::time::Instant::now();
        for (i, t) in plan.iter().enumerate() {
            let bytes = u64::from(t.ogm_pitch()) * u64::from(t.buf_h());
            let pixels = self.ogm_bufs.pixels[i % 2]
                .get(&self.device, bytes, self.max_binding)
                .clone();
            let mut encoder = self.device.create_command_encoder(&Default::default());
            encoder.copy_buffer_to_buffer(&sources[i % 2], 0, &pixels, 0, bytes);
            self.queue.submit([encoder.finish()]);
        }
        buffers::wait_idle(&self.device)?;
        self.check()?;
        Ok(start.elapsed())
    }
}
