//! The poses a pair could also be merged at: each map's turns onto itself at any angle, which join its
//! self-alignment's transforms (the aligner's `self_symmetry`, cached in the map), and the alternatives
//! they and the search's turned candidates offer the chosen pose, measured as the chosen pose is
//! ([`alias`]): a merge is ambiguous when one of them fits nearly as well
//! ([`crate::merge::pair::accept::MAX_ALIAS`]).

use crate::backend::Backend;
use crate::merge::pair::accept::{Features, MAX_SELF_SYMMETRY};
use crate::merge::pair::local::{local_both, local_fit};
use crate::merge::pair::prepare::{Prepared, Symmetry};
use crate::merge::pair::refine::{crop_to_map, icp, map_to_crop, verify};
use crate::merge::pair::score::{score_both, Probe};
use crate::merge::pair::symmetry::{self_turns, NEAR_IDENTITY_DEG};
use crate::merge::transform::{signed_deg, transform_distance, Rigid, DISTINCT_PX};
use crate::support::error::Result;

/// A self-transform of a map offers an alternative pose
/// ([`Features::alias`](crate::merge::pair::accept::Features::alias)) when the map matches itself under it at least
/// this well (the aligner's `self_symmetry` measure): a repeat over a good part of the map.
pub const ALIAS_SELF_MATCH: f64 = 0.2;
/// An alternative pose is as consistent as the chosen one when its residual conflict (the share of wall
/// pixels over 3 px deep in the other map's free space after each tile's best shift of a few px) exceeds
/// the chosen pose's by at most this.
pub const ALIAS_EXTRA_CONFLICT: f64 = 0.05;

/// An alternative is told apart from the chosen pose when it lays at least this many times as many wall
/// pixels over 3 px deep on the other map's free space (the scoring kernel's fine probe: both ways,
/// every wall pixel, no local shift)...
pub const ALIAS_TOLD_RATIO: f64 = 2.0;
/// ... and more by this many standard deviations of a count (the square root of the two counts
/// together): on clean maps a door's worth of pixels (a dozen or more) against none, on a cluttered map
/// a difference far above what its clutter puts on free space at any pose.
pub const ALIAS_TOLD_SIGMAS: f64 = 3.0;

/// A map's repeat is listed step by step ([`lattice_poses`]) up to this many poses tried for each map,
/// from every base pose together: a long corridor of equal rooms is a few dozen, but an office whose
/// rooms repeat in two directions, walked from each of its turns onto itself, is a thousand or two, and
/// a warehouse's racks in two directions can be more (then the repeat stays held, as it is without the
/// listing). A cost bound, not a decision's limit: a pair whose lattice outgrows it is declined for the
/// repeat it could not list, never merged for it; at most this many poses scored (about 3 s of one
/// warehouse pair on a 2-core VM; the listing runs only for a pair that would be merged otherwise).
pub const LATTICE_POSES: usize = 4096;

/// Poses composed two ways that land within this of each other are one pose (the distance of
/// [`transform_distance`]: px, and 10 px a degree).
const SAME_POSE_PX: f64 = 4.0;

/// An alternative laying under this share of the chosen pose's walls near the other map's walls is
/// no rival (the cheap screen before the local fits), and a step of a repeat's lattice that does ends
/// its line ([`lattice_poses`]).
const RIVAL_WALLS: f64 = 0.25;

/// Whether an alternative pose with `alt` contradicting wall pixels is told apart from a chosen pose with
/// `chosen` ([`ALIAS_TOLD_RATIO`], [`ALIAS_TOLD_SIGMAS`]): the overlap holds a detail that only the
/// chosen pose fits.
pub(in crate::merge) fn told_apart(chosen: usize, alt: usize) -> bool {
    let (c0, c1) = (chosen as f64, alt as f64);
    c1 > c0 && c1 >= ALIAS_TOLD_RATIO * c0 && c1 - c0 >= ALIAS_TOLD_SIGMAS * (c0 + c1).sqrt()
}

