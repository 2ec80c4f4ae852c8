//! `detect` over many maps: the detector (and its GPU set-up) is made once, the next map is read and
//! decoded on another thread while the current one is detected, and a progress bar runs on standard error.

use std::collections::HashSet;
use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use ogm_corners::output::{self, Format};
use ogm_corners::{overlay, Detector, Error, OccupancyMap, Result};

/// Maps decoded ahead of the detector: one waiting while one is detected bounds the memory to about three
/// maps.
const READ_AHEAD: usize = 1;

/// A file name for each map: its stem, or its folder for ROS's usual `map.yaml`, made unique with `-2`,
/// `-3`... in input order.
pub fn output_names(maps: &[PathBuf]) -> Vec<String> {
    let mut seen = HashSet::new();
    maps.iter()
        .map(|p| {
            let base = map_name(p);
            let mut name = base.clone();
            let mut n = 1;
            while !seen.insert(name.clone()) {
                n += 1;
                name = format!("{base}-{n}");
            }
            name
        })
        .collect()
}

/// A short name for a map file: its stem, or its folder's name when the stem is the generic `map`.
pub fn map_name(p: &Path) -> String {
    let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or("map");
    match (
        stem,
        p.parent()
            .and_then(|d| d.file_name())
            .and_then(|d| d.to_str()),
    ) {
        ("map", Some(dir)) => dir.to_string(),
        _ => stem.to_string(),
    }
}

/// Detects corners in every map, writing `out_dir/NAME.csv|json` (and `overlay_dir/NAME.png`), and a
/// line per map on standard output. A map that fails is reported and skipped; the call fails at the end
/// if any did.
pub fn detect_many(
    maps: &[PathBuf],
    detector: &mut Detector,
    format: Format,
    out_dir: &Path,
    overlay_dir: Option<&Path>,
) -> Result<()> {
    for dir in std::iter::once(out_dir).chain(overlay_dir) {
        fs::create_dir_all(dir).map_err(|e| Error::output(dir, e))?;
    }
    let names = output_names(maps);
    let ext = match format {
        Format::Csv => "csv",
        Format::Json => "json",
    };
    let bar = ProgressBar::new(maps.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} maps, {elapsed} (eta {eta}) {msg}")
            .expect("valid template"),
    );
    let backend = detector.backend_name();
    let options = detector.options();
    let started = Instant::now();
    let (mut failed, mut input_failures, mut keypoints, mut pixels) =
        (0usize, 0usize, 0usize, 0f64);
    let stdout = std::io::stdout();
    let mut summary = BufWriter::new(stdout.lock());
    std::thread::scope(|s| -> Result<()> {
        let (tx, rx) = mpsc::sync_channel(READ_AHEAD);
        s.spawn(move || {
            for path in maps {
                // The receiver hangs up only when the main loop stops early; then stop reading.
                if tx.send(OccupancyMap::load(path)).is_err() {
                    break;
                }
            }
        });
        for ((path, name), loaded) in maps.iter().zip(&names).zip(rx) {
            bar.set_message(name.clone());
            let result = loaded.and_then(|map| {
                for w in &map.warnings {
                    bar.suspend(|| eprintln!("ogm-corners: warning: {w}"));
                }
                let t = Instant::now();
                let det = detector.detect(&map)?;
                let ms = t.elapsed().as_secs_f64() * 1e3;
                let file = out_dir.join(format!("{name}.{ext}"));
                let f = fs::File::create(&file).map_err(|e| Error::output(&file, e))?;
                let mut w = BufWriter::new(f);
                output::write_keypoints(&mut w, format, &map, &det, &options, &backend)
                    .and_then(|_| w.flush())
                    .map_err(|e| Error::output(&file, e))?;
                if let Some(dir) = overlay_dir {
                    overlay::write_overlay(
                        &dir.join(format!("{name}.png")),
                        &map.image,
                        &det.keypoints,
                    )?;
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
                    bar.suspend(|| writeln!(summary, "{line}").and_then(|_| summary.flush()))
                        .map_err(|e| Error::output("<stdout>", e))?;
                }
                Err(e) => {
                    failed += 1;
                    input_failures += usize::from(matches!(e, Error::Input { .. }));
                    bar.suspend(|| eprintln!("ogm-corners: error: {e}"));
                }
            }
            bar.inc(1);
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    eprintln!(
        "ogm-corners: {} of {} maps done on {backend}, {keypoints} keypoints, {:.2} s ({:.0} Mpx/s \
         including reading and writing)",
        maps.len() - failed,
        maps.len(),
        secs,
        pixels / 1e6 / secs.max(1e-9)
    );
    match failed {
        0 => Ok(()),
        n if n == input_failures => Err(Error::Input {
            path: None,
            message: format!("{n} of {} maps could not be read (see above)", maps.len()),
        }),
        n => Err(Error::Internal(format!(
            "{n} of {} maps failed (see above)",
            maps.len()
        ))),
    }
}
