//! Files the tool reads and writes, made safe against careless and hostile use.
//!
//! - Outputs are written to a temporary file in the target's folder and renamed into place only when
//!   complete ([`AtomicFile`], [`write_atomic`]): a reader sees the old file or the whole new one, never a
//!   truncated one, also on a full disk, a crash or two runs writing the same file. Temporary files of an
//!   interrupted run are removed by [`remove_pending`] (the command-line tool calls it on SIGINT/SIGTERM).
//! - Outputs that would overwrite an input are refused ([`Inputs`]).
//! - Inputs are opened only when they are regular files ([`open_regular`]): a fifo would block forever, a
//!   device such as `/dev/zero` never ends.

use std::collections::HashMap;
use std::fs::{self, File};
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::support::error::{Error, Result};

/// Temporary files being written now, removed by [`remove_pending`] when the process is interrupted.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // A panic while holding the lock leaves a list that is still valid.
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes a temporary output: a file, or a staging folder with what is in it.
fn remove_temporary(p: &Path) {
    if fs::remove_file(p).is_err() {
        let _ = fs::remove_dir_all(p);
    }
}

/// Removes every temporary output file not yet renamed into place (for tests; a signal handler wants
/// [`remove_pending_and_exit`]).
pub fn remove_pending() {
    for p in pending().drain(..) {
        remove_temporary(&p);
    }
}

/// Removes every temporary output file not yet renamed into place and exits with `code`, holding the list
/// locked until the process is gone, so that no other thread registers (and leaves behind) a new one.
pub fn remove_pending_and_exit(code: i32) -> ! {
    let mut list = pending();
    for p in list.drain(..) {
        remove_temporary(&p);
    }
    std::process::exit(code)
}

/// A hidden staging folder inside `dir` (`.staging.XXXXXX`), removed when dropped and by an interrupt:
/// where a report's files are written before they are moved into `dir` together.
pub struct StagingDir {
    dir: Option<tempfile::TempDir>,
}

impl StagingDir {
    /// Makes it in `dir`.
    pub fn new_in(dir: &Path) -> Result<Self> {
        let mut list = pending();
        let t = tempfile::Builder::new()
            .prefix(".staging.")
            .tempdir_in(dir)
            .map_err(|e| Error::output(dir, e))?;
        list.push(t.path().to_path_buf());
        Ok(StagingDir { dir: Some(t) })
    }

    /// Its path.
    pub fn path(&self) -> &Path {
        self.dir.as_ref().expect("present until dropped").path()
    }
}

impl Drop for StagingDir {
    fn drop(&mut self) {
        if let Some(t) = self.dir.take() {
            let p = t.path().to_path_buf();
            drop(t);
            pending().retain(|q| q != &p);
        }
    }
}

/// An output file being written: a temporary file beside the target, renamed onto it by
/// [`AtomicFile::commit`]. Dropped without a commit, the temporary file is removed and the target is left
/// as it was.
///
/// A target that exists and is not a regular file (`/dev/null`, a fifo, a terminal) is written directly:
/// renaming onto it would replace the device, and such targets have no old content to protect.
///
/// Replacing by rename differs from rewriting in place as `mv` does: a read-only target is replaced, hard
/// links to the old file keep the old content, and the new file belongs to whoever ran the tool (its mode is
/// kept). Where a rename cannot replace the target (EBUSY: a single file bind-mounted into a container;
/// EXDEV) the file is rewritten in place, with a warning.
pub struct AtomicFile {
    target: PathBuf,
    /// None only after [`AtomicFile::commit`] took it.
    inner: Option<Inner>,
}

enum Inner {
    /// The open temporary file, and its path (removed when dropped, unless persisted).
    Temp(BufWriter<File>, tempfile::TempPath),
    Direct(BufWriter<File>),
}

