//! The detector API: options, keypoints, and the backend trait that the CPU and GPU implement.

use serde::Serialize;

use crate::baselines::{self, Baseline, BaselineParams, ExactParams};
use crate::error::Result;
use crate::fast::FastCpuBackend;
use crate::map::{MapImage, OccupancyMap, Thresholds};
use crate::rules::{RuleSet, RuleTable};
use crate::states::ClassTable;

/// A corner: pixel coordinates (origin top-left, x right, y down), the rule that fired and the code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct Keypoint {
    /// Row, counted down from the top. First so that the derived order is (y, x).
    pub y: u32,
    /// Column, counted right from the left edge.
    pub x: u32,
    /// The rule that accepted the neighbourhood: 4, 5 or 6 occupied neighbours.
    pub rule: u8,
    /// The 8-neighbour code (bit order in [`crate::rules`]); 0 for the baselines.
    pub code: u8,
    /// The baselines' integer response (see [`crate::baselines`]); 0 for the OGM detector.
    pub score: i64,
}

impl Keypoint {
    /// A baseline keypoint: position and score (rule and code 0).
    pub fn scored(x: u32, y: u32, score: i64) -> Self {
        Keypoint {
            y,
            x,
            rule: 0,
            code: 0,
            score,
        }
    }
}

/// Which detector.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DetectorKind {
    /// The OGM corner detector of the paper (the default).
    #[default]
    Ogm,
    /// One of the paper's baselines.
    Baseline(Baseline),
}

impl DetectorKind {
    /// The name used on the command line and in outputs.
    pub fn name(self) -> &'static str {
        match self {
            DetectorKind::Ogm => "ogm",
            DetectorKind::Baseline(Baseline::Harris) => "harris",
            DetectorKind::Baseline(Baseline::ShiTomasi) => "shi-tomasi",
            DetectorKind::Baseline(Baseline::Trajkovic) => "trajkovic",
        }
    }
}

/// How to detect.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DetectOptions {
    /// Which detector.
    pub detector: DetectorKind,
    /// The baselines' options (ignored by the OGM detector).
    pub baseline: BaselineParams,
    /// Which reading of the paper's rules.
    pub rules: RuleSet,
    /// Count unknown neighbours as occupied (by default they count as not occupied).
    pub unknown_as_occupied: bool,
}

/// The keypoints found in one map.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Detection {
    /// Map width in pixels.
    pub width: u32,
    /// Map height in pixels.
    pub height: u32,
    /// Keypoints sorted by (y, x).
    pub keypoints: Vec<Keypoint>,
}

/// Something that runs the classification and corner kernels: the CPU reference, or a GPU.
///
/// Implementations keep whatever set-up they need (devices, pipelines, buffers) between calls.
pub trait Backend {
    /// A short name for messages and benchmark records.
    fn name(&self) -> String;

    /// Classifies `image` with `classes`, then returns every free pixel whose neighbour code `rules`
    /// accepts, sorted by (y, x).
    fn detect(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        rules: &RuleTable,
        unknown_as_occupied: bool,
    ) -> Result<Vec<Keypoint>>;

    /// The score map of a baseline detector: one integer per pixel, row-major, exactly as
    /// [`crate::baselines::cpu_scores`] computes it.
    fn baseline_scores(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        params: &ExactParams,
    ) -> Result<Vec<i64>>;

    /// The keypoints of a baseline detector, sorted by (y, x). By default the score map from
    /// [`Backend::baseline_scores`] goes through the shared selection ([`crate::baselines::select`]); a
    /// backend may fuse the two as long as the result is identical.
    fn baseline_keypoints(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        params: &BaselineParams,
    ) -> Result<Vec<Keypoint>> {
        let exact = params.exact()?;
        let scores = self.baseline_scores(kind, image, &exact)?;
        Ok(
            baselines::select(kind, &scores, image.width(), image.height(), params)
                .into_iter()
                .map(|(x, y, score)| Keypoint::scored(x, y, score))
                .collect(),
        )
    }
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

    /// Detects corners in a loaded map, with the map's own thresholds.
    pub fn detect(&mut self, map: &OccupancyMap) -> Result<Detection> {
        self.detect_image(&map.image, &map.thresholds)
    }

    /// Detects corners in an image, reading its pixels with `thresholds`.
    pub fn detect_image(&mut self, image: &MapImage, thresholds: &Thresholds) -> Result<Detection> {
        let keypoints = match self.options.detector {
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
        Ok(Detection {
            width: image.width(),
            height: image.height(),
            keypoints,
        })
    }
}
