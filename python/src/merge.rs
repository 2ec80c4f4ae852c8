//! Merging: two maps (`merge`, `compose`, `overlay`) and many (`merge_many`). Verdicts and reports
//! travel as the command line's JSON, which the package turns into its classes.

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3};
use ogm_corners::merge::many::mosaic;
use ogm_corners::merge::many::{self, GlobalOptions};
use ogm_corners::merge::pair;
use ogm_corners::merge::{MergeOptions, Rigid};
use ogm_corners::{BackendChoice, Error, OccupancyMap};
use pyo3::prelude::*;

use crate::errors::{finite_transform, interruptible, to_py, unlocked, within_budget};
use crate::map::Map;
use ogm_corners::merge::footprint::{self, check_alignable};

/// A picture as a (height, width, 3) uint8 array.
fn rgb_array(py: Python<'_>, picture: image::RgbImage) -> PyResult<Bound<'_, PyArray3<u8>>> {
    let (w, h) = (picture.width() as usize, picture.height() as usize);
    let array = Array3::from_shape_vec((h, w, 3), picture.into_raw())
        .map_err(|e| to_py(Error::Internal(e.to_string())))?;
    Ok(array.into_pyarray(py))
}

/// The backend a name gives, opened.
pub(crate) fn backend(py: Python<'_>, name: &str) -> PyResult<Box<dyn ogm_corners::Backend>> {
    let choice = BackendChoice::parse(name).map_err(to_py)?;
    unlocked(py, || choice.open()).map(|(b, _)| b)
}

/// Aligns `b` onto `a` with no initial pose: the verdict as JSON.
#[pyfunction]
#[pyo3(signature = (a, b, backend="cpu"))]
pub fn merge(py: Python<'_>, a: &Map, b: &Map, backend: &str) -> PyResult<String> {
    let (ma, mb) = (&a.inner, &b.inner);
    // B at A's resolution and both preparations, counted before any is allocated (as the command line).
    let (fa, fb) = footprint::pair(ma, mb).map_err(to_py)?;
    within_budget(
        format_args!(
            "merging a {}x{} map and a {}x{} one (at the first's cells)",
            fa.width, fa.height, fb.width, fb.height
        ),
        fa.bytes().saturating_add(fb.bytes()),
    )?;
    check_alignable(&fa, &fb).map_err(to_py)?;
    let mut on = self::backend(py, backend)?;
    let merged = interruptible(py, || {
        pair::merge_pair(ma, mb, &MergeOptions::default(), on.as_mut())
    })?;
    serde_json::to_string(&merged.verdict()).map_err(|e| to_py(Error::Internal(e.to_string())))
}

/// The merged map of `a` and `b`, B placed by (theta degrees, tx, ty) in A's frame.
#[pyfunction]
pub fn compose(py: Python<'_>, a: &Map, b: &Map, transform: (f64, f64, f64)) -> PyResult<Map> {
    let t = rigid(finite_transform(transform)?);
    let (ma, mb) = (&a.inner, &b.inner);
    canvas_within_budget(ma, mb, &t, 1)?;
    interruptible(py, || pair::compose_pair(ma, mb, &t)).map(Map::wrap)
}

/// The picture of an alignment: A's and B's walls in two colours, agreement and conflicts.
#[pyfunction]
pub fn overlay<'py>(
    py: Python<'py>,
    a: &Map,
    b: &Map,
    transform: (f64, f64, f64),
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let t = rigid(finite_transform(transform)?);
    let (ma, mb) = (&a.inner, &b.inner);
    canvas_within_budget(ma, mb, &t, 6)?;
    let picture = interruptible(py, || pair::overlay_pair(ma, mb, &t))?;
    rgb_array(py, picture)
}

/// Refuses a merged canvas of `a` and `b` (B placed by `t`, at A's resolution) whose `per_px` bytes a
/// pixel, plus B brought to A's cells, are over the budget.
fn canvas_within_budget(
    a: &ogm_corners::OccupancyMap,
    b: &ogm_corners::OccupancyMap,
    t: &Rigid,
    per_px: u64,
) -> PyResult<()> {
    let (_, fb) = footprint::pair(a, b).map_err(to_py)?;
    let canvas = footprint::canvas(a, &fb, t).map_err(to_py)?;
    within_budget(
        format_args!("a merged canvas of {}x{}", canvas.width(), canvas.height()),
        canvas
            .pixels()
            .saturating_mul(per_px)
            .saturating_add(fb.width.saturating_mul(fb.height)),
    )
}