impl AtomicFile {
    /// Starts writing `target` (a symbolic link is followed: the file it points to is replaced).
    pub fn create(target: &Path) -> Result<Self> {
        let out_err = |e: &dyn std::fmt::Display| Error::output(target, e.to_string());
        if target
            .as_os_str()
            .to_string_lossy()
            .ends_with(std::path::MAIN_SEPARATOR)
        {
            return Err(Error::input(
                target,
                "names a folder (it ends in a separator); give a file name",
            ));
        }
        // Standard output or error under another name (`/dev/stdout`, `/dev/fd/1`, a link to them, or
        // the file they are redirected to): written through the descriptor itself. A rename would
        // replace the file the shell redirected into (`>> log` losing its earlier lines).
        if let Some(f) = open_descriptor(target).map_err(|e| out_err(&e))? {
            return Ok(AtomicFile {
                target: target.to_path_buf(),
                inner: Some(Inner::Direct(BufWriter::new(f))),
            });
        }
        match fs::metadata(target) {
            Ok(m) if m.is_dir() => return Err(out_err(&"is a folder")),
            Ok(m) if !m.is_file() => {
                let f = fs::OpenOptions::new()
                    .write(true)
                    .open(target)
                    .map_err(|e| out_err(&e))?;
                return Ok(AtomicFile {
                    target: target.to_path_buf(),
                    inner: Some(Inner::Direct(BufWriter::new(f))),
                });
            }
            _ => {}
        }
        // Write beside the file a link points to (also one that does not exist yet), so the rename
        // replaces or creates that file and keeps the link.
        let (real, dir) = rename_folder(target);
        let name = real
            .file_name()
            .ok_or_else(|| out_err(&"not a file name"))?
            .to_string_lossy()
            .into_owned();
        let mut builder = tempfile::Builder::new();
        // Hidden, and named after the target, so a stray one (after a power cut) says where it came from.
        // At most 200 bytes of the name, so the temporary name stays under the system's 255.
        let mut cut = name.len().min(200);
        while !name.is_char_boundary(cut) {
            cut -= 1;
        }
        let prefix = format!(".{}.", &name[..cut]);
        builder.prefix(&prefix).suffix(".tmp");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            // The mode a plain create would give (umask applies), not tempfile's private 0600.
            builder.permissions(fs::Permissions::from_mode(0o666));
        }
        // Created and registered under the lock, so an interrupt sees every temporary file that exists.
        let mut list = pending();
        let temp = builder.tempfile_in(&dir).map_err(|e| out_err(&e))?;
        list.push(temp.path().to_path_buf());
        drop(list);
        // A file that is replaced keeps its mode, as it would when rewritten in place.
        if let Ok(old) = fs::metadata(&real) {
            let _ = fs::set_permissions(temp.path(), old.permissions());
        }
        // Written through the plain file, so errors read as the system's ("No space left on device").
        let (file, path) = temp.into_parts();
        Ok(AtomicFile {
            target: real,
            inner: Some(Inner::Temp(BufWriter::with_capacity(1 << 16, file), path)),
        })
    }

    /// The final path.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Flushes, syncs (so a full disk shows up here, not later) and renames the file into place.
    pub fn commit(mut self) -> Result<()> {
        let target = std::mem::take(&mut self.target);
        let err = |e: io::Error| Error::write(&target, e);
        let Some(inner) = self.inner.take() else {
            return Ok(());
        };
        match inner {
            Inner::Direct(mut w) => w.flush().map_err(err),
            Inner::Temp(w, path) => {
                let name = path.to_path_buf();
                let done = w
                    .into_inner()
                    .map_err(|e| e.into_error())
                    .and_then(|f| f.sync_all())
                    .and_then(|_| match path.persist(&target) {
                        Ok(()) => Ok(()),
                        // A target that cannot be replaced by a rename (a single file bind-mounted into
                        // a container: EBUSY; another file system: EXDEV) is rewritten in place instead,
                        // which is not atomic; say so.
                        Err(e) if matches!(e.error.raw_os_error(), Some(16 | 18)) => {
                            crate::say!(
                                "ogm-corners: warning: {}: cannot be replaced atomically ({}); rewriting it in place",
                                target.display(),
                                e.error
                            );
                            fs::copy(&e.path, &target).map(drop)
                        }
                        Err(e) => Err(e.error),
                    });
                pending().retain(|p| p != &name);
                // On failure the TempPath (dropped with the error) removes the temporary file.
                done.map_err(err)
            }
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let Some(Inner::Temp(w, path)) = self.inner.take() {
            let name = path.to_path_buf();
            drop(w);
            // Removed first, then forgotten: an interrupt in between removes it again, harmlessly.
            drop(path);
            pending().retain(|p| p != &name);
        }
    }
}

