//! The detector API: a [`Detector`] runs one of the detectors on a backend and returns a [`Detection`].

use crate::backend::baselines::streamed::CandidateList;
use crate::backend::baselines::Candidate;
use crate::backend::fast::FastCpuBackend;
use crate::backend::rules::RuleTable;
use crate::backend::OgmWindow;
pub use crate::backend::{Backend, DetectOptions, DetectorKind, Keypoint};
use crate::detect::robust::RobustInfo;
use crate::map::states::ClassTable;
use crate::map::stream::{for_each_window, RowSource, Rows, Window, WindowPlan};
use crate::map::{GeoRef, MapImage, OccupancyMap, Thresholds};
use crate::support::error::{Error, Result};

/// The keypoints found in one map.
#[derive(Clone, Debug, PartialEq)]
pub struct Detection {
    /// Map width in pixels.
    pub width: u32,
    /// Map height in pixels.
    pub height: u32,
    /// Keypoints sorted by (y, x).
    pub keypoints: Vec<Keypoint>,
    /// What the robust detector measured (its grid angle); `None` for the other detectors.
    pub robust: Option<RobustInfo>,
}

/// Detects corners in maps; keep one and reuse it so backend set-up is paid once.
pub struct Detector {
    options: DetectOptions,
    rules: RuleTable,
    backend: Box<dyn Backend>,
    /// Pixels a streamed window holds, when not the backend's choice.
    window_bytes: Option<u64>,
}

impl Detector {
    /// A detector on the fast CPU backend ([`FastCpuBackend`]).
    pub fn new(options: DetectOptions) -> Self {
        Self::with_backend(options, Box::new(FastCpuBackend))
    }

    /// A detector on the given backend.
    pub fn with_backend(options: DetectOptions, backend: Box<dyn Backend>) -> Self {
        Detector {
            options,
            rules: RuleTable::new(options.rules),
            backend,
            window_bytes: None,
        }
    }

    /// Changes the options, keeping the backend (and its set-up).
    pub fn set_options(&mut self, options: DetectOptions) {
        if options.rules != self.options.rules {
            self.rules = RuleTable::new(options.rules);
        }
        self.options = options;
    }

    /// The options this detector was built with.
    pub fn options(&self) -> DetectOptions {
        self.options
    }

    /// The derived rule table.
    pub fn rule_table(&self) -> &RuleTable {
        &self.rules
    }

    /// The backend's name.
    pub fn backend_name(&self) -> String {
        self.backend.name()
    }

    /// Bytes the backend allocates to detect in a `width` x `height` map beyond the map and the keypoints
    /// ([`Backend::working_bytes`]).
    pub fn working_bytes(&self, width: u32, height: u32) -> u64 {
        self.backend.working_bytes(&self.options, width, height)
    }

    /// [`Detector::working_bytes`] with other options (the backend stays).
    pub fn working_bytes_with(&self, options: &DetectOptions, width: u32, height: u32) -> u64 {
        self.backend.working_bytes(options, width, height)
    }

    /// Detects corners in a loaded map, with the map's own thresholds; the robust detector's grid is
    /// anchored at the map's world origin where it has one ([`crate::detect::robust::Anchor::World`]).
    pub fn detect(&mut self, map: &OccupancyMap) -> Result<Detection> {
        let classes = ClassTable::new(&map.thresholds);
        self.detect_as(&map.image, &classes, false, map.georef.as_ref())
    }

    /// Detects corners in an image, reading its pixels with `thresholds` (no world frame: the robust
    /// detector's grid is anchored at the image's centre unless its options name a point).
    pub fn detect_image(&mut self, image: &MapImage, thresholds: &Thresholds) -> Result<Detection> {
        self.detect_as(image, &ClassTable::new(thresholds), false, None)
    }

    /// Detects corners in an image whose values `classes` reads, such as `nav_msgs/OccupancyGrid` cells
    /// in place ([`crate::map::GridThresholds::class_table`]). The baselines, which read grey levels,
    /// see the three states drawn as `map_server` draws them (a copy of the image).
    pub fn detect_classified(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
    ) -> Result<Detection> {
        self.detect_as(image, classes, true, None)
    }

