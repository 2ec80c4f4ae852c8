//! The poses a pair could also be merged at: each map's turns onto itself at any angle, which join its
//! self-alignment's transforms (the aligner's `self_symmetry`, cached in the map), and the alternatives
//! they and the search's turned candidates offer the chosen pose, measured as the chosen pose is
//! ([`alias`]): a merge is ambiguous when one of them fits nearly as well
//! ([`super::accept::MAX_ALIAS`]).

use super::local::{local_both, local_fit};
use super::prepare::{Prepared, Symmetry};
use super::refine::{crop_to_map, icp, map_to_crop};
use super::score::{score_both, Probe};
use super::symmetry::{self_turns, NEAR_IDENTITY_DEG};
use super::transform::{signed_deg, transform_distance, Rigid, DISTINCT_PX};
use crate::backend::Backend;
use crate::error::Result;

/// A self-transform of a map offers an alternative pose
/// ([`Features::alias`](super::accept::Features::alias)) when the map matches itself under it at least
/// this well (the aligner's `self_symmetry` measure): a repeat over a good part of the map.
pub const ALIAS_SELF_MATCH: f64 = 0.2;
/// An alternative pose is as consistent as the chosen one when its residual conflict (the share of wall
/// pixels over 3 px deep in the other map's free space after each tile's best shift of a few px) exceeds
/// the chosen pose's by at most this.
pub const ALIAS_EXTRA_CONFLICT: f64 = 0.05;

/// Adds to `out` the map's turns onto itself at any angle ([`self_turns`]) that the self-alignment did
/// not find (its hypotheses are the quarter turns of the dominant wall direction: a building of three or
/// five wings, or a half turn a few degrees off, escapes them): each turn fitted finely by ICP and kept
/// when it matches the map as well as a self-alignment's candidate must ([`ALIAS_SELF_MATCH`], the same
/// measure). A turn's sweep score is a share of the map's walls as the self-match is, so a turn under
/// that share is not fitted at all.
pub(super) fn add_turns(p: &Prepared, out: &mut Symmetry) {
    use rayon::prelude::*;
    let fitted: Vec<(Rigid, f64)> = self_turns(p)
        .par_iter()
        .filter(|t| t.score >= ALIAS_SELF_MATCH)
        .map(|t| {
            let crop = icp(p, p, t.crop);
            let l = local_fit(p, p, &crop);
            (crop_to_map(p, p, &crop), l.share * l.coverage)
        })
        .collect();
    for (full, matched) in fitted {
        let known = |x: &Rigid| transform_distance(x, &full) <= DISTINCT_PX;
        if matched >= ALIAS_SELF_MATCH
            && !known(&Rigid::IDENTITY)
            && !out.transforms.iter().any(known)
        {
            out.transforms.push(full);
        }
    }
}

