//! The `ogm-corners` command line: argument parsing and the options shared by the subcommands, one file
//! per subcommand beside this one. The work itself (detection, pictures, tables) is library code.
//!
//! The files: `detect.rs` (with `batch.rs`, `detect` over many maps), `demo.rs` (with `demo_merge.rs`,
//! the demo's whole job), `rules.rs`, `info.rs`, `bench.rs`, `eval.rs`, `compare.rs`, `merge.rs` (with its
//! many-map mode in `merge_many.rs`) and `merge_eval.rs`.
//!
//! A new command: one file here with its arguments struct (as `detect.rs`'s `DetectArgs`) and its `run`,
//! a variant of the `Command` enum below, and its tests in `tests/cli/`; the work itself belongs in the
//! library layer of its concern, the command only parses and calls.

mod batch;
mod bench;
mod compare;
mod demo;
mod demo_merge;
mod detect;
mod eval;
mod info;
mod merge;
mod merge_eval;
mod merge_many;
mod rules;

use std::io::{BufWriter, Write};
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Args, Parser, Subcommand, ValueEnum};

use ogm_corners::backend::fast::FastCpuBackend;
use ogm_corners::backend::gpu::GpuOptions;
use ogm_corners::backend::reference::coarsen::CellRule;
use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::detect::detector::BackendChoice;
use ogm_corners::detect::robust::{Anchor, RobustParams};
use ogm_corners::support::memory::{self, Budget};
use ogm_corners::{
    Backend, Baseline, BaselineParams, DetectOptions, Detector, DetectorKind, Error, Result,
    RuleSet,
};

/// Finds corners in robot occupancy grid maps with the OGM corner detector.
#[derive(Parser, Debug)]
#[command(name = "ogm-corners", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Most memory a run may allocate (e.g. 512M, 16G); what a command needs is estimated from the image
    /// headers and options before anything large is allocated. Default: the OGM_MAX_MEMORY variable, else
    /// 80% of the machine's memory.
    #[arg(long, global = true, value_name = "SIZE", value_parser = memory::parse_bytes)]
    max_memory: Option<u64>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Detect corners in a map (a ROS map_server .yaml, or a PGM/PNG image).
    Detect(detect::DetectArgs),
    /// Generate a synthetic office map, detect its corners, write map, overlay and keypoints.
    Demo(demo::DemoArgs),
    /// Print the rule table: the accepted 8-neighbour codes and the rule that accepts each.
    Rules(rules::RulesArgs),
    /// List the GPU adapters wgpu finds (WGPU_BACKEND and WGPU_ADAPTER_NAME select among them).
    Info(info::InfoArgs),
    /// Measure every detector on every backend (end to end, kernels, upload; peak memory of the CPU
    /// backends), median of repeats, on synthetic maps of several sizes and on real maps.
    Bench(bench::BenchArgs),
    /// Repeatability of every detector under known transforms: exact turns and mirror, rotations with
    /// translation, SLAM-like noise, partial overlap.
    Eval(eval::EvalArgs),
    /// The paper's Table I with timings: every detector's keypoint count and median times per backend on
    /// each map, and a contact sheet PNG per map.
    Compare(compare::CompareArgs),
    /// Align map B onto map A with no initial pose; write the merged map when confident (exit 0 merged,
    /// 3 declined, 2 bad input, 1 internal failure).
    Merge(merge::MergeArgs),
    /// Run the map merger over a pair set with ground truth: accepted and accurate, wrong accepts, times.
    MergeEval(merge_eval::MergeEvalArgs),
}

/// A summary table or JSON records.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum TextOrJsonMd {
    Md,
    Json,
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
    /// The OGM corner detector of the paper, exactly as it describes it.
    Ogm,
    /// The paper's rules made robust for real maps: turned to the walls, at several scales, concave and
    /// convex corners, ranked by strength.
    OgmRobust,
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
            DetectorArg::OgmRobust => DetectorKind::OgmRobust,
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
    /// Keep at most N keypoints, strongest first (default: all): the robust detector and the baselines
    /// (Shi-Tomasi as goodFeaturesToTrack's maxCorners, before its minimum distance); the paper's detector
    /// has no strength and refuses a cap it would exceed.
    #[arg(long, value_name = "N")]
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

/// `--anchor`: `world`, `centre` (or `center`), or a point `X,Y` in pixels.
fn parse_anchor(s: &str) -> std::result::Result<Anchor, String> {
    let point = || {
        let (x, y) = s.split_once(',')?;
        let (x, y) = (x.trim().parse::<f64>().ok()?, y.trim().parse::<f64>().ok()?);
        (x.is_finite() && y.is_finite()).then_some(Anchor::Point(x, y))
    };
    Anchor::named(s)
        .or_else(point)
        .ok_or_else(|| format!("expected world, centre or a point X,Y in pixels, got {s:?}"))
}

