//! The fast CPU baselines: placeholder that defers to the reference until the fused pipeline lands.

use crate::baselines::{self, Baseline, BaselineParams, ExactParams};
use crate::detector::Keypoint;
use crate::error::Result;
use crate::map::MapImage;

/// The score map of `kind`, identical to [`crate::baselines::cpu_scores`].
pub fn scores(kind: Baseline, image: &MapImage, params: &ExactParams) -> Vec<i64> {
    baselines::cpu_scores(kind, image, params)
}

/// The keypoints of `kind`, identical to the reference's score map followed by [`baselines::select`].
pub fn keypoints(kind: Baseline, image: &MapImage, params: &BaselineParams) -> Result<Vec<Keypoint>> {
    let exact = params.exact()?;
    let s = scores(kind, image, &exact);
    Ok(baselines::select(kind, &s, image.width(), image.height(), params)
        .into_iter()
        .map(|(x, y, v)| Keypoint::scored(x, y, v))
        .collect())
}
