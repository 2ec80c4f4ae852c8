//! A raw raster read straight into the windows' memory: where the operating system allows it (Linux,
//! a file system with `O_DIRECT`), a window the page cache does not hold goes from the disk to the window
//! by DMA, with no copy through the cache; a window it holds (asked with `mincore`) is copied from it,
//! since the disk would be slower. Elsewhere, or when the file system refuses, plain reads. The pixels are
//! never read through a memory map: a file cut short while it is read gives a clear error, never a SIGBUS.

use std::alloc::{self, Layout};
use std::fs::File;
use std::path::{Path, PathBuf};
use std::ptr::NonNull;

use crate::support::error::{Error, Result};

/// The alignment `O_DIRECT` asks of offsets, lengths and buffers: the page size, which every block
/// device's logical block size divides.
pub const ALIGN: usize = 4096;

/// Reads a window is split into, read side by side (on this project's VM disk, direct reads of 32 MiB
/// windows measured one at a time at 1.5 GB/s, four at once at 2.1-2.4 GB/s).
const READS_IN_FLIGHT: usize = 4;

/// Zeroed memory aligned to [`ALIGN`], grown on demand: a window's buffer.
pub struct AlignedBuf {
    ptr: NonNull<u8>,
    len: usize,
}

// SAFETY: an owned allocation, like a Vec<u8>.
unsafe impl Send for AlignedBuf {}

impl Default for AlignedBuf {
    fn default() -> Self {
        AlignedBuf {
            ptr: NonNull::dangling(),
            len: 0,
        }
    }
}

impl AlignedBuf {
    /// Makes the buffer at least `len` bytes long (rounded up to [`ALIGN`]); grown buffers are zeroed,
    /// kept contents are not preserved when it grows.
    pub fn reserve(&mut self, len: usize) -> Result<()> {
        if len <= self.len {
            return Ok(());
        }
        let len = len.next_multiple_of(ALIGN);
        let layout = Layout::from_size_align(len, ALIGN)
            .map_err(|_| Error::invalid(format!("a window of {len} bytes")))?;
        // SAFETY: the layout's size is not zero (len > self.len >= 0, rounded up to ALIGN).
        let p = unsafe { alloc::alloc_zeroed(layout) };
        let ptr = NonNull::new(p)
            .ok_or_else(|| Error::invalid(format!("cannot allocate a window of {len} bytes")))?;
        *self = AlignedBuf { ptr, len };
        Ok(())
    }

    /// The whole buffer.
    pub fn bytes(&self) -> &[u8] {
        // SAFETY: `len` initialised (zeroed) bytes at `ptr`, or an empty slice at a dangling pointer.
        unsafe { std::slice::from_raw_parts(self.ptr.as_ptr(), self.len) }
    }

    /// The whole buffer, writable.
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        // SAFETY: as in `bytes`, and `&mut self` makes this the only reference.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.as_ptr(), self.len) }
    }
}

impl Drop for AlignedBuf {
    fn drop(&mut self) {
        if self.len > 0 {
            // SAFETY: allocated in `reserve` with this size and alignment.
            unsafe {
                alloc::dealloc(
                    self.ptr.as_ptr(),
                    Layout::from_size_align_unchecked(self.len, ALIGN),
                )
            };
        }
    }
}

/// How the bytes of a [`RawFile::read`] came: for tests and measurements.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadStats {
    /// Bytes read with `O_DIRECT` (disk to window).
    pub direct: u64,
    /// Bytes copied from the page cache or read plainly.
    pub buffered: u64,
}

/// A file whose bytes from `offset` on are a raster, read into [`AlignedBuf`]s.
pub struct RawFile {
    path: PathBuf,
    file: File,
    /// The same file opened with `O_DIRECT`, when the system allows it.
    direct: Option<File>,
    /// Counts of how bytes came.
    pub stats: ReadStats,
}

