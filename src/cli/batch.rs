//! `detect` over many maps: the folders are searched (`map::find_maps`) and every output is checked
//! against the inputs before the first map is read; the detector (and its GPU set-up) is made once, the
//! next map is read and decoded on another thread while the current one is detected, and a progress bar
//! runs on standard error.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use ogm_corners::detect::output::{self, Format};
pub use ogm_corners::map::{map_name, output_names};
use ogm_corners::support::files::{self, Inputs};
use ogm_corners::support::memory::Budget;
use ogm_corners::{detect::overlay, Detector, Error, OccupancyMap, Result};

/// Maps decoded ahead of the detector: one waiting while one is detected. A batch holds up to three maps
/// at once (one detected, one waiting, one being decoded); the budget is checked per map.
const READ_AHEAD: usize = 1;

/// Where and how a batch writes.
pub struct Plan<'a> {
    /// Keypoint file format.
    pub format: Format,
    /// Folder of the keypoint files, `NAME.csv|json`.
    pub out_dir: &'a Path,
    /// Folder of the overlays, `NAME.png`, if wanted.
    pub overlay_dir: Option<&'a Path>,
    /// Memory budget per map (the map, the decoder, the detector, the overlay).
    pub budget: &'a Budget,
    /// What detection (and the overlay) will allocate for a `w` x `h` map, known before the backend
    /// opens: the reader checks it with each map's header, before decoding.
    pub extra: &'a (dyn Fn(u32, u32) -> u64 + Sync),
}

