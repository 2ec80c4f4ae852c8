//! The measurement behind `ogm-corners bench` and `compare`: median times of detectors on maps on the
//! chosen backends (end to end, GPU kernels, upload), the peak memory of the CPU stages, and a check that
//! every backend finds the same keypoints.

use std::fs;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::backend::baselines::{self, BaselineParams, ExactParams};
use crate::backend::fast::FastCpuBackend;
use crate::backend::gpu::{DeviceMap, GpuBackend, GpuOptions};
use crate::backend::reference::{classify::classify, ogm_corners::ogm_corners, ReferenceBackend};
use crate::backend::rules::{RuleSet, RuleTable};
use crate::backend::{Backend, DetectorKind, Keypoint};
use crate::map::states::ClassTable;
use crate::map::{map_name, MapImage, OccupancyMap};
use crate::support::error::{Error, Result};
use crate::support::stats::median;

/// The git commit the library was built from (build.rs; "unknown" without git).
pub const GIT_COMMIT: &str = env!("OGM_GIT_COMMIT");

/// Maps above this many pixels make the baselines on the reference or on a software GPU adapter take
/// minutes per measurement (16384 x 16384 is 268 Mpx); `--backend all` skips those combinations, and naming
/// the backend runs them. 32 Mi pixels lies between 4096 x 4096 (16.8 Mpx) and 8192 x 8192 (67 Mpx).
pub const SLOW_PIXELS: u64 = 32 << 20;

/// Which backends `bench` and `compare` time; a comma-separated list, or the option repeated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchBackend {
    /// The fast CPU path (all cores), the default detection backend.
    Cpu,
    /// The plain single-threaded CPU reference.
    Reference,
    /// The GPU adapter wgpu picks, software ones included; fails without one.
    Gpu,
    /// cpu, reference and gpu (when an adapter opens; a note on standard error when not). Skips the
    /// reference and software adapters for the baselines on maps over 32 Mi pixels: name them to run those.
    All,
}

/// How a backend came into the run: not at all, through `all`, or by name. Named wins over `all`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Want {
    No,
    All,
    Named,
}

/// The three backends a measurement can run on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Engine {
    Cpu,
    Reference,
    Gpu,
}

impl Engine {
    fn name(self) -> &'static str {
        match self {
            Engine::Cpu => "cpu",
            Engine::Reference => "reference",
            Engine::Gpu => "gpu",
        }
    }
}

/// One measurement: a detector on a map, on one backend, one stage.
#[derive(serde::Serialize, Debug, Clone)]
pub struct BenchRecord {
    /// Short name of the map ("synthetic", or the file's stem / folder).
    pub map: String,
    /// The file the map was read from (yaml or image); null for synthetic maps.
    pub source: Option<String>,
    /// The image file holding the pixels (a synthetic map's --save-map file); null when there is none.
    pub image: Option<String>,
    pub detector: &'static str,
    pub backend: &'static str,
    /// The CPU model (CPU backends) or the GPU adapter.
    pub adapter: String,
    pub width: u32,
    pub height: u32,
    /// `end_to_end` (image in memory to keypoints in memory); `kernel` (the reference's work before
    /// keypoint selection); on a GPU `kernel_resident` (timestamp queries around the kernels alone, the
    /// map's band already on the device), `upload` (the bands through the staging ring as the backend
    /// uploads them, alone), `upload_ref` (the same bands copied from staging buffers filled
    /// beforehand), `transfer_floor` (the same bands copied by the device from host memory: the
    /// bus alone, where the device can copy from host buffers) and, for the OGM detector, `device_map`
    /// (the map already in a device buffer, detected where it lies to keypoints on the host).
    pub stage: &'static str,
    pub median_ms: f64,
    pub mpx_per_s: f64,
    /// GPU stages: the map's bytes (one a pixel) over the median time, GB/s.
    pub gb_per_s: Option<f64>,
    /// `gb_per_s` as a percentage of the device's peak memory bandwidth (`--peak-bandwidth`, or the
    /// known figure for the adapter), for `kernel_resident`.
    pub peak_percent: Option<f64>,
    /// GPU `end_to_end` over `upload_ref` (a copy from filled staging buffers, within the device where
    /// they are device memory).
    pub vs_upload_ref: Option<f64>,
    /// GPU `end_to_end` over `transfer_floor`: how far end to end is from moving the map's bytes from
    /// host memory into the device alone.
    pub vs_transfer_floor: Option<f64>,
    /// With `--bandwidth`, CPU backends: the map's pixels a second (one byte each) as a percentage of the
    /// `read` record's GB/s, the plain read of the same bytes on the same threads in the same run.
    pub read_percent: Option<f64>,
    /// GPU `end_to_end` and `kernel_resident`: the most write passes a timed run took (passes over the
    /// map's tiles writing the keypoint list; one unless the list outgrew the buffer or the pass limit).
    pub write_passes: Option<usize>,
    /// GPU `end_to_end` and `kernel_resident`: the most compute dispatches a timed run recorded for the map.
    pub dispatches: Option<usize>,
    pub keypoints: usize,
    /// Peak resident memory of the process while this stage ran (CPU backends, Linux), map included.
    pub peak_rss_mb: Option<f64>,
    /// `peak_rss_mb` over the map's size in bytes (one byte a pixel).
    pub peak_rss_ratio: Option<f64>,
    /// Resident memory when the stage started (the map, the program, what the allocator keeps).
    pub rss_before_mb: Option<f64>,
}

