//! The GPU backend (`--backend gpu`): the WGSL kernels in `shaders/` run through wgpu, headless.
//!
//! The device, pipelines and buffers live in [`GpuBackend`] and are reused across calls. A map streams
//! through the device in bands (tiles with a halo, see [`tiles`]) staged in a ring of persistent buffers;
//! the OGM detector is one fused pass per band whose counts are scanned and scattered on the device in the
//! same submission, so the list is ordered, exactly sized and never truncated, and the host waits only at
//! the end of the call. The baselines' scores stay on the device and only their candidates come back.
//!
//! - `mod.rs`: the backend and its `Backend` impl; `adapter.rs`: adapter choice; `buffers.rs`: growing
//!   buffers and the staging ring; `tiles.rs`: the tile planner; `params.rs`: the kernels' parameter
//!   blocks; `profile.rs`: the bench stages;
//! - `ogm.rs` and `ogm_call.rs`: the OGM pipeline and one call of it; `device_map.rs`: maps already in a
//!   device buffer; `scan.rs`: the device scan;
//! - `baselines.rs` and `select.rs`: the baselines' scores and selection;
//! - `coarsen.rs` (the robust detector's coarsening) and `merge_score.rs` (the merger's scoring).
//!
//! A kernel's host code bears the kernel's name where it has a file of its own (`coarsen.rs`,
//! `merge_score.rs`, `scan.rs`). `shaders/lib/` holds what the host prepends to kernels, which are not
//! kernels and have no CPU twins: `baseline_common.wgsl`, and `int64_native.wgsl` or
//! `int64_emulated.wgsl` (the same 64-bit functions, native or emulated), before the baseline kernels;
//! `ogm_fetch_runs.wgsl` or `ogm_fetch_bytes.wgsl`, the pixel readers, before `ogm_corners.wgsl`.

mod adapter;
mod baselines;
mod buffers;
mod coarsen;
mod device_map;
mod merge_score;
mod ogm;
mod ogm_call;
mod params;
mod profile;
mod scan;
mod select;
pub mod tiles;

use adapter::{choose, looked_for, report};
pub use adapter::{list_adapters, AdapterReport};
use baselines::{BParams, BASELINE_BYTES_PER_PX, BASELINE_HALO};
use buffers::{Ring, Slot};
pub use device_map::DeviceMap;
use ogm::{OgmBuffers, OgmPipelines};

use std::sync::{Arc, Mutex};
use std::time::Duration;

use wgpu::util::DeviceExt;

use crate::backend::baselines::{Baseline, ExactParams};
use crate::backend::reference::merge_score::{FixedRigid, ScoreTarget};
use crate::backend::rules::RuleTable;
use crate::backend::{Backend, DetectOptions, DetectorKind, Keypoint, OgmWindow};
use crate::map::states::ClassTable;
use crate::map::stream::Rows;
use crate::map::MapImage;
use crate::support::error::{Error, Result};

/// Workgroup size of the baseline, coarsening and scoring kernels.
const WORKGROUP: u32 = 256;

/// The WGSL source of a kernel as the GPU receives it: the baseline kernels get the shared header and the
/// 64-bit integer library (native with SHADER_INT64, emulated otherwise) prepended. `None` for an unknown
/// name.
pub fn shader_source(kernel: &str, native_int64: bool) -> Option<String> {
    let body = match kernel {
        "coarsen" => return Some(include_str!("../../../shaders/coarsen.wgsl").to_string()),
        "merge_score" => {
            return Some(include_str!("../../../shaders/merge_score.wgsl").to_string())
        }
        "ogm_corners" => return Some(ogm_shader_source(false)),
        "scan" => return Some(include_str!("../../../shaders/scan.wgsl").to_string()),
        "select_maxima" => {
            return Some(include_str!("../../../shaders/select_maxima.wgsl").to_string())
        }
        "gaussian_blur" => include_str!("../../../shaders/gaussian_blur.wgsl"),
        "structure_tensor" => include_str!("../../../shaders/structure_tensor.wgsl"),
        "harris" => include_str!("../../../shaders/harris.wgsl"),
        "shi_tomasi" => include_str!("../../../shaders/shi_tomasi.wgsl"),
        "trajkovic" => include_str!("../../../shaders/trajkovic.wgsl"),
        _ => return None,
    };
    let int64 = if native_int64 {
        include_str!("../../../shaders/lib/int64_native.wgsl")
    } else {
        include_str!("../../../shaders/lib/int64_emulated.wgsl")
    };
    Some(format!(
        "{}\n{int64}\n{body}",
        include_str!("../../../shaders/lib/baseline_common.wgsl")
    ))
}