impl AtomicFile {
    fn writer(&mut self) -> io::Result<&mut dyn Write> {
        match &mut self.inner {
            Some(Inner::Temp(w, _)) => Ok(w),
            Some(Inner::Direct(w)) => Ok(w),
            None => Err(io::Error::other("output already committed")),
        }
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer()?.write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.writer()?.write_all(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer()?.flush()
    }
}

/// The descriptor `path` names, for writing, when it names one of this process's open descriptors:
/// `/dev/stdout`, `/dev/stderr`, `/dev/fd/N`, `/proc/self/fd/N` (or `/proc/<this pid>/fd/N`), or any
/// path (a link, the redirected file itself) that is the file standard output or error is. Standard
/// output and error are written through a duplicate of the descriptor (sharing its offset and append
/// mode, after what the tool printed); other descriptors are opened for appending.
fn open_descriptor(path: &Path) -> io::Result<Option<File>> {
    #[cfg(unix)]
    {
        use std::os::fd::AsFd;
        let stdout = || -> io::Result<File> {
            io::stdout().flush()?;
            Ok(File::from(io::stdout().as_fd().try_clone_to_owned()?))
        };
        let stderr =
            || -> io::Result<File> { Ok(File::from(io::stderr().as_fd().try_clone_to_owned()?)) };
        match descriptor_number(path) {
            Some(0) => {
                return Err(io::Error::other(
                    "is standard input, which cannot be written",
                ))
            }
            Some(1) => return stdout().map(Some),
            Some(2) => return stderr().map(Some),
            Some(_) => return fs::OpenOptions::new().append(true).open(path).map(Some),
            None => {}
        }
        // A path that is the very file standard output or error is (links followed).
        let Ok(meta) = fs::metadata(path) else {
            return Ok(None);
        };
        let id = FileId::from_meta(path, &meta);
        let same = |fd: std::os::fd::BorrowedFd<'_>| {
            File::from(fd.try_clone_to_owned().ok()?)
                .metadata()
                .ok()
                .map(|m| FileId::from_meta(path, &m) == id)
        };
        if same(io::stdout().as_fd()) == Some(true) {
            return stdout().map(Some);
        }
        if same(io::stderr().as_fd()) == Some(true) {
            return stderr().map(Some);
        }
        Ok(None)
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        Ok(None)
    }
}

/// N when `path` is spelled as one of this process's descriptors (`/dev/stdin|stdout|stderr`,
/// `/dev/fd/N`, `/proc/self/fd/N`, `/proc/thread-self/fd/N`, `/proc/<this pid>/fd/N`).
#[cfg(unix)]
fn descriptor_number(path: &Path) -> Option<u32> {
    let s = path.to_str()?;
    match s {
        "/dev/stdin" => return Some(0),
        "/dev/stdout" => return Some(1),
        "/dev/stderr" => return Some(2),
        _ => {}
    }
    let pid = format!("/proc/{}/fd/", std::process::id());
    [
        "/dev/fd/",
        "/proc/self/fd/",
        "/proc/thread-self/fd/",
        pid.as_str(),
    ]
    .iter()
    .find_map(|prefix| s.strip_prefix(prefix))
    .and_then(|n| n.parse().ok())
}

/// The file `path` names once links are followed, and the folder its temporary file is written in and
/// renamed from ([`AtomicFile`]).
fn rename_folder(path: &Path) -> (PathBuf, PathBuf) {
    let real = resolve(path);
    let dir = match real.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    (real, dir)
}

/// Refuses, before any work, an output whose folder does not exist or cannot be written (a read-only
/// folder or file system); a device or descriptor (`/dev/null`, `/dev/stdout`) is written in place and
/// passes.
pub fn check_writable(path: &Path) -> Result<()> {
    #[cfg(unix)]
    if descriptor_number(path).is_some() {
        return Ok(());
    }
    if fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        return Ok(());
    }
    let (_, dir) = rename_folder(path);
    if !dir.is_dir() {
        return Err(Error::input(path, "its folder does not exist"));
    }
    #[cfg(unix)]
    {
        use rustix::fs::{access, Access};
        if let Err(e) = access(&dir, Access::WRITE_OK | Access::EXEC_OK) {
            return Err(Error::input(
                path,
                format!(
                    "its folder cannot be written ({})",
                    io::Error::from_raw_os_error(e.raw_os_error())
                ),
            ));
        }
    }
    Ok(())
}

