//! `Map`: a loaded or built occupancy map, its pixels shared with numpy without copies.

use std::path::PathBuf;
use std::sync::Arc;

use numpy::ndarray::ArrayView2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use ogm_corners::map::states::ClassTable;
use ogm_corners::map::{GeoRef, GridThresholds, MapImage, PixelSource, Thresholds};
use ogm_corners::measure::synthetic::synthetic_set;
use ogm_corners::{map::synthetic, Error, OccupancyMap};

use crate::errors::{to_py, unlocked, within_budget};

/// Pixels read in place from a numpy array (C-contiguous uint8, or int8 cells viewed as uint8).
struct NumpyPixels {
    /// Keeps the array, and so its buffer, alive.
    _owner: Py<PyAny>,
    ptr: *const u8,
    len: usize,
}

// SAFETY: `_owner` keeps the array alive, and numpy neither frees nor moves an array's buffer while a
// reference to the array exists (`resize` refuses), so `ptr..ptr + len` stays valid on any thread. The
// bytes are read without the interpreter's lock, as numpy's own loops read them; the package documents
// that an array must not be written while a call reads it.
unsafe impl Send for NumpyPixels {}
unsafe impl Sync for NumpyPixels {}

impl PixelSource for NumpyPixels {
    fn bytes(&self) -> &[u8] {
        // SAFETY: see the `Send` impl; `len` bytes from `ptr` were a contiguous slice of the array.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

/// The size of an array's axis as a map dimension.
fn dim(n: usize, what: &str) -> PyResult<u32> {
    u32::try_from(n)
        .map_err(|_| PyValueError::new_err(format!("{what} {n} is more than a map can have")))
}

/// A map image over a 2-D uint8 array: read in place when C-contiguous (and `copy` is false), copied in
/// row order otherwise (a Fortran-ordered or strided array's memory is not its rows). A copy is counted
/// against the memory budget first and made with the interpreter's lock released.
pub fn image_of(array: &PyReadonlyArray2<'_, u8>, copy: bool) -> PyResult<MapImage> {
    let shape = array.shape();
    let (h, w) = (dim(shape[0], "height")?, dim(shape[1], "width")?);
    if w == 0 || h == 0 {
        return Err(to_py(Error::invalid(format!(
            "zero-size map ({w}x{h}): nothing to detect in"
        ))));
    }
    // `as_slice` also answers for a Fortran-ordered array (memory order, columns first): only a
    // C-contiguous one is its rows.
    let rows = if array.is_c_contiguous() {
        array.as_slice().ok()
    } else {
        None
    };
    if let (Some(slice), false) = (rows, copy) {
        let source = NumpyPixels {
            _owner: array.as_any().clone().unbind(),
            ptr: slice.as_ptr(),
            len: slice.len(),
        };
        return MapImage::shared(w, h, Arc::new(source)).map_err(to_py);
    }
    within_budget(
        format_args!("copying a {w}x{h} map"),
        u64::from(w) * u64::from(h),
    )?;
    let py = array.py();
    let pixels = match rows {
        Some(slice) => py.detach(|| slice.to_vec()),
        None => {
            let view = array.as_array();
            py.detach(|| view.iter().copied().collect())
        }
    };
    MapImage::new(w, h, pixels).map_err(to_py)
}

/// A georeference from Python's optional resolution and origin, checked to give every pixel of `image`
/// finite world coordinates.
fn georef_of(
    resolution: Option<f64>,
    origin: Option<(f64, f64, f64)>,
    image: &MapImage,
) -> PyResult<Option<GeoRef>> {
    let (r, (x, y, yaw)) = match (resolution, origin) {
        (None, None) => return Ok(None),
        (None, Some(_)) => {
            return Err(PyValueError::new_err(
                "an origin needs a resolution (metres a pixel)",
            ))
        }
        (Some(r), o) => (r, o.unwrap_or((0.0, 0.0, 0.0))),
    };
    let g = GeoRef::checked(r, [x, y, yaw]).map_err(to_py)?;
    g.check_finite(image.width(), image.height())
        .map_err(|m| to_py(Error::invalid(m)))?;
    Ok(Some(g))
}

/// A map image's thresholds, checked.
pub fn thresholds_of(negate: bool, occupied_thresh: f64, free_thresh: f64) -> PyResult<Thresholds> {
    let thresholds = Thresholds {
        negate,
        occupied_thresh,
        free_thresh,
    };
    thresholds
        .validate()
        .map_err(|m| to_py(Error::invalid(m)))?;
    Ok(thresholds)
}

/// An occupancy map: a greyscale image read as ROS `map_server` reads it (occupied, unknown, free), and,
/// from a yaml or an occupancy grid, where it lies in the world. Immutable: its pixels are shared with
/// numpy (`pixels`) without a copy.
#[pyclass(frozen, module = "ogm_corners._core", name = "Map")]
pub struct Map {
    pub inner: OccupancyMap,
}

impl Map {
    /// Wraps a library map, its pixels put behind a reference count so that clones share them.
    pub fn wrap(mut inner: OccupancyMap) -> Map {
        inner.image = inner.image.into_shared();
        Map { inner }
    }
}

#[pymethods]
impl Map {
    #[new]
    #[pyo3(signature = (pixels, resolution=None, origin=None, *, negate=false, occupied_thresh=0.65, free_thresh=0.196, copy=true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        pixels: PyReadonlyArray2<'_, u8>,
        resolution: Option<f64>,
        origin: Option<(f64, f64, f64)>,
        negate: bool,
        occupied_thresh: f64,
        free_thresh: f64,
        copy: bool,
    ) -> PyResult<Self> {
        let thresholds = thresholds_of(negate, occupied_thresh, free_thresh)?;
        let image = image_of(&pixels, copy)?;
        let georef = georef_of(resolution, origin, &image)?;
        Ok(Map::wrap(OccupancyMap {
            thresholds,
            georef,
            ..OccupancyMap::from_image(image)
        }))
    }

    /// A map from `nav_msgs/OccupancyGrid` cells (int8 viewed as uint8, row 0 at the bottom).
    #[staticmethod]
    #[pyo3(signature = (cells, width, height, resolution, origin, occupied_thresh=0.65, free_thresh=0.25))]
    #[allow(clippy::too_many_arguments)]
    fn _from_grid(
        py: Python<'_>,
        cells: PyReadonlyArray1<'_, u8>,
        width: u32,
        height: u32,
        resolution: f64,
        origin: (f64, f64, f64),
        occupied_thresh: f64,
        free_thresh: f64,
    ) -> PyResult<Self> {
        let owned;
        let cells: &[u8] = match cells.as_slice() {
            Ok(s) => s,
            Err(_) => {
                owned = cells.as_array().iter().copied().collect::<Vec<u8>>();
                &owned
            }
        };
        let t = GridThresholds {
            occupied_thresh,
            free_thresh,
        };
        let (x, y, yaw) = origin;
        let map = unlocked(py, || {
            OccupancyMap::from_occupancy_grid(cells, width, height, resolution, [x, y, yaw], &t)
        })?;
        Ok(Map::wrap(map))
    }

    /// Width in pixels.
    #[getter]
    fn width(&self) -> u32 {
        self.inner.image.width()
    }

    /// Height in pixels.
    #[getter]
    fn height(&self) -> u32 {
        self.inner.image.height()
    }

    /// Metres a pixel, or None for a map with no georeference.
    #[getter]
    fn resolution(&self) -> Option<f64> {
        self.inner.georef.map(|g| g.resolution)
    }

    /// (x, y, yaw) of the lower-left pixel's outer corner in metres and radians, or None.
    #[getter]
    fn origin(&self) -> Option<(f64, f64, f64)> {
        self.inner
            .georef
            .map(|g| (g.origin[0], g.origin[1], g.origin[2]))
    }

    /// (negate, occupied_thresh, free_thresh): how pixel values become states.
    #[getter]
    fn thresholds(&self) -> (bool, f64, f64) {
        let t = self.inner.thresholds;
        (t.negate, t.occupied_thresh, t.free_thresh)
    }

    /// The file the map was loaded from (its yaml, else its image), or None.
    #[getter]
    fn source(&self) -> Option<PathBuf> {
        self.inner.source().map(|p| p.to_path_buf())
    }

    /// What loading noticed that did not stop it (a `nan` yaw, bytes after the image).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings.clone()
    }

