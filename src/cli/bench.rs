//! `ogm-corners bench`: median times of every detector on every backend, on synthetic maps of several sizes
//! and on real maps, with the peak memory of the CPU backends. `compare` shares the measurement
//! ([`ogm_corners::measure::bench::Runner::measure_map`]).

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};

use ogm_corners::backend::gpu::GpuOptions;
use ogm_corners::backend::reference_working_bytes;
use ogm_corners::map::synthetic;
use ogm_corners::support::files::{self, Inputs};
use ogm_corners::support::memory::Budget;
use ogm_corners::{Baseline, DetectOptions, DetectorKind, Error, OccupancyMap, Result};

use crate::cli::batch::map_name;

use super::{parse_size, write_stdout, BaselineArgs, RulesArg, TextOrJson, ALL_DETECTORS};

use ogm_corners::measure::bench::{
    cpu_model, threads, BenchBackend, BenchMap, BenchRecord, Runner, GIT_COMMIT,
};

/// Which detectors `bench` times; a comma-separated list, or the option repeated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(super) enum DetectorChoice {
    /// The OGM corner detector of the paper.
    Ogm,
    /// The robust OGM detector.
    OgmRobust,
    /// Harris.
    Harris,
    /// Shi-Tomasi.
    ShiTomasi,
    /// Trajkovic-Hedley.
    Trajkovic,
    /// All five.
    All,
}

#[derive(Args, Debug)]
pub(super) struct BenchArgs {
    /// Maps to measure: .yaml or image files, or folders (searched recursively for every .yaml map and
    /// every .pgm/.png image that no yaml there names).
    maps: Vec<PathBuf>,
    /// A synthetic office map of WIDTHxHEIGHT; repeat for several. Without maps or sizes: 4096x4096. The
    /// full set: --size 1024x1024 --size 4096x4096 --size 16384x16384.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    size: Vec<(u32, u32)>,
    /// Seed of the synthetic maps.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Detectors: ogm, ogm-robust, harris, shi-tomasi, trajkovic or all; comma-separated or repeated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "ogm")]
    detector: Vec<DetectorChoice>,
    /// Backends: cpu, reference, gpu or all; comma-separated or repeated (e.g. --backend cpu,gpu).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "all")]
    backend: Vec<BenchBackend>,
    /// Timed runs per measurement (after one warm-up run), at most 1000; the median is reported.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
    /// Rule reading (OGM detector).
    #[arg(long, value_enum, default_value = "paper")]
    rules: RulesArg,
    /// The GPU's peak memory bandwidth in GB/s, which kernel_resident is reported against (known GPUs,
    /// such as the H200's 4800, need none).
    #[arg(long, value_name = "GB/s", value_parser = parse_bandwidth)]
    peak_bandwidth: Option<f64>,
    /// Also time a plain read of each map's bytes on all threads (the widest vector loads, before and
    /// after its detectors), and report every CPU record as a share of that read bandwidth (`% read`):
    /// how close a detector comes to the speed of memory.
    #[arg(long)]
    bandwidth: bool,
    /// GPU tuning: rows each OGM invocation walks down (1 to 16) instead of the backend's choice.
    #[arg(long, value_name = "ROWS", value_parser = clap::value_parser!(u32).range(1..=16))]
    gpu_strip_rows: Option<u32>,
    /// GPU tuning: copy each staged band into a device buffer before the kernel reads it, even where the
    /// kernel could read the staging buffer in place.
    #[arg(long)]
    gpu_copy_bands: bool,
    #[command(flatten)]
    baseline: BaselineArgs,
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    format: TextOrJson,
    /// Also write each synthetic map as a binary PGM, so other tools can time the same pixels: to PATH
    /// itself when it ends in .pgm (one --size), else into the folder PATH as synthetic-WxH-seedN.pgm. The
    /// records name the file (`image`).
    #[arg(long, value_name = "PATH")]
    save_map: Option<PathBuf>,
    /// Only write the synthetic map of the one --size to FILE (a binary PGM) and measure nothing: made
    /// and written row by row, so any size works (a 100000x100000 map is a 10 GB file); for timing
    /// `detect` on maps larger than memory.
    #[arg(long, value_name = "FILE", conflicts_with = "save_map")]
    write_map: Option<PathBuf>,
}

/// A map to load when its turn comes (so only one is in memory at a time).
enum Source {
    Synthetic(u32, u32),
    File(PathBuf),
}

