//! The placement of many maps from the graph of their pairwise candidates: triangle support and
//! contradiction of each edge, then groups grown by agglomeration (see the [module docs](super)).

use std::collections::{BTreeMap, BTreeSet};

use serde::Serialize;

use crate::backend::Backend;
use crate::map::OccupancyMap;
use crate::merge::many::calibrate::{Calibration, EdgeEvidence};
use crate::merge::many::mosaic::compose_many;
use crate::merge::many::{Edge, GlobalOptions, Pairwise};
use crate::merge::pair::accept::Features;
use crate::merge::pair::align::{align_prepared_with, check, Prepared};
use crate::merge::transform::Rigid;
use crate::support::error::Result;

/// Candidates below this pair rule value are not used (the pair test accepts from 0).
pub const WEAK_FROM: f64 = -16.0;
/// Two placements of a map agree within this turn, degrees...
pub const LOOP_DEG: f64 = 5.0;
/// ... and this displacement of its walls' centre, pixels.
pub const LOOP_PX: f64 = 60.0;
/// A group's placement into another is ambiguous when a distinct one has this share of its support.
pub const AMBIGUITY: f64 = 0.5;

/// Two maps put together contradict each other densely when less than [`DENSE_FREE_AGREE`] of the free
/// space falling in the other's known area lands on its free space (with at least [`DENSE_FREE_INSIDE`] of
/// it in there), or over [`DENSE_CONFLICT`] of their walls lie over 20 px deep in the other's free space.
/// Looser than the pair vetoes: a placement through other maps is off by a few pixels more than a pair's
/// own estimate, and bent maps drift apart by more than 3 px (of the real pairs' right candidates, free
/// agreement is 0.93 at least and deep conflict 0.18 at most; the fine conflict reaches 0.55).
pub fn densely_contradicted(f: &Features) -> bool {
    (f.free_inside >= DENSE_FREE_INSIDE && f.free_agree < DENSE_FREE_AGREE)
        || f.conflict > DENSE_CONFLICT
}

/// See [`densely_contradicted`].
pub const DENSE_FREE_AGREE: f64 = 0.90;
/// See [`densely_contradicted`].
pub const DENSE_FREE_INSIDE: f64 = 0.02;
/// See [`densely_contradicted`].
pub const DENSE_CONFLICT: f64 = 0.25;

/// An edge's own weight: its pair rule value on an exponential scale (e every 8), capped, so that one
/// strong pair does not outvote several cycles.
pub fn weight(e: &Edge) -> f64 {
    (e.score / 8.0).clamp(-4.0, 2.0).exp()
}

/// Whether two transforms of a map into one frame agree at its point `centre` (their rotations and where
/// they put it).
fn agree(x: &Rigid, y: &Rigid, centre: (f64, f64), options: &GlobalOptions) -> bool {
    let d = (x.theta_deg - y.theta_deg + 180.0).rem_euclid(360.0) - 180.0;
    let (p, q) = (x.apply(centre), y.apply(centre));
    d.abs() <= options.loop_deg && (p.0 - q.0).hypot(p.1 - q.1) <= options.loop_px
}

/// The edges of each unordered pair, by index into `pairwise.edges`.
fn by_pair(pairwise: &Pairwise) -> BTreeMap<(usize, usize), Vec<usize>> {
    let mut out: BTreeMap<(usize, usize), Vec<usize>> = BTreeMap::new();
    for (i, e) in pairwise.edges.iter().enumerate() {
        out.entry((e.a, e.b)).or_default().push(i);
    }
    out
}