    /// The pixels as a read-only (height, width) uint8 array sharing the map's memory.
    #[getter]
    fn pixels<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArray2<u8>>> {
        let image = &slf.get().inner.image;
        let shape = (image.height() as usize, image.width() as usize);
        let view = ArrayView2::from_shape(shape, image.pixels())
            .expect("a map's pixels fill its width and height");
        // SAFETY: the array keeps this frozen map alive, and a map's pixels never change or move while it
        // lives (nothing calls `pixels_mut` on a `Map`'s image).
        let array = unsafe { PyArray2::borrow_from_array(&view, slf.clone().into_any()) };
        let kwargs = PyDict::new(slf.py());
        kwargs.set_item("write", false)?;
        array.call_method("setflags", (), Some(&kwargs))?;
        Ok(array)
    }

    /// Each pixel's state as uint8: 0 free, 1 unknown, 2 occupied (`ogm_corners.State`).
    fn states<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u8>>> {
        let image = &self.inner.image;
        let classes = ClassTable::new(&self.inner.thresholds);
        let states: Vec<u8> = py.detach(|| {
            image
                .pixels()
                .iter()
                .map(|&v| classes.state(v) as u8)
                .collect()
        });
        let shape = [image.height() as usize, image.width() as usize];
        states.into_pyarray(py).reshape(shape)
    }

