//! `ogm-corners detect`: keypoints of one map to a file or standard output, or of many maps to a folder.
//!
//! It picks one of three routes:
//! - **Many maps or a folder** go to `batch.rs`.
//! - **One map** is streamed (`ogm_corners::detect::streamed`, whose doc gives the steps). The robust
//!   detector takes this route only when the map does not fit in memory whole: `robust::tiles`, tiles of
//!   its turned grid over a temporary copy of the rows.
//! - **The robust detector** otherwise needs the whole map: `OccupancyMap::load_within` loads it within
//!   the budget, `Detector::detect` runs `robust::detect` (orientation, the turned grid, `Backend::coarsen`
//!   at each scale, every grid phase as a tile of one coarse map, the rule table on the coarse maps at the
//!   cells of a lattice laid out from the grid's anchor, the map's world origin or its centre, strength,
//!   placement and selection in host code), and the keypoints and overlay are written atomically.

use std::io::Write;
use std::path::PathBuf;

use clap::Args;

use crate::cli::batch;

use ogm_corners::detect::output::{self, Format};
use ogm_corners::detect::overlay::OverlayCanvas;
use ogm_corners::map::find_maps;
use ogm_corners::support::files::{self, AtomicFile, Inputs};
use ogm_corners::support::memory::Budget;
use ogm_corners::{detect::overlay, detect::streamed, DetectorKind, Error, OccupancyMap, Result};

use super::{write_stdout, DetectOpts, FormatArg};

#[derive(Args, Debug)]
pub(super) struct DetectArgs {
    /// The maps: ROS .yaml files (each loads its image too), PGM/PNG images (ROS default thresholds), or
    /// folders of them. Several maps (or a folder) need --output DIR: one keypoint file per map.
    #[arg(required = true, value_name = "MAP")]
    maps: Vec<PathBuf>,
    #[command(flatten)]
    opts: DetectOpts,
    /// Output format.
    #[arg(long, value_enum, default_value = "csv")]
    format: FormatArg,
    /// Write the keypoints to FILE instead of standard output; with several maps, a folder that gets
    /// NAME.csv (or .json) per map.
    #[arg(short, long, value_name = "FILE|DIR")]
    output: Option<PathBuf>,
    /// Also write a PNG of the map with the keypoints marked; with several maps, a folder of NAME.png.
    #[arg(long, value_name = "PNG|DIR")]
    overlay: Option<PathBuf>,
}

impl DetectArgs {
    /// What detecting in a `w` x `h` map allocates beside the map: the backend's buffers, and the overlay
    /// when one is asked for.
    fn extra_bytes(&self, w: u32, h: u32) -> u64 {
        let overlay = if self.overlay.is_some() {
            overlay::overlay_bytes(w, h)
        } else {
            0
        };
        self.opts.working_bytes(w, h).saturating_add(overlay)
    }
}

pub(super) fn run(a: DetectArgs, budget: &Budget) -> Result<()> {
    let format = match a.format {
        FormatArg::Csv => Format::Csv,
        FormatArg::Json => Format::Json,
    };
    if a.maps.len() > 1 || a.maps[0].is_dir() {
        return run_batch(a, format, budget);
    }
    let path = &a.maps[0];
    if a.output.is_none() {
        super::check_stdout()?;
    }
    if a.opts.options().detector != DetectorKind::OgmRobust || !robust_fits(&a, budget)? {
        return run_streamed(&a, format, budget);
    }
    // The robust detector holds the map in memory when it fits (faster: no temporary file, no halos).
    // The map before the backend, so a bad map is the only message; the map, the backend's buffers and
    // the overlay are counted from the header, before the pixels are read.
    let map = OccupancyMap::load_within(path, budget, &|w, h| a.extra_bytes(w, h))?;
    for w in &map.warnings {
        ogm_corners::say!("ogm-corners: warning: {w}");
    }
    // Outputs are checked against the map's files before anything is computed or written.
    let mut inputs = Inputs::new();
    inputs.add(path);
    inputs.add_all(map.files());
    if let Some(o) = &a.output {
        inputs.claim_output(o, "--output")?;
    }
    if let Some(o) = &a.overlay {
        inputs.claim_output(o, "--overlay")?;
    }
    let mut detector = a.opts.detector()?;
    let det = detector.detect(&map)?;
    let options = detector.options();
    let backend = detector.backend_name();
    let write =
        |out: &mut dyn Write| output::write_keypoints(out, format, &map, &det, &options, &backend);
    match &a.output {
        Some(path) => files::write_atomic(path, write)?,
        None => write_stdout(write)?,
    }
    if let Some(png) = &a.overlay {
        overlay::write_overlay(png, &map.image, &det.keypoints)?;
    }
    Ok(())
}

/// Whether the robust detector fits the map in memory (from the header): otherwise it works in tiles from
/// a temporary copy of the map's rows, with the same keypoints.
fn robust_fits(a: &DetectArgs, budget: &Budget) -> Result<bool> {
    let map = OccupancyMap::open_rows(&a.maps[0])?;
    let (w, h) = map.size();
    let need = (u64::from(w) * u64::from(h))
        .saturating_add(map.decoder_bytes())
        .saturating_add(a.extra_bytes(w, h));
    Ok(ogm_corners::map::decode::check_in_memory(w, h).is_ok() && need <= budget.limit())
}