    /// The detection; `redraw`: the baselines read the states' grey levels, not the image's values;
    /// `frame`: where the map lies in the world, if known.
    fn detect_as(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        redraw: bool,
        frame: Option<&GeoRef>,
    ) -> Result<Detection> {
        let (w, h) = (image.width(), image.height());
        let mut robust = None;
        let keypoints = match self.options.detector {
            DetectorKind::OgmRobust => {
                let (k, info) = crate::detect::robust::detect(
                    &mut *self.backend,
                    image,
                    classes,
                    &self.rules,
                    &self.options.robust.in_frame(frame, h),
                )?;
                robust = Some(info);
                match self.options.max_corners {
                    Some(n) => strongest(k, n, DetectorKind::OgmRobust)?,
                    None => k,
                }
            }
            kind => {
                // The map in memory is one window of the streamed path.
                let grey;
                let image = if redraw && matches!(kind, DetectorKind::Baseline(_)) {
                    let value = classes.map_server_values();
                    let px = image.pixels().iter().map(|&v| value[v as usize]).collect();
                    grey = MapImage::new(w, h, px)?;
                    &grey
                } else {
                    image
                };
                let mut one = |f: &mut dyn FnMut(Window) -> Result<()>| {
                    f(Window {
                        rows: Rows::of(image),
                        core: (0, h as usize),
                    })
                    .map(|()| Vec::new())
                };
                let mut out = Vec::new();
                self.run_windows(&mut one, classes, (w, h), &mut |k| {
                    out.extend_from_slice(k);
                    Ok(())
                })?;
                out
            }
        };
        Ok(Detection {
            width: w,
            height: h,
            keypoints,
            robust,
        })
    }

    /// Detects corners in a map read row by row from `source`, whose values `classes` reads, holding a few
    /// windows of rows at a time ([`crate::map::stream`]): the memory is bounded by the windows and the
    /// keypoints, not by the map, and the keypoints are those of [`Detector::detect_image`] on the whole
    /// map, bit for bit, in the same order. They go to `sink` in (y, x) order: window by window for the OGM
    /// detector (without `max_corners`), at the end (in chunks of 65536) for the baselines, whose thresholds
    /// need the map's maximum, and with `max_corners`. `on_rows` sees each window's rows and core first (to
    /// draw a downsampled picture).
    ///
    /// The robust detector turns the whole map to its walls, so it reads the rows once into a temporary
    /// file and works in tiles of its turned grid ([`crate::detect::robust::tiles`]): memory bounded by one tile's
    /// window (and the corners no window could rule out); its keypoints come at the end. `on_rows` sees
    /// the rows as they are read.
    ///
    /// `frame` is where the map lies in the world, if known: the robust detector's grid is anchored at its
    /// origin ([`crate::detect::robust::Anchor::World`]), as [`Detector::detect`] anchors it.
    pub fn detect_streamed(
        &mut self,
        source: &mut dyn RowSource,
        classes: &ClassTable,
        frame: Option<&GeoRef>,
        sink: &mut dyn FnMut(&[Keypoint]) -> Result<()>,
        on_rows: &mut dyn FnMut(Rows, (usize, usize)),
    ) -> Result<Streamed> {
        let (w, h) = (source.width(), source.height());
        if self.options.detector == DetectorKind::OgmRobust {
            use crate::detect::robust::tiles::{detect_tiled, Spill};
            let params = self.options.robust.in_frame(frame, h);
            let plan = self.tile_plan()?;
            // A map the turned grid cannot hold is refused before its rows are copied.
            crate::map::grid::RotatedGrid::new(w, h, 0.0)?;
            let (mut spill, warnings) = Spill::from_source(source, on_rows)?;
            let (found, info) = detect_tiled(
                &mut *self.backend,
                &mut spill,
                classes,
                &self.rules,
                &params,
                &plan,
            )?;
            let found = match self.options.max_corners {
                Some(n) => strongest(found, n, DetectorKind::OgmRobust)?,
                None => found,
            };
            for chunk in found.chunks(SINK_CHUNK) {
                sink(chunk)?;
            }
            return Ok(Streamed {
                width: w,
                height: h,
                count: found.len() as u64,
                warnings,
                robust: Some(info),
            });
        }
        let plan = self.window_plan(w);
        let mut windows = |f: &mut dyn FnMut(Window) -> Result<()>| {
            for_each_window(source, plan, &mut |win| {
                on_rows(win.rows, win.core);
                f(win)
            })
        };
        let mut count = 0u64;
        let warnings = self.run_windows(&mut windows, classes, (w, h), &mut |k| {
            count += k.len() as u64;
            sink(k)
        })?;
        Ok(Streamed {
            width: w,
            height: h,
            count,
            warnings,
            robust: None,
        })
    }

