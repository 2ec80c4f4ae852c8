//! `Detector`: a detector and its backend (a GPU's device and pipelines) kept between calls; keypoints
//! come back as one numpy buffer of fixed-size records that the package views as a structured array.

use std::sync::Mutex;

use bytemuck::{Pod, Zeroable};
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use ogm_corners::backend::reference::coarsen::CellRule;
use ogm_corners::detect::robust::{Anchor, RobustParams};
use ogm_corners::map::GridThresholds;
use ogm_corners::{
    BackendChoice, Baseline, BaselineParams, DetectOptions, Detection, DetectorKind, Error, GeoRef,
    RuleSet,
};

use crate::errors::{interruptible, to_py, unlocked, within_budget};
use crate::map::{image_of, Map};

/// One keypoint as the package's numpy dtype lays it out (`ogm_corners._keypoints.RECORD`): 40 bytes,
/// the world position NaN when the map has no georeference (the package then leaves those fields out).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Record {
    x: u32,
    y: u32,
    rule: u8,
    code: u8,
    scale: u8,
    convex: u8,
    _pad: u32,
    score: i64,
    world_x: f64,
    world_y: f64,
}

/// The records of a detection as 64-bit words (5 a record), moved into numpy without a copy.
fn records(found: &Detection, georef: Option<GeoRef>) -> Vec<u64> {
    let mut words = Vec::with_capacity(found.keypoints.len() * WORDS);
    for k in &found.keypoints {
        let (world_x, world_y) = georef
            .map(|g| g.pixel_to_world(k.x, k.y, found.height))
            .unwrap_or((f64::NAN, f64::NAN));
        let record = Record {
            x: k.x,
            y: k.y,
            rule: k.rule,
            code: k.code,
            scale: k.scale,
            convex: u8::from(k.convex),
            _pad: 0,
            score: k.score,
            world_x,
            world_y,
        };
        words.extend_from_slice(&bytemuck::cast::<Record, [u64; WORDS]>(record));
    }
    words
}

/// 64-bit words a record.
const WORDS: usize = std::mem::size_of::<Record>() / 8;

/// The detector a name gives.
fn detector_kind(name: &str) -> PyResult<DetectorKind> {
    Ok(match name {
        "ogm" => DetectorKind::Ogm,
        "ogm-robust" => DetectorKind::OgmRobust,
        "harris" => DetectorKind::Baseline(Baseline::Harris),
        "shi-tomasi" => DetectorKind::Baseline(Baseline::ShiTomasi),
        "trajkovic" => DetectorKind::Baseline(Baseline::Trajkovic),
        other => {
            return Err(to_py(Error::invalid(format!(
                "unknown detector `{other}`: expected one of ogm, ogm-robust, harris, shi-tomasi, trajkovic"
            ))))
        }
    })
}

/// A detector with its backend; see the package's `ogm_corners.Detector`.
#[pyclass(frozen, module = "ogm_corners._core", name = "Detector")]
pub struct Detector {
    inner: Mutex<ogm_corners::Detector>,
    /// Kept beside the detector so that reading them never waits for a detection.
    name: &'static str,
    backend: String,
    note: Option<String>,
}