/// Adds to `out` the map's turns onto itself at any angle ([`self_turns`]) that the self-alignment did
/// not find (its hypotheses are the quarter turns of the dominant wall direction: a building of three or
/// five wings, or a half turn a few degrees off, escapes them): each turn fitted finely by ICP and kept
/// when it matches the map as well as a self-alignment's candidate must ([`ALIAS_SELF_MATCH`], the same
/// measure). A turn's sweep score is a share of the map's walls as the self-match is, so a turn under
/// that share is not fitted at all.
pub(in crate::merge) fn add_turns(p: &Prepared, out: &mut Symmetry) {
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

/// The best alternative to `best` (B's pixels to A's) that the maps' self-transforms offer
/// ([`alternative_poses`]) or the search found (`found`: the refined candidates turned from it, with
/// their [`local_both`] fits): among those distinct from `best` whose residual conflict is hardly
/// above its own ([`ALIAS_EXTRA_CONFLICT`]) and which, when they turn from it, no detail of the overlap
/// tells apart from it ([`told_apart`]), the one with the most evidence (wall pixels agreeing
/// locally, both ways): its evidence over `best`'s ([`Features::alias`], 0 without one) and the pose;
/// and the same among those nothing contradicts ([`walls_uncontradicted`], [`shares_free_space`]:
/// [`Features::alias_uncontradicted`]).
pub(in crate::merge) fn alias(
    src: &Prepared,
    dst: &Prepared,
    best: &Rigid,
    (sa, sb): (&Symmetry, &Symmetry),
    found: &[(Rigid, (f64, f64, f64))],
    repeats: Repeats,
    backend: &mut dyn Backend,
) -> Result<Alias> {
    let (poses, repeats_listed) =
        alternative_poses(src, dst, best, (sa, sb), found, repeats, backend)?;
    // Shifts are told apart as turns are where the lattice was listed, and on the screen that asks
    // whether listing it could matter.
    let judge_shifts = repeats_listed || repeats == Repeats::Screen;
    let turned: Vec<(Rigid, (f64, f64, f64))> = found
        .iter()
        .filter(|(t, _)| signed_deg(t.theta_deg - best.theta_deg).abs() > NEAR_IDENTITY_DEG)
        .copied()
        .collect();
    let none = Alias {
        ratio: 0.0,
        pose: None,
        uncontradicted: 0.0,
        uncontradicted_pose: None,
        repeats_listed,
        consistent: None,
    };
    if poses.len() < 2 && turned.is_empty() {
        return Ok(none);
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
            .filter(|&i| near(i) >= RIVAL_WALLS * near(0))
            .collect()
    };
    if screened.is_empty() && turned.is_empty() {
        return Ok(none);
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
    // The building-independent measure's count, apart from the test below: each pose's consistent
    // evidence (agreeing walls less those left deep in free space), the chosen pose's and the best
    // rival's, every rival counted whatever its contradictions (they are subtracted).
    let consistent = |(share, residual, n): (f64, f64, f64)| (share - residual) * n;
    let best_rival = fits[1..]
        .iter()
        .chain(turned.iter().map(|(_, fit)| fit))
        .map(|&fit| consistent(fit))
        .fold(f64::NEG_INFINITY, f64::max);
    let consistent = Some((consistent(fits[0]), best_rival));
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
    // The chosen pose's contradictions and free space, each measured once and only when a rival
    // needs them.
    let mut conflicts0 = None;
    let mut free0 = None;
    let mut found = Alias {
        ratio: 0.0,
        pose: None,
        uncontradicted: 0.0,
        uncontradicted_pose: None,
        repeats_listed,
        consistent,
    };
    for (t, fit) in rivals {
        // As consistent: once each tile of the overlap has had its few px of shift (bending), hardly
        // more walls on free space than the chosen pose (a few per hundred: what a missing wall or a
        // building's end adds). Its evidence may be smaller (a wrong pose among equal rooms often
        // overlaps more than the true one): it is reported as it is.
        let ratio = evidence(fit) / evidence0;
        if fit.1 > residual0 + ALIAS_EXTRA_CONFLICT {
            continue;
        }
        let rival = ratio > found.ratio;
        let unrefuted = ratio > found.uncontradicted && walls_uncontradicted(fit);
        if !rival && !unrefuted {
            continue;
        }
        // Unless it is a turn that a detail of the overlap tells apart: walls it lays deep on free
        // space that the chosen pose does not (a door of one map on the other's closed wall), counted
        // once it is fitted as finely as the chosen pose (a composed pose is a px or two off, and thin
        // walls a px or two off lie on free space). A shift only where its whole lattice was listed
        // ([`lattice_poses`]; or on the screen, whose verdict is a lower bound): a repeat is one step
        // of a lattice, so one contradicted step says nothing of the next (told apart alone, the
        // warehouse family's shifts let poses a period off through).
        let turned = signed_deg(t.theta_deg - best.theta_deg).abs() > NEAR_IDENTITY_DEG;
        let crop = map_to_crop(src, dst, &t);
        if turned || judge_shifts {
            let c0 = match conflicts0 {
                Some(c) => c,
                None => *conflicts0.insert(deep_conflicts(src, dst, &crops[0], backend)?),
            };
            if told_apart(c0, deep_conflicts(src, dst, &icp(src, dst, crop), backend)?) {
                continue;
            }
        }
        if rival {
            (found.ratio, found.pose) = (ratio, Some(t));
        }
        if unrefuted {
            let f0 = match free0 {
                Some(f) => f,
                None => *free0.insert(verify(src, dst, &[crops[0]], backend)?[0]),
            };
            if shares_free_space(&f0, &verify(src, dst, &[crop], backend)?[0]) {
                (found.uncontradicted, found.uncontradicted_pose) = (ratio, Some(t));
            }
        }
    }
    Ok(found)
}

/// The poses [`alias`] weighs against `best`: `best` first, then the chosen pose moved by each map's
/// self-transforms (and their inverses), on A's side or B's, and, for [`Repeats::List`] with a repeat
/// over [`MAX_SELF_SYMMETRY`], every step of its lattice ([`lattice_poses`]); those within
/// [`DISTINCT_PX`] of `best` left out. With whether the lattice was listed.
fn alternative_poses(
    src: &Prepared,
    dst: &Prepared,
    best: &Rigid,
    (sa, sb): (&Symmetry, &Symmetry),
    found: &[(Rigid, (f64, f64, f64))],
    repeats: Repeats,
    backend: &mut dyn Backend,
) -> Result<(Vec<Rigid>, bool)> {
    let mut poses = vec![*best];
    for s in &sa.transforms {
        poses.push(s.after(best));
        poses.push(s.inverse().after(best));
    }
    for s in &sb.transforms {
        poses.push(best.after(s));
        poses.push(best.after(&s.inverse()));
    }
    // A repeat strong enough to be held is judged pose by pose only when every step of its lattice
    // that could still lay the maps on each other is listed.
    let held = sa.repeat.max(sb.repeat) > MAX_SELF_SYMMETRY;
    let mut repeats_listed = false;
    if repeats == Repeats::List && held {
        // Every step from the chosen pose and from each of its turns (a turn of a building that
        // repeats is a turn and a step of the repeat away from the truth as often as not), the
        // search's turned candidates among them.
        let bases = lattice_bases(best, poses.iter().copied().chain(found.iter().map(|f| f.0)));
        if let Some(steps) = lattice_poses(src, dst, best, &bases, (sa, sb), backend)? {
            poses.extend(steps);
            repeats_listed = true;
        }
    }
    poses.retain(|t| t == best || transform_distance(t, best) > DISTINCT_PX);
    // A lattice's steps reached by each map's repeat are mostly one pose twice.
    if repeats_listed {
        poses = one_of_each(poses);
    }
    Ok((poses, repeats_listed))
}

/// Whether an alternative pose's local fit `(share, residual, measured)` lays its walls on the other
/// map's free space no more than a pose with none would seem to: after their tile's few px of shift,
/// fewer walls deep in free space than the told-apart test ([`told_apart`]) needs to see a detail
/// against none (9). A right pose of a real map keeps a few per hundred there (clutter, glass); a
/// pose that keeps none lays its walls only on walls and on unknown space.
fn walls_uncontradicted((_, residual, n): (f64, f64, f64)) -> bool {
    !told_apart(0, (residual * n).round() as usize)
}

/// Whether an alternative pose (`alt`, as the verification measures it) overlaps the maps as a merge
/// does: at least [`RIVAL_WALLS`] of the chosen pose's (`chosen`) share of free space falling in the
/// other map's known area. A pose that lays B's walls along A's outer walls, beside A, shares no free
/// space (measured: the real pairs' uncontradicted alternatives 0.01 at most, the symmetric halls'
/// turns 0.39-0.76, their chosen poses' 0.69-0.99): it contradicts nothing, but it merges nothing
/// either. Its free space on the other's walls is the other's walls on its free space, which the
/// walls' test has measured both ways.
fn shares_free_space(chosen: &Features, alt: &Features) -> bool {
    alt.free_inside >= RIVAL_WALLS * chosen.free_inside
}

/// `poses` with each pose within [`SAME_POSE_PX`] of an earlier one left out: a pose composed two ways
/// kept once.
fn one_of_each(poses: impl IntoIterator<Item = Rigid>) -> Vec<Rigid> {
    let mut kept: Vec<Rigid> = Vec::new();
    for t in poses {
        if !kept
            .iter()
            .any(|k| transform_distance(k, &t) <= SAME_POSE_PX)
        {
            kept.push(t);
        }
    }
    kept
}

/// How [`alias`] treats the maps' shifts onto themselves (a repeat, held when its self-match is over
/// [`MAX_SELF_SYMMETRY`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::merge) enum Repeats {
    /// The self-transforms' shifts are alternatives, never told apart (one step of a lattice says
    /// nothing of the next): for maps with no held repeat, or a lattice too large to list.
    Held,
    /// The screen before listing: the self-transforms' steps told apart as turns are, nothing listed;
    /// the alternative is a lower bound of what [`Repeats::List`] finds, so a pair this declines
    /// needs no listing.
    Screen,
    /// Every step of the lattice listed ([`lattice_poses`]) and judged pose by pose; held as
    /// [`Repeats::Held`] where the lattice is too large to list.
    List,
}

/// The best alternative pose [`alias`] found, and how the maps' repeats were judged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::merge) struct Alias {
    /// Its evidence over the chosen pose's ([`Features::alias`]), 0 without one.
    pub(in crate::merge) ratio: f64,
    /// The pose, B's pixels to A's.
    pub(in crate::merge) pose: Option<Rigid>,
    /// The same among the alternatives nothing contradicts ([`Features::alias_uncontradicted`]).
    pub(in crate::merge) uncontradicted: f64,
    /// That pose.
    pub(in crate::merge) uncontradicted_pose: Option<Rigid>,
    /// Whether a repeat over [`MAX_SELF_SYMMETRY`] had every step of its lattice listed and judged
    /// pose by pose ([`lattice_poses`]): then nothing of the self-match needs holding whatever the
    /// alternatives show.
    pub(in crate::merge) repeats_listed: bool,
    /// The chosen pose's consistent evidence (wall pixels agreeing after the local shifts, less those
    /// left deep in free space, both ways) and the best alternative's, counted the same way whatever
    /// its contradictions; `None` where no alternative was measured. What
    /// [`Features::evidence_ratio`](crate::merge::pair::accept::Features::evidence_ratio) weighs.
    pub(in crate::merge) consistent: Option<(f64, f64)>,
}