/// The best alternative to `best` (B's pixels to A's) that the maps' self-transforms offer (each of
/// them and its inverse applied on A's side or on B's) or the search found (`found`: the refined
/// candidates turned from it, with their [`local_both`] fits): among those distinct from `best` whose
/// residual conflict is hardly above its own ([`ALIAS_EXTRA_CONFLICT`]), the one with the most evidence
/// (wall pixels agreeing locally, both ways): its evidence over `best`'s
/// ([`Features::alias`](super::accept::Features::alias), 0 without one) and the pose.
pub(super) fn alias(
    src: &Prepared,
    dst: &Prepared,
    best: &Rigid,
    (sa, sb): (&Symmetry, &Symmetry),
    found: &[(Rigid, (f64, f64, f64))],
    backend: &mut dyn Backend,
) -> Result<(f64, Option<Rigid>)> {
    let mut poses = vec![*best];
    for s in &sa.transforms {
        poses.push(s.after(best));
        poses.push(s.inverse().after(best));
    }
    for s in &sb.transforms {
        poses.push(best.after(s));
        poses.push(best.after(&s.inverse()));
    }
    poses.retain(|t| t == best || transform_distance(t, best) > DISTINCT_PX);
    let turned: Vec<(Rigid, (f64, f64, f64))> = found
        .iter()
        .filter(|(t, _)| signed_deg(t.theta_deg - best.theta_deg).abs() > NEAR_IDENTITY_DEG)
        .copied()
        .collect();
    if poses.len() < 2 && turned.is_empty() {
        return Ok((0.0, None));
    }
    let crops: Vec<Rigid> = poses.iter().map(|t| map_to_crop(src, dst, t)).collect();
    // A cheap screen first (the kernel's counts): alternatives with under a quarter of the chosen pose's
    // walls near the other's walls are no rival.
    let screened: Vec<usize> = if poses.len() < 2 {
        Vec::new()
    } else {
        let (walls_d, walls_s) = score_both(src, dst, &crops, Probe::Walls, backend)?;
        let near = |i: usize| f64::from(walls_d[i][1] + walls_s[i][1]);
        (1..poses.len())
            .filter(|&i| near(i) >= 0.25 * near(0))
            .collect()
    };
    if screened.is_empty() && turned.is_empty() {
        return Ok((0.0, None));
    }
    let fits: Vec<(f64, f64, f64)> = {
        use rayon::prelude::*;
        std::iter::once(0)
            .chain(screened.iter().copied())
            .collect::<Vec<_>>()
            .par_iter()
            .map(|&i| local_both(src, dst, &crops[i]))
            .collect()
    };
    let rivals = screened
        .iter()
        .map(|&i| poses[i])
        .zip(fits[1..].iter().copied())
        .chain(turned);
    // Each pose's evidence, measured the same way for both: the wall pixels (both maps into each other)
    // that agree with the other map once each tile has had its few px of shift. (Less those still deep
    // in free space, it declined 20 right Halmstad pairs: their true poses keep 20-30% of their walls
    // there, furniture and glass, so the difference is mostly noise.)
    let evidence = |(share, _residual, n): (f64, f64, f64)| share * n;
    let (_, residual0, _) = fits[0];
    let evidence0 = evidence(fits[0]).max(1.0);
    let (mut top, mut pose) = (0.0, None);
    for (t, fit) in rivals {
        // As consistent: once each tile of the overlap has had its few px of shift (bending), hardly
        // more walls on free space than the chosen pose (a few per hundred: what a missing wall or a
        // building's end adds). Its evidence may be smaller (a wrong pose among equal rooms often
        // overlaps more than the true one): it is reported as it is.
        if fit.1 <= residual0 + ALIAS_EXTRA_CONFLICT && evidence(fit) / evidence0 > top {
            (top, pose) = (evidence(fit) / evidence0, Some(t));
        }
    }
    Ok((top, pose))
}

/// The `why:` line of a pair declined for an alternative pose `alt` with `ratio` of the chosen pose
/// `best`'s evidence: how the alternative differs from it (a turn, or a shift when it turns less than a
/// degree), in the units the test compares.
pub(super) fn ambiguous_why(best: &Rigid, alt: &Rigid, ratio: f64) -> String {
    let turn = signed_deg(alt.theta_deg - best.theta_deg);
    let how = if turn.abs() >= 1.0 {
        format!("turned by {turn:.0} deg")
    } else {
        // Where the alternative puts B's origin, from where the chosen pose does.
        format!(
            "shifted by {:.0} px",
            (alt.tx - best.tx).hypot(alt.ty - best.ty)
        )
    };
    let alt = alt.normalized();
    let place = format!(
        "(theta {:.1} deg, t ({:.0}, {:.0}))",
        alt.theta_deg, alt.tx, alt.ty
    );
    if ratio >= 1.0 {
        format!(
            "ambiguous: B fits A better {how} from the chosen pose {place} ({ratio:.2} of its \
             evidence: walls that agree after a few px of local shift), so it could be merged more than one way"
        )
    } else {
        format!(
            "ambiguous: B fits A {how} from the chosen pose {place} nearly as well ({ratio:.2} of its \
             evidence: walls that agree after a few px of local shift), so it could be merged more than one way"
        )
    }
}