impl RawFile {
    /// Opens `path`; `direct` asks for `O_DIRECT` reads where they work (a plain open otherwise).
    pub fn open(path: &Path, direct: bool) -> Result<Self> {
        let file = File::open(path).map_err(|e| Error::input(path, e.to_string()))?;
        // Plain reads go front to back: the kernel reads further ahead (as the decoder's reads do).
        #[cfg(unix)]
        let _ = rustix::fs::fadvise(&file, 0, None, rustix::fs::Advice::Sequential);
        let direct = if direct { open_direct(path) } else { None };
        Ok(RawFile {
            path: path.to_path_buf(),
            file,
            direct,
            stats: ReadStats::default(),
        })
    }

    /// Whether reads go around the page cache where they can.
    pub fn is_direct(&self) -> bool {
        self.direct.is_some()
    }

    /// Fills `buf[at..at + (end - start)]` with the file's bytes `start..end`, where `at` is congruent to
    /// `start` modulo [`ALIGN`] (so that aligned file offsets land on aligned addresses) and `at` is at
    /// least `start % ALIGN`. The buffer grows to `at + (end - start)` rounded up to [`ALIGN`]; a direct
    /// read also writes the file's bytes around the range up to the aligned offsets on either side (the
    /// bytes that lie there in the file). A file that ends before `end` is an error naming the byte where
    /// it ended.
    ///
    /// Ranges the page cache mostly holds are copied from it; the others go around it.
    pub fn read(&mut self, buf: &mut AlignedBuf, at: usize, start: u64, end: u64) -> Result<()> {
        let head = (start % ALIGN as u64) as usize;
        assert!(at % ALIGN == head && at >= head, "aligned placement");
        let len =
            usize::try_from(end - start).map_err(|_| Error::invalid("a window over 4 GiB"))?;
        buf.reserve((at + len).next_multiple_of(ALIGN))?;
        if let Some(direct) = self
            .direct
            .as_ref()
            .filter(|_| !mostly_cached(&self.file, start, end))
        {
            // From the aligned offset below `start` to the one above `end`, into aligned memory.
            let (from, dst) = (start - head as u64, at - head);
            let room = (at + len).next_multiple_of(ALIGN) - dst;
            match read_pieces(
                direct,
                &mut buf.bytes_mut()[dst..dst + room],
                from,
                ALIGN,
                READS_IN_FLIGHT,
            ) {
                Ok(got) if got >= head + len => {
                    self.stats.direct += (head + len) as u64;
                    return Ok(());
                }
                Ok(got) => return Err(self.short(from + got as u64, end)),
                // A file system that takes O_DIRECT at open but not at read: plain reads from here on.
                Err(e) if e.raw_os_error() == Some(einval()) => self.direct = None,
                Err(e) => return Err(self.io(e)),
            }
        }
        let out = &mut buf.bytes_mut()[at..at + len];
        // One piece: a copy from the cache is the CPU's work, and the detector shares the cores (measured
        // on two cores, 100000^2 from the cache: 1.2 s in one piece, 1.35 s in four).
        match read_pieces(&self.file, out, start, 1, 1) {
            Ok(got) if got == len => {
                self.stats.buffered += len as u64;
                Ok(())
            }
            Ok(got) => Err(self.short(start + got as u64, end)),
            Err(e) => Err(self.io(e)),
        }
    }

    fn short(&self, pos: u64, end: u64) -> Error {
        Error::input(
            &self.path,
            format!(
                "the file ends at byte {pos}, before the {end} its header promises (was it cut short while being read?)"
            ),
        )
    }

    fn io(&self, e: std::io::Error) -> Error {
        Error::input(&self.path, format!("reading failed: {e}"))
    }
}