#[pymethods]
impl Detector {
    #[new]
    #[pyo3(signature = (
        detector="ogm", backend="auto", *, rules="paper", unknown_as_occupied=false, max_corners=None,
        sigma=1.0, harris_k=0.04, quality=0.01, min_distance=3.0, t1=10_000, t2=20_000,
        min_scale=None, max_scale=None, angle=None, anchor=None, nms_radius=None, min_strength=None, convex=true,
        cell_occupied=None, cell_free=None, wall_gap=None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        detector: &str,
        backend: &str,
        rules: &str,
        unknown_as_occupied: bool,
        max_corners: Option<usize>,
        sigma: f64,
        harris_k: f64,
        quality: f64,
        min_distance: f64,
        t1: u32,
        t2: u32,
        min_scale: Option<u32>,
        max_scale: Option<u32>,
        angle: Option<f64>,
        anchor: Option<&Bound<'_, PyAny>>,
        nms_radius: Option<u32>,
        min_strength: Option<u32>,
        convex: bool,
        cell_occupied: Option<u32>,
        cell_free: Option<u32>,
        wall_gap: Option<u32>,
    ) -> PyResult<Self> {
        let rules = match rules {
            "paper" => RuleSet::Paper,
            "paper-mod2" => RuleSet::PaperMod2,
            other => {
                return Err(to_py(Error::invalid(format!(
                    "unknown rules `{other}`: expected paper or paper-mod2"
                ))))
            }
        };
        let r = RobustParams::default();
        let options = DetectOptions {
            detector: detector_kind(detector)?,
            baseline: BaselineParams {
                sigma,
                harris_k,
                quality,
                min_distance,
                max_corners,
                t1,
                t2,
            },
            rules,
            unknown_as_occupied,
            robust: RobustParams {
                min_scale: min_scale.unwrap_or(r.min_scale),
                max_scale: max_scale.unwrap_or(r.max_scale),
                nms_radius: nms_radius.unwrap_or(r.nms_radius),
                min_strength: min_strength.unwrap_or(r.min_strength),
                convex,
                angle,
                anchor: anchor_of(anchor)?,
                cells: CellRule {
                    occupied_pct: cell_occupied.unwrap_or(r.cells.occupied_pct),
                    free_pct: cell_free.unwrap_or(r.cells.free_pct),
                },
                wall_gap: wall_gap.unwrap_or(r.wall_gap),
            },
            max_corners,
        };
        let choice = BackendChoice::parse(backend).map_err(to_py)?;
        let (backend, note) = unlocked(py, || choice.open())?;
        let inner = ogm_corners::Detector::with_backend(options, backend);
        Ok(Detector {
            name: options.detector.name(),
            backend: inner.backend_name(),
            inner: Mutex::new(inner),
            note,
        })
    }

    /// The backend's name (for example `cpu (fast)`, or the GPU adapter).
    #[getter]
    fn backend(&self) -> String {
        self.backend.clone()
    }

    /// With backend="auto": which backend it picked and why.
    #[getter]
    fn backend_note(&self) -> Option<String> {
        self.note.clone()
    }

    /// The detector's name (ogm, ogm-robust, harris, shi-tomasi, trajkovic).
    #[getter]
    fn detector(&self) -> &'static str {
        self.name
    }

    /// Detects in a map: (records as uint64 words, the robust detector's grid angle).
    fn _detect_map<'py>(
        &self,
        py: Python<'py>,
        map: &Map,
    ) -> PyResult<(Bound<'py, PyArray1<u64>>, Option<f64>)> {
        let m = &map.inner;
        self.check_budget(py, m.image.width(), m.image.height())?;
        let (words, angle) = detecting(py, m.image.len() as u64, || {
            let found = self.lock().detect(m)?;
            Ok((records(&found, m.georef), angle_of(&found)))
        })?;
        Ok((words.into_pyarray(py), angle))
    }

    /// Seconds of one detection in `map` timed inside the extension, the lock released as for
    /// `_detect_map` (the Rust call that `python/benches/overhead.py` sets Python's calls against).
    fn _time_rust(&self, py: Python<'_>, map: &Map) -> PyResult<f64> {
        let m = &map.inner;
        unlocked(py, || {
            let mut d = self.lock();
            let start = std::time::Instant::now();
            let found = d.detect(m)?;
            let seconds = start.elapsed().as_secs_f64();
            drop(found);
            Ok(seconds)
        })
    }

    /// Detects in a 2-D array read in place: grey levels with the ROS defaults, or with `grid`,
    /// OccupancyGrid cells (int8 viewed as uint8) read as map_saver reads them.
    #[pyo3(signature = (pixels, grid, occupied_thresh=0.65, free_thresh=0.25))]
    fn _detect_array<'py>(
        &self,
        py: Python<'py>,
        pixels: PyReadonlyArray2<'py, u8>,
        grid: bool,
        occupied_thresh: f64,
        free_thresh: f64,
    ) -> PyResult<(Bound<'py, PyArray1<u64>>, Option<f64>)> {
        let image = image_of(&pixels, false)?;
        self.check_budget(py, image.width(), image.height())?;
        let classes = if grid {
            Some(
                GridThresholds {
                    occupied_thresh,
                    free_thresh,
                }
                .class_table()
                .map_err(to_py)?,
            )
        } else {
            None
        };
        let (words, angle) = detecting(py, image.len() as u64, || {
            let mut d = self.lock();
            let found = match &classes {
                Some(c) => d.detect_classified(&image, c)?,
                None => d.detect_image(&image, &Default::default())?,
            };
            Ok((records(&found, None), angle_of(&found)))
        })?;
        Ok((words.into_pyarray(py), angle))
    }
}

impl Detector {
    /// Refuses a detection whose working memory (the backend's buffers for a `w` x `h` map, as the
    /// command line counts them) is over the budget.
    fn check_budget(&self, py: Python<'_>, w: u32, h: u32) -> PyResult<()> {
        // The lock may be held by a detection on another thread: waited for with the interpreter free.
        let bytes = py.detach(|| self.lock().working_bytes(w, h));
        within_budget(
            format_args!("detecting in a {w}x{h} map with {}", self.name),
            bytes,
        )
    }

    /// The detector; a panic in an earlier call (reported then as an exception) does not stop later ones.
    fn lock(&self) -> std::sync::MutexGuard<'_, ogm_corners::Detector> {
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// Maps past this many pixels are detected so that Ctrl-C stops the call ([`interruptible`]: a worker
/// thread, some tens of microseconds more a call); below it the fast path ends in milliseconds and the
/// slowest detectors in about a second.
const INTERRUPTIBLE_FROM: u64 = 1 << 22;

/// Runs a detection in a map of `pixels` pixels: [`interruptible`] past [`INTERRUPTIBLE_FROM`], else
/// [`unlocked`].
fn detecting<T: Send>(
    py: Python<'_>,
    pixels: u64,
    f: impl FnOnce() -> ogm_corners::Result<T> + Send,
) -> PyResult<T> {
    if pixels > INTERRUPTIBLE_FROM {
        interruptible(py, f)
    } else {
        unlocked(py, f)
    }
}

/// The robust detector's `anchor` option: None or "world" (the map's world origin where it has one),
/// "centre" (or "center"), or a point (x, y) in pixels.
fn anchor_of(anchor: Option<&Bound<'_, PyAny>>) -> PyResult<Anchor> {
    let Some(a) = anchor else {
        return Ok(Anchor::World);
    };
    if let Ok(s) = a.extract::<String>() {
        return Anchor::named(&s).ok_or_else(|| {
            to_py(Error::invalid(format!(
                "unknown anchor {s:?}: expected \"world\", \"centre\" or a point (x, y) in pixels"
            )))
        });
    }
    match a.extract::<(f64, f64)>() {
        Ok((x, y)) => Ok(Anchor::Point(x, y)),
        Err(_) => Err(pyo3::exceptions::PyTypeError::new_err(
            "anchor is \"world\", \"centre\" or a point (x, y) in pixels",
        )),
    }
}

/// The robust detector's grid angle, degrees.
fn angle_of(found: &Detection) -> Option<f64> {
    found.robust.as_ref().map(|r| r.angle)
}