/// The poses a repeat's lattice is walked from: `best` and those of `poses` turned from it, one turn
/// reached through A's symmetry and B's being one base, so that its lattice is walked once.
fn lattice_bases(best: &Rigid, poses: impl IntoIterator<Item = Rigid>) -> Vec<Rigid> {
    one_of_each(
        std::iter::once(*best).chain(
            poses
                .into_iter()
                .filter(|t| signed_deg(t.theta_deg - best.theta_deg).abs() > NEAR_IDENTITY_DEG),
        ),
    )
}

/// Every step of the maps' repeats that could misplace the pair: the shifts among each map's
/// self-transforms (turned by under [`NEAR_IDENTITY_DEG`], taken as the translations they make at the
/// map's centre) composed with one another, breadth first from the chosen pose, a step kept and grown
/// from while it lays at least [`RIVAL_WALLS`] of the chosen pose's walls near the other map's (the screen
/// [`alias`] applies; a repeat that ends lays fewer walls with every step on, so a step that fails it
/// ends its line). `None` when a map's lattice reaches past [`LATTICE_POSES`] poses tried from all the
/// bases together: its steps are then not all listed, and the repeat stays held.
fn lattice_poses(
    src: &Prepared,
    dst: &Prepared,
    best: &Rigid,
    bases: &[Rigid],
    (sa, sb): (&Symmetry, &Symmetry),
    backend: &mut dyn Backend,
) -> Result<Option<Vec<Rigid>>> {
    let crop0 = map_to_crop(src, dst, best);
    let (d0, s0) = score_both(src, dst, &[crop0], Probe::Walls, backend)?;
    let near0 = f64::from(d0[0][1] + s0[0][1]);
    let mut out = Vec::new();
    // A's steps act on A's side of the pose (after it), B's on B's side (before it).
    for (map, sym, on_a) in [(dst, sa, true), (src, sb, false)] {
        let steps = repeat_steps(map, sym);
        if steps.is_empty() {
            continue;
        }
        let mut budget = LATTICE_POSES;
        for base in bases {
            let pose = |(x, y): (f64, f64)| {
                let shift = Rigid {
                    theta_deg: 0.0,
                    tx: x,
                    ty: y,
                };
                if on_a {
                    shift.after(base)
                } else {
                    base.after(&shift)
                }
            };
            let Some(reached) = walk_lattice(src, dst, &steps, &pose, near0, &mut budget, backend)?
            else {
                return Ok(None);
            };
            out.extend(reached);
        }
    }
    Ok(Some(out))
}

