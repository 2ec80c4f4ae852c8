//! The `ogm-corners` command line.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::time::Instant;

use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::batch::{self, map_name};

use ogm_corners::cpu::CpuBackend;
use ogm_corners::gpu::{self, GpuBackend, GpuOptions};
use ogm_corners::output::{self, Format};
use ogm_corners::overlay;
use ogm_corners::rules::code_picture;
use ogm_corners::synth;
use ogm_corners::{
    Baseline, BaselineParams, ClassTable, DetectOptions, Detector, DetectorKind, Error,
    OccupancyMap, Result, RuleSet, RuleTable,
};

/// Finds corners in robot occupancy grid maps with the OGM corner detector.
#[derive(Parser, Debug)]
#[command(name = "ogm-corners", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Detect corners in a map (a ROS map_server .yaml, or a PGM/PNG image).
    Detect(DetectArgs),
    /// Generate a synthetic office map, detect its corners, write map, overlay and keypoints.
    Demo(DemoArgs),
    /// Print the rule table: the accepted 8-neighbour codes and the rule that accepts each.
    Rules(RulesArgs),
    /// List the GPU adapters wgpu finds (WGPU_BACKEND and WGPU_ADAPTER_NAME select among them).
    Info(InfoArgs),
    /// Measure every detector on every backend (end to end, kernels, upload; peak memory of the CPU
    /// backends), median of repeats, on synthetic maps of several sizes and on real maps.
    Bench(bench::BenchArgs),
    /// Repeatability of every detector under known transforms: exact turns and mirror, rotations with
    /// translation, SLAM-like noise, partial overlap.
    Eval(EvalArgs),
    /// The paper's Table I with timings: every detector's keypoint count and median times per backend on
    /// each map, and a contact sheet PNG per map.
    Compare(CompareArgs),
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum RulesArg {
    /// The paper's "mod(...) = 0" read as mod 3 (44 codes).
    Paper,
    /// The same read as mod 2 (36 codes).
    PaperMod2,
}

