//! The CPU reference: one plain Rust twin per GPU kernel, named after its shader in `shaders/`.
//!
//! These are the oracle the other backends are tested against, so they favour obviousness over speed;
//! `ReferenceBackend` runs them as a backend (`--backend reference`).
//!
//! Each twin computes the same integers as its kernel: `ogm_corners.rs` beside
//! `shaders/ogm_corners.wgsl`, and likewise `scan`, `select_maxima`, `coarsen`, `merge_score`,
//! `gaussian_blur`, `structure_tensor`, `harris`, `shi_tomasi` and `trajkovic`.
//! `tests/backend/shaders.rs` (`every_kernel_has_a_cpu_twin_of_the_same_name`) enforces the pairing and
//! validates every kernel with naga without a GPU; `tests/backend/gpu_conformance.rs` checks that each
//! pair gives the same result on lavapipe. `classify.rs` is the reference's classification, which the GPU
//! does inside `ogm_corners`. What the GPU host prepends to kernels (`shaders/lib/`, see
//! [`crate::backend::gpu`]) is not a kernel and has no twin. The GPU's host code has the same names again
//! under `src/backend/gpu/` where it has its own file (`coarsen.rs`, `merge_score.rs`, `scan.rs`), and the
//! fast path's under `src/backend/fast/` (`coarsen.rs`).

pub mod classify;
pub mod coarsen;
pub mod gaussian_blur;
pub mod harris;
pub mod merge_score;
pub mod ogm_corners;
pub mod scan;
pub mod select_maxima;
pub mod shi_tomasi;
pub mod structure_tensor;
pub mod trajkovic;

use crate::backend::baselines::{self, Baseline, ExactParams};
use crate::backend::rules::RuleTable;
use crate::backend::{Backend, Keypoint};
use crate::map::states::ClassTable;
use crate::map::MapImage;
use crate::support::error::Result;

/// The CPU backend: classification then the rule table, pixel by pixel.
#[derive(Clone, Copy, Debug, Default)]
pub struct ReferenceBackend;

impl Backend for ReferenceBackend {
    fn name(&self) -> String {
        "cpu-reference".to_string()
    }

    fn detect(
        &mut self,
        image: &MapImage,
        classes: &ClassTable,
        rules: &RuleTable,
        unknown_as_occupied: bool,
    ) -> Result<Vec<Keypoint>> {
        let states = classify::classify(image, classes);
        Ok(ogm_corners::ogm_corners(
            &states,
            image.width(),
            image.height(),
            rules,
            unknown_as_occupied,
        ))
    }

    fn baseline_scores(
        &mut self,
        kind: Baseline,
        image: &MapImage,
        params: &ExactParams,
    ) -> Result<Vec<i64>> {
        Ok(baselines::cpu_scores(kind, image, params))
    }
}