/// Triangle support and contradiction of every edge; with `level`, the edges it excludes
/// ([`Calibration::excludes`]) take no part.
pub fn evidence(
    pairwise: &Pairwise,
    options: &GlobalOptions,
    level: Option<&Calibration>,
) -> Vec<EdgeEvidence> {
    use rayon::prelude::*;
    let excluded = |e: &Edge| level.is_some_and(|l| l.excludes(e.residual));
    let mut pairs = by_pair(pairwise);
    let edges = &pairwise.edges;
    for list in pairs.values_mut() {
        list.retain(|&i| !excluded(&edges[i]));
    }
    let of = |u: usize, v: usize| pairs.get(&(u.min(v), u.max(v))).map_or(&[][..], |v| v);
    // Each map's partners (ascending): a third map adds to an edge's evidence only through edges
    // with both its maps, so only their common partners are visited (ascending, as every third map
    // would be: the same sums). No map is its own partner, so neither of the edge's maps is among them.
    let mut partners: Vec<Vec<usize>> = vec![Vec::new(); pairwise.n];
    for (&(u, v), list) in &pairs {
        if !list.is_empty() {
            partners[u].push(v);
            partners[v].push(u);
        }
    }
    for p in &mut partners {
        p.sort_unstable();
    }
    edges
        .par_iter()
        .map(|e| {
            if excluded(e) {
                return EdgeEvidence {
                    excluded: true,
                    ..EdgeEvidence::default()
                };
            }
            let (i, j) = (e.a, e.b);
            let direct = e.toward(i); // j -> i
            let mut ev = EdgeEvidence {
                own: weight(e),
                ..EdgeEvidence::default()
            };
            let common = partners[i]
                .iter()
                .filter(|k| partners[j].binary_search(k).is_ok());
            for &k in common {
                let (ik, jk) = (of(i, k), of(j, k));
                let mut best: f64 = 0.0;
                let mut against: f64 = 0.0;
                for &x in ik {
                    let ex = &edges[x];
                    let k_to_i = ex.toward(i);
                    for &y in jk {
                        let ey = &edges[y];
                        // j -> k -> i.
                        let path = k_to_i.after(&ey.toward(k));
                        let w = weight(ex).min(weight(ey));
                        if agree(&direct, &path, e.at, options) {
                            best = best.max(w);
                            ev.confirmed |= e.accepted && ex.accepted && ey.accepted;
                        } else if e.accepted && ex.accepted && ey.accepted {
                            against = against.max(w);
                        }
                    }
                }
                ev.support += best;
                // Two accepted edges that compose to this one outweigh a contradiction through the
                // same third map.
                if best == 0.0 {
                    ev.contradicted += against;
                }
            }
            ev
        })
        .collect()
}

/// Whether an edge joins groups on its own: accepted by the pair test and not contradicted more than it
/// is supported, counting itself as one accepted edge (weight 1) however high its rule value: two cycles
/// of accepted edges that disagree with it outweigh it, whatever its own confidence (a wrong accept is
/// as confident as a right one).
fn trusted(e: &Edge, ev: &EdgeEvidence) -> bool {
    e.accepted && !ev.excluded && ev.contradicted < ev.own.min(1.0) + ev.support
}

/// Where each map lands and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MapPlacement {
    /// Its group (maps placed together), numbered by their first map; `None` when not placed.
    pub group: Option<usize>,
    /// Its pixels to its group's frame (the group's first map's pixels).
    pub pose: Rigid,
    /// Why it is not placed, when not.
    pub reason: Option<String>,
}

/// Why an edge was not used although the pair test accepted it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Dropped {
    /// The edge.
    pub edge: Edge,
    /// Why.
    pub reason: String,
}

/// The placement of every map.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Placement {
    /// One entry per map.
    pub maps: Vec<MapPlacement>,
    /// The groups' members, each group's first map first (its frame), groups by first map.
    pub groups: Vec<Vec<usize>>,
    /// The edges the placement rests on (the pose graph's), by index into the pairwise edges.
    pub kept: Vec<usize>,
    /// Accepted pairwise merges the placement contradicts.
    pub dropped: Vec<Dropped>,
    /// The set's level of conflict at confirmed poses, and the limit it set.
    pub level: Calibration,
}

/// One vote cluster: a placement of group `h` into group `g`'s frame and what stands behind it.
#[derive(Clone, Debug)]
struct Cluster {
    /// H's frame to G's.
    placement: Rigid,
    /// Sum over map pairs of their best agreeing vote.
    support: f64,
    /// Map pairs voting for it.
    pairs: usize,
    /// Whether a trusted edge ([`trusted`]) votes for it.
    trusted: bool,
    /// Whether an edge confirmed by a cycle votes for it.
    confirmed: bool,
    /// The edge whose placement it is.
    first: usize,
    /// The map pairs (G's map, H's map) voting for it, each with its best vote.
    votes: BTreeMap<(usize, usize), f64>,
}

/// State of the agglomeration.
struct Groups {
    /// Each map's group (by its first map) and pose in it.
    of: Vec<usize>,
    pose: Vec<Rigid>,
}

impl Groups {
    fn members(&self, g: usize) -> Vec<usize> {
        (0..self.of.len()).filter(|&m| self.of[m] == g).collect()
    }
}

