//! The detector API: a [`Detector`] runs one of the detectors on a backend and returns a [`Detection`].

pub use crate::backend::{Backend, DetectOptions, DetectorKind, Keypoint};
use crate::error::{Error, Result};
use crate::fast::FastCpuBackend;
use crate::map::{MapImage, OccupancyMap, Thresholds};
use crate::robust::RobustInfo;
use crate::rules::RuleTable;
use crate::states::ClassTable;

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

    /// Detects corners in a loaded map, with the map's own thresholds.
    pub fn detect(&mut self, map: &OccupancyMap) -> Result<Detection> {
        self.detect_image(&map.image, &map.thresholds)
    }

    /// Detects corners in an image, reading its pixels with `thresholds`.
    pub fn detect_image(&mut self, image: &MapImage, thresholds: &Thresholds) -> Result<Detection> {
        self.detect_as(image, &ClassTable::new(thresholds), false)
    }

    /// Detects corners in an image whose values `classes` reads, such as `nav_msgs/OccupancyGrid` cells
    /// in place ([`crate::map::GridThresholds::class_table`]). The baselines, which read grey levels,
    /// see the three states drawn as `map_server` draws them (a copy of the image).
    pub fn detect_classified(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
    ) -> Result<Detection> {
        self.detect_as(image, classes, true)
    }

    /// The detection; `redraw`: the baselines read the states' grey levels, not the image's values.
    fn detect_as(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        redraw: bool,
    ) -> Result<Detection> {
        let mut robust = None;
        let mut keypoints = match self.options.detector {
            DetectorKind::OgmRobust => {
                let (k, info) = crate::robust::detect(
                    &mut *self.backend,
                    image,
                    classes,
                    &self.rules,
                    &self.options.robust,
                )?;
                robust = Some(info);
                k
            }
            DetectorKind::Ogm => self.backend.detect(
                image,
                classes,
                &self.rules,
                self.options.unknown_as_occupied,
            )?,
            DetectorKind::Baseline(kind) if redraw => {
                let value = classes.map_server_values();
                let grey = image.pixels().iter().map(|&v| value[v as usize]).collect();
                let grey = MapImage::new(image.width(), image.height(), grey)?;
                self.backend
                    .baseline_keypoints(kind, &grey, &self.options.baseline)?
            }
            DetectorKind::Baseline(kind) => {
                self.backend
                    .baseline_keypoints(kind, image, &self.options.baseline)?
            }
        };
        if let Some(n) = self.options.max_corners {
            keypoints = strongest(keypoints, n, self.options.detector)?;
        }
        Ok(Detection {
            width: image.width(),
            height: image.height(),
            keypoints,
            robust,
        })
    }
}

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
        use crate::cpu::CpuBackend;
        use crate::gpu::{GpuBackend, GpuOptions};
        Ok(match self {
            BackendChoice::Cpu => (Box::new(FastCpuBackend), None),
            BackendChoice::Reference => (Box::new(CpuBackend), None),
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
        let mut grey = vec![crate::states::UNKNOWN; (w * h) as usize];
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
