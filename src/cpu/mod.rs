//! The CPU reference: one plain Rust twin per GPU kernel, named after its shader in `shaders/`.
//!
//! These are the oracle the other backends are tested against, so they favour obviousness over speed.

pub mod classify;
pub mod ogm_corners;

use crate::detector::{Backend, Keypoint};
use crate::error::Result;
use crate::map::MapImage;
use crate::rules::RuleTable;
use crate::states::ClassTable;

/// The CPU backend: classification then the rule table, pixel by pixel.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuBackend;

impl Backend for CpuBackend {
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
        let states = classify::classify(image, classes);
        Ok(ogm_corners::ogm_corners(
            &states,
            image.width(),
            image.height(),
            rules,
            unknown_as_occupied,
        ))
    }
}
