//! The scoring kernel's counts of one map's points landing on the other's flags, both ways, for many
//! candidate transforms at once (on any backend: the same integers).

use crate::backend::Backend;
use crate::backend::{FixedRigid, ScoreTarget};
use crate::merge::pair::prepare::Prepared;
use crate::merge::transform::Rigid;
use crate::support::error::Result;

/// The scoring kernel's counts for one transform: inside, near, deep.
pub(in crate::merge) type Counts = [u32; 3];

/// What the scoring kernel counts: which points of one map land on which flags of the other.
#[derive(Clone, Copy)]
pub(in crate::merge) enum Probe {
    /// Walls on the verification flags (inside, near within 5 px, over 20 px deep).
    Walls,
    /// Walls on the fine flags (inside, on an occupied pixel, over 3 px deep).
    Fine,
    /// Sampled walls on the fine flags (the polish's coarser steps).
    FineSample,
    /// Sampled walls on the screening flags (over 8 px deep, near within 5 px, over 20 px deep).
    Screen,
    /// Sampled free pixels on the free-space flags (known, free, occupied).
    Free,
}

impl Probe {
    pub(in crate::merge) fn points(self, p: &Prepared) -> &[[u32; 2]] {
        match self {
            Probe::Walls | Probe::Fine => &p.wall_points,
            Probe::Screen | Probe::FineSample => &p.screen_points,
            Probe::Free => &p.free_points,
        }
    }

    pub(in crate::merge) fn target(self, p: &Prepared) -> &ScoreTarget {
        match self {
            Probe::Walls => &p.flags,
            Probe::Fine | Probe::FineSample => &p.flags_fine,
            Probe::Screen => &p.flags_screen,
            Probe::Free => &p.flags_free,
        }
    }
}

/// Per transform (src crop to dst crop), the scoring kernel's counts of `probe`'s points of src mapped
/// into dst and of dst's mapped back by the inverse.
pub(in crate::merge) fn score_both(
    src: &Prepared,
    dst: &Prepared,
    transforms: &[Rigid],
    probe: Probe,
    backend: &mut dyn Backend,
) -> Result<(Vec<Counts>, Vec<Counts>)> {
    let fixed = |t: &Rigid| FixedRigid::new(t.theta_deg, t.tx, t.ty);
    let forward: Vec<FixedRigid> = transforms.iter().map(fixed).collect();
    let backward: Vec<FixedRigid> = transforms.iter().map(|t| fixed(&t.inverse())).collect();
    Ok((
        backend.score_transforms(probe.target(dst), probe.points(src), &forward)?,
        backend.score_transforms(probe.target(src), probe.points(dst), &backward)?,
    ))
}