    /// The map as `nav_msgs/OccupancyGrid` data: int8, row 0 at the bottom, 100 / 0 / -1.
    fn _grid_cells<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i8>> {
        let map = &self.inner;
        py.detach(|| map.to_occupancy_grid()).into_pyarray(py)
    }

    /// Writes NAME.yaml (with NAME.pgm) or NAME.pgm, both renamed into place together.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let map = &self.inner;
        unlocked(py, || map.save(&path))
    }

    /// The same pixels and thresholds with another georeference (no copy).
    #[pyo3(signature = (resolution, origin=None))]
    fn with_georef(&self, resolution: f64, origin: Option<(f64, f64, f64)>) -> PyResult<Map> {
        let georef = georef_of(Some(resolution), origin, &self.inner.image)?;
        Ok(Map::wrap(OccupancyMap {
            georef,
            ..self.inner.clone()
        }))
    }

    /// The files the map came from and what loading noticed: (yaml, image, warnings), for pickling.
    fn _files(&self) -> (Option<PathBuf>, Option<PathBuf>, Vec<String>) {
        let m = &self.inner;
        (
            m.yaml_path.clone(),
            m.image_path.clone(),
            m.warnings.clone(),
        )
    }

    /// The same map said to come from these files, with these warnings (a pickled map unpickled).
    fn _with_files(
        &self,
        yaml: Option<PathBuf>,
        image: Option<PathBuf>,
        warnings: Vec<String>,
    ) -> Map {
        Map::wrap(OccupancyMap {
            yaml_path: yaml,
            image_path: image,
            warnings,
            ..self.inner.clone()
        })
    }

    fn __repr__(&self) -> String {
        let m = &self.inner;
        let mut s = format!("Map({}x{}", m.image.width(), m.image.height());
        if let Some(g) = m.georef {
            s += &format!(
                ", resolution={}, origin=({}, {}, {})",
                g.resolution, g.origin[0], g.origin[1], g.origin[2]
            );
        }
        if let Some(p) = m.source() {
            s += &format!(", source={:?}", p.display().to_string());
        }
        s + ")"
    }
}