/// Fills `out` with the file's bytes from `pos` in `pieces` pieces (multiples of `align`) read side by
/// side, on threads of their own (never the compute pool's): a disk keeps several requests going at once.
/// Returns how many bytes from the start are filled: fewer than `out.len()` where the file ends.
fn read_pieces(
    file: &File,
    out: &mut [u8],
    pos: u64,
    align: usize,
    pieces: usize,
) -> std::io::Result<usize> {
    /// One piece: read until full or the end of the file.
    fn fill(file: &File, out: &mut [u8], pos: u64) -> std::io::Result<usize> {
        let mut got = 0;
        while got < out.len() {
            match read_at(file, &mut out[got..], pos + got as u64)? {
                0 => break,
                n => got += n,
            }
        }
        Ok(got)
    }
    if pieces <= 1 {
        return fill(file, out, pos);
    }
    let piece = out.len().div_ceil(pieces).next_multiple_of(align).max(1);
    let got: Vec<std::io::Result<usize>> = std::thread::scope(|s| {
        let parts: Vec<_> = out
            .chunks_mut(piece)
            .enumerate()
            .map(|(i, part)| s.spawn(move || fill(file, part, pos + (i * piece) as u64)))
            .collect();
        parts
            .into_iter()
            .map(|p| {
                p.join()
                    .unwrap_or_else(|_| Err(std::io::Error::other("a reader panicked")))
            })
            .collect()
    });
    // The filled prefix: pieces up to the first one cut short by the end of the file.
    let mut filled = 0;
    for (i, r) in got.into_iter().enumerate() {
        let n = r?;
        if filled == i * piece {
            filled += n;
        }
    }
    Ok(filled)
}

/// `pread`, retried when interrupted.
fn read_at(file: &File, out: &mut [u8], pos: u64) -> std::io::Result<usize> {
    #[cfg(unix)]
    use std::os::unix::fs::FileExt;
    #[cfg(windows)]
    use std::os::windows::fs::FileExt;
    loop {
        #[cfg(unix)]
        let r = file.read_at(out, pos);
        #[cfg(windows)]
        let r = file.seek_read(out, pos);
        match r {
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            r => return r,
        }
    }
}

/// `EINVAL`: what a read refused for its alignment returns.
fn einval() -> i32 {
    22
}

/// The file opened with `O_DIRECT`; None where the system or the file system refuses it (tmpfs, say).
#[cfg(target_os = "linux")]
fn open_direct(path: &Path) -> Option<File> {
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_DIRECT)
        .open(path)
        .ok()
}

#[cfg(not(target_os = "linux"))]
fn open_direct(_: &Path) -> Option<File> {
    None
}

/// Whether the page cache holds at least half the pages of bytes `start..end` of the file: `cachestat`, or
/// on older kernels (sampled at the range's start, middle and end) `mincore` over
/// a mapping that is never touched (so a file cut short cannot fault), which starts no disk read (as a
/// non-blocking read would: its readahead would then be read a second time around the cache). False
/// where that cannot be asked.
#[cfg(target_os = "linux")]
fn mostly_cached(file: &File, start: u64, end: u64) -> bool {
    use std::os::fd::AsRawFd;
    let page = ALIGN as u64;
    let (a, b) = (start - start % page, end.next_multiple_of(page));
    let (Ok(len), Ok(off)) = (usize::try_from(b - a), libc::off_t::try_from(a)) else {
        return false;
    };
    if len == 0 {
        return true;
    }
    if let Some(cached) = cachestat(file, a, b - a) {
        return 2 * cached >= (b - a) / page;
    }
    // SAFETY: a fresh read-only shared mapping of the file's pages, never read through; unmapped below.
    let map = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            len,
            libc::PROT_READ,
            libc::MAP_SHARED,
            file.as_raw_fd(),
            off,
        )
    };
    if map == libc::MAP_FAILED {
        return false;
    }
    // Three spots of 16 pages (start, middle, end) stand for the window: asking for every page of a
    // 32 MiB window cost a millisecond each, a fifth of a warm 100000^2 detection.
    let pages = len / ALIGN;
    let spot = 16.min(pages);
    let mut resident = [0u8; 16];
    let (mut held, mut asked) = (0, 0);
    for first in [0, (pages - spot) / 2, pages - spot] {
        // SAFETY: pages `first..first + spot` lie inside the `len` bytes mapped just above; `resident`
        // has a byte for each.
        let ok = unsafe {
            libc::mincore(
                map.cast::<u8>().add(first * ALIGN).cast(),
                spot * ALIGN,
                resident.as_mut_ptr(),
            )
        } == 0;
        if !ok {
            break;
        }
        held += resident[..spot].iter().filter(|&&r| r & 1 == 1).count();
        asked += spot;
    }
    // SAFETY: the mapping made above, `len` bytes.
    unsafe { libc::munmap(map, len) };
    asked > 0 && 2 * held >= asked
}