fn ext_of(p: &Path) -> String {
    p.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Where `--save-map` writes each synthetic map.
fn save_paths(
    save: Option<&Path>,
    sizes: &[(u32, u32)],
    seed: u64,
) -> Result<Vec<Option<PathBuf>>> {
    let Some(save) = save else {
        return Ok(vec![None; sizes.len()]);
    };
    if sizes.is_empty() {
        return Err(Error::invalid(
            "--save-map writes synthetic maps: give a --size",
        ));
    }
    if ext_of(save) == "pgm" {
        if sizes.len() > 1 {
            return Err(Error::invalid(format!(
                "--save-map {} names one file but there are {} sizes; give a folder",
                save.display(),
                sizes.len()
            )));
        }
        return Ok(vec![Some(save.to_path_buf())]);
    }
    files::create_dir(save)?;
    Ok(sizes
        .iter()
        .map(|(w, h)| Some(save.join(format!("synthetic-{w}x{h}-seed{seed}.pgm"))))
        .collect())
}

/// The detectors named, in the usual order, each once.
fn detector_list(choice: &[DetectorChoice]) -> Vec<DetectorKind> {
    ALL_DETECTORS
        .into_iter()
        .filter(|k| {
            choice.iter().any(|c| match c {
                DetectorChoice::All => true,
                DetectorChoice::Ogm => *k == DetectorKind::Ogm,
                DetectorChoice::OgmRobust => *k == DetectorKind::OgmRobust,
                DetectorChoice::Harris => *k == DetectorKind::Baseline(Baseline::Harris),
                DetectorChoice::ShiTomasi => *k == DetectorKind::Baseline(Baseline::ShiTomasi),
                DetectorChoice::Trajkovic => *k == DetectorKind::Baseline(Baseline::Trajkovic),
            })
        })
        .collect()
}

/// What `bench --format json` prints: the machine and build, then the records.
#[derive(serde::Serialize)]
struct BenchReport<'a> {
    version: &'static str,
    commit: &'static str,
    cpu: String,
    threads: usize,
    os: &'static str,
    arch: &'static str,
    /// The instruction set the fast CPU kernels ran on (`OGM_CORNERS_ISA` caps it).
    isa: &'static str,
    gpu: Option<&'a str>,
    repeat: u32,
    records: &'a [BenchRecord],
}

/// The most any detector of `kinds` allocates on any backend for a `w` x `h` map, beyond the map: the
/// reference's full-size buffers, and a GPU's score readback (8 bytes a pixel) for the baselines.
fn bench_bytes(kinds: &[DetectorKind], w: u32, h: u32) -> u64 {
    let px = u64::from(w) * u64::from(h);
    kinds
        .iter()
        .map(|&detector| {
            let options = DetectOptions {
                detector,
                ..DetectOptions::default()
            };
            reference_working_bytes(&options, w, h).saturating_add(match detector {
                DetectorKind::Ogm | DetectorKind::OgmRobust => 0,
                DetectorKind::Baseline(_) => px.saturating_mul(8),
            })
        })
        .max()
        .unwrap_or(0)
}

/// A bandwidth in GB/s: a positive finite number.
fn parse_bandwidth(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("expected a positive number of GB/s, got {s:?}")),
    }
}

/// `--write-map`: the synthetic map of the one size, row by row to a file.
fn write_map(a: &BenchArgs, path: &Path, budget: &Budget) -> Result<()> {
    let &[(w, h)] = a.size.as_slice() else {
        return Err(Error::invalid(
            "--write-map writes one synthetic map: give one --size",
        ));
    };
    if !a.maps.is_empty() {
        return Err(Error::invalid(
            "--write-map writes a synthetic map: give no maps",
        ));
    }
    let mut rows = synthetic::OfficeRows::new(w, h, a.seed)?;
    budget.check(
        format_args!("bench --write-map --size {w}x{h}"),
        rows.bytes(),
    )?;
    ogm_corners::map::stream::write_pgm(path, &mut rows)
}