/// The OGM detector's WGSL as the GPU receives it: the kernel with the library that reads its pixels
/// prepended, the aligned form (two 16-byte loads a run of 32 pixels) or, with `any_alignment`, the form
/// that reads a map at any byte offset and row pitch.
pub fn ogm_shader_source(any_alignment: bool) -> String {
    let fetch = if any_alignment {
        include_str!("../../../shaders/lib/ogm_fetch_bytes.wgsl")
    } else {
        include_str!("../../../shaders/lib/ogm_fetch_runs.wgsl")
    };
    format!(
        "{fetch}\n{}",
        include_str!("../../../shaders/ogm_corners.wgsl")
    )
}

/// Options of the GPU backend. The defaults suit real use; tests shrink them to force tiling and the
/// multi-pass output path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GpuOptions {
    /// Cap on the tile core size (width, height); `None` uses the device limits alone.
    pub tile: Option<(u32, u32)>,
    /// Keypoints the output buffer holds before it first grows.
    pub initial_keypoint_capacity: u32,
    /// Cap on keypoints written per pass; `None` uses the device's binding limit.
    pub max_keypoints_per_pass: Option<u32>,
    /// Keypoints each OGM workgroup's scratch holds before it first grows (a workgroup that finds more
    /// makes the call rerun with room for them).
    pub initial_workgroup_scratch: u32,
    /// Rows of one OGM slab (at most 2^24, the keypoint's row field); tests shrink it to run the slab path.
    pub slab_rows: u32,
    /// Rows each OGM invocation walks down (1 to 16); `None` lets the backend choose: 16, the fewest halo
    /// rows read twice, unless a small map would then leave a GPU short of workgroups.
    pub strip_rows: Option<u32>,
    /// Copy each staged band of a map into a device buffer before the OGM kernel reads it, even where the
    /// kernel could read the staging buffer itself (to test the copying path).
    pub copy_bands: bool,
    /// Use the exact 64-bit emulation even where the adapter has SHADER_INT64 (to test it).
    pub emulate_int64: bool,
    /// Upload budget of one band, bytes: a large map streams through the GPU in bands of about this size,
    /// the host staging the next band while the GPU runs the current one, instead of the whole map sitting
    /// on the device (and in host staging memory) at once. It also bounds the baselines' bands, the
    /// coarsening kernel's tiles and the scoring kernel's bands of target rows and chunks of points.
    pub max_tile_bytes: u64,
}

impl Default for GpuOptions {
    fn default() -> Self {
        GpuOptions {
            tile: None,
            initial_keypoint_capacity: 1 << 16,
            max_keypoints_per_pass: None,
            initial_workgroup_scratch: 512,
            slab_rows: 1 << 24,
            strip_rows: None,
            copy_bands: false,
            emulate_int64: false,
            max_tile_bytes: 64 << 20,
        }
    }
}

/// Statistics of the last call, for benchmarks and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuStats {
    /// Tiles the map was split into.
    pub tiles: usize,
    /// Write passes run: passes writing the keypoint list, one a slab of rows for the OGM detector (each
    /// over all the slab's tiles), one a tile for the baselines; more when a list outgrew its buffer (it
    /// then grows to the whole list, so a later call on a like map takes one).
    pub write_passes: usize,
    /// OGM runs repeated because a workgroup found more keypoints than its scratch held.
    pub scratch_reruns: usize,
    /// Compute dispatches the call recorded (every kernel and every level of the prefix scans, over all
    /// its tiles and passes): with `write_passes`, what one map costs in GPU launches.
    pub dispatches: usize,
    /// Bands of a map in host memory copied from staging into a device buffer before the OGM kernel read
    /// them: none where the kernel reads the staging buffers themselves.
    pub pixel_copies: usize,
    /// Keypoint buffer capacity after the call, in keypoints.
    pub keypoint_capacity: u64,
    /// Kernel time measured on the GPU (timestamp queries), when the adapter supports it.
    pub kernel_time: Option<Duration>,
}

