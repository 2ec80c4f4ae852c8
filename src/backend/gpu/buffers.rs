//! Device buffers that grow when a call needs more, and the staging ring that uploads map bands.
//!
//! The ring's buffers are created once (MAP_WRITE | COPY_SRC, mapped at creation) and recycled: each is
//! filled by several threads straight from the map's rows (row padding added on the way), unmapped, copied
//! to the device in the chunk's own submission, and mapped again when that submission completes
//! (`map_buffer_on_submit`), so no per-call staging allocation happens inside wgpu and the host fills the
//! next band while the GPU copies and runs the previous one.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{mpsc, Arc};

use rayon::prelude::*;

use super::tiles::Tile;
use crate::map::stream::Rows;
use crate::support::error::{Error, Result};

/// A reusable buffer that grows (to the next power of two, within `cap`) when a call needs more.
pub(super) struct Slot {
    buffer: Option<wgpu::Buffer>,
    /// Bytes of the current buffer.
    pub size: u64,
    usage: wgpu::BufferUsages,
    label: &'static str,
    /// Bumped whenever the buffer is replaced, so bind groups built on it know to rebuild.
    pub generation: u64,
}

impl Slot {
    pub fn new(label: &'static str, usage: wgpu::BufferUsages) -> Self {
        Slot {
            buffer: None,
            size: 0,
            usage,
            label,
            generation: 0,
        }
    }

    /// A buffer of at least `size` bytes (rounded up to 16); `cap` bounds the growth.
    pub fn get(&mut self, device: &wgpu::Device, size: u64, cap: u64) -> &wgpu::Buffer {
        let size = size.max(16).next_multiple_of(16);
        if self.buffer.is_none() || self.size < size {
            let grown = size.next_power_of_two().min(cap.max(size));
            self.buffer = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(self.label),
                size: grown,
                usage: self.usage,
                mapped_at_creation: false,
            }));
            self.size = grown;
            self.generation += 1;
        }
        self.buffer.as_ref().expect("buffer was just created")
    }
}

/// A staging buffer's state, shared with its map callback.
const IN_FLIGHT: u8 = 0;
const MAPPED: u8 = 1;
const FAILED: u8 = 2;

struct Staging {
    buffer: wgpu::Buffer,
    state: Arc<AtomicU8>,
    /// The submission that last used it, to wait on that one alone.
    submission: Option<wgpu::SubmissionIndex>,
}

/// A ring of persistent staging buffers for uploads.
pub(super) struct Ring {
    bufs: Vec<Option<Staging>>,
    next: usize,
    usage: wgpu::BufferUsages,
}

/// What one row of a staged band is: `len` bytes from `src` written at `dst`, zeros up to `dst + pitch`.
#[derive(Clone, Copy)]
struct RowCopy {
    src: usize,
    dst: usize,
    len: usize,
    pitch: usize,
}

impl Ring {
    /// A ring of `len` buffers; with `bindable`, kernels may read them in place (the device has
    /// `MAPPABLE_PRIMARY_BUFFERS`).
    pub fn new(len: usize, bindable: bool) -> Self {
        let mut usage = wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC;
        if bindable {
            usage |= wgpu::BufferUsages::STORAGE;
        }
        Ring {
            bufs: (0..len.max(1)).map(|_| None).collect(),
            next: 0,
            usage,
        }
    }

