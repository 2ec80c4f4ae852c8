//! The backends: what every backend implements and shares, and the three that implement it;
//! [`crate::detect::detector`] picks among them.
//!
//! - `mod.rs`: keypoints, detection options, working-memory estimates and the [`Backend`] trait;
//! - [`robust_params`]: the robust detector's options (every backend is given them, so they cannot live
//!   with the detector a layer up);
//! - [`rules`]: the rule table, derived from the paper's formulas;
//! - [`baselines`]: the baselines' parameters and the keypoint selection shared by every backend, in
//!   memory and over a stream;
//! - [`reference`](mod@reference): the plain single-threaded CPU reference ([`ReferenceBackend`],
//!   `--backend reference`), one twin per GPU kernel, the oracle every other backend is tested against;
//! - [`fast`] (the fast CPU path, `--backend cpu`, the default) and [`gpu`] (`--backend gpu`), a layer
//!   above the rest: both implement `Backend` and give the reference's keypoints bit for bit.
//!
//! The interface is this module: what the detectors and the merger use of a backend is named here (the
//! trait, the reference's [`ReferenceBackend`] that the merger scores with by default, and the data the
//! kernels take and give: the coarse [`Mosaic`] and its [`CellRule`], the scoring kernel's
//! [`ScoreTarget`] and [`FixedRigid`]). Only the detector's choice of backend names an implementation
//! directly (`tests/house/layering.rs` checks it, and lists the one reach left: the robust detector's
//! wall-direction histogram uses the fast path's bit-planes).
//!
//! A new backend is a type implementing `Backend` in its own folder beside `reference/`, `fast/` and
//! `gpu/`. `name`, `detect` and `baseline_scores` are the minimum: the trait's default methods route
//! windows and candidate lists through them, and coarsen and score transforms with the reference's
//! twins; a backend overrides the rest where it can do better. Choose it in `BackendChoice`
//! (`src/detect/detector.rs`), and test it bit for bit against the reference as
//! `tests/backend/fast_ogm.rs` and `tests/backend/gpu_conformance.rs` do.

pub mod baselines;
pub mod fast;
pub mod gpu;
pub mod reference;
pub mod robust_params;
pub mod rules;

use serde::Serialize;

use crate::backend::baselines::streamed::CandidateList;
use crate::backend::baselines::{Baseline, BaselineParams, Candidate, ExactParams};
use crate::backend::rules::{RuleSet, RuleTable};
use crate::map::grid::RotatedGrid;
use crate::map::states::ClassTable;
use crate::map::stream::Rows;
use crate::map::MapImage;
use crate::support::error::Result;
use robust_params::RobustParams;

pub use reference::coarsen::{CellRule, Mosaic, MAX_SCALE};
pub use reference::merge_score::{FixedRigid, ScoreTarget, FLAG_DEEP, FLAG_INSIDE, FLAG_NEAR};
pub use reference::ReferenceBackend;

/// A corner: pixel coordinates (origin top-left, x right, y down), the rule that fired and the code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct Keypoint {
    /// Row, counted down from the top. First so that the derived order is (y, x).
    pub y: u32,
    /// Column, counted right from the left edge.
    pub x: u32,
    /// The rule that accepted the neighbourhood: 4, 5 or 6 occupied neighbours.
    pub rule: u8,
    /// The 8-neighbour code (bit order in [`crate::backend::rules`]); 0 for the baselines.
    pub code: u8,
    /// The baselines' integer response (see [`crate::backend::baselines`]); the robust detector's strength (the
    /// shorter wall of the corner, pixels); 0 for the paper's OGM detector.
    pub score: i64,
    /// The robust detector's coarse scale (map pixels a cell side) the rule fired at; 1 otherwise.
    pub scale: u8,
    /// A convex corner of the robust detector (an occupied cell, roles swapped); false otherwise.
    pub convex: bool,
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
            scale: 1,
            convex: false,
        }
    }

    /// A keypoint of the paper's OGM detector: position, rule and code.
    pub fn ogm(x: u32, y: u32, rule: u8, code: u8) -> Self {
        Keypoint {
            y,
            x,
            rule,
            code,
            score: 0,
            scale: 1,
            convex: false,
        }
    }
}

/// Which detector.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DetectorKind {
    /// The OGM corner detector of the paper (the default).
    #[default]
    Ogm,
    /// The OGM rules made robust for real maps: turned to the walls, at several scales, concave and
    /// convex corners, ranked by strength ([`crate::detect::robust`]).
    OgmRobust,
    /// One of the paper's baselines.
    Baseline(Baseline),
}