/// The GPU backend: device, queue, pipelines and buffers, kept between calls.
pub struct GpuBackend {
    adapter: AdapterReport,
    device: wgpu::Device,
    queue: wgpu::Queue,
    options: GpuOptions,
    /// The OGM detector's pipelines and buffers (ogm.rs, scan.rs).
    ogm: OgmPipelines,
    ogm_bufs: OgmBuffers,
    /// Staging buffers for the map's bands, recycled (buffers.rs).
    ring: Ring,
    readback: Slot,
    /// Start and end timestamps of the baseline, coarsening and scoring passes.
    timestamps: Option<(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
    max_binding: u64,
    max_groups: u32,
    /// Alignment of a storage binding's offset, bytes.
    storage_align: u64,
    error: Arc<Mutex<Option<String>>>,
    stats: GpuStats,
    /// Host copy of a padded band for the coarsening and scoring kernels.
    staging: Vec<u8>,
    native_int64: bool,
    kernel_pipelines: std::collections::HashMap<&'static str, wgpu::ComputePipeline>,
    bp_buf: wgpu::Buffer,
    bp_core: wgpu::Buffer,
    base_pixels: Slot,
    /// The baselines' selection on the device (select.rs), made on first use.
    select: Option<select::Select>,
    blurred: Slot,
    tensor: Slot,
    scores: Slot,
    /// The device copies from buffers in host memory (`MAPPABLE_PRIMARY_BUFFERS`): the transfer floor.
    host_copies: bool,
}

impl GpuBackend {
    /// A backend on the adapter wgpu offers (see [`GpuBackend::open`]); fails with a clear error naming what
    /// it looked for when there is none.
    pub fn new(options: GpuOptions) -> Result<Self> {
        match Self::open(false, options)? {
            Some(b) => Ok(b),
            None => Err(Error::Unavailable(format!(
                "no GPU adapter found: looked for {}; install a Vulkan driver (on Debian: \
                 apt-get install mesa-vulkan-drivers, for the lavapipe software adapter) or use --backend cpu",
                looked_for()
            ))),
        }
    }

    /// Opens an adapter: the one `WGPU_ADAPTER_NAME` names, else the best GPU; with `hardware_only`,
    /// returns `Ok(None)` rather than a software adapter.
    pub fn open(hardware_only: bool, options: GpuOptions) -> Result<Option<Self>> {
        let Some((_instance, adapter)) = choose(hardware_only)? else {
            return Ok(None);
        };
        Self::from_adapter(&adapter, options).map(Some)
    }