    /// The next staging buffer, once the GPU is done with it, holding `head` (small parameter data) at
    /// offset 0 and then, from offset `rows_at`, the rows of tile `t` of the map rows `image`, each padded with zeros to
    /// `pitch` bytes and copied in parallel. Returns its index and the buffer, unmapped and ready to be
    /// copied from, and the band's bytes; call [`Ring::recycle`] on the encoder that copies it.
    pub fn stage_band(
        &mut self,
        device: &wgpu::Device,
        image: Rows,
        t: &Tile,
        pitch: usize,
        head: &[u8],
        rows_at: usize,
    ) -> Result<(usize, wgpu::Buffer, u64)> {
        let iw = image.width();
        let first = t.buf[1] as usize - image.first();
        let rows: Vec<RowCopy> = (0..t.buf_h() as usize)
            .map(|r| RowCopy {
                src: (first + r) * iw + t.buf[0] as usize,
                dst: r * pitch,
                len: t.buf_w() as usize,
                pitch,
            })
            .collect();
        let bytes = pitch as u64 * u64::from(t.buf_h());
        let pixels = image.pixels();
        let size = rows_at as u64 + bytes;
        let i = self.next;
        self.next = (self.next + 1) % self.bufs.len();
        let size = size
            .max(16)
            .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT * 4);
        if let Some(s) = &self.bufs[i] {
            if s.state.load(Ordering::Acquire) == IN_FLIGHT {
                let wait =
                    s.submission
                        .clone()
                        .map_or(wgpu::PollType::wait_indefinitely(), |idx| {
                            wgpu::PollType::Wait {
                                submission_index: Some(idx),
                                timeout: None,
                            }
                        });
                poll(device, wait)?;
            }
        }
        let reuse = self.bufs[i]
            .as_ref()
            .is_some_and(|s| s.buffer.size() >= size && s.state.load(Ordering::Acquire) == MAPPED);
        if !reuse {
            self.bufs[i] = Some(Staging {
                buffer: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("staging"),
                    size,
                    usage: self.usage,
                    mapped_at_creation: true,
                }),
                state: Arc::new(AtomicU8::new(MAPPED)),
                submission: None,
            });
        }
        let s = self.bufs[i].as_ref().expect("staging buffer was just made");
        {
            let mut view = s
                .buffer
                .get_mapped_range_mut(..)
                .map_err(|e| Error::Internal(format!("staging buffer map failed: {e}")))?;
            let all = view.slice(..);
            let (mut head_part, mut rest) = all.split_at(rows_at);
            head_part.slice(..head.len()).copy_from_slice(head);
            // Split the band into per-row destinations, then copy them on all threads.
            let mut parts = Vec::with_capacity(rows.len());
            let mut at = 0usize;
            for r in rows {
                let (_, tail) = rest.split_at(r.dst - at);
                let (row, tail) = tail.split_at(r.pitch);
                parts.push((RowView(row), r));
                rest = tail;
                at = r.dst + r.pitch;
            }
            parts.into_par_iter().for_each(|(RowView(mut row), r)| {
                row.slice(..r.len)
                    .copy_from_slice(&pixels[r.src..r.src + r.len]);
                if r.pitch > r.len {
                    row.slice(r.len..).fill(0);
                }
            });
        }
        s.buffer.unmap();
        s.state.store(IN_FLIGHT, Ordering::Release);
        Ok((i, s.buffer.clone(), bytes))
    }

    /// Maps staging buffer `i` again when `encoder`'s submission completes.
    pub fn recycle(&self, i: usize, encoder: &wgpu::CommandEncoder) {
        if let Some(s) = &self.bufs[i] {
            let state = s.state.clone();
            encoder.map_buffer_on_submit(&s.buffer, wgpu::MapMode::Write, .., move |r| {
                state.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
            });
        }
    }

    /// Records the submission that used staging buffer `i`.
    pub fn submitted(&mut self, i: usize, index: wgpu::SubmissionIndex) {
        if let Some(s) = &mut self.bufs[i] {
            s.submission = Some(index);
        }
    }
}

/// A bind group of `layout` binding whole buffers.
pub(super) fn bind_group_with(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    entries: &[(u32, &wgpu::Buffer)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = entries
        .iter()
        .map(|&(binding, b)| wgpu::BindGroupEntry {
            binding,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout,
        entries: &entries,
    })
}

/// A bind group of group 0 of `pipeline` binding whole buffers (a uniform's buffer may be longer than its
/// struct: the OGM and selection parameters are followed by the scan's levels).
pub(super) fn bind_group(
    device: &wgpu::Device,
    pipeline: &wgpu::ComputePipeline,
    entries: &[(u32, &wgpu::Buffer)],
) -> wgpu::BindGroup {
    bind_group_with(device, &pipeline.get_bind_group_layout(0), entries)
}

/// Waits as `wait` says for the device's work, driving map callbacks.
fn poll(device: &wgpu::Device, wait: wgpu::PollType) -> Result<()> {
    device
        .poll(wait)
        .map(|_| ())
        .map_err(|e| Error::Internal(format!("GPU poll failed: {e}")))
}

/// Waits until the device has finished all the work submitted so far.
pub(super) fn wait_idle(device: &wgpu::Device) -> Result<()> {
    poll(device, wgpu::PollType::wait_indefinitely())
}

/// One row's part of a mapped staging buffer, handed to a worker thread.
struct RowView<'a>(wgpu::WriteOnly<'a, [u8]>);

// SAFETY: a WriteOnly view is a pointer and a length into mapped memory; wgpu makes it Sync for any
// target but Send only for sized ones. The rows are disjoint (split_at), each moved to exactly one thread,
// and all are dropped before the mapping ends (the view's scope), so sending one is as safe as sharing it.
unsafe impl Send for RowView<'_> {}

/// The first `size` bytes of `buf` (MAP_READ), after the device finishes the work queued so far.
pub(super) fn map_read(device: &wgpu::Device, buf: &wgpu::Buffer, size: u64) -> Result<Vec<u8>> {
    let size = size.max(4).next_multiple_of(4);
    let slice = buf.slice(0..size);
    let (tx, rx) = mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    wait_idle(device)?;
    rx.recv()
        .map_err(|_| Error::Internal("GPU buffer map was dropped".into()))?
        .map_err(|e| Error::Internal(format!("GPU buffer map failed: {e}")))?;
    let data = slice
        .get_mapped_range()
        .map_err(|e| Error::Internal(format!("GPU buffer map failed: {e}")))?
        .to_vec();
    buf.unmap();
    Ok(data)
}
