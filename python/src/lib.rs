//! `ogm_corners._core`: the compiled half of the Python package. The pure-Python package around it
//! (`python/ogm_corners/`) shapes the API; this module converts between numpy and the Rust library and
//! releases the interpreter's lock while the library works.
//!
//! The package, `python/`, is a workspace member:
//! - `src/`: this pyo3 extension: maps and numpy (`map.rs`), detection (`detect.rs`), merging
//!   (`merge.rs`), work done elsewhere (`distributed.rs`), errors (`errors.rs`);
//! - `ogm_corners/`: the pure-Python package around it (`_map.py`, `_detect.py`, `_keypoints.py`,
//!   `_merge.py`, `synthetic.py`, `_core.pyi`); `ros/`: the ROS 2 `map_merge` node, `node.py` on rclpy
//!   over `live.py`, its logic with no ROS import, and `replay.py`, a bag through it;
//! - `tests/` (pytest), `examples/merge_rosbag.py`, `benches/overhead.py`.

mod detect;
mod distributed;
mod errors;
mod map;
mod merge;

use pyo3::prelude::*;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MAX_PARTNERS", merge::MAX_PARTNERS)?;
    m.add_class::<map::Map>()?;
    m.add_class::<detect::Detector>()?;
    m.add_class::<merge::ManyMerge>()?;
    m.add_class::<merge::MergeCache>()?;
    m.add_function(wrap_pyfunction!(map::load_map, m)?)?;
    m.add_function(wrap_pyfunction!(map::synthetic_office, m)?)?;
    m.add_function(wrap_pyfunction!(map::synthetic_robot_maps, m)?)?;
    m.add_function(wrap_pyfunction!(map::synthetic_fleet, m)?)?;
    m.add_function(wrap_pyfunction!(merge::merge, m)?)?;
    m.add_function(wrap_pyfunction!(merge::compose, m)?)?;
    m.add_function(wrap_pyfunction!(merge::overlay, m)?)?;
    m.add_function(wrap_pyfunction!(merge::merge_many, m)?)?;
    m.add_function(wrap_pyfunction!(distributed::merge_many_on, m)?)?;
    m.add_function(wrap_pyfunction!(distributed::_prepare_encoded, m)?)?;
    m.add_function(wrap_pyfunction!(distributed::_align_encoded, m)?)?;
    m.add(
        "BackendUnavailableError",
        m.py().get_type::<errors::BackendUnavailableError>(),
    )?;
    // Before the first parallel call, as the command line does: the package says it as a warning.
    m.add("_THREADS_NOTE", ogm_corners::support::threads::cap_pool())?;
    Ok(())
}