/// The placement of every map over the pairwise candidates and their evidence ([`evidence`], with the
/// set's `level`), deterministic; `maps` prepared from `images`; `backend` scores the dense checks.
pub fn place(
    pairwise: &Pairwise,
    maps: &[Prepared],
    images: &[&OccupancyMap],
    ev: &[EdgeEvidence],
    level: &Calibration,
    options: &GlobalOptions,
    backend: &mut dyn Backend,
) -> Result<Placement> {
    let n = pairwise.n;
    let edges = &pairwise.edges;
    let joined = join_groups(pairwise, maps, images, ev, options, backend)?;
    let (groups, ambiguous, contradicted) =
        (&joined.groups, &joined.ambiguous, &joined.contradicted);
    let (kept, dropped) = kept_and_dropped(pairwise, groups, ev, level, options);
    let mut sizes = vec![0usize; n];
    for &g in &groups.of {
        sizes[g] += 1;
    }
    let group_list: Vec<Vec<usize>> = (0..n)
        .filter(|&g| sizes[g] >= 2 && groups.of[g] == g)
        .map(|g| groups.members(g))
        .collect();
    let maps_out = (0..n)
        .map(|m| {
            let g = groups.of[m];
            if sizes[g] >= 2 {
                MapPlacement {
                    group: Some(group_list.iter().position(|l| l[0] == g).unwrap_or(0)),
                    pose: groups.pose[m],
                    reason: None,
                }
            } else {
                let reason = if contradicted[m] {
                    "its placements by the other maps are contradicted densely (walls on free space), or \
                     their mosaics fail the pair test"
                } else if ambiguous[m] {
                    "ambiguous: the other maps support two different placements of it alike"
                } else if edges.iter().any(|e| (e.a == m || e.b == m) && e.accepted) {
                    "its accepted pairwise merges are contradicted by cycles"
                } else {
                    "no confident alignment with any other map (no accepted pair, no confirming cycle)"
                };
                MapPlacement {
                    group: None,
                    pose: Rigid::IDENTITY,
                    reason: Some(unalignable(pairwise, m).unwrap_or_else(|| reason.to_string())),
                }
            }
        })
        .collect();
    Ok(Placement {
        maps: maps_out,
        groups: group_list,
        kept,
        dropped,
        level: *level,
    })
}

/// Groups joined one at a time, and the maps left ambiguous or contradicted on the way.
struct Joined {
    groups: Groups,
    ambiguous: Vec<bool>,
    contradicted: Vec<bool>,
}

/// Joins groups, starting from one a map, the best-supported placement first, while one passes the
/// checks: the strongest usable cluster of votes between two groups, clear of its runner-up, that fits
/// one canvas, is densely consistent and (unless a trusted edge stands behind it) whose mosaics agree.
fn join_groups(
    pairwise: &Pairwise,
    maps: &[Prepared],
    images: &[&OccupancyMap],
    ev: &[EdgeEvidence],
    options: &GlobalOptions,
    backend: &mut dyn Backend,
) -> Result<Joined> {
    let n = pairwise.n;
    let edges = &pairwise.edges;
    let mut groups = Groups {
        of: (0..n).collect(),
        pose: vec![Rigid::IDENTITY; n],
    };
    // Joins refused, by the two groups (first map and size: a group that grew is tried again) and the
    // cluster's first edge.
    let mut rejected: BTreeSet<(usize, usize, usize, usize, usize)> = BTreeSet::new();
    let key = |g: usize, h: usize, first: usize, groups: &Groups| {
        (
            g,
            h,
            groups.members(g).len(),
            groups.members(h).len(),
            first,
        )
    };
    let mut ambiguous = vec![false; n];
    let mut contradicted = vec![false; n];
    loop {
        // Each round may run dense checks of mosaics: a raised stop (Ctrl-C in Python) ends it here.
        crate::support::stop::check()?;
        // Every pair of groups' best placement: those a trusted edge stands behind first, the strongest
        // first; then those only cycles or several pairs stand behind (the groups' mosaics must pass the
        // pair test).
        let mut options_now: Vec<(usize, usize, Cluster, bool)> = Vec::new();
        let mut sizes = vec![0usize; n];
        for &g in &groups.of {
            sizes[g] += 1;
        }
        // Only groups that some voting edge links have a placement to offer: one pass over the
        // edges, not one per pair of groups (which made a set of hundreds of maps cubic).
        for ((g, h), between) in links(&groups, edges, ev) {
            let clusters = clusters(g, &between, &groups, edges, ev, options);
            // Two single maps: their pair test has spoken.
            let mosaic_worth = sizes[g] + sizes[h] > 2;
            let valid = |c: &Cluster| c.trusted || (mosaic_worth && (c.pairs >= 2 || c.confirmed));
            // The strongest placement that may join: a stronger one the cycles distrust (a
            // contradicted accept) neither joins nor hides the one they agree with.
            let mut usable = clusters.iter().filter(|c| valid(c));
            let Some(best) = usable.next() else {
                continue;
            };
            let runner_up = usable.map(|c| c.support).fold(0.0, f64::max);
            if runner_up >= AMBIGUITY * best.support {
                for m in groups.members(h).into_iter().chain(groups.members(g)) {
                    ambiguous[m] = true;
                }
                continue;
            }
            if !rejected.contains(&key(g, h, best.first, &groups)) {
                options_now.push((g, h, best.clone(), best.trusted));
            }
        }
        options_now.sort_by(|x, y| {
            y.3.cmp(&x.3)
                .then(y.2.support.total_cmp(&x.2.support))
                .then((x.0, x.1).cmp(&(y.0, y.1)))
        });
        let mut merged = false;
        for (g, h, c, trusted) in options_now {
            let ok = fits_one_canvas(g, h, &c, &groups, maps, images)
                && densely_consistent(g, h, &c, &groups, maps, backend)?
                && (trusted || mosaics_agree(g, h, &c, &groups, images, options, backend)?);
            if ok {
                for m in groups.members(h) {
                    groups.pose[m] = c.placement.after(&groups.pose[m]).normalized();
                    groups.of[m] = g;
                }
                merged = true;
                break;
            }
            for m in groups.members(h).into_iter().chain(groups.members(g)) {
                contradicted[m] = true;
            }
            rejected.insert(key(g, h, c.first, &groups));
        }
        if !merged {
            break;
        }
    }
    Ok(Joined {
        groups,
        ambiguous,
        contradicted,
    })
}