/// One map read row by row: the keypoints written as they come, the overlay drawn downsampled on the way;
/// memory bounded by a few windows of rows, whatever the map's size.
fn run_streamed(a: &DetectArgs, format: Format, budget: &Budget) -> Result<()> {
    let path = &a.maps[0];
    let mut map = OccupancyMap::open_rows(path)?;
    for w in &map.warnings {
        ogm_corners::say!("ogm-corners: warning: {w}");
    }
    let mut inputs = Inputs::new();
    inputs.add(path);
    inputs.add(&map.image_path);
    if let Some(o) = &a.output {
        inputs.claim_output(o, "--output")?;
    }
    if let Some(o) = &a.overlay {
        inputs.claim_output(o, "--overlay")?;
    }
    let mut detector = a.opts.detector()?;
    streamed::check_streamed_budget(&mut detector, &map, a.overlay.is_some(), budget)?;
    let (w, h) = map.size();
    let mut canvas = a.overlay.as_ref().map(|_| OverlayCanvas::new(w, h));
    // A file is written beside its target and renamed when complete; standard output as it comes.
    let mut file = a.output.as_deref().map(AtomicFile::create).transpose()?;
    let stdout = std::io::stdout();
    let mut pipe = PipeOut {
        inner: std::io::BufWriter::new(stdout.lock()),
        closed: false,
    };
    // With a cap, the paper's detector may refuse the map only once the cap is passed, after keypoints
    // were written: for standard output they are held in a temporary file until the run is done, so a
    // refused run prints nothing but its error.
    let mut spool = match (&a.output, a.opts.options().max_corners) {
        (None, Some(_)) => Some(std::io::BufWriter::new(
            tempfile::tempfile().map_err(|e| Error::write("a temporary file", e))?,
        )),
        _ => None,
    };
    let (out, name): (&mut dyn Write, String) = match (&mut file, &a.output, &mut spool) {
        (Some(f), Some(o), _) => (f, o.display().to_string()),
        (_, _, Some(s)) => (s, "<stdout>".into()),
        _ => (&mut pipe, "<stdout>".into()),
    };
    let mut outputs = [streamed::Output {
        out,
        format,
        name: name.clone(),
    }];
    let done = streamed::detect_to(&mut detector, &mut map, &mut outputs, canvas.as_mut())
        .and_then(|d| {
            let [o] = &mut outputs;
            o.out
                .flush()
                .map(|()| d)
                .map_err(|e| Error::write(&name, e))
        });
    let done = done.and_then(|d| match spool {
        Some(s) => unspool(s, &mut pipe).map(|()| d),
        None => Ok(d),
    });
    let done = match done {
        // `| head`: the reader has what it wanted.
        Err(_) if pipe.closed => return Ok(()),
        other => other?,
    };
    // The overlay before the keypoint file is renamed into place: a failed overlay leaves neither.
    if let (Some(png), Some(c)) = (&a.overlay, canvas.as_mut()) {
        c.write(png, &[])?;
    }
    if let Some(f) = file {
        f.commit()?;
    }
    for w in &done.warnings {
        ogm_corners::say!("ogm-corners: warning: {w}");
    }
    Ok(())
}

/// The keypoints held back for standard output, written there now that the run is done.
fn unspool(spool: std::io::BufWriter<std::fs::File>, out: &mut dyn Write) -> Result<()> {
    use std::io::Seek as _;
    let name = "a temporary file";
    let mut file = spool
        .into_inner()
        .map_err(|e| Error::write(name, e.into_error()))?;
    file.rewind().map_err(|e| Error::write(name, e))?;
    std::io::copy(&mut file, out).map_err(|e| Error::write("<stdout>", e))?;
    out.flush().map_err(|e| Error::write("<stdout>", e))
}

/// Standard output that remembers a closed pipe, so that `| head` ends the run quietly.
struct PipeOut<W: Write> {
    inner: W,
    closed: bool,
}

impl<W: Write> Write for PipeOut<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let r = self.inner.write(buf);
        self.closed |= matches!(&r, Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe);
        r
    }

    fn flush(&mut self) -> std::io::Result<()> {
        let r = self.inner.flush();
        self.closed |= matches!(&r, Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe);
        r
    }
}

/// Many maps (or folders) into the folder `--output`: unreadable entries are reported and skipped, and make
/// the run fail at the end.
fn run_batch(a: DetectArgs, format: Format, budget: &Budget) -> Result<()> {
    let Some(out) = a.output.as_deref() else {
        return Err(Error::invalid(if a.maps.len() > 1 {
            format!(
                "{} maps: give --output DIR for one keypoint file per map",
                a.maps.len()
            )
        } else {
            format!(
                "{} is a folder: give --output DIR for one keypoint file per map",
                a.maps[0].display()
            )
        }));
    };
    let found = find_maps(&a.maps);
    for n in &found.notes {
        ogm_corners::say!("ogm-corners: note: {n}");
    }
    for p in &found.problems {
        ogm_corners::say!("ogm-corners: error: {p}");
    }
    if found.maps.is_empty() {
        return Err(Error::invalid("no maps to detect in (see above)"));
    }
    let extra = |w: u32, h: u32| a.extra_bytes(w, h);
    let plan = batch::Plan {
        format,
        out_dir: out,
        overlay_dir: a.overlay.as_deref(),
        budget,
        extra: &extra,
    };
    // Set-up (a GPU device and its pipelines) is paid once for the whole batch.
    let done = batch::detect_many(&found.maps, || a.opts.detector(), &plan);
    match (done, found.problems.len()) {
        (Err(e), _) => Err(e),
        (Ok(()), 0) => Ok(()),
        (Ok(()), n) => Err(Error::invalid(format!(
            "{n} {} could not be read and {} skipped (see above); the other maps are done",
            if n == 1 { "entry" } else { "entries" },
            if n == 1 { "was" } else { "were" }
        ))),
    }
}
