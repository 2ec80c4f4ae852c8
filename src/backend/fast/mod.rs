//! The fast CPU backend (`--backend cpu`, the default): the same results as the reference in
//! [`crate::backend::reference`], bit for bit, computed with bit-planes, SIMD compares and every core
//! (rayon), streaming the map in bands of rows so that memory beyond the map stays small.
//!
//! The reference stays the oracle: the conformance tests compare this backend with it on every map they
//! cover.
//!
//! - [`simd`]: the instruction set picked at run time (`Isa`: AVX-512, AVX2, portable;
//!   `OGM_CORNERS_ISA` caps it) and `Lanes`, bit vectors of 64-bit words over each, so that the OGM
//!   kernel ([`ogm`]) is written once and compiled three times, each tested against the reference;
//! - [`bitplanes`]: classification into bit-planes, the fast twin of the reference's `classify`;
//! - [`coarsen`]: the fast twin of the coarsening kernel, of the same name;
//! - [`baselines`] (with `baseline_tensor.rs` and `baseline_trajkovic.rs`): the baselines' scores and
//!   keypoints in bands of rows;
//! - [`read`]: the plain read that `bench --bandwidth` measures the detectors against.

mod baseline_tensor;
mod baseline_trajkovic;
pub mod baselines;
pub mod bitplanes;
pub mod coarsen;
pub mod ogm;
pub mod read;
pub mod simd;

use crate::backend::baselines::{Baseline, BaselineParams, Candidate, ExactParams};
use crate::backend::reference::coarsen::CellRule;
use crate::backend::rules::RuleTable;
use crate::backend::{
    maxima_of_window_scores, reference_working_bytes, Backend, DetectOptions, DetectorKind,
    Keypoint, OgmWindow,
};
use crate::map::grid::RotatedGrid;
use crate::map::states::ClassTable;
use crate::map::stream::Rows;
use crate::map::MapImage;
use crate::support::error::Result;

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
        rule: CellRule,
    ) -> Result<Vec<MapImage>> {
        Ok(coarsen::coarsen(image, classes, grid, scales, rule))
    }

    fn baseline_scores(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        params: &ExactParams,
    ) -> Result<Vec<i64>> {
        Ok(baselines::scores(kind, image, params))
    }

    fn detect_rows(&mut self, w: OgmWindow) -> Result<Vec<Keypoint>> {
        Ok(ogm::ogm_corners_rows(
            w.rows,
            w.core,
            w.classes,
            w.rules,
            w.unknown_as_occupied,
        ))
    }

    fn baseline_rows(
        &mut self,
        kind: Baseline,
        rows: Rows,
        core: (usize, usize),
        params: &BaselineParams,
        known_max: i64,
    ) -> Result<(Vec<Candidate>, i64)> {
        if let Some(found) = baselines::window_candidates(kind, rows, core, params, known_max)? {
            return Ok(found);
        }
        // Kernels the fast path does not cover: the default route (whose scores the reference computes).
        maxima_of_window_scores(self, kind, rows, core, params)
    }

    /// 32 MiB: the fast path keeps only a few rows per thread beside the window; larger windows split
    /// into more bands per thread (measured on a 100000^2 map: 16 MiB 5.2 s, 32 MiB 4.9 s, 64 MiB 4.7 s).
    fn window_bytes(&self, _options: &DetectOptions) -> u64 {
        32 << 20
    }

    /// Per band in flight (one per thread at most): OGM keeps 7 rows of bit-planes; the baselines keep
    /// their rolling rows (blur 3 x i16, horizontal sums 9 x i32, products 3 x i32, scratch, and 3 rows of
    /// i64 scores: under 96 bytes a column). Baseline options the fast path does not cover fall back to
    /// the reference.
    fn working_bytes(&self, options: &DetectOptions, width: u32, height: u32) -> u64 {
        let (w, h) = (u64::from(width), u64::from(height));
        let per_band = match options.detector {
            DetectorKind::Ogm => 7 * 8 * w.div_ceil(64),
            DetectorKind::OgmRobust => {
                return crate::backend::robust_params::robust_working_bytes(
                    width,
                    height,
                    &options.robust,
                )
            }
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