    /// The tiles the robust detector works in when streamed: windows of about
    /// [`Detector::window_bytes`] each.
    pub fn tile_plan(&self) -> Result<crate::detect::robust::tiles::TilePlan> {
        crate::detect::robust::tiles::TilePlan::with_bytes(
            &self.options.robust,
            self.window_bytes(),
        )
    }

    /// How [`Detector::detect_streamed`] cuts a map `width` wide into windows: about
    /// [`Backend::window_bytes`] of pixels each, or what [`Detector::set_window_bytes`] set.
    pub fn window_plan(&self, width: u32) -> WindowPlan {
        let bytes = self.window_bytes();
        let halo = match self.options.detector {
            DetectorKind::Ogm => crate::map::stream::OGM_HALO,
            _ => crate::map::stream::HALO,
        };
        WindowPlan::with_bytes(width, bytes, halo)
    }

    /// Sets the pixels a streamed window holds (`None`: the backend's choice). Smaller windows hold less
    /// memory and pay more halo rows; the keypoints are the same for every size.
    pub fn set_window_bytes(&mut self, bytes: Option<u64>) {
        self.window_bytes = bytes;
    }

    /// The pixels a streamed window holds now ([`Detector::set_window_bytes`], else the backend's choice;
    /// for the robust detector, the working memory of a tile's window, [`ROBUST_WINDOW_BYTES`] unless set).
    pub fn window_bytes(&self) -> u64 {
        self.window_bytes
            .unwrap_or_else(|| match self.options.detector {
                DetectorKind::OgmRobust => ROBUST_WINDOW_BYTES,
                _ => self.backend.window_bytes(&self.options),
            })
    }

    /// Bytes [`Detector::detect_streamed`] allocates for a `width` x `height` map beyond the keypoints
    /// (and the decoder's own buffers): the windows in flight, and the backend's working memory for one.
    pub fn streamed_bytes(&self, width: u32, height: u32) -> u64 {
        if self.options.detector == DetectorKind::OgmRobust {
            // One tile's window at a time, and a chunk of the temporary file's rows; a plan the options
            // refuse needs nothing (the detection reports them).
            // A window never exceeds the whole grid (and its crop the map).
            let whole =
                crate::detect::robust::robust_working_bytes(width, height, &self.options.robust)
                    .saturating_add(u64::from(width) * u64::from(height));
            return self.tile_plan().map_or(0, |p| {
                p.bytes()
                    .min(whole)
                    .saturating_add(crate::detect::robust::tiles::Spill::bytes(width))
            });
        }
        let plan = self.window_plan(width);
        let rows = (plan.core_rows + 2 * plan.halo).min(height as usize) as u32;
        plan.bytes(width, height)
            .saturating_add(self.backend.working_bytes(&self.options, width, rows))
    }

