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
pub mod coarsen;
pub mod ogm;

use crate::backend::{reference_working_bytes, Backend, DetectOptions, DetectorKind, Keypoint};
use crate::baselines::{Baseline, BaselineParams, ExactParams};
use crate::error::Result;
use crate::grid::RotatedGrid;
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

    fn coarsen(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        grid: &RotatedGrid,
        scales: &[u32],
    ) -> Result<Vec<MapImage>> {
        Ok(coarsen::coarsen(image, classes, grid, scales))
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

    /// Per band in flight (one per thread at most): OGM keeps 7 rows of bit-planes; the baselines keep
    /// their rolling rows (blur 3 x i16, horizontal sums 9 x i32, products 3 x i32, scratch, and 3 rows of
    /// i64 scores: under 96 bytes a column). Baseline options the fast path does not cover fall back to
    /// the reference.
    fn working_bytes(&self, options: &DetectOptions, width: u32, height: u32) -> u64 {
        let (w, h) = (u64::from(width), u64::from(height));
        let per_band = match options.detector {
            DetectorKind::Ogm => 7 * 8 * w.div_ceil(64),
            DetectorKind::OgmRobust => return crate::robust::robust_working_bytes(width, height),
            DetectorKind::Baseline(kind) => {
                let covered = options
                    .baseline
                    .exact()
                    .is_ok_and(|p| baselines::covers(kind, &p));
                if !covered {
                    return reference_working_bytes(options, width, height);
                }
                96 * (w + 2)
            }
        };
        let bands = (rayon::current_num_threads() as u64).clamp(1, h.max(1));
        per_band.saturating_mul(bands)
    }
}