fn rigid((theta_deg, tx, ty): (f64, f64, f64)) -> Rigid {
    Rigid { theta_deg, tx, ty }
}

/// Many maps placed; see the package's `ogm_corners.ManyMerge`. It keeps what its methods draw from: the
/// report, the maps as placed and each group's members and poses (not the pairs' verdicts), which is also
/// what it is pickled as.
#[pyclass(frozen, module = "ogm_corners._core", name = "ManyMerge")]
pub struct ManyMerge {
    report: String,
    maps: Vec<OccupancyMap>,
    groups: Vec<Vec<usize>>,
    poses: Vec<Rigid>,
}

impl ManyMerge {
    /// What Python keeps of a many-map merge.
    pub(crate) fn of(m: many::ManyMerge) -> PyResult<ManyMerge> {
        let report =
            serde_json::to_string(&m.report).map_err(|e| to_py(Error::Internal(e.to_string())))?;
        let poses = m.run.placement.maps.iter().map(|p| p.pose).collect();
        Ok(ManyMerge {
            report,
            groups: m.run.placement.groups,
            poses,
            maps: m.maps,
        })
    }

    fn check(&self, g: usize) -> PyResult<()> {
        let n = self.groups.len();
        if g >= n {
            return Err(pyo3::exceptions::PyIndexError::new_err(format!(
                "group {g} of {n}"
            )));
        }
        Ok(())
    }

    /// Group `g`'s maps and their poses in its frame.
    fn group(&self, g: usize) -> (Vec<&OccupancyMap>, Vec<Rigid>) {
        self.groups[g]
            .iter()
            .map(|&m| (&self.maps[m], self.poses[m]))
            .unzip()
    }
}

#[pymethods]
impl ManyMerge {
    /// The report (`merge ... --poses` JSON).
    fn _report(&self) -> String {
        self.report.clone()
    }

    /// Group `g`'s merged map.
    fn _merged(&self, py: Python<'_>, g: usize) -> PyResult<Map> {
        self.check(g)?;
        let (ms, ps) = self.group(g);
        interruptible(py, || mosaic::compose_many(&ms, &ps).map(|(m, _)| m)).map(Map::wrap)
    }

    /// Group `g`'s picture, each map's walls in its own colour.
    fn _overlay<'py>(&self, py: Python<'py>, g: usize) -> PyResult<Bound<'py, PyArray3<u8>>> {
        self.check(g)?;
        let (ms, ps) = self.group(g);
        let picture = interruptible(py, || mosaic::overlay_many(&ms, &ps))?;
        rgb_array(py, picture)
    }

    /// What it is pickled as: the report, the maps as placed, the groups' members and every map's pose
    /// (theta degrees, tx, ty).
    #[allow(clippy::type_complexity)]
    fn _parts(&self) -> (String, Vec<Map>, Vec<Vec<usize>>, Vec<(f64, f64, f64)>) {
        (
            self.report.clone(),
            self.maps.iter().cloned().map(Map::wrap).collect(),
            self.groups.clone(),
            self.poses
                .iter()
                .map(|p| (p.theta_deg, p.tx, p.ty))
                .collect(),
        )
    }

    /// A merge from its [`ManyMerge::_parts`] (unpickling), checked: every group's members are maps
    /// of the set, each in one group, every pose finite.
    #[staticmethod]
    fn _from_parts(
        report: String,
        maps: Vec<PyRef<'_, Map>>,
        groups: Vec<Vec<usize>>,
        poses: Vec<(f64, f64, f64)>,
    ) -> PyResult<ManyMerge> {
        let bad = |m: String| pyo3::exceptions::PyValueError::new_err(m);
        if poses.len() != maps.len() {
            return Err(bad(format!(
                "{} poses for {} maps",
                poses.len(),
                maps.len()
            )));
        }
        let mut seen = vec![false; maps.len()];
        for g in &groups {
            if g.is_empty() {
                return Err(bad("a group with no maps".into()));
            }
            for &m in g {
                if m >= maps.len() || std::mem::replace(&mut seen[m], true) {
                    return Err(bad(format!(
                        "map {m} is not one of the {} maps, or is in two groups",
                        maps.len()
                    )));
                }
            }
        }
        let poses = poses
            .into_iter()
            .map(|p| finite_transform(p).map(rigid))
            .collect::<PyResult<Vec<_>>>()?;
        Ok(ManyMerge {
            report,
            maps: maps.iter().map(|m| m.inner.clone()).collect(),
            groups,
            poses,
        })
    }
}