/// A map to measure, with the names that go into its records.
pub struct BenchMap {
    pub label: String,
    pub source: Option<PathBuf>,
    pub image_path: Option<PathBuf>,
    pub map: OccupancyMap,
}

impl BenchMap {
    /// A map loaded from `path` (what the user named or a folder held).
    pub fn from_file(path: &Path, map: OccupancyMap) -> Self {
        BenchMap {
            label: map_name(path),
            source: Some(path.to_path_buf()),
            image_path: map.image_path.clone(),
            map,
        }
    }
}

/// One detector's results on one map: its records on every backend, and the keypoints they agreed on.
pub struct Measured {
    pub kind: DetectorKind,
    pub keypoints: Vec<Keypoint>,
    pub records: Vec<BenchRecord>,
}

/// The GPU adapter found when the run started.
struct GpuInfo {
    label: String,
    software: bool,
}

/// Peak resident memory over a stretch of work, from /proc/self (Linux).
struct PeakRss {
    before_kb: u64,
}

/// A field of /proc/self/status in kB (`VmRSS`, `VmHWM`).
fn status_kb(field: &str) -> Option<u64> {
    let s = fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

impl PeakRss {
    /// Resets the high-water mark (writing 5 to clear_refs sets VmHWM to the current RSS, Linux 4.0+);
    /// None where that is not possible, so that a lifetime peak is never reported as this stage's.
    fn start() -> Option<Self> {
        fs::write("/proc/self/clear_refs", "5").ok()?;
        Some(PeakRss {
            before_kb: status_kb("VmRSS")?,
        })
    }

    /// Resident memory when started and the peak since.
    fn finish(self) -> Option<Memory> {
        let peak = status_kb("VmHWM")?;
        Some(Memory {
            before_mb: self.before_kb as f64 / 1e3,
            peak_mb: peak as f64 / 1e3,
        })
    }
}

/// Resident memory over a stage, MB.
#[derive(Clone, Copy, Debug)]
struct Memory {
    before_mb: f64,
    peak_mb: f64,
}

/// The reference's twins of the GPU kernels on `image`: the work before keypoint selection; returns how
/// many cells or candidates it produced.
fn reference_kernels(
    kind: DetectorKind,
    image: &MapImage,
    classes: &ClassTable,
    rules: &RuleTable,
    exact: &ExactParams,
) -> Result<usize> {
    let (w, h) = (image.width(), image.height());
    Ok(match kind {
        DetectorKind::Ogm => ogm_corners(&classify(image, classes), w, h, rules, false).len(),
        DetectorKind::OgmRobust => {
            let robust = crate::detect::robust::detect(
                &mut ReferenceBackend,
                image,
                classes,
                rules,
                &Default::default(),
            )?;
            robust.0.len()
        }
        DetectorKind::Baseline(k) => baselines::cpu_scores(k, image, exact).len(),
    })
}

/// The GPU's transfer stages of `image`, medians of `repeat` runs after a warm-up each: `upload` (through
/// the staging ring), `upload_ref` and, where the device copies from host buffers, `transfer_floor`; end
/// to end's ratios to the last two are set on `e2e`. `record` makes a stage's record from its median.
fn transfer_stages(
    g: &mut GpuBackend,
    image: &MapImage,
    repeat: u32,
    e2e: &mut BenchRecord,
    record: &dyn Fn(&'static str, f64) -> BenchRecord,
    cmd: &str,
) -> Result<Vec<BenchRecord>> {
    let medians = |f: &mut dyn FnMut() -> Result<Duration>| -> Result<f64> {
        f()?; // warm-up
        let mut t = Vec::with_capacity(repeat as usize);
        for _ in 0..repeat {
            t.push(f()?.as_secs_f64() * 1e3);
        }
        Ok(median(t))
    };
    let up = medians(&mut || g.upload_time(image))?;
    let floor = medians(&mut || g.upload_ref_time(image))?;
    e2e.vs_upload_ref = Some(e2e.median_ms / floor);
    let mut out = vec![record("upload", up), record("upload_ref", floor)];
    if g.copies_from_host() {
        let bus = medians(&mut || g.transfer_floor_time(image))?;
        e2e.vs_transfer_floor = Some(e2e.median_ms / bus);
        out.push(record("transfer_floor", bus));
    } else {
        crate::say!(
            "ogm-corners: {cmd}: {} cannot copy from host buffers; no transfer_floor row",
            g.adapter().name
        );
    }
    Ok(out)
}

/// The OGM detector on `image` held in a device buffer ([`GpuBackend::detect_device_map`]): the map is
/// put there before the clock, rows `width` bytes apart; each timed run detects to keypoints on the host.
/// Returns the median ms and the most write passes and dispatches a timed run took, or `None` (said on
/// standard error) where the device has no buffer that large. Its keypoints must be `want`.
fn device_map_stage(
    g: &mut GpuBackend,
    image: &MapImage,
    tables: (&ClassTable, &RuleTable),
    repeat: u32,
    want: &[Keypoint],
    cmd: &str,
) -> Result<Option<(f64, usize, usize)>> {
    let buffer = match g.device_map_buffer(image) {
        Ok(b) => b,
        Err(Error::Unavailable(why)) => {
            crate::say!("ogm-corners: {cmd}: {why}; no device_map row");
            return Ok(None);
        }
        Err(e) => return Err(e),
    };
    let map = DeviceMap {
        buffer: &buffer,
        offset: 0,
        width: image.width(),
        height: image.height(),
        bytes_per_row: u64::from(image.width()),
    };
    let mut launches = Vec::new();
    let (got, ms, _) = timed(repeat, || {
        let kps = g.detect_device_map(&map, tables.0, tables.1, false)?;
        let s = g.stats();
        launches.push((s.write_passes, s.dispatches));
        Ok(kps)
    })?;
    if got != want {
        return Err(Error::Internal(format!(
            "the device map's keypoints differ from the map's in memory: {}",
            first_difference(&got, want)
        )));
    }
    let (passes, dispatches) = most_launches(&launches);
    Ok(Some((ms, passes.unwrap_or(0), dispatches.unwrap_or(0))))
}

/// The most write passes and dispatches the timed runs took (`launches` has the warm-up's first, which
/// may grow the buffers and so take more).
fn most_launches(launches: &[(usize, usize)]) -> (Option<usize>, Option<usize>) {
    let timed = || launches.iter().skip(1);
    (timed().map(|l| l.0).max(), timed().map(|l| l.1).max())
}

/// A stage's record of detector `kind` on `engine` (`adapter`, the CPU model or the GPU) for map `m`,
/// from its median ms, memory and keypoints.
fn recorder(
    m: &BenchMap,
    kind: DetectorKind,
    engine: Engine,
    adapter: String,
) -> impl Fn(&'static str, f64, Option<Memory>, usize) -> BenchRecord + '_ {
    let (w, h) = (m.map.image.width(), m.map.image.height());
    let mpx = f64::from(w) * f64::from(h) / 1e6;
    move |stage, ms: f64, mem: Option<Memory>, n: usize| BenchRecord {
        map: m.label.clone(),
        source: m.source.as_ref().map(|p| p.display().to_string()),
        image: m.image_path.as_ref().map(|p| p.display().to_string()),
        detector: kind.name(),
        backend: engine.name(),
        adapter: adapter.clone(),
        width: w,
        height: h,
        stage,
        median_ms: ms,
        mpx_per_s: mpx / (ms / 1e3),
        gb_per_s: (engine == Engine::Gpu).then(|| mpx / 1e3 / (ms / 1e3)),
        peak_percent: None,
        vs_upload_ref: None,
        vs_transfer_floor: None,
        read_percent: None,
        write_passes: None,
        dispatches: None,
        keypoints: n,
        peak_rss_mb: mem.map(|m| m.peak_mb),
        peak_rss_ratio: mem.map(|m| m.peak_mb * 1e6 / (f64::from(w) * f64::from(h))),
        rss_before_mb: mem.map(|m| m.before_mb),
    }
}

/// The `kernel_resident` record of the kernel times `kernel` (the warm-up's first; the median is of
/// the timed runs), against the device's peak bandwidth `peak_gbs`; `None` where there are no times (said,
/// with `why_none`), and for the robust detector, which dispatches dozens of kernels between host stages
/// while the stats time only the last: no row rather than a wrong one.
fn kernel_record(
    kind: DetectorKind,
    kernel: &[f64],
    make: &dyn Fn(&'static str, f64) -> BenchRecord,
    peak_gbs: Option<f64>,
    why_none: &dyn Fn() -> String,
    cmd: &str,
) -> Option<BenchRecord> {
    if kind == DetectorKind::OgmRobust {
        return None;
    }
    if kernel.len() < 2 {
        crate::say!("ogm-corners: {cmd}: {}; no kernel_resident row", why_none());
        return None;
    }
    let mut r = make("kernel_resident", median(kernel[1..].to_vec()));
    r.peak_percent = peak_gbs
        .zip(r.gb_per_s)
        .map(|(peak, got)| 100.0 * got / peak);
    Some(r)
}

/// Runs `f` once to warm up (first-use costs stay out of the median), then `repeat` timed times. Returns
/// the warm-up's result, the median time in ms, and the memory over all the runs.
fn timed<T>(repeat: u32, mut f: impl FnMut() -> Result<T>) -> Result<(T, f64, Option<Memory>)> {
    let rss = PeakRss::start();
    let first = f()?;
    let mut times = Vec::with_capacity(repeat as usize);
    for _ in 0..repeat {
        let t = Instant::now();
        let r = f()?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
        drop(r); // outside the timed span
    }
    Ok((first, median(times), rss.and_then(PeakRss::finish)))
}

/// The CPU's model name.
pub fn cpu_model() -> String {
    fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
}

pub fn threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The first difference between two keypoint lists, for the disagreement error.
fn first_difference(a: &[Keypoint], b: &[Keypoint]) -> String {
    let show = |k: Option<&Keypoint>| {
        k.map_or("nothing".to_string(), |k| {
            format!(
                "(x {}, y {}, rule {}, code {}, score {})",
                k.x, k.y, k.rule, k.code, k.score
            )
        })
    };
    let i = a
        .iter()
        .zip(b)
        .position(|(x, y)| x != y)
        .unwrap_or(a.len().min(b.len()));
    format!(
        "first difference at index {i}: {} vs {}",
        show(a.get(i)),
        show(b.get(i))
    )
}

/// What `options` sets that the defaults leave to the backend, in words ("" for the defaults).
fn gpu_tuning(options: &GpuOptions) -> String {
    let mut said = Vec::new();
    if let Some(s) = options.strip_rows {
        said.push(format!("strips of {s} rows"));
    }
    if options.copy_bands {
        said.push("bands copied to device buffers".to_string());
    }
    said.join(", ")
}

/// Times detectors on maps on the chosen backends, checking that the backends agree.
pub struct Runner {
    cmd: &'static str,
    cpu: Want,
    reference: Want,
    gpu_want: Want,
    gpu_info: Option<GpuInfo>,
    /// The GPU's peak memory bandwidth, GB/s, when known: `kernel_resident` is reported against it.
    peak_gbs: Option<f64>,
    gpu: Option<GpuBackend>,
    /// The options the GPU backend is opened with.
    gpu_options: GpuOptions,
    repeat: u32,
    rule_set: RuleSet,
    params: BaselineParams,
    progress: bool,
}

/// The times of plain reads of a map's bytes ([`Runner::read_times`]), ms.
#[derive(Clone, Debug, Default)]
pub struct ReadTimes(Vec<f64>);

impl Runner {
    /// A runner for `backends`; opens the GPU once to check it is there (`gpu` named: an error without
    /// one; through `all`: a note on standard error, and no GPU rows). `cmd` names the subcommand in notes.
    pub fn new(
        cmd: &'static str,
        backends: &[BenchBackend],
        repeat: u32,
        rule_set: RuleSet,
        params: BaselineParams,
    ) -> Result<Self> {
        params.exact()?; // bad baseline options fail before any measuring
        let (mut cpu, mut reference, mut gpu_want) = (Want::No, Want::No, Want::No);
        for b in backends {
            match b {
                BenchBackend::Cpu => cpu = Want::Named,
                BenchBackend::Reference => reference = Want::Named,
                BenchBackend::Gpu => gpu_want = Want::Named,
                BenchBackend::All => {
                    cpu = cpu.max(Want::All);
                    reference = reference.max(Want::All);
                    gpu_want = gpu_want.max(Want::All);
                }
            }
        }
        let gpu = match gpu_want {
            Want::No => None,
            Want::Named => Some(GpuBackend::new(GpuOptions::default())?),
            Want::All => GpuBackend::new(GpuOptions::default())
                .map_err(|e| crate::say!("ogm-corners: {cmd}: no GPU rows: {e}"))
                .ok(),
        };
        let peak_gbs = gpu
            .as_ref()
            .and_then(|g| known_peak_bandwidth(&g.adapter().name));
        let gpu_info = gpu.as_ref().map(|g| {
            let a = g.adapter();
            GpuInfo {
                label: format!("{} ({}, {})", a.name, a.backend, a.device_type),
                software: a.device_type == "Cpu",
            }
        });
        Ok(Runner {
            cmd,
            cpu,
            reference,
            gpu_want,
            gpu_info,
            peak_gbs,
            gpu,
            gpu_options: GpuOptions::default(),
            repeat,
            rule_set,
            params,
            progress: std::io::stderr().is_terminal(),
        })
    }

    /// Sets the GPU's peak memory bandwidth (GB/s) that `kernel_resident` is reported against, in place of
    /// the known figure for the adapter.
    pub fn set_peak_bandwidth(&mut self, gbs: Option<f64>) {
        if gbs.is_some() {
            self.peak_gbs = gbs;
        }
    }

    /// Opens the GPU backend with `options` from here on (the GPU's tuning choices, such as the strip
    /// height, measured against the defaults); the adapter's label in the records names what differs from
    /// the defaults.
    pub fn set_gpu_options(&mut self, options: GpuOptions) -> Result<()> {
        let tuned = gpu_tuning(&options);
        if let Some(info) = self.gpu_info.as_mut().filter(|_| !tuned.is_empty()) {
            info.label = format!("{}; {tuned}", info.label);
        }
        if self.gpu.is_some() {
            self.gpu = Some(GpuBackend::new(options)?);
        }
        self.gpu_options = options;
        Ok(())
    }

    /// Times `repeat` plain reads of the map's bytes on all threads ([`crate::backend::fast::read::read_all`]), after
    /// one to warm up: the read bandwidth the CPU records are reported against. Taken before and after a
    /// map's detectors, so that a drift in the machine's speed over the run shows in both.
    pub fn read_times(&self, m: &BenchMap) -> ReadTimes {
        let px = m.map.image.pixels();
        std::hint::black_box(crate::backend::fast::read::read_all(px));
        ReadTimes(
            (0..self.repeat)
                .map(|_| {
                    let t = Instant::now();
                    std::hint::black_box(crate::backend::fast::read::read_all(
                        std::hint::black_box(px),
                    ));
                    t.elapsed().as_secs_f64() * 1e3
                })
                .collect(),
        )
    }

    /// The `read` record of a map from its read times (every one taken), and each CPU record's share of it
    /// (`read_percent`).
    pub fn read_record(
        &self,
        m: &BenchMap,
        times: &[ReadTimes],
        records: &mut [BenchRecord],
    ) -> BenchRecord {
        let (w, h) = (m.map.image.width(), m.map.image.height());
        let mpx = f64::from(w) * f64::from(h) / 1e6;
        let ms = median(times.iter().flat_map(|t| t.0.iter().copied()).collect());
        let gbs = mpx / 1e3 / (ms / 1e3);
        for r in records.iter_mut() {
            if r.backend != Engine::Gpu.name() {
                r.read_percent = Some(100.0 * r.mpx_per_s / 1e3 / gbs);
            }
        }
        BenchRecord {
            map: m.label.clone(),
            source: m.source.as_ref().map(|p| p.display().to_string()),
            image: m.image_path.as_ref().map(|p| p.display().to_string()),
            detector: "read",
            backend: Engine::Cpu.name(),
            adapter: cpu_model(),
            width: w,
            height: h,
            stage: "read",
            median_ms: ms,
            mpx_per_s: mpx / (ms / 1e3),
            gb_per_s: Some(gbs),
            peak_percent: None,
            vs_upload_ref: None,
            vs_transfer_floor: None,
            read_percent: Some(100.0),
            write_passes: None,
            dispatches: None,
            keypoints: 0,
            peak_rss_mb: None,
            peak_rss_ratio: None,
            rss_before_mb: None,
        }
    }

    /// The GPU adapter the run found ("name (backend, type)"), if it opened one.
    pub fn gpu_label(&self) -> Option<&str> {
        self.gpu_info.as_ref().map(|g| g.label.as_str())
    }

    /// Whether `all` leaves this combination out as too slow (see [`SLOW_PIXELS`]).
    fn too_slow(&self, engine: Engine, kind: DetectorKind, pixels: u64) -> bool {
        let (want, slow) = match engine {
            Engine::Cpu => (self.cpu, false),
            Engine::Reference => (self.reference, true),
            Engine::Gpu => (
                self.gpu_want,
                self.gpu_info.as_ref().is_some_and(|g| g.software),
            ),
        };
        want == Want::All && slow && kind != DetectorKind::Ogm && pixels > SLOW_PIXELS
    }

    /// Times each of `kinds` on `m` on every chosen backend: the CPU ones first, then the GPU, which is
    /// reopened per map when CPU backends run too, so that its buffers do not count in their peak memory.
    /// Fails when two backends find different keypoint lists.
    pub fn measure_map(&mut self, m: &BenchMap, kinds: &[DetectorKind]) -> Result<Vec<Measured>> {
        let (w, h) = (m.map.image.width(), m.map.image.height());
        let pixels = u64::from(w) * u64::from(h);
        let cpu_side = self.cpu != Want::No || self.reference != Want::No;
        if cpu_side {
            self.gpu = None;
        }
        let mut out: Vec<Measured> = kinds
            .iter()
            .map(|&kind| Measured {
                kind,
                keypoints: Vec::new(),
                records: Vec::new(),
            })
            .collect();
        let mut first: Vec<Option<&'static str>> = vec![None; kinds.len()];
        let mut skipped = Vec::new();
        let mut engines = Vec::new();
        if self.cpu != Want::No {
            engines.push(Engine::Cpu);
        }
        if self.reference != Want::No {
            engines.push(Engine::Reference);
        }
        if self.gpu_info.is_some() {
            engines.push(Engine::Gpu);
        }
        for engine in engines {
            if engine == Engine::Gpu && self.gpu.is_none() {
                self.gpu = Some(GpuBackend::new(self.gpu_options)?);
            }
            for (i, o) in out.iter_mut().enumerate() {
                if self.too_slow(engine, o.kind, pixels) {
                    skipped.push(format!("{} on {}", o.kind.name(), engine.name()));
                    continue;
                }
                if self.progress {
                    crate::say!(
                        "ogm-corners: {}: {} {w}x{h} {} on {}",
                        self.cmd,
                        m.label,
                        o.kind.name(),
                        engine.name()
                    );
                }
                let (records, kps) = self.measure(m, o.kind, engine)?;
                match first[i] {
                    None => {
                        first[i] = Some(engine.name());
                        o.keypoints = kps;
                    }
                    Some(a) if o.keypoints != kps => {
                        return Err(Error::Internal(format!(
                            "backends disagree on {} ({w}x{h}), detector {}: {a} found {} keypoints, {} found {}; {}",
                            m.label,
                            o.kind.name(),
                            o.keypoints.len(),
                            engine.name(),
                            kps.len(),
                            first_difference(&o.keypoints, &kps)
                        )));
                    }
                    Some(_) => {}
                }
                o.records.extend(records);
            }
        }
        if !skipped.is_empty() {
            crate::say!(
                "ogm-corners: {}: {} {w}x{h}: skipped {} (--backend all leaves out the reference and software \
                 GPU adapters on baselines over {} Mpx: minutes each; name the backend to run them, e.g. \
                 --backend cpu,reference,gpu)",
                self.cmd,
                m.label,
                skipped.join(", "),
                SLOW_PIXELS as f64 / 1e6
            );
        }
        Ok(out)
    }

    /// The records of one detector on one backend, and its keypoints.
    fn measure(
        &mut self,
        m: &BenchMap,
        kind: DetectorKind,
        engine: Engine,
    ) -> Result<(Vec<BenchRecord>, Vec<Keypoint>)> {
        let image = &m.map.image;
        let classes = ClassTable::new(&m.map.thresholds);
        let rules = RuleTable::new(self.rule_set);
        let params = self.params;
        let exact = params.exact()?;
        let repeat = self.repeat;
        // End to end through the backend trait: image in memory to keypoints in memory.
        let end_to_end = |b: &mut dyn Backend| -> Result<Vec<Keypoint>> {
            match kind {
                DetectorKind::Ogm => b.detect(image, &classes, &rules, false),
                DetectorKind::OgmRobust => {
                    crate::detect::robust::detect(b, image, &classes, &rules, &Default::default())
                        .map(|r| r.0)
                }
                DetectorKind::Baseline(k) => b.baseline_keypoints(k, image, &params),
            }
        };
        let adapter = match engine {
            Engine::Cpu | Engine::Reference => cpu_model(),
            Engine::Gpu => self
                .gpu_info
                .as_ref()
                .map_or_else(String::new, |g| g.label.clone()),
        };
        let record = recorder(m, kind, engine, adapter);
        let mut records = Vec::new();
        let keypoints =
            match engine {
                Engine::Cpu => {
                    let (kps, ms, mem) = timed(repeat, || end_to_end(&mut FastCpuBackend))?;
                    records.push(record("end_to_end", ms, mem, kps.len()));
                    kps
                }
                Engine::Reference => {
                    let (kps, ms, mem) = timed(repeat, || end_to_end(&mut ReferenceBackend))?;
                    records.push(record("end_to_end", ms, mem, kps.len()));
                    // The reference's "kernels" are the twins of the GPU kernels: the work before selection.
                    let (_, ms, mem) = timed(repeat, || {
                        reference_kernels(kind, image, &classes, &rules, &exact)
                    })?;
                    records.push(record("kernel", ms, mem, kps.len()));
                    kps
                }
                Engine::Gpu => {
                    let g = self
                        .gpu
                        .as_mut()
                        .ok_or_else(|| Error::Internal("GPU backend not open".into()))?;
                    let (mut kernel, mut launches) = (Vec::new(), Vec::new());
                    let (kps, ms, _) = timed(repeat, || {
                        let kps = end_to_end(&mut *g)?;
                        let s = g.stats();
                        kernel.extend(s.kernel_time.map(|k| k.as_secs_f64() * 1e3));
                        launches.push((s.write_passes, s.dispatches));
                        Ok(kps)
                    })?;
                    let (passes, dispatches) = most_launches(&launches);
                    let gpu_record = |stage, ms| {
                        let mut r = record(stage, ms, None, kps.len());
                        (r.write_passes, r.dispatches) = (passes, dispatches);
                        r
                    };
                    records.push(gpu_record("end_to_end", ms));
                    let e2e = records.len() - 1;
                    let why_none = || format!("{} has no timestamp queries", g.adapter().name);
                    records.extend(kernel_record(
                        kind,
                        &kernel,
                        &gpu_record,
                        self.peak_gbs,
                        &why_none,
                        self.cmd,
                    ));
                    let (r, e2e) = (&record, &mut records[e2e]);
                    let stages = transfer_stages(
                        g,
                        image,
                        repeat,
                        e2e,
                        &|st, ms| r(st, ms, None, 0),
                        self.cmd,
                    )?;
                    records.extend(stages.into_iter().map(|mut r| {
                        r.keypoints = kps.len();
                        r
                    }));
                    let tables = (&classes, &rules);
                    let resident = (kind == DetectorKind::Ogm)
                        .then(|| device_map_stage(g, image, tables, repeat, &kps, self.cmd));
                    records.extend(resident.transpose()?.flatten().map(
                        |(ms, passes, dispatches)| {
                            let mut r = record("device_map", ms, None, kps.len());
                            (r.write_passes, r.dispatches) = (Some(passes), Some(dispatches));
                            r
                        },
                    ));
                    kps
                }
            };
        Ok((records, keypoints))
    }

    /// Header lines naming the machine, the build and the backends.
    pub fn header(&self, seed: Option<u64>) -> Vec<String> {
        let mut lines = vec![format!(
            "# ogm-corners {} (git {GIT_COMMIT}); {} ({} threads, {}), {} {}; median of {} timed runs after a warm-up",
            env!("CARGO_PKG_VERSION"),
            cpu_model(),
            threads(),
            crate::backend::fast::simd::Isa::active().name(),
            std::env::consts::OS,
            std::env::consts::ARCH,
            self.repeat
        )];
        let mut b = Vec::new();
        if self.cpu != Want::No {
            b.push(format!(
                "cpu = fast CPU path on {} threads",
                rayon::current_num_threads()
            ));
        }
        if self.reference != Want::No {
            b.push("reference = single-threaded CPU reference".to_string());
        }
        if let Some(g) = &self.gpu_info {
            b.push(format!("gpu = {}", g.label));
        }
        lines.push(format!("# backends: {}", b.join("; ")));
        if let Some(g) = &self.gpu {
            let a = g.adapter();
            lines.push(format!(
                "# gpu: driver {}; subgroup size {}-{}; timestamp period {} ns; largest binding {} MiB; \
                 memory heaps not exposed by wgpu (scripts/gpu-bench.sh records vulkaninfo); peak bandwidth {}",
                a.driver,
                a.subgroup_sizes.0,
                a.subgroup_sizes.1,
                g.timestamp_period(),
                a.max_storage_buffer_binding_size.min(a.max_buffer_size) >> 20,
                self.peak_gbs
                    .map_or("unknown (--peak-bandwidth)".to_string(), |p| format!("{p} GB/s"))
            ));
            lines.push(
                "# gpu stages: kernel_resident = timestamp queries around the kernels alone; upload = the \
                 bands through the staging ring; upload_ref = the same bands from staging filled beforehand; \
                 transfer_floor = the bands copied by the device from host memory; x ref, x floor = \
                 end_to_end over those; device_map = the map already in a device buffer, detected to \
                 keypoints on the host"
                    .to_string(),
            );
        }
        if let Some(seed) = seed {
            lines.push(format!(
                "# synthetic: the office map of ogm_corners::map::synthetic, seed {seed}"
            ));
        }
        if self.cpu != Want::No || self.reference != Want::No {
            lines.push(
                "# peak MB: the process's peak resident memory while that CPU stage ran, map included; \
                 x map: peak over the map's bytes; start MB: resident when the stage started"
                    .to_string(),
            );
        }
        lines
    }
}

/// The peak memory bandwidth of GPUs we know by name, GB/s (vendor data sheets).
fn known_peak_bandwidth(adapter: &str) -> Option<f64> {
    const KNOWN: [(&str, f64); 6] = [
        ("H200", 4800.0),
        ("H100 80GB HBM3", 3350.0),
        ("H100 PCIe", 2000.0),
        ("A100-SXM4-80GB", 2039.0),
        ("L40S", 864.0),
        ("RTX 4090", 1008.0),
    ];
    KNOWN
        .iter()
        .find(|(name, _)| adapter.contains(name))
        .map(|&(_, gbs)| gbs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::baselines::Baseline;

    fn runner(cpu: Want, reference: Want, gpu_want: Want, software: bool) -> Runner {
        Runner {
            cmd: "test",
            cpu,
            reference,
            gpu_want,
            gpu_info: Some(GpuInfo {
                label: "test".into(),
                software,
            }),
            peak_gbs: None,
            gpu: None,
            gpu_options: GpuOptions::default(),
            repeat: 1,
            rule_set: RuleSet::Paper,
            params: BaselineParams::default(),
            progress: false,
        }
    }

    #[test]
    fn tuned_gpu_options_are_named_in_the_adapter_label() {
        let mut r = runner(Want::No, Want::No, Want::Named, false);
        r.set_gpu_options(GpuOptions::default()).unwrap();
        assert_eq!(r.gpu_info.as_ref().unwrap().label, "test");
        let tuned = GpuOptions {
            strip_rows: Some(8),
            copy_bands: true,
            ..GpuOptions::default()
        };
        r.set_gpu_options(tuned).unwrap();
        assert_eq!(
            r.gpu_info.as_ref().unwrap().label,
            "test; strips of 8 rows, bands copied to device buffers"
        );
        assert_eq!(r.gpu_options, tuned);
    }

    #[test]
    fn all_leaves_out_only_slow_backends_on_huge_baselines() {
        let harris = DetectorKind::Baseline(Baseline::Harris);
        let huge = 16384 * 16384;
        let r = runner(Want::All, Want::All, Want::All, true);
        assert!(r.too_slow(Engine::Reference, harris, huge));
        assert!(r.too_slow(Engine::Gpu, harris, huge));
        assert!(!r.too_slow(Engine::Cpu, harris, huge));
        assert!(!r.too_slow(Engine::Reference, DetectorKind::Ogm, huge));
        assert!(!r.too_slow(Engine::Reference, harris, 4096 * 4096));
        // A hardware adapter, or a backend named on the command line, always runs.
        assert!(!runner(Want::All, Want::All, Want::All, false).too_slow(
            Engine::Gpu,
            harris,
            huge
        ));
        let named = runner(Want::All, Want::Named, Want::Named, true);
        assert!(!named.too_slow(Engine::Reference, harris, huge));
        assert!(!named.too_slow(Engine::Gpu, harris, huge));
    }

    #[test]
    fn first_difference_names_the_index_and_both_keypoints() {
        let a = [Keypoint::scored(1, 2, 5), Keypoint::scored(3, 4, 6)];
        let b = [Keypoint::scored(1, 2, 5), Keypoint::scored(3, 4, 7)];
        let m = first_difference(&a, &b);
        assert!(
            m.contains("index 1") && m.contains("score 6") && m.contains("score 7"),
            "{m}"
        );
        assert!(first_difference(&a, &a[..1]).contains("vs nothing"));
    }
}
