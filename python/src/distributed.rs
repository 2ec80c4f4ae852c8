//! Many maps placed with the work done elsewhere: `merge_many_on` runs the placement here and hands each
//! map's preparation and each chosen pair's alignment to a Python executor (`ogm_corners.distributed`:
//! Ray tasks, or the in-process reference executor), as bytes it can store and send by reference
//! ([`ogm_corners::merge::many::codec`], [`many::PairRecord`]). `_prepare_encoded` and `_align_encoded` are
//! what the executor's workers run.

use std::cell::RefCell;

use numpy::PyReadonlyArray2;
use ogm_corners::merge::many::codec::{self, Form};
use ogm_corners::merge::many::prescreen::Signature;
use ogm_corners::merge::many::{self, poses, Engine, GlobalOptions, PairRecord};
use ogm_corners::merge::pair::align::Prepared;
use ogm_corners::{Error, MapImage, OccupancyMap};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::errors::{interruptible, to_py, unlocked, within_budget};
use crate::map::{image_of, thresholds_of, Map};
use crate::merge::ManyMerge;

/// An engine whose work a Python executor does (its `prepare` and `align` methods). A Python exception
/// the executor raises is kept and raised again once the run has ended.
struct PyEngine {
    executor: Py<PyAny>,
    options: String,
    raised: RefCell<Option<PyErr>>,
}

impl PyEngine {
    /// Calls the executor, keeping a Python exception for later and ending the run with a note of it.
    fn call<T>(&self, f: impl FnOnce(Python<'_>) -> PyResult<T>) -> ogm_corners::Result<T> {
        Python::attach(|py| {
            f(py).map_err(|e| {
                let text = e.to_string();
                *self.raised.borrow_mut() = Some(e);
                Error::Internal(format!("the executor raised: {text}"))
            })
        })
    }
}

impl Engine for PyEngine {
    fn prepare(
        &mut self,
        maps: &[(usize, &OccupancyMap)],
        signatures: bool,
    ) -> ogm_corners::Result<Vec<(Prepared, Option<Signature>)>> {
        // Each decoded straight from the executor's bytes (no copy of them kept).
        let decoded: Vec<ogm_corners::Result<(Prepared, Option<Signature>)>> = self.call(|py| {
            let items: Vec<(usize, Map)> = maps
                .iter()
                .map(|&(k, m)| (k, Map::wrap(m.clone())))
                .collect();
            let out = self
                .executor
                .call_method1(py, "prepare", (items, signatures))?;
            let mut decoded = Vec::with_capacity(maps.len());
            for item in out.bind(py).try_iter()? {
                let (p, s): (Bound<'_, PyBytes>, Option<Bound<'_, PyBytes>>) = item?.extract()?;
                decoded.push(decode_one(
                    p.as_bytes(),
                    s.as_ref().map(|s| s.as_bytes()),
                    signatures,
                ));
            }
            Ok(decoded)
        })?;
        if decoded.len() != maps.len() {
            return Err(Error::invalid(format!(
                "the executor prepared {} maps of {}",
                decoded.len(),
                maps.len()
            )));
        }
        decoded.into_iter().collect()
    }