/// The edges the placement rests on (per pair within a group, the best-voting one that agrees) and
/// the accepted edges it does not use, each with why.
fn kept_and_dropped(
    pairwise: &Pairwise,
    groups: &Groups,
    ev: &[EdgeEvidence],
    level: &Calibration,
    options: &GlobalOptions,
) -> (Vec<usize>, Vec<Dropped>) {
    let edges = &pairwise.edges;
    let mut kept = Vec::new();
    let mut dropped = Vec::new();
    for (&(u, v), list) in &by_pair(pairwise) {
        let same = groups.of[u] == groups.of[v];
        let implied = groups.pose[u].inverse().after(&groups.pose[v]); // v -> u
        let agreeing = list
            .iter()
            .copied()
            .filter(|&i| same && agree(&edges[i].toward(u), &implied, edges[i].at_in(v), options))
            .filter(|&i| ev[i].vote() > 0.0)
            .max_by(|&x, &y| ev[x].vote().total_cmp(&ev[y].vote()).then(y.cmp(&x)));
        if let Some(i) = agreeing {
            kept.push(i);
        }
        for &i in list {
            let e = &edges[i];
            if !e.accepted {
                continue;
            }
            let x = e.toward(u);
            if same && agree(&x, &implied, e.at_in(v), options) {
                continue;
            }
            let reason = drop_reason(e, u, v, same, &implied, &ev[i], level);
            dropped.push(Dropped { edge: *e, reason });
        }
    }
    (kept, dropped)
}

/// Why accepted edge `e` between maps `u` and `v` (`same`: in one group, placed `implied` there) is not
/// used, given its evidence `ev` and the set's `level`.
fn drop_reason(
    e: &Edge,
    u: usize,
    v: usize,
    same: bool,
    implied: &Rigid,
    ev: &EdgeEvidence,
    level: &Calibration,
) -> String {
    if same {
        let x = e.toward(u);
        let at = e.at_in(v);
        let (p, q) = (x.apply(at), implied.apply(at));
        let turn = (x.theta_deg - implied.theta_deg + 180.0).rem_euclid(360.0) - 180.0;
        format!(
            "the placement through the other maps differs by {:.1} deg and {:.0} px where \
             the two overlap",
            turn.abs(),
            (p.0 - q.0).hypot(p.1 - q.1)
        )
    } else if let (true, Some(limit)) = (ev.excluded, level.limit) {
        format!(
            "{:.0}% of its walls lie in the other map's free space (after a few px of local \
             shift), far above this set's pairs that cycles confirm (a median {:.0}%, at most \
             {:.0}% allowed)",
            100.0 * e.residual,
            100.0 * level.median,
            100.0 * limit
        )
    } else if ev.vote() == 0.0 {
        "contradicted by cycles: other maps compose to another placement".to_string()
    } else {
        "not used: it would join two groups that other pairs place apart, or the maps \
         it puts together contradict each other densely"
            .to_string()
    }
}