/// Preparations and pair alignments kept from one `merge_many` to the next; see the package's
/// `ogm_corners.MergeCache`.
#[pyclass(frozen, module = "ogm_corners._core", name = "MergeCache")]
#[derive(Default)]
pub struct MergeCache {
    inner: std::sync::Mutex<many::Cache>,
}

#[pymethods]
impl MergeCache {
    #[new]
    fn new() -> MergeCache {
        MergeCache::default()
    }

    /// (maps reused, maps prepared, pairs reused, pairs aligned) in the last run.
    fn _last_use(&self, py: Python<'_>) -> (usize, usize, usize, usize) {
        // Without the interpreter's lock: a run holding the cache must not stop every Python thread.
        let u = py.detach(|| self.lock().last_use());
        (
            u.maps_reused,
            u.maps_prepared,
            u.pairs_reused,
            u.pairs_aligned,
        )
    }
}

impl MergeCache {
    fn lock(&self) -> std::sync::MutexGuard<'_, many::Cache> {
        // A run that panicked leaves a cache whose entries are each whole: still usable.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The most `partners` a many-map merge takes (as the command line's `--partners`).
pub(crate) const MAX_PARTNERS: usize = 1000;

/// The arguments every many-map merge checks first: `partners` within [`MAX_PARTNERS`], two maps or
/// more, a name for each.
pub(crate) fn check_many(maps: usize, names: usize, partners: usize) -> PyResult<()> {
    if partners > MAX_PARTNERS {
        return Err(to_py(Error::invalid(format!(
            "partners must be at most {MAX_PARTNERS} (0 aligns every pair); got {partners}"
        ))));
    }
    if maps < 2 {
        return Err(to_py(Error::invalid(format!(
            "merge needs at least two maps; found {maps}"
        ))));
    }
    if names != maps {
        return Err(to_py(Error::invalid(format!(
            "{names} names for {maps} maps"
        ))));
    }
    Ok(())
}

/// Places every map at once (groups of maps of one place), each map's pose in its group's merged map.
#[pyfunction]
#[pyo3(signature = (maps, names, backend="cpu", cache=None, partners=3))]
pub fn merge_many(
    py: Python<'_>,
    maps: Vec<PyRef<'_, Map>>,
    names: Vec<String>,
    backend: &str,
    cache: Option<PyRef<'_, MergeCache>>,
    partners: usize,
) -> PyResult<ManyMerge> {
    check_many(maps.len(), names.len(), partners)?;
    // Every map at the first georeferenced map's cells and its preparation, held at once.
    // A cache holds the last run's preparations while this run's are made: counted as a second run.
    let run_bytes = footprint::many_bytes(maps.iter().map(|m| &m.inner)).map_err(to_py)?;
    within_budget(
        format_args!("{} maps and their preparation", maps.len()),
        run_bytes.saturating_mul(if cache.is_some() { 2 } else { 1 }),
    )?;
    let mut on = self::backend(py, backend)?;
    // Clones share the pixels (Map::wrap), so this copies no image.
    let owned: Vec<ogm_corners::OccupancyMap> = maps.iter().map(|m| m.inner.clone()).collect();
    let cache = cache.as_deref();
    let inner = interruptible(py, || {
        let mut fresh = many::Cache::new();
        let mut held = cache.map(MergeCache::lock);
        many::merge_maps_cached(
            owned,
            &names,
            &GlobalOptions::with_partners(partners),
            on.as_mut(),
            &|_, _| {},
            held.as_deref_mut().unwrap_or(&mut fresh),
        )
    })?;
    ManyMerge::of(inner)
}
