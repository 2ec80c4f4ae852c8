//! Where every map lands: the placement over the graph of all pairwise candidates and each group's pose
//! graph, the second stage of [`super::run`].

use super::{calibrate, graph, posegraph, rounds, verify};
use super::{GlobalOptions, PairRecord, Pairwise};
use crate::merge::pair::align::Prepared;
use crate::merge::transform::Rigid;
use crate::support::error::Result;

/// Half the side of the square of points where a pose-graph constraint is measured, pixels (150, 300 and
/// the moved map's wall bounding box tried on 80 random sets of 3-8 F5 maps: 2, 3 and 3 pairs of 1070
/// derived beyond the success limit, all within 5% of it).
const CONSTRAINT_SPREAD: f64 = 150.0;

/// Where an edge's constraint is measured: its overlap centre and the corners of a square around it
/// (in the moved map's pixels). Where the two maps overlap is where their pairwise transform is right:
/// maps bend, and far from the overlap it may be tens of pixels off.
fn around((x, y): (f64, f64)) -> Vec<(f64, f64)> {
    let r = CONSTRAINT_SPREAD;
    vec![
        (x, y),
        (x - r, y - r),
        (x + r, y - r),
        (x - r, y + r),
        (x + r, y + r),
    ]
}

/// Where every map lands: the graph's placement ([`graph::place`]) with each group's poses from the
/// pose graph over the edges it kept ([`posegraph::solve`]); `maps` prepared from `images`.
pub fn place(
    pairwise: &Pairwise,
    maps: &[Prepared],
    images: &[&crate::map::OccupancyMap],
    options: &GlobalOptions,
    backend: &mut dyn crate::backend::Backend,
) -> Result<graph::Placement> {
    // The cycles once to find the confirmed pairs and the set's level; then again without the
    // candidates far above it, so that they neither vote nor confirm others.
    let first = graph::evidence(pairwise, options, None);
    let level = calibrate::calibrate(pairwise, &first);
    let ev = if pairwise.edges.iter().any(|e| level.excludes(e.residual)) {
        graph::evidence(pairwise, options, Some(&level))
    } else {
        first
    };
    let mut placement = graph::place(pairwise, maps, images, &ev, &level, options, backend)?;
    let kept: Vec<posegraph::Kept> = placement
        .kept
        .iter()
        .map(|&i| posegraph::Kept {
            u: pairwise.edges[i].a,
            v: pairwise.edges[i].b,
            accepted: pairwise.edges[i].accepted,
            weight: ev[i].vote(),
        })
        .collect();
    placement.kept = posegraph::rests_on(maps.len(), &kept)
        .into_iter()
        .map(|k| placement.kept[k])
        .collect();
    let start: Vec<Rigid> = placement.maps.iter().map(|m| m.pose).collect();
    for members in &placement.groups {
        let constraints: Vec<posegraph::Constraint> = placement
            .kept
            .iter()
            .filter(|&&i| members.contains(&pairwise.edges[i].a))
            .map(|&i| {
                let e = &pairwise.edges[i];
                posegraph::Constraint {
                    u: e.a,
                    v: e.b,
                    transform: e.transform,
                    points: around(e.at),
                    weight: ev[i].vote(),
                }
            })
            .collect();
        let solved = posegraph::solve(&start, members[0], &constraints);
        // The least squares only spreads the loop errors: a solution that moves a map further than two
        // placements may disagree (an ill-conditioned system) keeps the agglomeration's poses.
        let moved_far = members.iter().any(|&m| {
            let c = maps[m].reference_in_map()[4];
            let (p, q) = (start[m].apply(c), solved[m].apply(c));
            let turn = (start[m].theta_deg - solved[m].theta_deg + 180.0).rem_euclid(360.0) - 180.0;
            // Written so that a NaN counts as moved far.
            !(turn.abs() <= options.loop_deg && (p.0 - q.0).hypot(p.1 - q.1) <= options.loop_px)
        });
        if !moved_far {
            for &m in members {
                placement.maps[m].pose = solved[m];
            }
        }
    }
    Ok(placement)
}

/// Pairs whose records did not hold on the maps (the maps' indices, why).
type Refused = Vec<(usize, usize, String)>;

/// Why each record (map `b` onto map `a`) does not hold on the maps ([`verify`]), `None` where it does;
/// checked in parallel, a raised stop ending the checks not started.
fn why_not_each(
    maps: &[Prepared],
    records: &[((usize, usize), &PairRecord)],
    options: &GlobalOptions,
) -> Result<Vec<Option<String>>> {
    use rayon::prelude::*;
    let stop = crate::support::stop::current();
    records
        .par_iter()
        .map(|&((a, b), r)| {
            crate::support::stop::with(stop.clone(), || {
                crate::support::stop::check()?;
                verify::why_not(&maps[a], &maps[b], r, options)
            })
        })
        .collect()
}

/// The carried records (`start`) that hold on the maps, and the pairs whose records do not, with why.
pub(super) fn vouched(
    maps: &[Prepared],
    start: rounds::Aligned,
    options: &GlobalOptions,
) -> Result<(rounds::Aligned, Refused)> {
    let records: Vec<((usize, usize), &PairRecord)> = start.iter().map(|(&p, r)| (p, r)).collect();
    let verdicts = why_not_each(maps, &records, options)?;
    let mut refused = Vec::new();
    let mut kept = rounds::Aligned::new();
    for (((a, b), r), why) in start.into_iter().zip(verdicts) {
        match why {
            Some(why) => refused.push((a, b, why)),
            None => {
                kept.insert((a, b), r);
            }
        }
    }
    Ok((kept, refused))
}

/// Refuses an engine's answer for `pairs` unless it is one record a pair and each holds on the maps
/// ([`verify`]): an executor elsewhere may be wrong, and a wrong record would place maps wrongly.
pub(super) fn refuse_unfounded(
    maps: &[Prepared],
    pairs: &[(usize, usize)],
    records: &[PairRecord],
    options: &GlobalOptions,
) -> Result<()> {
    if records.len() != pairs.len() {
        return Err(crate::Error::invalid(format!(
            "the engine aligned {} pairs of {}",
            records.len(),
            pairs.len()
        )));
    }
    let each: Vec<((usize, usize), &PairRecord)> = pairs.iter().copied().zip(records).collect();
    let verdicts = why_not_each(maps, &each, options)?;
    match pairs
        .iter()
        .zip(verdicts)
        .find_map(|(p, why)| Some((p, why?)))
    {
        Some(((a, b), why)) => Err(crate::Error::invalid(format!(
            "the engine's alignment of map {b} onto map {a} does not hold on the maps: {why}"
        ))),
        None => Ok(()),
    }
}