/// The edges with a vote between two groups, by the two groups (`g < h`), each list ascending.
fn links(
    groups: &Groups,
    edges: &[Edge],
    ev: &[EdgeEvidence],
) -> BTreeMap<(usize, usize), Vec<usize>> {
    let mut out: BTreeMap<(usize, usize), Vec<usize>> = BTreeMap::new();
    for (i, e) in edges.iter().enumerate() {
        let (x, y) = (groups.of[e.a], groups.of[e.b]);
        if x != y && ev[i].vote() > 0.0 {
            out.entry((x.min(y), x.max(y))).or_default().push(i);
        }
    }
    out
}

/// The votes of the edges `between` group `g` and another group H ([`links`]) for placements of H into
/// G, clustered, the best supported first.
fn clusters(
    g: usize,
    between: &[usize],
    groups: &Groups,
    edges: &[Edge],
    ev: &[EdgeEvidence],
    options: &GlobalOptions,
) -> Vec<Cluster> {
    // Proposals: (edge, map of G, map of H, placement H -> G, vote).
    let mut proposals: Vec<(usize, usize, usize, Rigid, f64)> = Vec::new();
    for &i in between {
        let e = &edges[i];
        // One map in each group ([`links`]): u in G, v in H.
        let (u, v) = if groups.of[e.a] == g {
            (e.a, e.b)
        } else {
            (e.b, e.a)
        };
        let vote = ev[i].vote();
        // H -> v's pixels -> u's pixels -> G.
        let y = groups.pose[u]
            .after(&e.toward(u))
            .after(&groups.pose[v].inverse());
        proposals.push((i, u, v, y, vote));
    }
    proposals.sort_by(|x, y| y.4.total_cmp(&x.4).then(x.0.cmp(&y.0)));
    let mut clusters: Vec<Cluster> = Vec::new();
    for &(i, u, v, y, vote) in &proposals {
        // Compared where the edge's maps overlap, in H's frame.
        let at = groups.pose[v].apply(edges[i].at_in(v));
        let k = match clusters
            .iter()
            .position(|c| agree(&c.placement, &y, at, options))
        {
            Some(k) => k,
            None => {
                clusters.push(Cluster {
                    placement: y,
                    support: 0.0,
                    pairs: 0,
                    trusted: false,
                    confirmed: false,
                    first: i,
                    votes: BTreeMap::new(),
                });
                clusters.len() - 1
            }
        };
        let c = &mut clusters[k];
        let best = c.votes.entry((u, v)).or_insert(0.0);
        *best = best.max(vote);
        c.trusted |= trusted(&edges[i], &ev[i]);
        c.confirmed |= ev[i].support > 0.0;
    }
    for c in &mut clusters {
        c.support = c.votes.values().sum();
        c.pairs = c.votes.len();
    }
    clusters.sort_by(|x, y| y.support.total_cmp(&x.support).then(x.first.cmp(&y.first)));
    clusters
}

/// Whether placing group H into G by the cluster's placement puts no overlapping pair of their maps that
/// does not vote for it in dense contradiction ([`densely_contradicted`] on the transform it implies
/// between them). The voters' own pair evidence stands for them: a rigid placement through other maps
/// can be tens of pixels off for a bent pair.
fn densely_consistent(
    g: usize,
    h: usize,
    cluster: &Cluster,
    groups: &Groups,
    maps: &[Prepared],
    backend: &mut dyn Backend,
) -> Result<bool> {
    let bounds = |m: usize, t: &Rigid| {
        let pts = maps[m].bounds_in_map().map(|p| t.apply(p));
        let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
        for p in pts {
            lo = (lo.0.min(p.0), lo.1.min(p.1));
            hi = (hi.0.max(p.0), hi.1.max(p.1));
        }
        (lo, hi)
    };
    let placement = &cluster.placement;
    for u in groups.members(g) {
        let bu = bounds(u, &groups.pose[u]);
        for v in groups.members(h) {
            if cluster.votes.contains_key(&(u, v)) {
                continue;
            }
            let pv = placement.after(&groups.pose[v]);
            let bv = bounds(v, &pv);
            let overlap = bu.0 .0 <= bv.1 .0
                && bv.0 .0 <= bu.1 .0
                && bu.0 .1 <= bv.1 .1
                && bv.0 .1 <= bu.1 .1;
            if !overlap {
                continue;
            }
            let t = groups.pose[u].inverse().after(&pv); // v -> u
            let f = check(&maps[u], &maps[v], &t, backend)?;
            if densely_contradicted(&f) {
                return Ok(false);
            }
        }
    }
    Ok(true)
}

