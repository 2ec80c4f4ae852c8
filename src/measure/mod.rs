//! Measuring: the harness that says how well the detectors and the merger do, apart from the algorithm
//! it measures (nothing below this layer imports it).
//!
//! - [`detection`]: the detectors' repeatability and annotated-corner recall, with its table, plots and
//!   page (`eval`);
//! - [`compare`]: the detectors side by side, the paper's Table I and contact sheets (`compare`);
//! - [`bench`](mod@bench): the measurement behind `bench` and `compare`: median times, peak memory,
//!   backends agreeing;
//! - [`pairs`]: pair sets with ground truth and their success test;
//! - [`synthetic`]: synthetic pairs, sets and the hard families, cut with exact truth from any map, and
//!   robots exploring a synthetic building (the demo's);
//! - [`merging`]: `merge-eval`: pairs, families, leave-one-building-out, many maps (`many`), its cache and
//!   its page.

pub mod bench;
pub mod compare;
pub mod detection;
pub mod merging;
pub mod pairs;
pub mod synthetic;