/// Writes `path` atomically with `f`: the file appears, complete, only when `f` succeeded.
pub fn write_atomic(path: &Path, f: impl FnOnce(&mut dyn Write) -> io::Result<()>) -> Result<()> {
    let mut file = AtomicFile::create(path)?;
    f(&mut file).map_err(|e| Error::write(path, e))?;
    file.commit()
}

/// Outputs that stand together (a merged map, its yaml, its picture, the poses): each written into its
/// temporary file, and all renamed into place by [`Staged::commit`] only once every one was written, so a
/// failure (a full disk, a missing folder) leaves none of them, and an interrupt almost never some.
#[derive(Default)]
pub struct Staged {
    files: Vec<AtomicFile>,
}

impl Staged {
    /// Writes `path` with `f` into its temporary file.
    pub fn write(
        &mut self,
        path: &Path,
        f: impl FnOnce(&mut dyn Write) -> io::Result<()>,
    ) -> Result<()> {
        let mut file = AtomicFile::create(path)?;
        // Flushed now: a device written directly (`/dev/full`) fails here, before any file is renamed.
        f(&mut file)
            .and_then(|()| file.flush())
            .map_err(|e| Error::write(path, e))?;
        self.files.push(file);
        Ok(())
    }

    /// Renames every file into place, in the order written.
    pub fn commit(self) -> Result<()> {
        for f in self.files {
            f.commit()?;
        }
        Ok(())
    }
}

/// Writes a PNG atomically.
pub fn write_png(path: &Path, img: &image::RgbImage) -> Result<()> {
    write_atomic(path, |w| encode_png(w, img))
}

/// `img` as a PNG into `w`, marked as the tool's picture (a `Software` text chunk, [`crate::support::marks`]) so
/// that a folder run never reads it back as a map.
pub fn encode_png(w: &mut dyn Write, img: &image::RgbImage) -> io::Result<()> {
    let mut encoder = png::Encoder::new(w, img.width(), img.height());
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    // The settings the `image` crate's encoder used before the mark.
    encoder.set_compression(png::Compression::Balanced);
    encoder.set_filter(png::Filter::Adaptive);
    encoder
        .add_text_chunk(
            crate::support::marks::PNG_KEYWORD.to_string(),
            crate::support::marks::PICTURE.to_string(),
        )
        .map_err(io::Error::other)?;
    let mut writer = encoder.write_header().map_err(io::Error::other)?;
    writer
        .write_image_data(img.as_raw())
        .map_err(io::Error::other)?;
    writer.finish().map_err(io::Error::other)
}

/// Creates `dir` (and its parents) unless it exists; a file in its place is a usage error (exit 2), not
/// the system's "File exists".
pub fn create_dir(dir: &Path) -> Result<()> {
    match fs::metadata(dir) {
        Ok(m) if m.is_dir() => return Ok(()),
        Ok(m) => {
            return Err(Error::input(
                dir,
                format!("is {}, not a folder (a folder is needed here)", kind_of(&m)),
            ))
        }
        Err(_) => {}
    }
    fs::create_dir_all(dir).map_err(|e| Error::output(dir, e))
}