/// Pages of bytes `off..off + len` of the file in the page cache, by `cachestat` (Linux 6.5 and later:
/// no mapping, whose removal would interrupt every core running this process); None where the kernel
/// lacks it.
#[cfg(target_os = "linux")]
fn cachestat(file: &File, off: u64, len: u64) -> Option<u64> {
    use std::os::fd::AsRawFd;
    #[repr(C)]
    struct Range {
        off: u64,
        len: u64,
    }
    #[repr(C)]
    #[derive(Default)]
    struct Stat {
        nr_cache: u64,
        nr_dirty: u64,
        nr_writeback: u64,
        nr_evicted: u64,
        nr_recently_evicted: u64,
    }
    // The same number on every architecture (one table for system calls added since Linux 5.1).
    const SYS_CACHESTAT: libc::c_long = 451;
    let range = Range { off, len };
    let mut stat = Stat::default();
    // SAFETY: the kernel reads `range` and writes `stat`, both live #[repr(C)] structs of the layouts
    // cachestat(2) defines; flags 0.
    let r = unsafe {
        libc::syscall(
            SYS_CACHESTAT,
            file.as_raw_fd(),
            &range as *const Range,
            &mut stat as *mut Stat,
            0u32,
        )
    };
    (r == 0).then_some(stat.nr_cache)
}

#[cfg(not(target_os = "linux"))]
fn mostly_cached(_: &File, _: u64, _: u64) -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    /// Every offset and length, direct or not, reads the file's bytes; a file shorter than asked is a
    /// clear error.
    #[test]
    fn reads_any_range_and_names_a_short_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("raster.bin");
        let bytes: Vec<u8> = (0..3 * ALIGN + 777).map(|i| (i * 31 % 251) as u8).collect();
        let mut file = std::fs::File::create(&path).unwrap();
        file.write_all(&bytes).unwrap();
        file.sync_all().unwrap();
        for direct in [false, true] {
            // Out of the page cache, so that the direct reads are what is tested where they happen.
            #[cfg(unix)]
            rustix::fs::fadvise(&file, 0, None, rustix::fs::Advice::DontNeed).unwrap();
            let mut f = RawFile::open(&path, direct).unwrap();
            let mut buf = AlignedBuf::default();
            for (start, end) in [
                (0, 10),
                (5, ALIGN + 3),
                (ALIGN, 3 * ALIGN),
                (17, bytes.len()),
            ] {
                let at = start % ALIGN + ALIGN;
                f.read(&mut buf, at, start as u64, end as u64).unwrap();
                assert_eq!(&buf.bytes()[at..at + end - start], &bytes[start..end]);
            }
            if f.is_direct() {
                assert!(f.stats.direct > 0, "{:?}", f.stats);
            } else if direct {
                eprintln!("NOTE: this file system refuses O_DIRECT: only plain reads tested here");
            }
            let e = f
                .read(&mut buf, 0, 0, bytes.len() as u64 + 1)
                .unwrap_err()
                .to_string();
            assert!(e.contains(&format!("ends at byte {}", bytes.len())), "{e}");
        }
        // The cache question: a file just read is held; evicted, it is not (where the file system lets
        // its pages go: tmpfs keeps them).
        #[cfg(target_os = "linux")]
        {
            let _ = std::fs::read(&path).unwrap();
            assert!(mostly_cached(&file, 0, bytes.len() as u64));
            rustix::fs::fadvise(&file, 0, None, rustix::fs::Advice::DontNeed).unwrap();
            if mostly_cached(&file, 0, bytes.len() as u64) {
                eprintln!("NOTE: this file system keeps evicted pages: the uncached answer is not tested here");
            }
        }
        // Cut short after it was opened: an error naming where it ended, never a fault.
        let mut f = RawFile::open(&path, true).unwrap();
        file.set_len(ALIGN as u64 + 10).unwrap();
        let mut buf = AlignedBuf::default();
        let e = f
            .read(&mut buf, 0, 0, 3 * ALIGN as u64)
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("ends at byte {}", ALIGN + 10)), "{e}");
    }
}