pub(super) fn bench(a: BenchArgs, budget: &Budget) -> Result<()> {
    if let Some(path) = &a.write_map {
        return write_map(&a, path, budget);
    }
    let kinds = detector_list(&a.detector);
    let sizes = if a.maps.is_empty() && a.size.is_empty() {
        vec![(4096, 4096)]
    } else {
        a.size.clone()
    };
    super::check_stdout()?;
    // Every size and path is checked before anything is printed or measured.
    check_sizes(&sizes, &kinds, budget)?;
    let mut inputs = Inputs::new();
    let (sources, mut problems) = sources_of(&a.maps, &sizes, &mut inputs)?;
    let saves = save_paths(a.save_map.as_deref(), &sizes, a.seed)?;
    for s in saves.iter().flatten() {
        inputs.claim_output(s, "--save-map")?;
    }
    // One a size, in the order the synthetic sources come.
    let mut saves = saves.into_iter();
    let mut runner = Runner::new(
        "bench",
        &a.backend,
        a.repeat,
        a.rules.into(),
        a.baseline.params(),
    )?;
    runner.set_peak_bandwidth(a.peak_bandwidth);
    runner.set_gpu_options(GpuOptions {
        strip_rows: a.gpu_strip_rows,
        copy_bands: a.gpu_copy_bands,
        ..GpuOptions::default()
    })?;
    let label_w = sources
        .iter()
        .map(|s| match s {
            Source::Synthetic(..) => "synthetic".len(),
            Source::File(p) => map_name(p).len(),
        })
        .max()
        .unwrap_or(0)
        .max(3);
    let text = a.format == TextOrJson::Text;
    if text {
        print_header(&runner, &a, !sizes.is_empty(), label_w)?;
    }
    let mut all = Vec::new();
    for src in sources {
        let bm = match src {
            Source::Synthetic(w, h) => synthetic_map(w, h, a.seed, saves.next().flatten())?,
            Source::File(p) => {
                match OccupancyMap::load_within(&p, budget, &|w, h| bench_bytes(&kinds, w, h)) {
                    Ok(map) => BenchMap::from_file(&p, map),
                    // One bad map does not end the measurement of the others; the run fails at the end.
                    Err(e) => {
                        ogm_corners::say!("ogm-corners: error: {e}");
                        problems += 1;
                        continue;
                    }
                }
            }
        };
        let records = measure(&mut runner, bm, &kinds, a.bandwidth)?;
        if text {
            print_records(&records, label_w)?;
        } else {
            all.extend(records);
        }
    }
    if !text {
        write_json(&runner, a.repeat, &all)?;
    }
    match problems {
        0 => Ok(()),
        // A problem is a map that could not be read, or a folder with none: said above, each.
        1 => Err(Error::invalid(
            "1 input could not be used and was skipped (see above); the others were measured",
        )),
        n => Err(Error::invalid(format!(
            "{n} inputs could not be used and were skipped (see above); the others were measured"
        ))),
    }
}

/// Each synthetic size is one the generator draws, within the memory budget with its detectors.
fn check_sizes(sizes: &[(u32, u32)], kinds: &[DetectorKind], budget: &Budget) -> Result<()> {
    for &(w, h) in sizes {
        synthetic::check_office_size(w, h)?;
        let px = u64::from(w) * u64::from(h);
        budget.check(
            format_args!("bench --size {w}x{h}"),
            px.saturating_add(bench_bytes(kinds, w, h)),
        )?;
    }
    Ok(())
}

/// The sizes' synthetic maps, then every map file of `paths` (folders searched), each read up to its
/// header; with the number of inputs that could not be used (each said on standard error).
fn sources_of(
    paths: &[PathBuf],
    sizes: &[(u32, u32)],
    inputs: &mut Inputs,
) -> Result<(Vec<Source>, usize)> {
    let mut sources: Vec<Source> = sizes
        .iter()
        .map(|&(w, h)| Source::Synthetic(w, h))
        .collect();
    let mut problems = 0;
    for p in paths {
        if p.is_dir() {
            let found = ogm_corners::map::find_maps(std::slice::from_ref(p));
            for n in found.notes {
                ogm_corners::say!("ogm-corners: note: {n}");
            }
            for n in &found.problems {
                ogm_corners::say!("ogm-corners: error: {n}");
            }
            problems += found.problems.len();
            for m in &found.maps {
                inputs.add(m);
            }
            sources.extend(found.maps.into_iter().map(Source::File));
        } else if p.exists() {
            inputs.add(p);
            sources.push(Source::File(p.clone()));
        } else {
            return Err(Error::input(p, "no such file or folder"));
        }
    }
    // Every map file read up to its header before the first measurement: a bad one is reported (and left
    // out) now, and the image a yaml names is protected from --save-map like the yaml itself.
    sources.retain(|src| match src {
        Source::Synthetic(..) => true,
        Source::File(p) => match OccupancyMap::probe(p) {
            Ok((_, _, image)) => {
                inputs.add(&image);
                true
            }
            Err(e) => {
                ogm_corners::say!("ogm-corners: error: {e}");
                problems += 1;
                false
            }
        },
    });
    if sources.is_empty() {
        return Err(Error::invalid("no maps to measure (see above)"));
    }
    Ok((sources, problems))
}

/// A synthetic office map of `w` x `h`, written to `saved` when given (`--save-map`).
fn synthetic_map(w: u32, h: u32, seed: u64, saved: Option<PathBuf>) -> Result<BenchMap> {
    // Large maps are drawn on all threads so that making them does not dominate the run.
    let image = if u64::from(w) * u64::from(h) > synthetic::PARALLEL_PIXELS {
        synthetic::office_map_parallel(w, h, seed)?
    } else {
        synthetic::office_map(w, h, seed)?
    };
    if let Some(p) = &saved {
        image.write_pgm(p)?;
        ogm_corners::say!(
            "ogm-corners: bench: wrote {}",
            ogm_corners::support::error::one_line(&p.display().to_string())
        );
    }
    Ok(BenchMap {
        label: "synthetic".to_string(),
        source: None,
        image_path: saved,
        map: OccupancyMap::from_image(image),
    })
}