/// Opens `path` for reading when it is a regular file (after following links), with its length. Fifos,
/// devices and folders are refused before opening: reading them would block or never end.
pub fn open_regular(path: &Path) -> Result<(File, u64)> {
    let meta = fs::metadata(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    if !meta.is_file() {
        return Err(Error::input(
            path,
            format!("not a regular file ({})", kind_of(&meta)),
        ));
    }
    let f = File::open(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    Ok((f, meta.len()))
}

/// What kind of file system entry `meta` describes, for messages.
pub fn kind_of(meta: &fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a folder";
    }
    if t.is_file() {
        return "a file";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a fifo";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

/// Reads a small text file whole, refusing files over `max` bytes before reading them.
pub fn read_small_text(path: &Path, max: u64, what: &str) -> Result<String> {
    let (f, len) = open_regular(path)?;
    if len > max {
        return Err(Error::input(
            path,
            format!("{len} bytes is too large for {what} (at most {max})"),
        ));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    // `take` also bounds a file that grows while it is read.
    f.take(max + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    if bytes.len() as u64 > max {
        return Err(Error::input(
            path,
            format!("too large for {what} (over {max} bytes)"),
        ));
    }
    String::from_utf8(bytes).map_err(|e| {
        Error::input(
            path,
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// The identity of an existing file: device and inode on Unix, so hard links, symbolic links and other
/// spellings of one file compare equal; the canonical path elsewhere.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct FileId(IdInner);

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
enum IdInner {
    #[cfg(unix)]
    Inode(u64, u64),
    #[cfg_attr(unix, allow(dead_code))]
    Path(PathBuf),
}

impl FileId {
    /// The identity of `path` (links followed), or None when it does not exist.
    pub fn of(path: &Path) -> Option<FileId> {
        let meta = fs::metadata(path).ok()?;
        Some(Self::from_meta(path, &meta))
    }

    /// The identity from metadata already read for `path`.
    pub fn from_meta(path: &Path, meta: &fs::Metadata) -> FileId {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let _ = path;
            FileId(IdInner::Inode(meta.dev(), meta.ino()))
        }
        #[cfg(not(unix))]
        {
            let _ = meta;
            FileId(IdInner::Path(
                fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()),
            ))
        }
    }
}

/// The input files of a run, so that no output overwrites one (`-o map.pgm`, an overlay folder that is
/// the map folder), and no two outputs of one run are the same file.
#[derive(Default, Debug)]
pub struct Inputs {
    /// Each input's identity and the path it was named by.
    files: HashMap<FileId, PathBuf>,
    /// Each claimed output (resolved) and the option that named it. Maps, so a batch of many maps stays
    /// linear.
    outputs: HashMap<PathBuf, String>,
}

impl Inputs {
    /// No inputs yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records an input file (missing files are ignored: loading them reports the error).
    pub fn add(&mut self, path: &Path) {
        if let Some(id) = FileId::of(path) {
            self.files.entry(id).or_insert_with(|| path.to_path_buf());
        }
    }

    /// Records every file of `paths` (a map's yaml and image: `OccupancyMap::files`).
    pub fn add_all<'p>(&mut self, paths: impl IntoIterator<Item = &'p Path>) {
        for p in paths {
            self.add(p);
        }
    }

    /// Refuses `output` (named by `option`, e.g. "--overlay") when it is one of the inputs or an output
    /// already claimed in this run; otherwise claims it.
    pub fn claim_output(&mut self, output: &Path, option: &str) -> Result<()> {
        if let Some(id) = FileId::of(output) {
            if let Some(input) = self.files.get(&id) {
                return Err(Error::invalid(format!(
                    "{option} {} is the input {}: refusing to overwrite it",
                    output.display(),
                    input.display()
                )));
            }
        }
        let resolved = resolve(output);
        if let Some(other) = self.outputs.get(&resolved) {
            return Err(Error::invalid(format!(
                "{option} {} is also the output of {other}: give different paths",
                output.display()
            )));
        }
        self.outputs.insert(resolved, option.to_string());
        Ok(())
    }
}

/// Where writing `path` lands: its canonical path when it exists; otherwise, links followed (a dangling
/// link names the file it will create) and the folder made canonical. For comparing paths of files that
/// may not exist yet.
pub fn resolve(path: &Path) -> PathBuf {
    let mut p = path.to_path_buf();
    // A bounded number of hops, as the system allows (40 on Linux), so a loop of links ends.
    for _ in 0..40 {
        if let Ok(c) = fs::canonicalize(&p) {
            return c;
        }
        match fs::read_link(&p) {
            Ok(target) => {
                p = match p.parent() {
                    Some(dir) if target.is_relative() => dir.join(target),
                    _ => target,
                }
            }
            Err(_) => break,
        }
    }
    let dir = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match (fs::canonicalize(dir), p.file_name()) {
        (Ok(d), Some(n)) => d.join(n),
        _ => p,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `remove_pending` removes every pending file of the process: tests that write take turns.
    static SERIAL: Mutex<()> = Mutex::new(());

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("ogm-files-{}-{name}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    fn entries(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_failed_write_keeps_the_old_file_and_leaves_no_temporary() {
        let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
        let d = dir("fail");
        let p = d.join("out.csv");
        fs::write(&p, "old\n").unwrap();
        let r = write_atomic(&p, |w| {
            w.write_all(b"half a line")?;
            Err(io::Error::other("disk full"))
        });
        assert!(r.is_err());
        assert_eq!(fs::read_to_string(&p).unwrap(), "old\n");
        assert_eq!(entries(&d), ["out.csv"]);
        write_atomic(&p, |w| w.write_all(b"new\n")).unwrap();
        assert_eq!(fs::read_to_string(&p).unwrap(), "new\n");
        assert_eq!(entries(&d), ["out.csv"]);
    }

    #[test]
    fn nothing_appears_before_commit_and_pending_files_are_removed() {
        let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
        let d = dir("pending");
        let p = d.join("k.json");
        let mut f = AtomicFile::create(&p).unwrap();
        f.write_all(b"{").unwrap();
        f.flush().unwrap();
        assert!(!p.exists());
        assert_eq!(entries(&d).len(), 1, "one temporary file");
        remove_pending();
        assert!(entries(&d).is_empty());
        drop(f);
    }

    #[cfg(unix)]
    #[test]
    fn a_link_is_kept_and_its_file_replaced_and_devices_are_written_directly() {
        let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
        let d = dir("link");
        let real = d.join("real.csv");
        fs::write(&real, "old").unwrap();
        let link = d.join("link.csv");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        write_atomic(&link, |w| w.write_all(b"new")).unwrap();
        assert!(fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(fs::read_to_string(&real).unwrap(), "new");
        write_atomic(Path::new("/dev/null"), |w| w.write_all(b"x")).unwrap();
        // A dangling link creates the file it names, and is one output with it.
        let dangling = d.join("dangling.csv");
        std::os::unix::fs::symlink("later.csv", &dangling).unwrap();
        let mut inputs = Inputs::new();
        inputs.claim_output(&d.join("later.csv"), "-o").unwrap();
        assert!(inputs.claim_output(&dangling, "--overlay").is_err());
        write_atomic(&dangling, |w| w.write_all(b"made")).unwrap();
        assert_eq!(fs::read_to_string(d.join("later.csv")).unwrap(), "made");
        assert!(fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device_like());
    }

    trait CharDev {
        fn is_char_device_like(&self) -> bool;
    }
    impl CharDev for fs::FileType {
        fn is_char_device_like(&self) -> bool {
            #[cfg(unix)]
            {
                use std::os::unix::fs::FileTypeExt;
                self.is_char_device()
            }
            #[cfg(not(unix))]
            {
                true
            }
        }
    }

    #[test]
    fn outputs_equal_to_inputs_or_to_each_other_are_refused() {
        let d = dir("inputs");
        let map = d.join("map.pgm");
        fs::write(&map, "P5\n1 1\n255\n\0").unwrap();
        let mut inputs = Inputs::new();
        inputs.add(&map);
        let spelled = d.join(".").join("map.pgm");
        let e = inputs.claim_output(&spelled, "-o").unwrap_err();
        assert!(e.to_string().contains("refusing to overwrite"), "{e}");
        inputs.claim_output(&d.join("a.csv"), "-o").unwrap();
        let e = inputs
            .claim_output(&d.join(".").join("a.csv"), "--overlay")
            .unwrap_err();
        assert!(e.to_string().contains("also the output of -o"), "{e}");
    }

    #[test]
    fn non_regular_inputs_and_large_texts_are_refused_before_reading() {
        let e = open_regular(Path::new("/dev/zero")).unwrap_err();
        assert!(
            e.to_string().contains("not a regular file (a device)"),
            "{e}"
        );
        let d = dir("small");
        let p = d.join("big.yaml");
        fs::write(&p, vec![b'a'; 100]).unwrap();
        let e = read_small_text(&p, 50, "a map yaml").unwrap_err();
        assert!(e.to_string().contains("too large"), "{e}");
        assert_eq!(read_small_text(&p, 100, "x").unwrap().len(), 100);
    }
}