impl DetectorKind {
    /// The name used on the command line and in outputs.
    pub fn name(self) -> &'static str {
        match self {
            DetectorKind::Ogm => "ogm",
            DetectorKind::OgmRobust => "ogm-robust",
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
    /// Count unknown neighbours as occupied (by default they count as not occupied); the paper's detector
    /// only.
    pub unknown_as_occupied: bool,
    /// The robust detector's options.
    pub robust: RobustParams,
    /// Keep at most this many keypoints, strongest first (ties in (y, x) order); the paper's detector has
    /// no strength, so it refuses a cap it would exceed.
    pub max_corners: Option<usize>,
}

/// Something that runs the classification and corner kernels: the CPU reference, or a GPU.
///
/// Implementations keep whatever set-up they need (devices, pipelines, buffers) between calls; they are
/// `Send`, so a detector can move to the thread that runs it (Python releases its lock around a call).
pub trait Backend: Send {
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
    /// [`crate::backend::baselines::cpu_scores`] computes it.
    fn baseline_scores(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        params: &ExactParams,
    ) -> Result<Vec<i64>>;

    /// The keypoints of a baseline detector, sorted by (y, x): the map as one window through
    /// [`Backend::baseline_rows`] and the shared selection ([`CandidateList`]), the path a streamed map
    /// takes window by window.
    fn baseline_keypoints(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        params: &BaselineParams,
    ) -> Result<Vec<Keypoint>> {
        let core = (0, image.height() as usize);
        let (found, max) = self.baseline_rows(kind, Rows::of(image), core, params, i64::MIN)?;
        let mut list = CandidateList::new(kind, params);
        list.add(found, max);
        Ok(list
            .finish(image.width(), image.height(), params)
            .into_iter()
            .map(|(x, y, score)| Keypoint::scored(x, y, score))
            .collect())
    }

    /// The OGM keypoints of a window's core rows ([`OgmWindow`]), sorted by (y, x). By default the window
    /// is detected as an image of its own ([`Backend::detect`]) and the core's rows kept.
    fn detect_rows(&mut self, window: OgmWindow) -> Result<Vec<Keypoint>> {
        let image = window.rows.image()?;
        let found = self.detect(
            &image,
            window.classes,
            window.rules,
            window.unknown_as_occupied,
        )?;
        Ok(in_core(found, window.rows.first(), window.core))
    }

    /// The candidates of a baseline in rows `core` of a window, in (y, x) order: its positive 3x3 local
    /// maxima (over neighbours in the map), and the window's part of the map's largest score: a value no
    /// larger than that score, and equal to it in the window that holds it whenever it is positive.
    /// Candidates that fail the quality threshold against `known_max` (the windows before's largest part,
    /// `i64::MIN` for none) may be left out. By default the window's score map ([`Backend::baseline_scores`]
    /// of the window as an image) is searched on the host.
    fn baseline_rows(
        &mut self,
        kind: Baseline,
        rows: Rows,
        core: (usize, usize),
        params: &BaselineParams,
        known_max: i64,
    ) -> Result<(Vec<Candidate>, i64)> {
        let _ = known_max;
        maxima_of_window_scores(self, kind, rows, core, params)
    }

    /// Pixels a window of a streamed map should hold ([`crate::map::stream::WindowPlan`]): small enough that
    /// [`crate::map::stream::WINDOWS_IN_FLIGHT`] windows and the backend's working memory for one stay a few tens
    /// of megabytes, large enough that the halo rows and each window's set-up stay a small share.
    fn window_bytes(&self, options: &DetectOptions) -> u64 {
        let _ = options;
        4 << 20
    }

    /// The coarse maps of `image` sampled on `grid`, one per scale, exactly as
    /// [`crate::backend::reference::coarsen::coarsen`] computes them (the default).
    fn coarsen(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        grid: &RotatedGrid,
        scales: &[u32],
        rule: crate::backend::reference::coarsen::CellRule,
    ) -> Result<Vec<MapImage>> {
        Ok(scales
            .iter()
            .map(|&s| crate::backend::reference::coarsen::coarsen(image, classes, grid, s, rule))
            .collect())
    }

    /// Per transform, the counts of `points` landing on each flag of `target` (inside, near, deep),
    /// exactly as [`crate::backend::reference::merge_score::score_transforms`] computes them (the default).
    fn score_transforms(
        &mut self,
        target: &ScoreTarget,
        points: &[[u32; 2]],
        transforms: &[FixedRigid],
    ) -> Result<Vec<[u32; 3]>> {
        crate::backend::reference::merge_score::score_transforms(target, points, transforms)
    }

