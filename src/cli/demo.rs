//! `ogm-corners demo`: a synthetic office map, its corners, and every output the tool writes.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use ogm_corners::files;
use ogm_corners::memory::Budget;
use ogm_corners::output::{self, Format};
use ogm_corners::{overlay, synth, OccupancyMap, Result};

use super::{parse_size, write_stdout, DetectOpts};

#[derive(Args, Debug)]
pub(super) struct DemoArgs {
    /// Output folder.
    #[arg(short, long, value_name = "DIR", default_value = "demo-out")]
    output: PathBuf,
    /// Map size, WIDTHxHEIGHT.
    #[arg(long, value_name = "WxH", default_value = "1024x768", value_parser = parse_size)]
    size: (u32, u32),
    /// Seed of the synthetic map.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    opts: DetectOpts,
}

pub(super) fn run(a: DemoArgs, budget: &Budget) -> Result<()> {
    let (w, h) = a.size;
    let dir = &a.output;
    super::check_stdout()?;
    // Everything is checked before the folder is made or anything is allocated: the size, then the memory
    // (the map, once: it is written, dropped and read back; the detector's buffers; the overlay).
    synth::check_office_size(w, h)?;
    let mut detector = a.opts.detector()?;
    let px = u64::from(w) * u64::from(h);
    budget.check(
        format_args!("demo --size {w}x{h}"),
        px.saturating_add(detector.working_bytes(w, h))
            .saturating_add(overlay::overlay_bytes(w, h)),
    )?;
    let image = synth::office_map(w, h, a.seed)?;
    files::create_dir(dir)?;
    let pgm = dir.join("demo-map.pgm");
    let yaml = dir.join("demo-map.yaml");
    image.write_pgm(&pgm)?;
    drop(image);
    let yaml_text = format!(
        "# Synthetic office map made by `ogm-corners demo --size {w}x{h} --seed {}`\n{}",
        a.seed,
        ogm_corners::map::map_yaml_text("demo-map.pgm", 0.05, [0.0; 3])
    );
    files::write_atomic(&yaml, |out| out.write_all(yaml_text.as_bytes()))?;
    // Load it back as a user's map would be, so the demo runs the whole path.
    let map = OccupancyMap::load_within(&yaml, budget, &|w, h| detector.working_bytes(w, h))?;
    let start = Instant::now();
    let det = detector.detect(&map)?;
    let elapsed = start.elapsed();
    let csv = dir.join("keypoints.csv");
    let json = dir.join("keypoints.json");
    let overlay_png = dir.join("overlay.png");
    let options = detector.options();
    let backend = detector.backend_name();
    for (path, format) in [(&csv, Format::Csv), (&json, Format::Json)] {
        files::write_atomic(path, |out| {
            output::write_keypoints(out, format, &map, &det, &options, &backend)
        })?;
    }
    overlay::write_overlay(&overlay_png, &map.image, &det.keypoints)?;
    let mpx = w as f64 * h as f64 / 1e6;
    let secs = elapsed.as_secs_f64();
    write_stdout(|out| {
        writeln!(
            out,
            "{} corners in a {w}x{h} synthetic office map ({mpx:.2} Mpx) in {:.2} ms on {} ({:.0} Mpx/s)",
            det.keypoints.len(),
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