/// Loads a ROS map yaml (and its image) or an image alone (PGM, PNG).
#[pyfunction]
pub fn load_map(py: Python<'_>, path: PathBuf) -> PyResult<Map> {
    unlocked(py, || OccupancyMap::load(&path)).map(Map::wrap)
}

/// The seeded synthetic office map of `ogm-corners demo`, georeferenced at `resolution` with origin 0.
#[pyfunction]
#[pyo3(signature = (width=1024, height=768, seed=1, resolution=0.05))]
pub fn synthetic_office(
    py: Python<'_>,
    width: u32,
    height: u32,
    seed: u64,
    resolution: f64,
) -> PyResult<Map> {
    let georef = GeoRef::checked(resolution, [0.0; 3]).map_err(to_py)?;
    let image = unlocked(py, || {
        synthetic::check_office_size(width, height)?;
        synthetic::office_map(width, height, seed)
    })?;
    Ok(Map::wrap(OccupancyMap {
        georef: Some(georef),
        ..OccupancyMap::from_image(image)
    }))
}

/// A pixel transform as Python has it: (theta degrees, tx, ty).
type Transform = (f64, f64, f64);

/// `n` overlapping robot maps cut from `source` (each turned and shifted, with speckle at `noise`), each
/// with its exact pose (theta degrees, tx, ty: its pixels to the source's).
#[pyfunction]
#[pyo3(signature = (source, n, noise=0.0, seed=1))]
pub fn synthetic_robot_maps(
    py: Python<'_>,
    source: &Map,
    n: usize,
    noise: f64,
    seed: u64,
) -> PyResult<Vec<(Map, Transform)>> {
    if !(0.0..=1.0).contains(&noise) {
        return Err(PyValueError::new_err(format!(
            "noise must lie in [0, 1], got {noise}"
        )));
    }
    if n > 64 {
        return Err(PyValueError::new_err(format!(
            "at most 64 robot maps, got {n}"
        )));
    }
    let src = &source.inner;
    let crops = py
        .detach(|| synthetic_set(src, n, noise, seed))
        .ok_or_else(|| {
            PyValueError::new_err(
                "no robot maps can be cut from this map: its known area is too small (or n is 0)",
            )
        })?;
    let georef = src.georef.map(|g| GeoRef {
        origin: [0.0; 3],
        ..g
    });
    Ok(crops
        .into_iter()
        .map(|c| {
            let p = c.pose;
            (
                Map::wrap(OccupancyMap { georef, ..c.map }),
                (p.theta_deg, p.tx, p.ty),
            )
        })
        .collect())
}

/// The synthetic fleet of `merge-eval --global --set-size n --buildings b`: `n` robot maps cut from `b`
/// synthetic offices (seeds `seed`, `seed + 1`, ...), a share each, as (name, map) (names `oK-part-NN`).
#[pyfunction]
#[pyo3(signature = (n, buildings=4, seed=1))]
pub fn synthetic_fleet(
    py: Python<'_>,
    n: usize,
    buildings: usize,
    seed: u64,
) -> PyResult<Vec<(String, Map)>> {
    if !(1..=2000).contains(&n) || !(1..=64).contains(&buildings) {
        return Err(PyValueError::new_err(format!(
            "n must lie in 1..=2000 and buildings in 1..=64; got {n} and {buildings}"
        )));
    }
    let (names, maps, _) = unlocked(py, || {
        ogm_corners::measure::merging::many::synthetic_mixed(n, buildings, seed)
    })?;
    Ok(names
        .into_iter()
        .zip(maps.into_iter().map(Map::wrap))
        .collect())
}