/// The poses `pose` makes of the lattice `steps` span, breadth first from its origin, a step kept and
/// grown from while it lays at least [`RIVAL_WALLS`] of `near0` walls (the chosen pose's) near the other
/// map's; `None` when the steps to try outgrow `budget` (what is tried is taken from it).
fn walk_lattice(
    src: &Prepared,
    dst: &Prepared,
    steps: &[(f64, f64)],
    pose: &dyn Fn((f64, f64)) -> Rigid,
    near0: f64,
    budget: &mut usize,
    backend: &mut dyn Backend,
) -> Result<Option<Vec<Rigid>>> {
    // Steps closer than half the shortest one are the same step reached two ways.
    let same = 0.5
        * steps
            .iter()
            .map(|v| v.0.hypot(v.1))
            .fold(f64::MAX, f64::min);
    let mut tried: Vec<(f64, f64)> = vec![(0.0, 0.0)];
    let mut frontier: Vec<(f64, f64)> = vec![(0.0, 0.0)];
    let mut out = Vec::new();
    while !frontier.is_empty() {
        let mut next: Vec<(f64, f64)> = Vec::new();
        for f in &frontier {
            for v in steps {
                let x = (f.0 + v.0, f.1 + v.1);
                let seen = |y: &(f64, f64)| (x.0 - y.0).hypot(x.1 - y.1) < same;
                if !tried.iter().any(seen) && !next.iter().any(seen) {
                    next.push(x);
                }
            }
        }
        if next.is_empty() {
            break;
        }
        if next.len() > *budget {
            return Ok(None);
        }
        *budget -= next.len();
        let crops: Vec<Rigid> = next
            .iter()
            .map(|&x| map_to_crop(src, dst, &pose(x)))
            .collect();
        let (walls_d, walls_s) = score_both(src, dst, &crops, Probe::Walls, backend)?;
        tried.extend(next.iter().copied());
        frontier = (0..next.len())
            .filter(|&i| f64::from(walls_d[i][1] + walls_s[i][1]) >= RIVAL_WALLS * near0)
            .map(|i| next[i])
            .collect();
        out.extend(frontier.iter().map(|&x| pose(x)));
    }
    Ok(Some(out))
}

