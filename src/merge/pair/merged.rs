//! Two maps merged: B brought to A's resolution, aligned onto A with no initial pose, the world form of
//! the transform, and the merged map and its picture (what `merge A B` and the Python `merge` do).

use std::borrow::Cow;

use serde::Serialize;

use crate::backend::Backend;
use crate::map::OccupancyMap;
use crate::merge::pair::align::{align_with, Alignment, Features, MergeOptions};
use crate::merge::transform::{to_world, Rigid, WorldRigid};
use crate::merge::{compose, resample};
use crate::support::error::Result;

/// The verdict on a pair ([`merge_pair`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PairMerge {
    /// The alignment of B (at A's resolution) onto A, accepted or not.
    pub alignment: Alignment,
    /// B's pixels per A pixel before aligning (its resolution over A's; 1 when they agree): the
    /// transform applies to B resampled to A's resolution.
    pub b_scale: f64,
    /// The pose of B's map frame in A's (metres, radians), when both maps are georeferenced.
    pub world: Option<WorldRigid>,
}

/// The verdict on a pair as `merge A B --format json` writes it (and the Python package reads it).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    /// Whether the merge is confident.
    pub accepted: bool,
    /// Why not, when not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// B's pixels to A's (B at A's resolution when they differ).
    pub transform: Rigid,
    /// B's map frame in A's, when both are georeferenced.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub world: Option<WorldRigid>,
    /// B's pixels per A pixel before aligning (1 when the resolutions agree).
    pub b_scale: f64,
    /// The acceptance rule's value minus its threshold.
    pub score: f64,
    /// The share of B's known area that falls in A's.
    pub overlap: f64,
    /// The verification's features.
    pub features: Features,
}

impl PairMerge {
    /// The verdict to report.
    pub fn verdict(&self) -> Verdict {
        let al = &self.alignment;
        Verdict {
            accepted: al.accepted,
            reason: al.reason.clone(),
            transform: al.transform,
            world: self.world,
            b_scale: self.b_scale,
            score: al.score,
            overlap: al.features.inside,
            features: al.features,
        }
    }
}

/// `b` at `a`'s resolution (resampled by nearest neighbour only when both are georeferenced and their
/// resolutions differ), and `b`'s resolution over `a`'s.
pub fn at_resolution_of<'b>(
    a: &OccupancyMap,
    b: &'b OccupancyMap,
) -> Result<(Cow<'b, OccupancyMap>, f64)> {
    match a.georef {
        Some(ga) => resample::at_resolution(b, ga.resolution).map(|(b, k)| (b, k.unwrap_or(1.0))),
        None => Ok((Cow::Borrowed(b), 1.0)),
    }
}

/// Aligns `b` onto `a` with no initial pose ([`align_with`], candidates scored on `backend`), `b` first
/// brought to `a`'s resolution.
pub fn merge_pair(
    a: &OccupancyMap,
    b: &OccupancyMap,
    options: &MergeOptions,
    backend: &mut dyn Backend,
) -> Result<PairMerge> {
    let (b, b_scale) = at_resolution_of(a, b)?;
    let alignment = align_with(a, &b, options, backend)?;
    let world = world_of(a, &b, &alignment.transform);
    Ok(PairMerge {
        alignment,
        b_scale,
        world,
    })
}

/// The world form of `t` (B's pixels, at A's resolution, to A's), when both maps are georeferenced.
fn world_of(a: &OccupancyMap, b_resampled: &OccupancyMap, t: &Rigid) -> Option<WorldRigid> {
    match (a.georef, b_resampled.georef) {
        (Some(ga), Some(gb)) => Some(to_world(
            t,
            &ga,
            a.image.height(),
            &gb,
            b_resampled.image.height(),
        )),
        _ => None,
    }
}

/// The merged map of `a` and `b` in A's frame, B placed by `t` (B's pixels at A's resolution to A's, as
/// [`merge_pair`] gives it); see [`compose::compose`].
pub fn compose_pair(a: &OccupancyMap, b: &OccupancyMap, t: &Rigid) -> Result<OccupancyMap> {
    let (b, _) = at_resolution_of(a, b)?;
    compose::compose(a, &b, t)
}

/// The picture of the alignment ([`compose::overlay`]), `t` as for [`compose_pair`].
pub fn overlay_pair(a: &OccupancyMap, b: &OccupancyMap, t: &Rigid) -> Result<image::RgbImage> {
    let (b, _) = at_resolution_of(a, b)?;
    compose::overlay(a, &b, t)
}