/// The robust detector's options ([`ogm_corners::detect::robust::RobustParams`]).
#[derive(Args, Debug, Clone)]
pub(super) struct RobustArgs {
    /// Robust detector: smallest coarse scale, pixels a cell side.
    #[arg(long, default_value_t = RobustParams::default().min_scale)]
    min_scale: u32,
    /// Robust detector: largest coarse scale (at most 15).
    #[arg(long, default_value_t = RobustParams::default().max_scale)]
    max_scale: u32,
    /// Robust detector: the map's wall direction in degrees, instead of estimating it.
    #[arg(long, value_name = "DEGREES", allow_negative_numbers = true)]
    angle: Option<f64>,
    /// Robust detector: where its turned grid is anchored: `world`, the origin of the map's frame (its
    /// yaml's `origin`; the centre for an image without one), so a crop of the map or the map grown at
    /// its edges keeps its keypoints; `centre`, so the map turned by quarter turns or mirrored does; or a
    /// point `X,Y` in pixels.
    #[arg(long, value_name = "world|centre|X,Y", default_value = "world", value_parser = parse_anchor)]
    anchor: Anchor,
    /// Robust detector: drop keypoints within this many pixels of a stronger one.
    #[arg(long, default_value_t = RobustParams::default().nms_radius)]
    nms_radius: u32,
    /// Robust detector: drop corners whose shorter wall runs fewer pixels than this.
    #[arg(long, default_value_t = RobustParams::default().min_strength)]
    min_strength: u32,
    /// Robust detector: concave corners only (no wall ends or outer corners).
    #[arg(long)]
    no_convex: bool,
    /// Robust detector: percent of a coarse cell's samples that must be occupied for the cell to be.
    #[arg(long, value_name = "PERCENT", default_value_t = CellRule::default().occupied_pct)]
    cell_occupied: u32,
    /// Robust detector: percent of a coarse cell's samples that must be free for a cell that is not
    /// occupied to be free.
    #[arg(long, value_name = "PERCENT", default_value_t = CellRule::default().free_pct)]
    cell_free: u32,
    /// Robust detector: unknown pixels bridged across a wall when placing a corner on its centre line.
    #[arg(long, value_name = "PIXELS", default_value_t = RobustParams::default().wall_gap)]
    wall_gap: u32,
}

impl RobustArgs {
    pub(super) fn params(&self) -> RobustParams {
        RobustParams {
            min_scale: self.min_scale,
            max_scale: self.max_scale,
            nms_radius: self.nms_radius,
            min_strength: self.min_strength,
            convex: !self.no_convex,
            angle: self.angle,
            anchor: self.anchor,
            cells: CellRule {
                occupied_pct: self.cell_occupied,
                free_pct: self.cell_free,
            },
            wall_gap: self.wall_gap,
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
    #[command(flatten)]
    robust: RobustArgs,
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
            robust: self.robust.params(),
            max_corners: self.baseline.max_corners,
        }
    }

    fn detector(&self) -> Result<Detector> {
        detector_on(self.backend, self.options())
    }

    /// What the chosen backend will allocate for a `w` x `h` map (with `auto`, the larger of the GPU's
    /// and the CPU's), known before the backend is opened, so a map can be refused from its header.
    fn working_bytes(&self, w: u32, h: u32) -> u64 {
        let o = self.options();
        let gpu = || ogm_corners::backend::gpu::gpu_working_bytes(&GpuOptions::default(), &o, w, h);
        match self.backend {
            BackendArg::Cpu => FastCpuBackend.working_bytes(&o, w, h),
            BackendArg::Reference => ReferenceBackend.working_bytes(&o, w, h),
            BackendArg::Gpu => gpu(),
            BackendArg::Auto => FastCpuBackend.working_bytes(&o, w, h).max(gpu()),
        }
    }
}

/// A detector with `options` on the backend the user chose (auto says which on standard error).
fn detector_on(backend: BackendArg, options: DetectOptions) -> Result<Detector> {
    Ok(Detector::with_backend(options, backend_on(backend)?))
}

/// The backend the user chose (auto says which on standard error).
fn backend_on(backend: BackendArg) -> Result<Box<dyn Backend>> {
    let choice = match backend {
        BackendArg::Auto => BackendChoice::Auto,
        BackendArg::Cpu => BackendChoice::Cpu,
        BackendArg::Reference => BackendChoice::Reference,
        BackendArg::Gpu => BackendChoice::Gpu,
    };
    let (backend, note) = choice.open()?;
    if let Some(note) = note {
        ogm_corners::say!("ogm-corners: {note}");
    }
    Ok(backend)
}