/// A map's repeat's steps: its self-transforms turned by under [`NEAR_IDENTITY_DEG`], each as the
/// translation it makes at the centre of the map's crop (a building repeats by translation; the few
/// tenths of a degree a fit leaves would grow with every step composed), both ways.
fn repeat_steps(p: &Prepared, sym: &Symmetry) -> Vec<(f64, f64)> {
    let c = (p.off.0 + p.w as f64 / 2.0, p.off.1 + p.h as f64 / 2.0);
    sym.transforms
        .iter()
        .filter(|s| signed_deg(s.theta_deg).abs() <= NEAR_IDENTITY_DEG)
        .flat_map(|s| {
            let (x, y) = s.apply(c);
            [(x - c.0, y - c.1), (c.0 - x, c.1 - y)]
        })
        .collect()
}

/// The wall pixels of both maps (every one) over 3 px deep in the other map's free space at `t` (B's
/// crop pixels to A's), with no local shift: the scoring kernel's fine probe, as the fine conflict
/// counts them. (After the local fit's tile shifts, a tile with a few walls shifted to fit them pushes
/// others onto free space: tens of pixels on clean maps, as many as a door makes.)
fn deep_conflicts(
    src: &Prepared,
    dst: &Prepared,
    t: &Rigid,
    backend: &mut dyn Backend,
) -> Result<usize> {
    let (d, s) = score_both(src, dst, &[*t], Probe::Fine, backend)?;
    Ok((d[0][2] + s[0][2]) as usize)
}