    fn align(
        &mut self,
        _maps: &[Prepared],
        pairs: &[(usize, usize)],
        _options: &GlobalOptions,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> ogm_corners::Result<Vec<PairRecord>> {
        let records: Vec<String> = self.call(|py| {
            self.executor
                .call_method1(py, "align", (pairs.to_vec(), self.options.clone()))?
                .extract(py)
        })?;
        progress(pairs.len(), pairs.len());
        records.iter().map(|r| PairRecord::from_json(r)).collect()
    }
}

/// A map's placement part and signature as the executor returned them, checked.
fn decode_one(
    p: &[u8],
    s: Option<&[u8]>,
    signatures: bool,
) -> ogm_corners::Result<(Prepared, Option<Signature>)> {
    let (p, _) = codec::decode_prepared(p)?;
    let s =
        match (s, signatures) {
            (Some(s), true) => Some(codec::decode_signature(s)?),
            (None, false) => None,
            _ => return Err(Error::invalid(
                "the executor returned a signature where none was asked for, or none where one was",
            )),
        };
    Ok((p, s))
}

/// [`crate::merge::merge_many`] with the preparations and pair alignments done by `executor`.
#[pyfunction]
#[pyo3(signature = (maps, names, executor, backend="cpu", partners=3))]
pub fn merge_many_on(
    py: Python<'_>,
    maps: Vec<PyRef<'_, Map>>,
    names: Vec<String>,
    executor: Py<PyAny>,
    backend: &str,
    partners: usize,
) -> PyResult<ManyMerge> {
    let backend_name = backend;
    crate::merge::check_many(maps.len(), names.len(), partners)?;
    // Here: the maps and what a placement reads of each preparation (about 3 bytes a pixel).
    let px: u64 = maps
        .iter()
        .map(|m| u64::from(m.inner.image.width()) * u64::from(m.inner.image.height()))
        .sum();
    within_budget(
        format_args!("{} maps and their placement data", maps.len()),
        px.saturating_mul(5),
    )?;
    let mut on = crate::merge::backend(py, backend_name)?;
    let owned: Vec<OccupancyMap> = maps.iter().map(|m| m.inner.clone()).collect();
    let options = GlobalOptions::with_partners(partners);
    let mut engine = PyEngine {
        executor,
        options: poses::options_id(&options),
        raised: RefCell::new(None),
    };
    let outcome = interruptible(py, || {
        many::merge_maps_with(
            owned,
            &names,
            &options,
            on.as_mut(),
            &|_, _| {},
            &mut many::Cache::new(),
            &mut engine,
        )
    });
    if let Some(e) = engine.raised.take() {
        return Err(e);
    }
    ManyMerge::of(outcome?)
}

/// A map's preparation as bytes: whole, its placement part, its signature when asked for.
type Encoded<'py> = (
    Bound<'py, PyBytes>,
    Bound<'py, PyBytes>,
    Option<Bound<'py, PyBytes>>,
);

/// A map's preparation for a worker of a distributed run: (the whole preparation, the part a placement
/// reads, the pre-screen signature when `signature`), each as bytes.
#[pyfunction]
#[pyo3(signature = (pixels, negate, occupied_thresh, free_thresh, signature))]
pub fn _prepare_encoded<'py>(
    py: Python<'py>,
    pixels: PyReadonlyArray2<'_, u8>,
    negate: bool,
    occupied_thresh: f64,
    free_thresh: f64,
    signature: bool,
) -> PyResult<Encoded<'py>> {
    let thresholds = thresholds_of(negate, occupied_thresh, free_thresh)?;
    let image: MapImage = image_of(&pixels, true)?;
    let map = OccupancyMap {
        thresholds,
        ..OccupancyMap::from_image(image)
    };
    let need = ogm_corners::merge::footprint::footprint(&map, None)
        .map_err(to_py)?
        .bytes();
    within_budget("a map's preparation", need)?;
    let (full, light, sig) = unlocked(py, || {
        let p = Prepared::new(&map);
        let s = signature
            .then(|| Signature::of(&map).map(|s| codec::encode_signature(&s)))
            .transpose()?;
        Ok((
            codec::encode_prepared(&p, Form::Full),
            codec::encode_prepared(&p, Form::Placement),
            s,
        ))
    })?;
    Ok((
        PyBytes::new(py, &full),
        PyBytes::new(py, &light),
        sig.map(|s| PyBytes::new(py, &s)),
    ))
}

/// One pair's alignment for a worker of a distributed run: map `b`'s whole preparation aligned onto map
/// `a`'s, as its record (JSON). `options` is the id of the options the run places with
/// (`poses::options_id`): a worker of another version refuses rather than answer differently.
#[pyfunction]
pub fn _align_encoded(py: Python<'_>, a: &[u8], b: &[u8], options: &str) -> PyResult<String> {
    let global_options = GlobalOptions::default();
    let here = poses::options_id(&global_options);
    if options != here {
        return Err(to_py(Error::invalid(format!(
            "this worker aligns with options {here}, the run places with {options}: install the same \
             ogm-corners version everywhere"
        ))));
    }
    unlocked(py, || {
        let (pa, fa) = codec::decode_prepared(a)?;
        let (pb, fb) = codec::decode_prepared(b)?;
        if fa != Form::Full || fb != Form::Full {
            return Err(Error::invalid(
                "a pair is aligned from whole preparations, not their placement form",
            ));
        }
        let al = ogm_corners::merge::pair::align::align_prepared(&pa, &pb, &global_options.pair)?;
        Ok(PairRecord::of(&pa, &pb, &al, &global_options).to_json())
    })
}