/// Every record of one map, with `--bandwidth` the plain read first; the map is dropped after, so only
/// one is in memory at a time.
fn measure(
    runner: &mut Runner,
    bm: BenchMap,
    kinds: &[DetectorKind],
    bandwidth: bool,
) -> Result<Vec<BenchRecord>> {
    let before = bandwidth.then(|| runner.read_times(&bm));
    let mut records: Vec<BenchRecord> = runner
        .measure_map(&bm, kinds)?
        .into_iter()
        .flat_map(|m| m.records)
        .collect();
    if let Some(before) = before {
        let after = runner.read_times(&bm);
        let read = runner.read_record(&bm, &[before, after], &mut records);
        records.insert(0, read);
    }
    Ok(records)
}

/// The text table's header: the machine and build, then the column names.
fn print_header(runner: &Runner, a: &BenchArgs, synthetic: bool, label_w: usize) -> Result<()> {
    let mut lines = runner.header(synthetic.then_some(a.seed));
    if a.bandwidth {
        lines.push(format!(
            "# read: a plain read of the map's bytes on all threads ({} loads), timed before and after its \
             detectors; % read: a CPU record's pixels a second (one byte each) over the read's bytes a second",
            ogm_corners::backend::fast::simd::Isa::best().name()
        ));
    }
    lines.push(format!(
        "{:<label_w$}  {:<11}  {:<10}  {:<9}  {:<15}  {:>10}  {:>9}  {:>9}  {:>9}  {:>6}  {:>8}  {:>8}  {:>6}  {:>6}  {:>7}  {:>6}  {:>6}  {:>10}",
        "map",
        "size",
        "detector",
        "backend",
        "stage",
        "median ms",
        "Mpx/s",
        "keypoints",
        "peak MB",
        "x map",
        "start MB",
        "GB/s",
        "% peak",
        "x ref",
        "x floor",
        "% read",
        "passes",
        "dispatches"
    ));
    write_stdout(|out| {
        for l in &lines {
            writeln!(out, "{l}")?;
        }
        out.flush()
    })
}

/// One map's records as rows of the text table.
fn print_records(records: &[BenchRecord], label_w: usize) -> Result<()> {
    let f = |v: Option<f64>, p: usize| v.map_or("-".to_string(), |v| format!("{v:.p$}"));
    let n = |v: Option<usize>| v.map_or("-".to_string(), |v| v.to_string());
    write_stdout(|out| {
        for r in records {
            writeln!(
                out,
                "{:<label_w$}  {:<11}  {:<10}  {:<9}  {:<15}  {:>10.3}  {:>9.1}  {:>9}  {:>9}  {:>6}  {:>8}  {:>8}  {:>6}  {:>6}  {:>7}  {:>6}  {:>6}  {:>10}",
                r.map,
                format!("{}x{}", r.width, r.height),
                r.detector,
                r.backend,
                r.stage,
                r.median_ms,
                r.mpx_per_s,
                r.keypoints,
                f(r.peak_rss_mb, 1),
                f(r.peak_rss_ratio, 2),
                f(r.rss_before_mb, 1),
                f(r.gb_per_s, 2),
                f(r.peak_percent, 1),
                f(r.vs_upload_ref, 2),
                f(r.vs_transfer_floor, 2),
                f(r.read_percent, 1),
                n(r.write_passes),
                n(r.dispatches)
            )?;
        }
        out.flush()
    })
}

/// Every map's records as one JSON report with the machine and the build.
fn write_json(runner: &Runner, repeat: u32, all: &[BenchRecord]) -> Result<()> {
    let report = BenchReport {
        version: env!("CARGO_PKG_VERSION"),
        commit: GIT_COMMIT,
        cpu: cpu_model(),
        threads: threads(),
        os: std::env::consts::OS,
        arch: std::env::consts::ARCH,
        isa: ogm_corners::backend::fast::simd::Isa::active().name(),
        gpu: runner.gpu_label(),
        repeat,
        records: all,
    };
    write_stdout(|out| {
        serde_json::to_writer_pretty(&mut *out, &report)?;
        writeln!(out)?;
        out.flush()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detector_list_is_ordered_and_unique() {
        use DetectorChoice::*;
        assert_eq!(detector_list(&[All, Ogm]), ALL_DETECTORS.to_vec());
        assert_eq!(
            detector_list(&[Trajkovic, Ogm, Trajkovic]),
            [
                DetectorKind::Ogm,
                DetectorKind::Baseline(Baseline::Trajkovic)
            ]
        );
    }
}