/// Detects corners in every map, writing `out_dir/NAME.csv|json` (and `overlay_dir/NAME.png`), each
/// atomically, and a line per map on standard output (while it can be written). No output may overwrite an input (a map, its yaml or
/// its image): that is checked for every file before the first map is read. A map that fails is reported
/// and skipped; the call fails at the end if any did, saying what failed.
/// The detector is made by `make_detector` once the outputs are checked (opening a GPU takes a moment).
pub fn detect_many(
    maps: &[PathBuf],
    make_detector: impl FnOnce() -> Result<Detector>,
    plan: &Plan,
) -> Result<()> {
    let names = output_names(maps);
    let outputs = claim_outputs(maps, &names, plan)?;
    let detector = &mut make_detector()?;
    let bar = ProgressBar::new(maps.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} maps, {elapsed} (eta {eta}) {msg}")
            .expect("valid template"),
    );
    let backend = detector.backend_name();
    let options = detector.options();
    let started = Instant::now();
    let (mut keypoints, mut pixels) = (0usize, 0f64);
    // What failed, by kind: unreadable maps (bad input) and outputs that could not be written.
    let (mut bad_maps, mut unwritten, mut other) = (0usize, Vec::new(), 0usize);
    let stdout = std::io::stdout();
    let mut summary = BufWriter::new(stdout.lock());
    let mut summary_open = true;
    std::thread::scope(|s| -> Result<()> {
        let (tx, rx) = mpsc::sync_channel(READ_AHEAD);
        let (budget, extra) = (plan.budget, plan.extra);
        s.spawn(move || {
            for path in maps {
                // Checked from the header with the detector's buffers, before the pixels are decoded.
                let loaded = OccupancyMap::load_within(path, budget, extra);
                // The receiver hangs up only when the main loop stops early; then stop reading.
                if tx.send(loaded).is_err() {
                    break;
                }
            }
        });
        for (((path, name), loaded), (file, png)) in maps.iter().zip(&names).zip(rx).zip(&outputs) {
            bar.set_message(name.clone());
            let result = loaded.and_then(|map| {
                for w in &map.warnings {
                    bar.suspend(|| ogm_corners::say!("ogm-corners: warning: {w}"));
                }
                let t = Instant::now();
                let det = detector.detect(&map)?;
                let ms = t.elapsed().as_secs_f64() * 1e3;
                files::write_atomic(file, |w| {
                    output::write_keypoints(w, plan.format, &map, &det, &options, &backend)
                })?;
                if let Some(png) = png {
                    overlay::write_overlay(png, &map.image, &det.keypoints)?;
                }
                keypoints += det.keypoints.len();
                pixels += f64::from(det.width) * f64::from(det.height);
                Ok(format!(
                    "{}\t{}x{}\t{} keypoints\t{ms:.2} ms\t{}",
                    path.display(),
                    det.width,
                    det.height,
                    det.keypoints.len(),
                    file.display()
                ))
            });
            match result {
                Ok(line) => {
                    // The summary is a courtesy: the results are the files. A closed pipe (`| head`) or a
                    // closed standard output stops the summary, not the batch.
                    if summary_open {
                        summary_open = bar
                            .suspend(|| writeln!(summary, "{line}").and_then(|_| summary.flush()))
                            .is_ok();
                    }
                }
                Err(e) => {
                    match &e {
                        Error::Input { .. } => bad_maps += 1,
                        Error::Output { .. } => unwritten.push(e.to_string()),
                        _ => other += 1,
                    }
                    bar.suspend(|| ogm_corners::say!("ogm-corners: error: {e}"));
                }
            }
            bar.inc(1);
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    let failed = bad_maps + unwritten.len() + other;
    ogm_corners::say!(
        "ogm-corners: {} of {} maps done on {backend}, {keypoints} keypoints, {:.2} s ({:.0} Mpx/s \
         including reading and writing)",
        maps.len() - failed,
        maps.len(),
        secs,
        pixels / 1e6 / secs.max(1e-9)
    );
    if failed == 0 {
        return Ok(());
    }
    Err(failure(
        maps.len(),
        bad_maps,
        &unwritten,
        other,
        plan.out_dir,
    ))
}

/// Each map's output file (and overlay), claimed against the inputs (the maps and their yamls' images)
/// before the first map is read, their folders made.
fn claim_outputs(
    maps: &[PathBuf],
    names: &[String],
    plan: &Plan,
) -> Result<Vec<(PathBuf, Option<PathBuf>)>> {
    let ext = match plan.format {
        Format::Csv => "csv",
        Format::Json => "json",
    };
    let outputs: Vec<(PathBuf, Option<PathBuf>)> = names
        .iter()
        .map(|n| {
            (
                plan.out_dir.join(format!("{n}.{ext}")),
                plan.overlay_dir.map(|d| d.join(format!("{n}.png"))),
            )
        })
        .collect();
    let mut inputs = Inputs::new();
    for p in maps {
        inputs.add(p);
        // A yaml's image too; the yaml is read again (bounded, small) when the map loads.
        if let Some(img) = ogm_corners::map::yaml_image(p) {
            inputs.add(&img);
        }
    }
    for (file, png) in &outputs {
        inputs.claim_output(file, "--output")?;
        if let Some(png) = png {
            inputs.claim_output(png, "--overlay")?;
        }
    }
    for dir in std::iter::once(plan.out_dir).chain(plan.overlay_dir) {
        files::create_dir(dir)?;
    }
    Ok(outputs)
}

/// The batch's error when maps failed: `bad_maps` unreadable, `unwritten` outputs, `other` failures in
/// the detector, of `n`.
fn failure(n: usize, bad_maps: usize, unwritten: &[String], other: usize, out_dir: &Path) -> Error {
    let failed = bad_maps + unwritten.len() + other;
    let mut parts = Vec::new();
    if bad_maps > 0 {
        parts.push(format!("{bad_maps} could not be read"));
    }
    if let Some(first) = unwritten.first() {
        parts.push(format!(
            "{} could not be written (first: {first})",
            unwritten.len()
        ));
    }
    if other > 0 {
        parts.push(format!("{other} failed in the detector"));
    }
    let message = format!(
        "{failed} of {n} maps failed: {} (see above)",
        parts.join(", ")
    );
    // Bad maps alone are the input's fault (exit 2); outputs that could not be written are not (exit 1),
    // and "internal" is kept for failures in the detector itself.
    if failed == bad_maps {
        Error::invalid(message)
    } else if other == 0 {
        Error::output(out_dir, message)
    } else {
        Error::Internal(message)
    }
}