    /// Bytes this backend allocates on the host to detect with `options` in a `width` x `height` map,
    /// beyond the map itself and the keypoints it returns (24 bytes each, data-dependent): what a caller
    /// adds to the map's size before checking a memory budget. An upper bound of the buffers that grow
    /// with the map; the default is the plain reference's full-size buffers.
    fn working_bytes(&self, options: &DetectOptions, width: u32, height: u32) -> u64 {
        reference_working_bytes(options, width, height)
    }
}

/// A window of a map for the OGM detector ([`Backend::detect_rows`]): the rows held, the core rows whose
/// keypoints are wanted, and how the map is read.
#[derive(Clone, Copy, Debug)]
pub struct OgmWindow<'a> {
    /// The rows held: the core and the rows around it the map has (at least one each side).
    pub rows: Rows<'a>,
    /// Map rows `core.0..core.1` whose keypoints are wanted.
    pub core: (usize, usize),
    /// Each pixel value's state.
    pub classes: &'a ClassTable,
    /// The codes accepted as corners.
    pub rules: &'a RuleTable,
    /// Unknown neighbours count as occupied.
    pub unknown_as_occupied: bool,
}

/// Keypoints of a window detected as an image of its own, kept when their map row (`first` + their row) is
/// in `core`, in map rows.
pub fn in_core(found: Vec<Keypoint>, first: usize, core: (usize, usize)) -> Vec<Keypoint> {
    found
        .into_iter()
        .filter_map(|mut k| {
            let y = first + k.y as usize;
            k.y = y as u32;
            (core.0..core.1).contains(&y).then_some(k)
        })
        .collect()
}

/// [`Backend::baseline_rows`] by the default route: the window's score map ([`Backend::baseline_scores`] of
/// the window as an image of its own), searched on the host ([`window_maxima`]).
pub fn maxima_of_window_scores<B: Backend + ?Sized>(
    backend: &mut B,
    kind: Baseline,
    rows: Rows,
    core: (usize, usize),
    params: &BaselineParams,
) -> Result<(Vec<Candidate>, i64)> {
    let scores = backend.baseline_scores(kind, &rows.image()?, &params.exact()?)?;
    Ok(window_maxima(&scores, rows, core))
}

/// The positive 3x3 local maxima of rows `core` of a window's score map (`scores`: one per pixel of
/// `rows`), and the largest score of those rows (`i64::MIN` for none).
pub fn window_maxima(scores: &[i64], rows: Rows, core: (usize, usize)) -> (Vec<Candidate>, i64) {
    let (w, first) = (rows.width(), rows.first());
    let held = rows.end() - first;
    let mut out = Vec::new();
    let mut max = i64::MIN;
    for y in core.0..core.1 {
        let r = y - first;
        for (x, &v) in scores[r * w..(r + 1) * w].iter().enumerate() {
            max = max.max(v);
            // The window's own edges are the map's wherever a core row touches them.
            if v > 0 && crate::backend::reference::select_maxima::local_max(scores, w, held, x, r) {
                out.push((x as u32, y as u32, v));
            }
        }
    }
    (out, max)
}

/// The reference's buffers: a copy of the window it detects in (the whole map in memory; not for the robust
/// detector), then one state per pixel (OGM); the blurred map, the gradient products and the
/// structure tensor alive together (Harris, Shi-Tomasi: 1 + 12 + 12 bytes a pixel), then the score map
/// and, for Shi-Tomasi, the selection's buffers ([`shi_tomasi_selection_bytes`]); or the low-resolution
/// and full score maps (Trajkovic: 2 + 8).
pub fn reference_working_bytes(options: &DetectOptions, width: u32, height: u32) -> u64 {
    let px = u64::from(width) * u64::from(height);
    // The window the reference detects in, copied into an image of its own (the backends' default route).
    let window = if options.detector == DetectorKind::OgmRobust {
        0
    } else {
        px
    };
    window.saturating_add(match options.detector {
        DetectorKind::Ogm => px,
        DetectorKind::OgmRobust => {
            robust_params::robust_working_bytes(width, height, &options.robust)
        }
        DetectorKind::Baseline(Baseline::Harris) => px.saturating_mul(25),
        DetectorKind::Baseline(Baseline::ShiTomasi) => px.saturating_mul(25).max(
            px.saturating_mul(8)
                .saturating_add(shi_tomasi_selection_bytes(options, width, height)),
        ),
        DetectorKind::Baseline(Baseline::Trajkovic) => px.saturating_mul(10),
    })
}

/// What goodFeaturesToTrack's selection allocates beside a full score map: the thresholded copy (8 bytes a
/// pixel) and an empty list per grid cell of `min_distance` (24 bytes a cell: a pixel each at distances up
/// to 1).
pub fn shi_tomasi_selection_bytes(options: &DetectOptions, width: u32, height: u32) -> u64 {
    let px = u64::from(width) * u64::from(height);
    let d = options.baseline.min_distance;
    let cell = if d.is_finite() {
        d.max(1.0).ceil().min(65536.0) as u64
    } else {
        65536
    };
    let cells = u64::from(width).div_ceil(cell) * u64::from(height).div_ceil(cell);
    px.saturating_mul(8)
        .saturating_add(cells.saturating_mul(24))
}