    fn from_adapter(adapter: &wgpu::Adapter, options: GpuOptions) -> Result<Self> {
        let report = report(adapter);
        // Timestamps, 64-bit integers where the adapter has them, and buffers the host maps that kernels
        // may also read (the OGM kernel reads its staged bands in place) and that the GPU copies from
        // (bench's transfer floor, profile.rs).
        let features = adapter.features()
            & (wgpu::Features::TIMESTAMP_QUERY
                | wgpu::Features::SHADER_INT64
                | wgpu::Features::MAPPABLE_PRIMARY_BUFFERS);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("ogm-corners"),
            required_features: features,
            required_limits: adapter.limits(),
            memory_hints: wgpu::MemoryHints::Performance,
            ..Default::default()
        }))
        .map_err(|e| Error::Unavailable(format!("cannot open {}: {e}", report.name)))?;
        Self::with_device(report, device, queue, options)
    }

    /// A backend on a device the caller opened (a mapping pipeline's own), so that maps it keeps in its
    /// buffers can be detected where they are ([`GpuBackend::detect_device_map`]). `adapter` is the one
    /// the device came from. The backend uses what the device was opened with: its limits bound the
    /// tiles, and timestamps, 64-bit integers and host-memory copies are used where its features include
    /// them. It installs the device's uncaptured-error handler (replacing one set before), so that a
    /// device error fails the backend's call instead of panicking.
    pub fn from_device(
        adapter: &wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
        options: GpuOptions,
    ) -> Result<Self> {
        Self::with_device(report(adapter), device, queue, options)
    }

    /// The device the backend runs on, for making buffers it can read ([`DeviceMap`]).
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The device's queue, for writing maps into buffers on it.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    fn with_device(
        mut report: AdapterReport,
        device: wgpu::Device,
        queue: wgpu::Queue,
        options: GpuOptions,
    ) -> Result<Self> {
        let limits = device.limits();
        let features = device.features();
        report.timestamp_query = features.contains(wgpu::Features::TIMESTAMP_QUERY);
        report.shader_int64 = features.contains(wgpu::Features::SHADER_INT64);
        let native_int64 = report.shader_int64 && !options.emulate_int64;
        let host_copies = features.contains(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS);
        // wgpu's default handler panics; keep the error and report it from the call instead.
        let error = Arc::new(Mutex::new(None::<String>));
        let slot = error.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let mut s = slot.lock().unwrap_or_else(|p| p.into_inner());
            s.get_or_insert_with(|| e.to_string().replace('\n', " "));
        }));
        let timestamps = report.timestamp_query.then(|| {
            let set = device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("kernel timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            });
            let resolve = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp readback"),
                size: 16,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            (set, resolve, read)
        });
        let uniform = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: std::mem::size_of::<BParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let backend = GpuBackend {
            native_int64,
            kernel_pipelines: Default::default(),
            bp_buf: uniform("baseline params (buffer pixels)"),
            bp_core: uniform("baseline params (core pixels)"),
            base_pixels: Slot::new("baseline pixels", storage),
            select: None,
            blurred: Slot::new("blurred", wgpu::BufferUsages::STORAGE),
            tensor: Slot::new("tensor", wgpu::BufferUsages::STORAGE),
            scores: Slot::new(
                "scores",
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            ),
            max_binding: limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size),
            max_groups: limits.max_compute_workgroups_per_dimension,
            storage_align: u64::from(limits.min_storage_buffer_offset_alignment).max(16),
            ogm: OgmPipelines::new(&device),
            ogm_bufs: OgmBuffers::new(&device, options.initial_workgroup_scratch),
            ring: Ring::new(2, host_copies),
            adapter: report,
            device,
            queue,
            options,
            readback: Slot::new(
                "readback",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            timestamps,
            error,
            stats: GpuStats::default(),
            staging: Vec::new(),
            host_copies,
        };
        backend.check()?;
        Ok(backend)
    }

    /// Alignment of a storage binding's offset on this device, bytes.
    fn storage_align(&self) -> u64 {
        self.storage_align
    }

    /// Whether the OGM kernel reads a staged band in its staging buffer, with no copy into device
    /// memory: where buffers the host maps may also be bound to kernels (`MAPPABLE_PRIMARY_BUFFERS`).
    /// With a resizable BAR the staging buffer is device memory already.
    pub fn reads_staging(&self) -> bool {
        self.host_copies && !self.options.copy_bands
    }

    /// The adapter in use.
    pub fn adapter(&self) -> &AdapterReport {
        &self.adapter
    }

    /// The baseline tiles of rows `core` of a `w` x `h` map: within the binding limit at the largest
    /// buffer's bytes per pixel.
    fn baseline_plan(&self, w: u32, h: u32, core: (usize, usize)) -> Result<Vec<tiles::Tile>> {
        let (y0, y1) = (core.0 as u32, core.1 as u32);
        // Within one binding at the largest buffer's bytes per pixel, and a band of raw pixels within the
        // staging budget.
        let max_px =
            (self.max_binding / BASELINE_BYTES_PER_PX).min(self.options.max_tile_bytes.max(1));
        let (tw, th) = tiles::tile_size_halo(w, y1 - y0, max_px, BASELINE_HALO, self.options.tile)
            .ok_or_else(|| {
                Error::Unavailable(format!(
                    "{}'s buffer limit ({} bytes) is too small for any tile",
                    self.adapter.name, self.max_binding
                ))
            })?;
        Ok(tiles::plan_rows(w, h, y0, y1, tw, th, BASELINE_HALO))
    }

    /// Begins a detection call: fails with a device error left from before, and clears the statistics.
    fn start_call(&mut self) -> Result<()> {
        self.check()?;
        self.stats = GpuStats {
            kernel_time: self.timestamps.as_ref().map(|_| Duration::ZERO),
            ..GpuStats::default()
        };
        Ok(())
    }

    /// Nanoseconds per timestamp tick.
    pub fn timestamp_period(&self) -> f32 {
        self.queue.get_timestamp_period()
    }

    /// Statistics of the last call.
    pub fn stats(&self) -> GpuStats {
        self.stats
    }

    /// Fails with the first device error seen since the last check.
    fn check(&self) -> Result<()> {
        let mut slot = self.error.lock().unwrap_or_else(|p| p.into_inner());
        match slot.take() {
            Some(e) => Err(Error::Internal(format!(
                "GPU error on {}: {e}",
                self.adapter.name
            ))),
            None => Ok(()),
        }
    }

    /// Submits `encoder`, then copies the first `size` bytes of `src` back to the host; with `timed`, adds
    /// the passes' time (their first and last timestamps) to the call's kernel time.
    fn submit_and_read(
        &mut self,
        mut encoder: wgpu::CommandEncoder,
        src: &wgpu::Buffer,
        size: u64,
        timed: bool,
    ) -> Result<Vec<u8>> {
        let size = size.next_multiple_of(4);
        let read = self.readback.get(&self.device, size, u64::MAX).clone();
        encoder.copy_buffer_to_buffer(src, 0, &read, 0, size);
        if timed {
            self.resolve_timestamps(&mut encoder);
        }
        self.queue.submit([encoder.finish()]);
        let data = self.map_read(&read, size)?;
        if timed {
            self.add_kernel_time()?;
        }
        Ok(data)
    }

    /// Records the copy of the passes' two timestamps to the host into `encoder`.
    fn resolve_timestamps(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some((set, resolve, ts_read)) = &self.timestamps {
            encoder.resolve_query_set(set, 0..2, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, ts_read, 0, 16);
        }
    }

    /// Adds the time between the timestamps [`Self::resolve_timestamps`] copied to the call's kernel time.
    fn add_kernel_time(&mut self) -> Result<()> {
        if let Some((_, _, ts_read)) = &self.timestamps {
            let ts_read = ts_read.clone();
            let ts = self.map_read(&ts_read, 16)?;
            let t0 = u64::from_le_bytes(ts[0..8].try_into().expect("8 bytes"));
            let t1 = u64::from_le_bytes(ts[8..16].try_into().expect("8 bytes"));
            let ns = t1.saturating_sub(t0) as f64 * f64::from(self.queue.get_timestamp_period());
            let prev = self.stats.kernel_time.unwrap_or_default();
            self.stats.kernel_time = Some(prev + Duration::from_nanos(ns as u64));
        }
        Ok(())
    }

    fn map_read(&self, buf: &wgpu::Buffer, size: u64) -> Result<Vec<u8>> {
        let data = buffers::map_read(&self.device, buf, size)?;
        self.check()?;
        Ok(data)
    }

    /// A 2D dispatch of at least `groups` workgroups within the per-dimension limit.
    fn dispatch_shape_groups(&self, groups: u32) -> (u32, u32) {
        let groups = groups.max(1);
        let gx = groups.min(self.max_groups);
        (gx, groups.div_ceil(gx))
    }

    /// Records one compute pass per (pipeline, bind group, workgroups); the first pass writes the start
    /// timestamp and the last the end one, so the kernels' time covers them all.
    fn encode(
        &mut self,
        dispatches: &[(&wgpu::ComputePipeline, &wgpu::BindGroup, (u32, u32))],
    ) -> wgpu::CommandEncoder {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let ts = self.timestamps.as_ref().map(|t| &t.0);
        let last = dispatches.len().saturating_sub(1);
        self.stats.dispatches += dispatches.len();
        for (n, (pipeline, bind_group, (gx, gy))) in dispatches.iter().enumerate() {
            let mut pass = Self::pass(&mut encoder, ts, n == 0, n == last);
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, *bind_group, &[]);
            pass.dispatch_workgroups(*gx, *gy, 1);
        }
        encoder
    }

    fn pass<'e>(
        encoder: &'e mut wgpu::CommandEncoder,
        ts: Option<&'e wgpu::QuerySet>,
        begin: bool,
        end: bool,
    ) -> wgpu::ComputePass<'e> {
        encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: None,
            timestamp_writes: ts.filter(|_| begin || end).map(|query_set| {
                wgpu::ComputePassTimestampWrites {
                    query_set,
                    beginning_of_pass_write_index: begin.then_some(0),
                    end_of_pass_write_index: end.then_some(1),
                }
            }),
        })
    }

    fn bind(
        &self,
        pipeline: &wgpu::ComputePipeline,
        entries: &[(u32, &wgpu::Buffer)],
    ) -> wgpu::BindGroup {
        buffers::bind_group(&self.device, pipeline, entries)
    }
}