/// Whether the two groups joined by the cluster's placement fit one merged map
/// ([`crate::merge::many::mosaic::fits`], on the maps' prepared boxes, which hold their known areas).
fn fits_one_canvas(
    g: usize,
    h: usize,
    cluster: &Cluster,
    groups: &Groups,
    maps: &[Prepared],
    images: &[&OccupancyMap],
) -> bool {
    let (mut boxes, mut poses, mut total) = (Vec::new(), Vec::new(), 0u64);
    for (k, moved) in [(g, false), (h, true)] {
        for m in groups.members(k) {
            let b = maps[m].bounds_in_map();
            let clamp = |v: f64| v.max(0.0) as u32;
            boxes.push((clamp(b[0].0), clamp(b[0].1), clamp(b[3].0), clamp(b[3].1)));
            poses.push(if moved {
                cluster.placement.after(&groups.pose[m])
            } else {
                groups.pose[m]
            });
            total = total.saturating_add(images[m].image.len() as u64);
        }
    }
    crate::merge::many::mosaic::fits(&boxes, &poses, total)
}

/// Whether the pair test, run on the two groups' merged maps, accepts a placement of H into G that agrees
/// with the cluster's: what a join that no accepted edge stands behind must pass. Maps of one place give
/// alike wrong answers for a map of another place, so their agreeing weak votes are not independent
/// evidence; their mosaics cover more of the place than any one map and so test it better.
fn mosaics_agree(
    g: usize,
    h: usize,
    cluster: &Cluster,
    groups: &Groups,
    images: &[&OccupancyMap],
    options: &GlobalOptions,
    backend: &mut dyn Backend,
) -> Result<bool> {
    let mosaic = |k: usize| {
        let members = groups.members(k);
        let maps: Vec<&OccupancyMap> = members.iter().map(|&m| images[m]).collect();
        let poses: Vec<Rigid> = members.iter().map(|&m| groups.pose[m]).collect();
        compose_many(&maps, &poses)
    };
    // A canvas too large to compose is no evidence either way: not joined. A stop is no verdict: passed on.
    let (a, b) = (mosaic(g), mosaic(h));
    for r in [&a, &b] {
        if let Err(crate::Error::Interrupted) = r {
            return Err(crate::Error::Interrupted);
        }
    }
    let (Ok((a, fa)), Ok((b, fb))) = (a, b) else {
        return Ok(false);
    };
    let (pa, pb) = (Prepared::new(&a), Prepared::new(&b));
    let al = align_prepared_with(&pa, &pb, &options.pair, backend)?;
    if !al.accepted {
        return Ok(false);
    }
    // The cluster's placement between the mosaics' pixels: H's mosaic -> H's frame -> G's frame -> G's
    // mosaic.
    let shift = |x: i64, y: i64| Rigid {
        theta_deg: 0.0,
        tx: x as f64,
        ty: y as f64,
    };
    let expected = shift(-fa.x0, -fa.y0)
        .after(&cluster.placement)
        .after(&shift(fb.x0, fb.y0));
    Ok(agree(
        &al.transform,
        &expected,
        pb.reference_in_map()[4],
        options,
    ))
}

/// Why map `m` could not be aligned at all, when each of its pairs was declined before any search for
/// the same kind of reason (too large to correlate with the other map, or no walls to align): that
/// reason, rather than a want of confidence.
fn unalignable(pairwise: &Pairwise, m: usize) -> Option<String> {
    const BEFORE_ANY_SEARCH: [&str; 2] = [
        crate::merge::pair::coarse::TOO_LARGE,
        crate::merge::pair::align::NO_WALLS,
    ];
    let mine: Vec<&str> = pairwise
        .pairs
        .iter()
        .filter(|p| p.a == m || p.b == m)
        .map(|p| p.reason.as_deref().unwrap_or(""))
        .collect();
    let kind = BEFORE_ANY_SEARCH
        .into_iter()
        .find(|k| !mine.is_empty() && mine.iter().all(|r| r.contains(k)))?;
    let first = mine.first()?;
    Some(format!(
        "none of its pairs could be aligned ({kind}): {first}"
    ))
}