/// The maps of a long-running command (`eval`, `compare`): files as given and folders searched as
/// `detect` searches them, each read up to its image header (and checked against `budget` with `extra`
/// bytes for the command's work), so that a bad or too large map stops the run before the first
/// measurement rather than after hours; and the input set (maps and the images their yamls name) that no
/// output of the run may overwrite.
fn map_inputs(
    args: &[std::path::PathBuf],
    budget: &Budget,
    extra: &dyn Fn(u32, u32) -> u64,
) -> Result<(Vec<std::path::PathBuf>, ogm_corners::support::files::Inputs)> {
    let found = ogm_corners::map::find_maps(args);
    for n in &found.notes {
        ogm_corners::say!("ogm-corners: note: {n}");
    }
    if let Some(first) = found.problems.first() {
        // The search skips what it cannot read; this command stops at it instead.
        let first = first.strip_prefix("skipped ").unwrap_or(first);
        return Err(Error::invalid(format!(
            "{first}{}",
            match found.problems.len() {
                1 => String::new(),
                n => format!(" (and {} more)", n - 1),
            }
        )));
    }
    let mut inputs = ogm_corners::support::files::Inputs::new();
    for p in &found.maps {
        claim_input(p, budget, extra, &mut inputs)?;
    }
    Ok((found.maps, inputs))
}

/// Reads map `p` up to its image header, checks the map plus `extra(w, h)` bytes against the budget, and
/// records it and its image as inputs no output may overwrite.
fn claim_input(
    p: &std::path::Path,
    budget: &Budget,
    extra: &dyn Fn(u32, u32) -> u64,
    inputs: &mut ogm_corners::support::files::Inputs,
) -> Result<(u32, u32)> {
    let (w, h, image) = ogm_corners::OccupancyMap::probe(p)?;
    budget.check(
        format_args!("{}: a {w}x{h} map", p.display()),
        (u64::from(w) * u64::from(h)).saturating_add(extra(w, h)),
    )?;
    inputs.add(p);
    inputs.add(&image);
    Ok((w, h))
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
    let budget = Budget::from_option(cli.max_memory)?;
    // A misspelt instruction-set cap would otherwise be ignored: the user asked for something specific.
    ogm_corners::backend::fast::simd::Isa::from_env().map_err(Error::invalid)?;
    match cli.command {
        Command::Detect(a) => detect::run(a, &budget),
        Command::Demo(a) if a.detect_only => demo::run(a, &budget),
        Command::Demo(a) => demo_merge::run(&a, &budget),
        Command::Rules(a) => rules::run(a),
        Command::Info(a) => info::run(a),
        Command::Bench(a) => bench::bench(a, &budget),
        Command::Eval(a) => eval::run(a, &budget),
        Command::Compare(a) => compare::run(a, &budget),
        Command::Merge(a) if a.is_pair() => merge::run(a, &budget),
        Command::Merge(a) => merge_many::run(a, &budget),
        Command::MergeEval(a) => merge_eval::run(a, &budget),
    }
}

/// Whether standard output was closed when the process started (`>&-`). Rust's runtime reopens a
/// closed standard descriptor as /dev/null before `main`, and writes there succeed silently; so the check
/// runs before the runtime, as an ELF constructor (Linux), while fd 1 is still as the caller left it. A
/// /dev/null given on purpose (`>/dev/null`, Python's `subprocess.DEVNULL`) is an open descriptor and fine.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

#[cfg(target_os = "linux")]
#[used]
#[link_section = ".init_array"]
static CHECK_STDOUT_AT_START: extern "C" fn() = note_closed_stdout;

#[cfg(target_os = "linux")]
extern "C" fn note_closed_stdout() {
    use std::os::fd::AsFd;
    // `as_fd` only names descriptor 1; fcntl fails with EBADF when nothing is open there.
    let closed = rustix::io::fcntl_getfd(std::io::stdout().as_fd()).is_err();
    STDOUT_CLOSED.store(closed, Ordering::Relaxed);
}

/// Whether standard output can be written: an error naming it when it was closed at start.
pub fn check_stdout() -> Result<()> {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return Err(Error::output(
            "<stdout>",
            "standard output is closed; redirect it or give --output",
        ));
    }
    Ok(())
}

/// Writes to standard output; a closed pipe (`| head`) ends quietly rather than as an error, a standard
/// output closed from the start is an error.
fn write_stdout(f: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> Result<()> {
    check_stdout()?;
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    match f(&mut out).and_then(|_| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(Error::write("<stdout>", e)),
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum TextOrJson {
    Text,
    Json,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum TableFormat {
    Md,
    Csv,
    Json,
}

impl From<TableFormat> for ogm_corners::detect::output::TableFormat {
    fn from(f: TableFormat) -> Self {
        match f {
            TableFormat::Md => Self::Md,
            TableFormat::Csv => Self::Csv,
            TableFormat::Json => Self::Json,
        }
    }
}

const ALL_DETECTORS: [DetectorKind; 5] = [
    DetectorKind::Ogm,
    DetectorKind::OgmRobust,
    DetectorKind::Baseline(Baseline::Harris),
    DetectorKind::Baseline(Baseline::ShiTomasi),
    DetectorKind::Baseline(Baseline::Trajkovic),
];