    /// The OGM detector and the baselines over the windows `windows` hands to its argument; keypoints to
    /// `sink`. Returns what `windows` returns (the source's warnings).
    fn run_windows(
        &mut self,
        windows: &mut WindowsOf,
        classes: &ClassTable,
        (w, h): (u32, u32),
        sink: &mut dyn FnMut(&[Keypoint]) -> Result<()>,
    ) -> Result<Vec<String>> {
        let Detector {
            options,
            rules,
            backend,
            ..
        } = self;
        let max_corners = options.max_corners;
        match options.detector {
            DetectorKind::OgmRobust => {
                Err(Error::Internal("the robust detector has no windows".into()))
            }
            DetectorKind::Ogm => {
                let mut held = Vec::new();
                let warnings = windows(&mut |win| {
                    let found = backend.detect_rows(OgmWindow {
                        rows: win.rows,
                        core: win.core,
                        classes,
                        rules,
                        unknown_as_occupied: options.unknown_as_occupied,
                    })?;
                    match max_corners {
                        None => sink(&found),
                        Some(_) => {
                            held.extend(found);
                            Ok(())
                        }
                    }
                })?;
                if let Some(n) = max_corners {
                    sink_strongest(held, n, DetectorKind::Ogm, sink)?;
                }
                Ok(warnings)
            }
            DetectorKind::Baseline(kind) => {
                let params = options.baseline;
                let mut list = CandidateList::new(kind, &params);
                let warnings = windows(&mut |win| {
                    let (found, max) = backend.baseline_rows(
                        kind,
                        win.rows,
                        win.core,
                        &params,
                        list.known_max(),
                    )?;
                    list.add(found, max);
                    Ok(())
                })?;
                let found = list.finish(w, h, &params);
                let scored = |c: &[Candidate]| -> Vec<Keypoint> {
                    c.iter()
                        .map(|&(x, y, v)| Keypoint::scored(x, y, v))
                        .collect()
                };
                match max_corners {
                    Some(n) => sink_strongest(scored(&found), n, options.detector, sink)?,
                    // In chunks: a second list of all the keypoints would double the peak on huge maps.
                    None => {
                        for chunk in found.chunks(SINK_CHUNK) {
                            sink(&scored(chunk))?;
                        }
                    }
                }
                Ok(warnings)
            }
        }
    }
}

/// Hands the `n` strongest of `found` ([`strongest`]) to `sink`, unless there are none.
fn sink_strongest(
    found: Vec<Keypoint>,
    n: usize,
    kind: DetectorKind,
    sink: &mut dyn FnMut(&[Keypoint]) -> Result<()>,
) -> Result<()> {
    let kept = strongest(found, n, kind)?;
    if kept.is_empty() {
        return Ok(());
    }
    sink(&kept)
}

/// Something that calls its argument on every window of a map and returns the source's warnings.
type WindowsOf<'a> = dyn FnMut(&mut dyn FnMut(Window) -> Result<()>) -> Result<Vec<String>> + 'a;

/// Keypoints handed to a sink at once when they are all known (the baselines).
const SINK_CHUNK: usize = 1 << 16;

/// What a streamed detection saw ([`Detector::detect_streamed`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Streamed {
    /// Map width in pixels.
    pub width: u32,
    /// Map height in pixels.
    pub height: u32,
    /// Keypoints handed to the sink.
    pub count: u64,
    /// The source's warnings (such as trailing bytes ignored).
    pub warnings: Vec<String>,
    /// What the robust detector measured (its grid angle); `None` for the other detectors.
    pub robust: Option<RobustInfo>,
}

/// Working memory of a streamed robust detection's tile window by default: tiles of about 4,600 samples
/// a side at the default scales (the halo and ring around a tile are about 980 samples, so larger tiles
/// waste less).
pub const ROBUST_WINDOW_BYTES: u64 = 512 << 20;

/// Where to detect: the backends a user chooses among by name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BackendChoice {
    /// A hardware GPU adapter when there is one, else the fast CPU path (software adapters such as
    /// lavapipe are slower than the CPU, so not picked).
    #[default]
    Auto,
    /// The fast CPU path: all cores, bit-planes and SIMD.
    Cpu,
    /// The plain single-threaded CPU reference, the oracle the other backends are tested against.
    Reference,
    /// A GPU adapter through wgpu (software adapters included); an error without one.
    Gpu,
}

