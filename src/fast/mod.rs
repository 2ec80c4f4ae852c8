//! The fast CPU backend: the same results as the reference in [`crate::cpu`], bit for bit, computed with
//! bit-planes, SIMD compares and every core (rayon), streaming the map in bands of rows so that memory
//! beyond the map stays small.
//!
//! The reference stays the oracle: the conformance tests compare this backend with it on every map they
//! cover.

mod baseline_tensor;
mod baseline_trajkovic;
pub mod baselines;
pub mod bitplanes;
pub mod ogm;

use crate::baselines::{Baseline, BaselineParams, ExactParams};
use crate::detector::{Backend, Keypoint};
use crate::error::Result;
use crate::map::MapImage;
use crate::rules::RuleTable;
use crate::states::ClassTable;

/// The fast CPU backend (the default). Threads come from rayon's global pool (`RAYON_NUM_THREADS`).
#[derive(Clone, Copy, Debug, Default)]
pub struct FastCpuBackend;

impl Backend for FastCpuBackend {
    fn name(&self) -> String {
        "cpu".to_string()
    }

    fn detect(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        rules: &RuleTable,
        unknown_as_occupied: bool,
    ) -> Result<Vec<Keypoint>> {
        Ok(ogm::ogm_corners(image, classes, rules, unknown_as_occupied))
    }

    fn baseline_scores(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        params: &ExactParams,
    ) -> Result<Vec<i64>> {
        Ok(baselines::scores(kind, image, params))
    }

    fn baseline_keypoints(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        params: &BaselineParams,
    ) -> Result<Vec<Keypoint>> {
        baselines::keypoints(kind, image, params)
    }
}
