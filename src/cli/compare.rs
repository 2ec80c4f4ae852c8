//! `ogm-corners compare`: the paper's Table I with timings, and a contact sheet per map
//! (see [`ogm_corners::measure::compare`]).

use std::path::PathBuf;

use clap::Args;

use crate::cli::batch::output_names;

use ogm_corners::backend::reference_working_bytes;
use ogm_corners::measure::compare::ComparePage;
use ogm_corners::measure::compare::{self, CompareRecord};
use ogm_corners::support::files;
use ogm_corners::support::memory::Budget;
use ogm_corners::{
    Baseline, BaselineParams, DetectOptions, DetectorKind, OccupancyMap, Result, RuleSet,
};

use super::{write_stdout, TableFormat, ALL_DETECTORS};
use ogm_corners::measure::bench::{BenchBackend, BenchMap, Runner};

#[derive(Args, Debug)]
pub(super) struct CompareArgs {
    /// Maps (yaml or image), or folders of them (searched as `detect` searches them).
    #[arg(required = true)]
    maps: Vec<PathBuf>,
    /// Which backends to time: cpu, reference, gpu or all; comma-separated or repeated.
    #[arg(long, value_enum, value_delimiter = ',', default_values = ["cpu", "reference"])]
    backend: Vec<BenchBackend>,
    /// Folder for the table (compare.md) and the contact sheets.
    #[arg(long, value_name = "DIR", default_value = "compare-out")]
    out: PathBuf,
    /// Format of the table on standard output.
    #[arg(long, value_enum, default_value = "md")]
    format: TableFormat,
    /// Also write an HTML report into DIR: `index.html` (the table, sortable by a click on a column, and
    /// each map's contact sheet), opened from disk, no server.
    #[arg(long, value_name = "DIR")]
    html: Option<PathBuf>,
    /// Timed runs per measurement (after one warm-up), at most 1000; medians are reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
}

pub(super) fn run(a: CompareArgs, budget: &Budget) -> Result<()> {
    super::check_stdout()?;
    // Every path is checked, and no output may overwrite an input, before the first measurement.
    // The largest buffers: the reference's for Harris, plus a GPU's score readback, plus the sheet.
    let harris = DetectOptions {
        detector: DetectorKind::Baseline(Baseline::Harris),
        ..DetectOptions::default()
    };
    let extra = |w: u32, h: u32| {
        let px = u64::from(w) * u64::from(h);
        reference_working_bytes(&harris, w, h)
            .saturating_add(px.saturating_mul(8))
            .saturating_add(compare::SHEET_BYTES)
    };
    let (maps, mut inputs) = super::map_inputs(&a.maps, budget, &extra)?;
    let table_path = a.out.join("compare.md");
    inputs.claim_output(&table_path, "--out")?;
    // One sheet per map, names made unique as batch detect makes them.
    let names = output_names(&maps);
    let sheets: Vec<PathBuf> = names
        .iter()
        .map(|n| a.out.join(format!("{n}-contact-sheet.png")))
        .collect();
    for s in &sheets {
        inputs.claim_output(s, "--out")?;
    }
    if let Some(dir) = &a.html {
        inputs.claim_output(&dir.join(ogm_corners::support::report::INDEX), "--html")?;
        for (i, n) in names.iter().enumerate() {
            inputs.claim_output(&dir.join(compare::sheet_file(i, n)), "--html")?;
        }
    }
    // The same measurement as `bench` (backends checked to agree keypoint for keypoint).
    let mut runner = Runner::new(
        "compare",
        &a.backend,
        a.repeat,
        RuleSet::Paper,
        BaselineParams::default(),
    )?;
    files::create_dir(&a.out)?;
    let mut page = a.html.as_deref().map(ComparePage::create).transpose()?;
    let mut rows = Vec::new();
    for (i, ((p, name), sheet_path)) in maps.iter().zip(&names).zip(&sheets).enumerate() {
        let map = OccupancyMap::load_within(p, budget, &extra)?;
        let bm = BenchMap::from_file(p, map);
        let name = name.clone();
        let mut found = Vec::new();
        for m in runner.measure_map(&bm, &ALL_DETECTORS)? {
            let pick = |b: &str, s: &str| {
                m.records
                    .iter()
                    .find(|r| r.backend == b && r.stage == s)
                    .map(|r| r.median_ms)
            };
            rows.push(CompareRecord {
                map: name.clone(),
                width: bm.map.image.width(),
                height: bm.map.image.height(),
                detector: m.kind.name(),
                keypoints: m.keypoints.len(),
                cpu_end_to_end_ms: pick("cpu", "end_to_end"),
                reference_kernel_ms: pick("reference", "kernel"),
                reference_end_to_end_ms: pick("reference", "end_to_end"),
                gpu_kernel_ms: pick("gpu", "kernel_resident"),
                gpu_end_to_end_ms: pick("gpu", "end_to_end"),
            });
            found.push((m.kind, m.keypoints));
        }
        let sheet = compare::contact_sheet(&name, &bm.map, &found);
        files::write_png(sheet_path, &sheet)?;
        ogm_corners::say!(
            "ogm-corners: wrote {}",
            ogm_corners::support::error::one_line(&sheet_path.display().to_string())
        );
        if let Some(page) = &mut page {
            page.add_sheet(i, &name, p, &sheet)?;
        }
    }
    let md = compare::markdown(&rows);
    files::write_atomic(&table_path, |out| out.write_all(md.as_bytes()))?;
    if let Some(page) = page {
        let about = format!(
            "{} maps, {} timed runs per measurement after a warm-up (medians).",
            maps.len(),
            a.repeat
        );
        let index = page.finish(&rows, &about)?;
        ogm_corners::say!(
            "ogm-corners: wrote {}",
            ogm_corners::support::error::one_line(&index.display().to_string())
        );
    }
    write_stdout(|out| compare::write_table(out, a.format.into(), &rows))
}