impl BackendChoice {
    /// The names users write: `auto`, `cpu`, `reference`, `gpu`.
    pub const NAMES: [&'static str; 4] = ["auto", "cpu", "reference", "gpu"];

    /// The choice a name gives (as [`BackendChoice::NAMES`]), or a one-line error listing them.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "auto" => Ok(BackendChoice::Auto),
            "cpu" => Ok(BackendChoice::Cpu),
            "reference" => Ok(BackendChoice::Reference),
            "gpu" => Ok(BackendChoice::Gpu),
            other => Err(Error::invalid(format!(
                "unknown backend `{other}`: expected one of {}",
                Self::NAMES.join(", ")
            ))),
        }
    }

    /// Opens the backend. With `Auto` the second value says which it picked and why, for the caller to
    /// tell its user (the command line prints it on standard error).
    pub fn open(self) -> Result<(Box<dyn Backend>, Option<String>)> {
        use crate::backend::gpu::{GpuBackend, GpuOptions};
        use crate::backend::reference::ReferenceBackend;
        Ok(match self {
            BackendChoice::Cpu => (Box::new(FastCpuBackend), None),
            BackendChoice::Reference => (Box::new(ReferenceBackend), None),
            BackendChoice::Gpu => (Box::new(GpuBackend::new(GpuOptions::default())?), None),
            BackendChoice::Auto => match GpuBackend::open(true, GpuOptions::default()) {
                Ok(Some(g)) => {
                    let note = format!("backend: gpu ({}, {})", g.adapter().name, g.adapter().backend);
                    (Box::new(g), Some(note))
                }
                Ok(None) => (
                    Box::new(FastCpuBackend),
                    Some(
                        "backend: cpu (no hardware GPU adapter found; --backend gpu accepts software ones)"
                            .to_string(),
                    ),
                ),
                Err(e @ Error::Input { .. }) => return Err(e),
                Err(e) => (
                    Box::new(FastCpuBackend),
                    Some(format!("backend: cpu (the GPU could not be opened: {e})")),
                ),
            },
        })
    }
}

/// The `n` strongest keypoints (ties: (y, x) order), back in (y, x) order. The paper's detector has no
/// strength to rank by: a cap it would exceed is refused rather than cut at an arbitrary place.
pub fn strongest(
    mut keypoints: Vec<Keypoint>,
    n: usize,
    kind: DetectorKind,
) -> Result<Vec<Keypoint>> {
    if keypoints.len() <= n {
        return Ok(keypoints);
    }
    if kind == DetectorKind::Ogm {
        return Err(Error::invalid(format!(
            "the paper's OGM detector has no strength to keep the {n} strongest of {} keypoints by; \
             use --detector ogm-robust or a baseline with --max-corners",
            keypoints.len()
        )));
    }
    keypoints.sort_by(|a, b| b.score.cmp(&a.score).then(a.cmp(b)));
    keypoints.truncate(n);
    keypoints.sort_unstable();
    Ok(keypoints)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::GridThresholds;

    /// A room of OccupancyGrid cells (100 walls, 0 free, -1 outside) as bytes, and the same room as the
    /// map_server image.
    fn room() -> (MapImage, MapImage) {
        let (w, h) = (12u32, 10u32);
        let mut cells = vec![-1i8 as u8; (w * h) as usize];
        let mut grey = vec![crate::map::states::UNKNOWN; (w * h) as usize];
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let wall = x == 1 || y == 1 || x == w - 2 || y == h - 2;
                let i = (y * w + x) as usize;
                cells[i] = if wall { 100 } else { 0 };
                grey[i] = if wall { 0 } else { 254 };
            }
        }
        (
            MapImage::new(w, h, cells).unwrap(),
            MapImage::new(w, h, grey).unwrap(),
        )
    }

    #[test]
    fn grid_cells_detect_as_their_map_server_image() {
        let (cells, grey) = room();
        let classes = GridThresholds::default().class_table().unwrap();
        for kind in [
            DetectorKind::Ogm,
            DetectorKind::OgmRobust,
            DetectorKind::Baseline(crate::Baseline::Harris),
            DetectorKind::Baseline(crate::Baseline::Trajkovic),
        ] {
            let mut d = Detector::new(DetectOptions {
                detector: kind,
                ..DetectOptions::default()
            });
            let from_cells = d.detect_classified(&cells, &classes).unwrap();
            let from_grey = d.detect_image(&grey, &Thresholds::default()).unwrap();
            assert_eq!(from_cells, from_grey, "{}", kind.name());
            if kind == DetectorKind::Ogm {
                assert_eq!(from_cells.keypoints.len(), 4);
            }
        }
    }

    #[test]
    fn backend_names() {
        for name in BackendChoice::NAMES {
            assert!(BackendChoice::parse(name).is_ok());
        }
        assert_eq!(BackendChoice::parse("cpu").unwrap(), BackendChoice::Cpu);
        let e = BackendChoice::parse("tpu").unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown backend `tpu`: expected one of auto, cpu, reference, gpu"
        );
        let (b, note) = BackendChoice::Reference.open().unwrap();
        assert_eq!((b.name().as_str(), note), ("cpu-reference", None));
    }
}