/// [`Backend::working_bytes`] of a GPU backend opened with `gpu`, known before opening it: the staging
/// ring's two bands (each at most [`GpuOptions::max_tile_bytes`]), and for Shi-Tomasi the minimum-distance
/// grid. The baselines' scores stay on the device; their candidates (positive local maxima, 16 bytes each)
/// come back like keypoints, data-dependent.
pub fn gpu_working_bytes(
    gpu: &GpuOptions,
    options: &DetectOptions,
    width: u32,
    height: u32,
) -> u64 {
    let ring = gpu
        .max_tile_bytes
        .saturating_add(ogm::PARAMS_BYTES)
        .saturating_mul(2);
    let px = u64::from(width) * u64::from(height);
    match options.detector {
        DetectorKind::OgmRobust => {
            crate::backend::robust_params::robust_working_bytes(width, height, &options.robust)
                .saturating_add(ring)
        }
        DetectorKind::Baseline(Baseline::ShiTomasi) => {
            crate::backend::shi_tomasi_selection_bytes(options, width, height)
                .saturating_sub(px.saturating_mul(8))
                .saturating_add(ring)
        }
        DetectorKind::Ogm | DetectorKind::Baseline(_) => ring,
    }
}

impl Backend for GpuBackend {
    fn baseline_scores(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        params: &ExactParams,
    ) -> Result<Vec<i64>> {
        self.start_call()?;
        let plan =
            self.baseline_plan(image.width(), image.height(), (0, image.height() as usize))?;
        self.stats.tiles = plan.len();
        let mut out = vec![0i64; image.len()];
        for t in &plan {
            self.run_baseline_tile(kind, image, params, t, &mut out)?;
        }
        self.check()?;
        Ok(out)
    }

