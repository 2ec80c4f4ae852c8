//! `ogm-corners demo`: the whole job on a synthetic building: robots explore it, each map's corners are
//! found, the maps are merged with no known poses and checked against the truth. `--detect-only`: one
//! synthetic office map, its corners, and every output `detect` writes.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use ogm_corners::detect::output::{self, Format};
use ogm_corners::detect::overlay::OverlayCanvas;
use ogm_corners::support::files::{self, AtomicFile};
use ogm_corners::support::memory::Budget;
use ogm_corners::{
    detect::overlay, detect::streamed, map::synthetic, DetectorKind, OccupancyMap, Result,
};

use super::{parse_size, write_stdout, DetectOpts};

#[derive(Args, Debug)]
pub(super) struct DemoArgs {
    /// Output folder.
    #[arg(short, long, value_name = "DIR", default_value = "demo-out")]
    pub(super) output: PathBuf,
    /// Map size, WIDTHxHEIGHT.
    #[arg(long, value_name = "WxH", default_value = "1024x768", value_parser = parse_size)]
    pub(super) size: (u32, u32),
    /// Seed of the synthetic map.
    #[arg(long, default_value_t = 1)]
    pub(super) seed: u64,
    /// Robots exploring the building.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(2..=12))]
    pub(super) robots: u32,
    /// Only the detection: one synthetic office map and its corners (no robots, no merging).
    #[arg(long)]
    pub(super) detect_only: bool,
    #[command(flatten)]
    pub(super) opts: DetectOpts,
}

/// `demo --detect-only`: one synthetic office map, its corners, and every output `detect` writes.
pub(super) fn run(a: DemoArgs, budget: &Budget) -> Result<()> {
    let (w, h) = a.size;
    let dir = &a.output;
    super::check_stdout()?;
    // Everything is checked before the folder is made or anything is allocated: the size, then the memory.
    // The map is made row by row and written; the detection then reads it back as a user's map, streamed
    // (or, for the robust detector, whole: the map, the detector's buffers, the overlay).
    let mut rows = synthetic::OfficeRows::new(w, h, a.seed)?;
    let mut detector = a.opts.detector()?;
    let streamed = detector.options().detector != DetectorKind::OgmRobust;
    let detect_bytes = if streamed {
        detector
            .streamed_bytes(w, h)
            .saturating_add(overlay::overlay_bytes(w, h))
    } else {
        synthetic::check_office_size(w, h)?;
        (u64::from(w) * u64::from(h))
            .saturating_add(detector.working_bytes(w, h))
            .saturating_add(overlay::overlay_bytes(w, h))
    };
    budget.check(
        format_args!("demo --size {w}x{h}"),
        rows.bytes().max(detect_bytes),
    )?;
    files::create_dir(dir)?;
    let pgm = dir.join("demo-map.pgm");
    let yaml = dir.join("demo-map.yaml");
    ogm_corners::map::stream::write_pgm(&pgm, &mut rows)?;
    drop(rows);
    let yaml_text = format!(
        "# Synthetic office map made by `ogm-corners demo --size {w}x{h} --seed {}`\n{}",
        a.seed,
        ogm_corners::map::map_yaml_text("demo-map.pgm", 0.05, [0.0; 3])
    );
    files::write_atomic(&yaml, |out| out.write_all(yaml_text.as_bytes()))?;
    let csv = dir.join("keypoints.csv");
    let json = dir.join("keypoints.json");
    let overlay_png = dir.join("overlay.png");
    let backend = detector.backend_name();
    let (count, elapsed, how) = if streamed {
        // Streamed from the file: the keypoint files are written as the rows are read.
        let mut map = OccupancyMap::open_rows(&yaml)?;
        let mut canvas = OverlayCanvas::new(w, h);
        let (mut csv_file, mut json_file) = (AtomicFile::create(&csv)?, AtomicFile::create(&json)?);
        let start = Instant::now();
        let mut outputs = [
            streamed::Output {
                out: &mut csv_file,
                format: Format::Csv,
                name: csv.display().to_string(),
            },
            streamed::Output {
                out: &mut json_file,
                format: Format::Json,
                name: json.display().to_string(),
            },
        ];
        let done = streamed::detect_to(&mut detector, &mut map, &mut outputs, Some(&mut canvas))?;
        let elapsed = start.elapsed();
        canvas.write(&overlay_png, &[])?;
        csv_file.commit()?;
        json_file.commit()?;
        (done.count, elapsed, "read from disk, streamed")
    } else {
        let map = OccupancyMap::load_within(&yaml, budget, &|w, h| detector.working_bytes(w, h))?;
        let start = Instant::now();
        let det = detector.detect(&map)?;
        let elapsed = start.elapsed();
        let options = detector.options();
        for (path, format) in [(&csv, Format::Csv), (&json, Format::Json)] {
            files::write_atomic(path, |out| {
                output::write_keypoints(out, format, &map, &det, &options, &backend)
            })?;
        }
        overlay::write_overlay(&overlay_png, &map.image, &det.keypoints)?;
        (det.keypoints.len() as u64, elapsed, "in memory")
    };
    let mpx = w as f64 * h as f64 / 1e6;
    let secs = elapsed.as_secs_f64();
    write_stdout(|out| {
        writeln!(
            out,
            "{count} corners in a {w}x{h} synthetic office map ({mpx:.2} Mpx) in {:.2} ms on {} ({:.0} Mpx/s, {how})",
            secs * 1e3,
            backend,
            mpx / secs.max(1e-9)
        )?;
        for p in [&yaml, &pgm, &overlay_png, &csv, &json] {
            writeln!(out, "wrote {}", p.display())?;
        }
        Ok(())
    })
}