#[cfg(test)]
mod tests {
    use super::{shares_free_space, told_apart, walls_uncontradicted};
    use crate::merge::pair::accept::Features;

    #[test]
    fn a_grid_of_equal_rooms_walked_from_each_of_its_turns_is_listed_whole() {
        use super::{lattice_bases, lattice_poses, LATTICE_POSES};
        use crate::backend::ReferenceBackend;
        use crate::map::OccupancyMap;
        use crate::merge::pair::align::self_symmetry_with;
        use crate::merge::pair::prepare::Prepared;
        use crate::merge::transform::Rigid;
        // An 8 x 8 grid of equal rooms (a few walls left out, two cabinets).
        let layout = crate::measure::synthetic::grid_rooms(3).unwrap();
        let p = Prepared::new(&OccupancyMap::from_image(layout.image.clone()));
        let mut backend = ReferenceBackend;
        let sym = self_symmetry_with(&p, &mut backend).unwrap();
        let best = Rigid::IDENTITY;
        let bases = lattice_bases(&best, sym.transforms.iter().copied());
        // The identity and the grid's turns onto itself: each a base its lattice is walked from.
        assert!(bases.len() >= 2, "{} bases", bases.len());
        let listed = lattice_poses(&p, &p, &best, &bases, (sym, sym), &mut backend)
            .unwrap()
            .expect("the lattice outgrew its bound");
        // Over a thousand poses (the bound was once 1024, and such a grid was then held unlisted),
        // among them the grid shifted by any few rooms either way.
        assert!(listed.len() > 1024 && listed.len() <= LATTICE_POSES);
        let (px, py) = (layout.lattice[0].0, layout.lattice[1].1);
        for (i, j) in [(1.0, 0.0), (0.0, -1.0), (3.0, 2.0), (-2.0, 3.0)] {
            let shift = Rigid {
                theta_deg: 0.0,
                tx: i * px,
                ty: j * py,
            };
            assert!(
                listed
                    .iter()
                    .any(|t| crate::merge::transform::transform_distance(t, &shift) < 8.0),
                "no pose {i} rooms across and {j} down"
            );
        }
    }

    #[test]
    fn a_pose_is_uncontradicted_with_fewer_walls_on_free_space_than_a_detail_needs() {
        // 8 of 10000 sampled walls deep in free space are not told from none; 9 are a detail.
        assert!(walls_uncontradicted((0.9, 0.0008, 10_000.0)));
        assert!(!walls_uncontradicted((0.9, 0.0009, 10_000.0)));
        // A real map's right pose keeps a few in a hundred there (clutter, glass): never uncontradicted.
        assert!(!walls_uncontradicted((0.9, 0.03, 2_000.0)));
    }

    #[test]
    fn a_pose_laid_beside_the_other_map_shares_no_free_space() {
        let with = |free_inside| Features {
            free_inside,
            ..Features::default()
        };
        assert!(shares_free_space(&with(0.8), &with(0.5)));
        assert!(shares_free_space(&with(0.8), &with(0.2)));
        assert!(!shares_free_space(&with(0.8), &with(0.19)));
        assert!(!shares_free_space(&with(0.3), &with(0.01)));
    }

    #[test]
    fn a_pose_is_told_apart_by_a_few_contradictions_on_clean_maps_and_many_on_cluttered_ones() {
        // Clean maps: a door's worth of walls on free space against none.
        assert!(told_apart(0, 12));
        assert!(!told_apart(0, 8));
        assert!(!told_apart(0, 0));
        // A cluttered map: a few hundred more is clutter, twice as many and far beyond it is a detail.
        assert!(!told_apart(3000, 3200));
        assert!(!told_apart(3000, 5900));
        assert!(told_apart(3000, 6100));
        // Never the other way.
        assert!(!told_apart(20, 0));
    }
}
