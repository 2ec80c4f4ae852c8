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
        let mut robust = None;
        let mut keypoints = match self.options.detector {
            DetectorKind::OgmRobust => {
                let classes = ClassTable::new(thresholds);
                let (k, info) = crate::robust::detect(
                    &mut *self.backend,
                    image,
                    &classes,
                    &self.rules,
                    &self.options.robust,
                )?;
                robust = Some(info);
                k
            }
            DetectorKind::Ogm => {
                let classes = ClassTable::new(thresholds);
                self.backend.detect(
                    image,
                    &classes,
                    &self.rules,
                    self.options.unknown_as_occupied,
                )?
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
