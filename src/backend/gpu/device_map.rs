//! Maps already on the GPU: the OGM detector run on a map that a caller keeps in a `wgpu::Buffer` of the
//! backend's device (a GPU mapping pipeline's grid), read where it lies: no upload, no staging, no copy.
//! Rows whose runs start 16-byte aligned are read as staged bands are (`shaders/lib/ogm_fetch_runs.wgsl`);
//! any other offset or pitch through `shaders/lib/ogm_fetch_bytes.wgsl`. Same keypoints, same order.

use super::*;

/// A map held in a buffer on the backend's device: one byte a cell, row-major, row `y` starting at byte
/// `offset + y * bytes_per_row`, values read through the same [`ClassTable`] as a map in memory.
#[derive(Clone, Copy, Debug)]
pub struct DeviceMap<'a> {
    /// The buffer; made with [`wgpu::BufferUsages::STORAGE`] on [`GpuBackend::device`] (or the device
    /// the backend was made from, [`GpuBackend::from_device`]). It must be that device's: wgpu names
    /// buffers by index within their instance, so a buffer of another instance's device is not refused
    /// but read as whichever buffer of this device has its index.
    pub buffer: &'a wgpu::Buffer,
    /// Byte of the map's first cell in the buffer; any value.
    pub offset: u64,
    /// Cells a row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Bytes from a row's first cell to the next row's; at least `width`, any value.
    pub bytes_per_row: u64,
}

/// Where a call's pixels come from: the host's rows, staged band by band and copied to the device, or a
/// map already in a device buffer, which the kernels read where it is.
#[derive(Clone, Copy)]
pub(super) enum Source<'a> {
    Host(Rows<'a>),
    Device(&'a DeviceMap<'a>),
}

impl Source<'_> {
    pub(super) fn size(&self) -> (u32, u32) {
        match self {
            Source::Host(rows) => (rows.width() as u32, rows.height() as u32),
            Source::Device(map) => (map.width, map.height),
        }
    }
}

/// Where one band of a device map is bound: the binding's range in the buffer, the byte of the band's
/// first pixel within it, and whether its runs start 16-byte aligned.
pub(super) struct Window {
    pub offset: u64,
    pub size: u64,
    pub first_byte: u32,
    pub runs: bool,
}

impl DeviceMap<'_> {
    /// The byte just past the map's last cell, or an error naming what does not fit.
    fn end(&self) -> Result<u64> {
        let bad = |m: String| Err(Error::invalid(format!("device map: {m}")));
        if self.bytes_per_row < u64::from(self.width) {
            return bad(format!(
                "bytes_per_row {} is less than the width {}",
                self.bytes_per_row, self.width
            ));
        }
        if self.width > u32::MAX - 64 {
            return bad(format!("a width of {} cells is over 2^32 - 65", self.width));
        }
        if self.bytes_per_row > u64::from(u32::MAX) {
            return bad(format!(
                "bytes_per_row {} is over 2^32 - 1",
                self.bytes_per_row
            ));
        }
        let end = u64::from(self.height.saturating_sub(1))
            .checked_mul(self.bytes_per_row)
            .and_then(|v| v.checked_add(self.offset))
            .and_then(|v| v.checked_add(u64::from(self.width)));
        let size = self.buffer.size();
        match end {
            Some(end) if end <= size => Ok(end),
            _ => bad(format!(
                "{} x {} cells from byte {} with {} bytes a row run past the buffer's {} bytes",
                self.width, self.height, self.offset, self.bytes_per_row, size
            )),
        }
    }

    /// Checks the map against its buffer before anything is recorded: a clear error rather than a
    /// device error.
    fn validate(&self) -> Result<()> {
        let end = self.end()?;
        if !self.buffer.usage().contains(wgpu::BufferUsages::STORAGE) {
            return Err(Error::invalid(
                "device map: its buffer was made without BufferUsages::STORAGE, so no kernel can read it",
            ));
        }
        // Storage bindings are whole 4-byte words.
        if end.next_multiple_of(4) > self.buffer.size() {
            return Err(Error::invalid(format!(
                "device map: its last cell is in the buffer's last, partial 4-byte word (buffer of {} \
                 bytes); make the buffer a multiple of 4 bytes",
                self.buffer.size()
            )));
        }
        Ok(())
    }

    /// The binding of tile `t` (a full-width band with its halo rows): from its first pixel, rounded
    /// down to the device's offset alignment `align`, to its last, rounded up to whole words (16-byte
    /// ones where the runs are aligned and the buffer has them).
    pub(super) fn window(&self, t: &tiles::Tile, align: u64) -> Window {
        let row = |y: u32| self.offset + u64::from(y) * self.bytes_per_row + u64::from(t.buf[0]);
        let start = row(t.buf[1]);
        let end = row(t.buf[3] - 1) + u64::from(t.buf_w());
        let offset = start / align * align;
        let first_byte = (start - offset) as u32;
        let whole = (end - offset).next_multiple_of(16);
        let runs = first_byte.is_multiple_of(16)
            && self.bytes_per_row.is_multiple_of(16)
            && offset + whole <= self.buffer.size();
        let size = if runs {
            whole
        } else {
            (end - offset).next_multiple_of(4)
        };
        Window {
            offset,
            size,
            first_byte,
            runs,
        }
    }
}

impl GpuBackend {
    /// Every keypoint of a map held in a buffer on the backend's device, in (y, x) order: the same list
    /// as [`Backend::detect`] on the same cells. The kernels read the map where it lies, band by band
    /// within the device's binding limit; only the keypoints cross to the host. Work the caller
    /// submitted to the queue before (filling the map) is done first. An invalid map (too small a
    /// buffer, a pitch under the width, a buffer without `STORAGE`) is an input error, checked before
    /// anything runs.
    pub fn detect_device_map(
        &mut self,
        map: &DeviceMap,
        classes: &ClassTable,
        rules: &RuleTable,
        unknown_as_occupied: bool,
    ) -> Result<Vec<Keypoint>> {
        map.validate()?;
        let core = (0, map.height as usize);
        self.ogm_call(
            Source::Device(map),
            core,
            classes,
            rules,
            unknown_as_occupied,
        )
    }
}