    fn name(&self) -> String {
        format!("gpu ({}, {})", self.adapter.name, self.adapter.backend)
    }

    fn coarsen(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        grid: &crate::map::grid::RotatedGrid,
        scales: &[u32],
        rule: crate::backend::reference::coarsen::CellRule,
    ) -> Result<Vec<MapImage>> {
        self.coarsen_maps(image, classes, grid, scales, rule)
    }

    fn score_transforms(
        &mut self,
        target: &ScoreTarget,
        points: &[[u32; 2]],
        transforms: &[FixedRigid],
    ) -> Result<Vec<[u32; 3]>> {
        self.score_transforms_gpu(target, points, transforms)
    }

    /// The host side: see [`gpu_working_bytes`].
    fn working_bytes(&self, options: &DetectOptions, width: u32, height: u32) -> u64 {
        gpu_working_bytes(&self.options, options, width, height)
    }

    fn detect(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        rules: &RuleTable,
        unknown_as_occupied: bool,
    ) -> Result<Vec<Keypoint>> {
        let core = (0, image.height() as usize);
        self.detect_rows(OgmWindow {
            rows: Rows::of(image),
            core,
            classes,
            rules,
            unknown_as_occupied,
        })
    }

    fn detect_rows(&mut self, w: OgmWindow) -> Result<Vec<Keypoint>> {
        let src = device_map::Source::Host(w.rows);
        self.ogm_call(src, w.core, w.classes, w.rules, w.unknown_as_occupied)
    }

    /// The device's candidates of the core's rows ([`GpuBackend::baseline_candidates_rows`]): only the
    /// candidates cross to the host, not the score map.
    fn baseline_rows(
        &mut self,
        kind: Baseline,
        rows: Rows,
        core: (usize, usize),
        params: &crate::backend::baselines::BaselineParams,
        _known_max: i64,
    ) -> Result<(Vec<crate::backend::baselines::Candidate>, i64)> {
        self.baseline_candidates_rows(kind, rows, core, &params.exact()?)
    }

    /// Windows of 16 MiB: the device keeps its own tiles, the host only the windows.
    fn window_bytes(&self, _options: &DetectOptions) -> u64 {
        16 << 20
    }
}