impl From<RulesArg> for RuleSet {
    fn from(r: RulesArg) -> Self {
        match r {
            RulesArg::Paper => RuleSet::Paper,
            RulesArg::PaperMod2 => RuleSet::PaperMod2,
        }
    }
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum BackendArg {
    /// A hardware GPU adapter when there is one, else the CPU (says which on standard error).
    Auto,
    /// The fast CPU path: all cores, bit-planes and SIMD.
    Cpu,
    /// The plain single-threaded CPU reference, the oracle the other backends are tested against.
    Reference,
    /// A GPU adapter through wgpu (software adapters such as lavapipe included); fails without one.
    Gpu,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum FormatArg {
    Csv,
    Json,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum DetectorArg {
    /// The OGM corner detector of the paper.
    Ogm,
    /// Harris (Gaussian blur, Sobel, structure tensor, k; OpenCV's cornerHarris).
    Harris,
    /// Shi-Tomasi (minimum eigenvalue, OpenCV's goodFeaturesToTrack selection).
    ShiTomasi,
    /// Trajkovic-Hedley, 4-neighbour, two resolutions.
    Trajkovic,
}

impl From<DetectorArg> for DetectorKind {
    fn from(d: DetectorArg) -> Self {
        match d {
            DetectorArg::Ogm => DetectorKind::Ogm,
            DetectorArg::Harris => DetectorKind::Baseline(Baseline::Harris),
            DetectorArg::ShiTomasi => DetectorKind::Baseline(Baseline::ShiTomasi),
            DetectorArg::Trajkovic => DetectorKind::Baseline(Baseline::Trajkovic),
        }
    }
}

/// The baselines' options; defaults are the paper's configuration.
#[derive(Args, Debug, Clone)]
struct BaselineArgs {
    /// Gaussian sigma of the 3x3 blur before Harris and Shi-Tomasi.
    #[arg(long, default_value_t = 1.0)]
    sigma: f64,
    /// Harris k (at most three decimals).
    #[arg(long, default_value_t = 0.04)]
    harris_k: f64,
    /// Harris and Shi-Tomasi quality level (fraction of the strongest response).
    #[arg(long, default_value_t = 0.01)]
    quality: f64,
    /// Shi-Tomasi minimum distance between keypoints, pixels.
    #[arg(long, default_value_t = 3.0)]
    min_distance: f64,
    /// Shi-Tomasi maximum number of keypoints, strongest first (default: all).
    #[arg(long)]
    max_corners: Option<usize>,
    /// Trajkovic low-resolution threshold T1 (squared grey levels).
    #[arg(long, default_value_t = 10_000)]
    t1: u32,
    /// Trajkovic full-resolution threshold T2 (squared grey levels).
    #[arg(long, default_value_t = 20_000)]
    t2: u32,
}

impl BaselineArgs {
    fn params(&self) -> BaselineParams {
        BaselineParams {
            sigma: self.sigma,
            harris_k: self.harris_k,
            quality: self.quality,
            min_distance: self.min_distance,
            max_corners: self.max_corners,
            t1: self.t1,
            t2: self.t2,
        }
    }
}

#[derive(Args, Debug)]
struct DetectOpts {
    /// Which detector.
    #[arg(long, value_enum, default_value = "ogm")]
    detector: DetectorArg,
    #[command(flatten)]
    baseline: BaselineArgs,
    /// Which reading of the paper's rules to use (OGM detector).
    #[arg(long, value_enum, default_value = "paper")]
    rules: RulesArg,
    /// Count unknown neighbours as occupied.
    #[arg(long)]
    unknown_as_occupied: bool,
    /// Where to run the detector.
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
}

impl DetectOpts {
    fn options(&self) -> DetectOptions {
        DetectOptions {
            detector: self.detector.into(),
            baseline: self.baseline.params(),
            rules: self.rules.into(),
            unknown_as_occupied: self.unknown_as_occupied,
        }
    }

    fn detector(&self) -> Result<Detector> {
        detector_on(self.backend, self.options())
    }
}

/// A detector with `options` on the backend the user chose (auto says which on standard error).
fn detector_on(backend: BackendArg, options: DetectOptions) -> Result<Detector> {
    Ok(match backend {
        BackendArg::Cpu => Detector::new(options),
        BackendArg::Reference => Detector::with_backend(options, Box::new(CpuBackend)),
        BackendArg::Gpu => {
            Detector::with_backend(options, Box::new(GpuBackend::new(GpuOptions::default())?))
        }
        BackendArg::Auto => match GpuBackend::open(true, GpuOptions::default()) {
            Ok(Some(g)) => {
                eprintln!(
                    "ogm-corners: backend: gpu ({}, {})",
                    g.adapter().name,
                    g.adapter().backend
                );
                Detector::with_backend(options, Box::new(g))
            }
            Ok(None) => {
                eprintln!("ogm-corners: backend: cpu (no hardware GPU adapter found; --backend gpu accepts software ones)");
                Detector::new(options)
            }
            Err(e @ Error::Input { .. }) => return Err(e),
            Err(e) => {
                eprintln!("ogm-corners: backend: cpu (the GPU could not be opened: {e})");
                Detector::new(options)
            }
        },
    })
}

#[derive(Args, Debug)]
struct DetectArgs {
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

#[derive(Args, Debug)]
struct DemoArgs {
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

#[derive(Clone, Copy, Debug, ValueEnum)]
enum RulesFormat {
    Text,
    Csv,
}

#[derive(Args, Debug)]
struct RulesArgs {
    /// Which reading of the paper's rules to print.
    #[arg(long, value_enum, default_value = "paper")]
    rules: RulesArg,
    /// Output format: text with a picture of each code, or CSV `code,rule`.
    #[arg(long, value_enum, default_value = "text")]
    format: RulesFormat,
    /// Only one code per rotation class (the smallest), as pictured in the README.
    #[arg(long)]
    canonical: bool,
}

/// Parses `WIDTHxHEIGHT`.
fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, got `{s}`"))?;
    let w: u32 = w.trim().parse().map_err(|_| format!("bad width `{w}`"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("bad height `{h}`"))?;
    if w == 0 || h == 0 {
        return Err(format!("zero-size map {w}x{h}"));
    }
    Ok((w, h))
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Detect(a) => detect(a),
        Command::Demo(a) => demo(a),
        Command::Rules(a) => rules(a),
        Command::Info(a) => info(a),
        Command::Bench(a) => bench::bench(a),
        Command::Eval(a) => eval(a),
        Command::Compare(a) => compare(a),
    }
}

fn detect(a: DetectArgs) -> Result<()> {
    let format = match a.format {
        FormatArg::Csv => Format::Csv,
        FormatArg::Json => Format::Json,
    };
    if a.maps.len() > 1 || a.maps[0].is_dir() {
        let (maps, notes) = ogm_corners::map::find_maps(&a.maps)?;
        for n in notes {
            eprintln!("ogm-corners: note: {n}");
        }
        let Some(out) = a.output.as_deref() else {
            return Err(Error::invalid(format!(
                "{} maps: give --output DIR for one keypoint file per map",
                maps.len()
            )));
        };
        // Set-up (a GPU device and its pipelines) is paid once for the whole batch.
        let mut detector = a.opts.detector()?;
        return batch::detect_many(&maps, &mut detector, format, out, a.overlay.as_deref());
    }
    let map = OccupancyMap::load(&a.maps[0])?;
    for w in &map.warnings {
        eprintln!("ogm-corners: warning: {w}");
    }
    let mut detector = a.opts.detector()?;
    let det = detector.detect(&map)?;
    let options = detector.options();
    let backend = detector.backend_name();
    let write = |out: &mut dyn Write| {
        output::write_keypoints(out, format, &map, &det, &options, &backend)?;
        out.flush()
    };
    match &a.output {
        Some(path) => {
            let file = fs::File::create(path).map_err(|e| Error::output(path, e))?;
            write(&mut BufWriter::new(file)).map_err(|e| Error::output(path, e))?;
        }
        None => write_stdout(write)?,
    }
    if let Some(png) = &a.overlay {
        overlay::write_overlay(png, &map.image, &det.keypoints)?;
    }
    Ok(())
}

/// Writes to standard output; a closed pipe (`| head`) ends quietly rather than as an error.
fn write_stdout(f: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> Result<()> {
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    match f(&mut out) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(Error::output("<stdout>", e)),
    }
}

fn demo(a: DemoArgs) -> Result<()> {
    let (w, h) = a.size;
    let dir = &a.output;
    fs::create_dir_all(dir).map_err(|e| Error::output(dir, e))?;
    let image = synth::office_map(w, h, a.seed)?;
    let pgm = dir.join("demo-map.pgm");
    let yaml = dir.join("demo-map.yaml");
    image.write_pgm(&pgm)?;
    let yaml_text = format!(
        "# Synthetic office map made by `ogm-corners demo --size {w}x{h} --seed {}`\n\
         image: demo-map.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n\
         occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n",
        a.seed
    );
    fs::write(&yaml, yaml_text).map_err(|e| Error::output(&yaml, e))?;
    // Load it back as a user's map would be, so the demo runs the whole path.
    let map = OccupancyMap::load(&yaml)?;
    let mut detector = a.opts.detector()?;
    let start = Instant::now();
    let det = detector.detect(&map)?;
    let elapsed = start.elapsed();
    let csv = dir.join("keypoints.csv");
    let json = dir.join("keypoints.json");
    let overlay_png = dir.join("overlay.png");
    let options = detector.options();
    let backend = detector.backend_name();
    for (path, format) in [(&csv, Format::Csv), (&json, Format::Json)] {
        let file = fs::File::create(path).map_err(|e| Error::output(path, e))?;
        let mut out = BufWriter::new(file);
        output::write_keypoints(&mut out, format, &map, &det, &options, &backend)
            .and_then(|_| out.flush())
            .map_err(|e| Error::output(path, e))?;
    }
    overlay::write_overlay(&overlay_png, &map.image, &det.keypoints)?;
    let mpx = w as f64 * h as f64 / 1e6;
    let secs = elapsed.as_secs_f64();
    println!(
        "{} corners in a {w}x{h} synthetic office map ({mpx:.2} Mpx) in {:.2} ms on {} ({:.0} Mpx/s)",
        det.keypoints.len(),
        secs * 1e3,
        backend,
        mpx / secs.max(1e-9)
    );
    for p in [&yaml, &pgm, &overlay_png, &csv, &json] {
        println!("wrote {}", p.display());
    }
    Ok(())
}

fn rules(a: RulesArgs) -> Result<()> {
    let table = RuleTable::new(a.rules.into());
    let codes = if a.canonical {
        table.canonical()
    } else {
        table.accepted().collect()
    };
    write_stdout(|out| {
        match a.format {
            RulesFormat::Csv => {
                writeln!(out, "code,rule")?;
                for (c, r) in &codes {
                    writeln!(out, "{c},{r}")?;
                }
            }
            RulesFormat::Text => {
                writeln!(
                    out,
                    "# rules {}: {} codes{}; bit0 Q (top-left), clockwise to bit7 A' (left); # occupied",
                    table.rule_set(),
                    codes.len(),
                    if a.canonical {
                        " (one per rotation class)"
                    } else {
                        ""
                    }
                )?;
                for (c, r) in &codes {
                    let pic = code_picture(*c);
                    writeln!(out, "\ncode {c:3} (0b{c:08b})  rule {r}")?;
                    for line in pic {
                        writeln!(out, "    {line}")?;
                    }
                }
            }
        }
        out.flush()
    })
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum TextOrJson {
    Text,
    Json,
}

#[derive(Args, Debug)]
struct InfoArgs {
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    format: TextOrJson,
}

fn info(a: InfoArgs) -> Result<()> {
    let adapters = gpu::list_adapters();
    write_stdout(|out| {
        if a.format == TextOrJson::Json {
            serde_json::to_writer_pretty(&mut *out, &adapters)?;
            writeln!(out)?;
            return out.flush();
        }
        if adapters.is_empty() {
            writeln!(
                out,
                "no adapters found (WGPU_BACKEND={}); install a Vulkan driver, e.g. mesa-vulkan-drivers",
                std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "unset".into())
            )?;
        }
        for (i, r) in adapters.iter().enumerate() {
            writeln!(out, "adapter {i}: {}", r.name)?;
            writeln!(
                out,
                "  backend: {}, device type: {}",
                r.backend, r.device_type
            )?;
            writeln!(out, "  driver: {}", r.driver)?;
            writeln!(
                out,
                "  max_storage_buffer_binding_size: {} MiB, max_buffer_size: {} MiB",
                r.max_storage_buffer_binding_size >> 20,
                r.max_buffer_size >> 20
            )?;
            writeln!(
                out,
                "  max_compute_workgroups_per_dimension: {}, timestamp queries: {}, shader int64: {}",
                r.max_compute_workgroups_per_dimension, r.timestamp_query, r.shader_int64
            )?;
        }
        out.flush()
    })
}

mod bench;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum TableFormat {
    Md,
    Csv,
    Json,
}

#[derive(Args, Debug)]
struct EvalArgs {
    /// Maps (yaml or image).
    #[arg(required = true)]
    maps: Vec<PathBuf>,
    /// Random trials per condition (exact transforms run once).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    trials: u32,
    /// Seed of the random transforms.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Match distance, pixels.
    #[arg(long, default_value_t = 2.0)]
    tolerance: f64,
    /// Output format.
    #[arg(long, value_enum, default_value = "md")]
    format: TableFormat,
    /// Where to run the detectors.
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// Also write plots of repeatability against noise and rotation (averaged over the maps) to DIR.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
}

/// Writes `repeatability-noise.png` and `repeatability-rotation.png`: mean over maps, a line per detector.
fn eval_plots(dir: &std::path::Path, rows: &[EvalRecord]) -> Result<()> {
    use ogm_corners::plot::{line_plot, Series};
    fs::create_dir_all(dir).map_err(|e| Error::output(dir, e))?;
    let colours = [
        ("ogm", image::Rgb([220, 20, 20])),
        ("harris", image::Rgb([30, 90, 220])),
        ("shi-tomasi", image::Rgb([20, 160, 60])),
        ("trajkovic", image::Rgb([240, 140, 0])),
    ];
    for (cond, file, x_label, x_scale) in [
        (
            "noise",
            "repeatability-noise.png",
            "NOISE % (SPECKLE AND WALL JITTER)",
            100.0,
        ),
        (
            "rotation",
            "repeatability-rotation.png",
            "ROTATION (DEGREES) WITH RANDOM SHIFT",
            1.0,
        ),
    ] {
        let series: Vec<Series> = colours
            .iter()
            .map(|(det, colour)| {
                let mut levels: Vec<f64> = rows
                    .iter()
                    .filter(|r| r.condition == cond && r.detector == *det)
                    .map(|r| r.level)
                    .collect();
                levels.sort_by(f64::total_cmp);
                levels.dedup();
                let points = levels
                    .into_iter()
                    .filter_map(|lv| {
                        let v: Vec<f64> = rows
                            .iter()
                            .filter(|r| r.condition == cond && r.detector == *det && r.level == lv)
                            .filter_map(|r| r.repeatability)
                            .collect();
                        (!v.is_empty())
                            .then(|| (lv * x_scale, v.iter().sum::<f64>() / v.len() as f64))
                    })
                    .collect();
                Series {
                    label: det.to_uppercase(),
                    colour: *colour,
                    points,
                }
            })
            .collect();
        let maps = rows
            .iter()
            .map(|r| &r.map)
            .collect::<std::collections::BTreeSet<_>>()
            .len();
        let title = format!("REPEATABILITY VS {} ({maps} MAPS)", cond.to_uppercase());
        let path = dir.join(file);
        line_plot(&title, x_label, &series, 900, 520)
            .save_with_format(&path, image::ImageFormat::Png)
            .map_err(|e| Error::output(&path, e))?;
        eprintln!("ogm-corners: wrote {}", path.display());
    }
    Ok(())
}

/// One row of `eval`.
#[derive(serde::Serialize, Debug)]
struct EvalRecord {
    map: String,
    detector: &'static str,
    condition: &'static str,
    level: f64,
    repeatability: Option<f64>,
    trials: u32,
}

fn eval(a: EvalArgs) -> Result<()> {
    use ogm_corners::eval::{conditions, repeatability, Pair};
    if !(a.tolerance.is_finite() && a.tolerance >= 0.0) {
        return Err(Error::invalid(format!(
            "tolerance must be >= 0, got {}",
            a.tolerance
        )));
    }
    let maps = a
        .maps
        .iter()
        .map(|p| OccupancyMap::load(p).map(|m| (p.display().to_string(), m)))
        .collect::<Result<Vec<_>>>()?;
    // Every detector with its default (the paper's) options.
    let mut detector = detector_on(a.backend, DetectOptions::default())?;
    let kinds = [
        DetectorKind::Ogm,
        DetectorKind::Baseline(Baseline::Harris),
        DetectorKind::Baseline(Baseline::ShiTomasi),
        DetectorKind::Baseline(Baseline::Trajkovic),
    ];
    let mut rows = Vec::new();
    for (name, map) in &maps {
        let (w, h) = (map.image.width(), map.image.height());
        for cond in conditions() {
            let trials = if cond.is_exact() { 1 } else { a.trials };
            let pairs = (0..trials)
                .map(|t| Pair::new(&map.image, cond.transform(w, h, a.seed, u64::from(t))))
                .collect::<Result<Vec<_>>>()?;
            for kind in kinds {
                detector.set_options(DetectOptions {
                    detector: kind,
                    ..DetectOptions::default()
                });
                let mut scores = Vec::new();
                for pair in &pairs {
                    if let Some(r) = repeatability(&mut detector, pair, a.tolerance)? {
                        scores.push(r);
                    }
                }
                rows.push(EvalRecord {
                    map: name.clone(),
                    detector: kind.name(),
                    condition: cond.name,
                    level: cond.level,
                    repeatability: (!scores.is_empty())
                        .then(|| scores.iter().sum::<f64>() / scores.len() as f64),
                    trials,
                });
            }
        }
    }
    if let Some(dir) = &a.plot {
        eval_plots(dir, &rows)?;
    }
    write_stdout(|out| {
        match a.format {
            TableFormat::Json => {
                serde_json::to_writer_pretty(&mut *out, &rows)?;
                writeln!(out)?;
            }
            TableFormat::Csv => {
                writeln!(out, "map,detector,condition,level,repeatability,trials")?;
                for r in &rows {
                    let rep = r.repeatability.map_or(String::new(), |v| format!("{v:.4}"));
                    writeln!(
                        out,
                        "{},{},{},{},{rep},{}",
                        r.map, r.detector, r.condition, r.level, r.trials
                    )?;
                }
            }
            TableFormat::Md => {
                writeln!(
                    out,
                    "| map | detector | condition | level | repeatability | trials |"
                )?;
                writeln!(out, "|---|---|---|---|---|---|")?;
                for r in &rows {
                    let rep = r
                        .repeatability
                        .map_or("n/a".to_string(), |v| format!("{:.1}%", 100.0 * v));
                    writeln!(
                        out,
                        "| {} | {} | {} | {} | {rep} | {} |",
                        r.map, r.detector, r.condition, r.level, r.trials
                    )?;
                }
            }
        }
        out.flush()
    })
}

#[derive(Args, Debug)]
struct CompareArgs {
    /// Maps (yaml or image).
    #[arg(required = true)]
    maps: Vec<PathBuf>,
    /// Which backends to time: cpu, reference, gpu or all; comma-separated or repeated.
    #[arg(long, value_enum, value_delimiter = ',', default_values = ["cpu", "reference"])]
    backend: Vec<bench::BenchBackend>,
    /// Folder for the table (compare.md) and the contact sheets.
    #[arg(long, value_name = "DIR", default_value = "compare-out")]
    out: PathBuf,
    /// Format of the table on standard output.
    #[arg(long, value_enum, default_value = "md")]
    format: TableFormat,
    /// Timed runs per measurement (after one warm-up); medians are reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    repeat: u32,
}

/// One row of `compare`: a detector on a map.
#[derive(serde::Serialize, Debug)]
struct CompareRecord {
    map: String,
    width: u32,
    height: u32,
    detector: &'static str,
    keypoints: usize,
    /// The fast CPU path, end to end.
    cpu_end_to_end_ms: Option<f64>,
    /// The single-threaded reference: its work before keypoint selection, and end to end.
    reference_kernel_ms: Option<f64>,
    reference_end_to_end_ms: Option<f64>,
    gpu_kernel_ms: Option<f64>,
    gpu_end_to_end_ms: Option<f64>,
}

const ALL_DETECTORS: [DetectorKind; 4] = [
    DetectorKind::Ogm,
    DetectorKind::Baseline(Baseline::Harris),
    DetectorKind::Baseline(Baseline::ShiTomasi),
    DetectorKind::Baseline(Baseline::Trajkovic),
];

/// Side of one contact-sheet panel, pixels.
const PANEL: u32 = 560;

/// Four panels (one per detector) of the map's explored part with the keypoints marked, labelled.
fn contact_sheet(
    name: &str,
    map: &OccupancyMap,
    found: &[(DetectorKind, Vec<ogm_corners::Keypoint>)],
) -> image::RgbImage {
    use ogm_corners::plot::{draw_text, fill};
    // Crop to what the robot saw (anything not unknown), with a margin: the rest is empty grey.
    let classes = ClassTable::new(&map.thresholds);
    let (w, h) = (map.image.width(), map.image.height());
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for y in 0..h {
        for x in 0..w {
            if classes.state(map.image.get(x, y)) != ogm_corners::CellState::Unknown {
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
            }
        }
    }
    if x1 <= x0 {
        (x0, y0, x1, y1) = (0, 0, w, h);
    }
    let m = 8;
    let (x0, y0, x1, y1) = (
        x0.saturating_sub(m),
        y0.saturating_sub(m),
        (x1 + m).min(w),
        (y1 + m).min(h),
    );
    let (cw, ch) = (x1 - x0, y1 - y0);
    let px = (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .map(|(x, y)| map.image.get(x, y))
        .collect();
    let crop = ogm_corners::MapImage::new(cw, ch, px).expect("non-empty crop");
    let side = cw.max(ch);
    let (zoom, shrink) = if side <= PANEL {
        ((PANEL / side).clamp(1, 8), 1)
    } else {
        (1, side.div_ceil(PANEL))
    };
    let (label_h, title_h) = (22u32, 34u32);
    let mut sheet = image::RgbImage::from_pixel(
        2 * PANEL + 30,
        title_h + 2 * (PANEL + label_h) + 30,
        image::Rgb([255, 255, 255]),
    );
    let black = image::Rgb([0, 0, 0]);
    draw_text(
        &mut sheet,
        10,
        8,
        &format!("{name}: {w}X{h}, CROPPED TO THE EXPLORED AREA"),
        2,
        black,
    );
    for (i, (kind, kps)) in found.iter().enumerate() {
        let shifted: Vec<ogm_corners::Keypoint> = kps
            .iter()
            .filter(|k| k.x >= x0 && k.x < x1 && k.y >= y0 && k.y < y1)
            .map(|k| ogm_corners::Keypoint {
                x: k.x - x0,
                y: k.y - y0,
                ..*k
            })
            .collect();
        let panel = overlay::render_overlay_at(&crop, &shifted, zoom, shrink);
        let (ox, oy) = (
            10 + (i as u32 % 2) * (PANEL + 10),
            title_h + (i as u32 / 2) * (PANEL + label_h + 10),
        );
        draw_text(
            &mut sheet,
            i64::from(ox),
            i64::from(oy) + 4,
            &format!("{}: {} KEYPOINTS", kind.name(), kps.len()),
            2,
            black,
        );
        fill(
            &mut sheet,
            i64::from(ox),
            i64::from(oy + label_h),
            i64::from(PANEL),
            i64::from(PANEL),
            image::Rgb([205, 205, 205]),
        );
        image::imageops::overlay(&mut sheet, &panel, i64::from(ox), i64::from(oy + label_h));
    }
    sheet
}

fn compare(a: CompareArgs) -> Result<()> {
    fs::create_dir_all(&a.out).map_err(|e| Error::output(&a.out, e))?;
    // The same measurement as `bench` (backends checked to agree keypoint for keypoint).
    let mut runner = bench::Runner::new(
        "compare",
        &a.backend,
        a.repeat,
        RuleSet::Paper,
        BaselineParams::default(),
    )?;
    let mut rows = Vec::new();
    for p in &a.maps {
        let bm = bench::BenchMap::from_file(p, OccupancyMap::load(p)?);
        let name = map_name(p);
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
                gpu_kernel_ms: pick("gpu", "kernel"),
                gpu_end_to_end_ms: pick("gpu", "end_to_end"),
            });
            found.push((m.kind, m.keypoints));
        }
        let map = &bm.map;
        let sheet_path = a.out.join(format!("{name}-contact-sheet.png"));
        contact_sheet(&name, map, &found)
            .save_with_format(&sheet_path, image::ImageFormat::Png)
            .map_err(|e| Error::output(&sheet_path, e))?;
        eprintln!("ogm-corners: wrote {}", sheet_path.display());
    }
    let ms = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    let mut md = String::from("| map | size | detector | keypoints | CPU end-to-end ms | reference kernel ms | reference end-to-end ms | GPU kernel ms | GPU end-to-end ms |\n|---|---|---|---|---|---|---|---|---|\n");
    for r in &rows {
        md += &format!(
            "| {} | {}x{} | {} | {} | {} | {} | {} | {} | {} |\n",
            r.map,
            r.width,
            r.height,
            r.detector,
            r.keypoints,
            ms(r.cpu_end_to_end_ms),
            ms(r.reference_kernel_ms),
            ms(r.reference_end_to_end_ms),
            ms(r.gpu_kernel_ms),
            ms(r.gpu_end_to_end_ms)
        );
    }
    let md_path = a.out.join("compare.md");
    fs::write(&md_path, &md).map_err(|e| Error::output(&md_path, e))?;
    write_stdout(|out| {
        match a.format {
            TableFormat::Md => write!(out, "{md}")?,
            TableFormat::Json => {
                serde_json::to_writer_pretty(&mut *out, &rows)?;
                writeln!(out)?;
            }
            TableFormat::Csv => {
                writeln!(out, "map,width,height,detector,keypoints,cpu_end_to_end_ms,reference_kernel_ms,reference_end_to_end_ms,gpu_kernel_ms,gpu_end_to_end_ms")?;
                for r in &rows {
                    let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.3}"));
                    writeln!(
                        out,
                        "{},{},{},{},{},{},{},{},{},{}",
                        r.map,
                        r.width,
                        r.height,
                        r.detector,
                        r.keypoints,
                        f(r.cpu_end_to_end_ms),
                        f(r.reference_kernel_ms),
                        f(r.reference_end_to_end_ms),
                        f(r.gpu_kernel_ms),
                        f(r.gpu_end_to_end_ms)
                    )?;
                }
            }
        }
        out.flush()
    })
}

/// Exit status for an error that reached the top.
pub fn exit_code(e: &Error) -> i32 {
    e.exit_code()
}
