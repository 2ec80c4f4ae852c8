//! A map detected from its file in constant memory: rows streamed through the detector
//! ([`Detector::detect_streamed`]), keypoints written as they come, and the overlay drawn downsampled on
//! the way.
//!
//! Step by step: `OccupancyMap::open_rows` reads the yaml and the image header only;
//! `check_streamed_budget` counts the windows, the backend's buffers, the decoder's and the overlay's
//! against the memory budget (shrinking the windows if that is enough); then `detect_to` calls
//! `Detector::detect_streamed`, which cuts the rows into windows (`map::stream::for_each_window`: a core
//! and a halo, the next window read while one is detected) and hands each to the backend
//! (`Backend::detect_rows` for the OGM detector, `Backend::baseline_rows` for the baselines). OGM
//! keypoints go to the output (`output::KeypointWriter`) window by window; the baselines' candidates are
//! collected in a `baselines::streamed::CandidateList` and selected once the map's maximum is known. The
//! overlay (`overlay::OverlayCanvas`) is drawn downsampled as the rows pass. The command line writes the
//! keypoint file to a temporary file (`support::files::AtomicFile`), renamed into place only when complete.

use std::io::Write;

use crate::detect::detector::{Detector, DetectorKind, Streamed};
use crate::detect::output::{About, Format, KeypointWriter};
use crate::detect::overlay::{overlay_bytes, OverlayCanvas};
use crate::map::states::ClassTable;
use crate::map::MapRows;
use crate::support::error::{Error, Result};
use crate::support::memory::Budget;

/// Checks that streaming `map` through `detector` (with an overlay when `overlay`) fits `budget`, making its
/// windows smaller when that is enough: the windows in flight and the backend's buffers for one, the
/// decoder's buffers (a whole frame for an interlaced PNG, which cannot be read row by row), and the
/// overlay's downsampled picture. The keypoints come on top: for the baselines, which select them at the
/// end, their candidates (16 bytes each) and the selection's lists; none for the OGM detector, whose
/// keypoints are written as they come.
pub fn check_streamed_budget(
    detector: &mut Detector,
    map: &MapRows,
    overlay: bool,
    budget: &Budget,
) -> Result<()> {
    let (w, h) = map.size();
    let overlay = if overlay { overlay_bytes(w, h) } else { 0 };
    let need = |d: &Detector| {
        d.streamed_bytes(w, h)
            .saturating_add(map.decoder_bytes())
            .saturating_add(overlay)
    };
    // A tight limit gets smaller windows (down to a megabyte, or the fewest rows), not a refusal: the
    // keypoints are the same for every window size. The robust detector's tile window takes what is left
    // of half the limit: the corners its windows report come on top (about one a keypoint, 64 bytes, and
    // as much again for the whole map's suppression at the end: 290 thousand on a 30000^2 office map),
    // with the allocator's slack.
    if detector.options().detector == DetectorKind::OgmRobust {
        let window = detector.window_bytes().max(1);
        let others = need(detector).saturating_sub(window.min(need(detector)));
        let room = (budget.limit() / 2).saturating_sub(others);
        detector.set_window_bytes(Some(room.clamp(1, window)));
    }
    while need(detector) > budget.limit() && detector.window_bytes() > 1 << 20 {
        let smaller = detector.window_bytes() / 2;
        detector.set_window_bytes(Some(smaller));
    }
    let need = need(detector);
    if map.holds_whole_image() && need > budget.limit() {
        return Err(Error::input(
            &map.image_path,
            format!(
                "an interlaced (Adam7) PNG cannot be read row by row: decoding this {w}x{h} image holds all of it ({} bytes), above the memory limit of {} bytes; save it without interlacing",
                map.decoder_bytes(),
                budget.limit()
            ),
        ));
    }
    budget
        .check(format_args!("streaming a {w}x{h} map"), need)
        .map_err(|e| match e {
            Error::Input {
                path: None,
                message,
            } => Error::input(map.source_path(), message),
            other => other,
        })
}

/// One keypoint file written while streaming.
pub struct Output<'a> {
    /// Where it goes.
    pub out: &'a mut dyn Write,
    /// In which format.
    pub format: Format,
    /// Its name in messages.
    pub name: String,
}

/// Streams `map` through `detector`, writing its keypoints to every one of `outputs` as they come, and
/// drawing the map and its keypoints on `canvas` when given.
pub fn detect_to(
    detector: &mut Detector,
    map: &mut MapRows,
    outputs: &mut [Output],
    canvas: Option<&mut OverlayCanvas>,
) -> Result<Streamed> {
    let (w, h) = map.size();
    let about = About {
        map: Some(map.source_path().display().to_string()),
        width: w,
        height: h,
        georef: map.georef,
        options: detector.options(),
        backend: detector.backend_name(),
        angle_deg: None,
        anchor_px: None,
    };
    let classes = ClassTable::new(&map.thresholds);
    // Both callbacks draw on the canvas (rows, then marks), one at a time.
    let canvas = std::cell::RefCell::new(canvas);
    let mut on_rows = |rows: crate::map::stream::Rows, core: (usize, usize)| {
        if let Some(c) = canvas.borrow_mut().as_deref_mut() {
            c.add_rows(rows, core);
        }
    };
    if detector.options().detector == DetectorKind::OgmRobust {
        // Its keypoints come at the end, with the angle the file's header names.
        let mut found = Vec::new();
        let done = detector.detect_streamed(
            &mut map.source,
            &classes,
            map.georef.as_ref(),
            &mut |k| {
                found.extend_from_slice(k);
                Ok(())
            },
            &mut on_rows,
        )?;
        let about = About {
            angle_deg: done.robust.map(|r| r.angle),
            anchor_px: done.robust.map(|r| [r.anchor.0, r.anchor.1]),
            ..about
        };
        let mut writers = begin(outputs, &about)?;
        if let Some(c) = canvas.borrow_mut().as_deref_mut() {
            c.mark(&found);
        }
        for (w, name) in writers.iter_mut() {
            w.push(&found).map_err(|e| Error::write(&*name, e))?;
        }
        end(writers)?;
        return Ok(done);
    }
    let mut writers = begin(outputs, &about)?;
    let done = detector.detect_streamed(
        &mut map.source,
        &classes,
        map.georef.as_ref(),
        &mut |k| {
            if let Some(c) = canvas.borrow_mut().as_deref_mut() {
                c.mark(k);
            }
            for (w, name) in writers.iter_mut() {
                w.push(k).map_err(|e| Error::write(&*name, e))?;
            }
            Ok(())
        },
        &mut on_rows,
    )?;
    end(writers)?;
    Ok(done)
}

/// Begins a keypoint file on every output.
fn begin<'a>(
    outputs: &'a mut [Output],
    about: &About,
) -> Result<Vec<(KeypointWriter<'a>, String)>> {
    let mut writers = Vec::with_capacity(outputs.len());
    for o in outputs.iter_mut() {
        let name = o.name.clone();
        let w = KeypointWriter::begin(&mut *o.out, o.format, about)
            .map_err(|e| Error::write(&name, e))?;
        writers.push((w, name));
    }
    Ok(writers)
}

/// Ends every keypoint file.
fn end(writers: Vec<(KeypointWriter<'_>, String)>) -> Result<()> {
    for (w, name) in writers {
        w.end().map_err(|e| Error::write(&name, e))?;
    }
    Ok(())
}
