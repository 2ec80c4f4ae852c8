//! `merge-eval --global`: many maps placed at once, checked against pair ground truth: per building, mixed
//! sets of two buildings, and the cost as the number of maps grows.

use std::io::{self, Write};

use serde::Serialize;

use crate::backend::ReferenceBackend;
use crate::map::OccupancyMap;
use crate::measure::pairs::TruePair;
use crate::merge::many::graph::Placement;
use crate::merge::many::{GlobalOptions, Pairwise, Run, Timing};
use crate::merge::transform::Rigid;
use crate::support::error::Result;

/// Many maps placed: the pairwise alignments, the placement, the time.
#[derive(Clone, Debug, Serialize)]
pub struct SetResult {
    /// The maps' names, as given.
    pub names: Vec<String>,
    /// Every pair's alignment.
    pub pairwise: Pairwise,
    /// The placement.
    pub placement: Placement,
    /// Where the time went.
    pub timing: Timing,
}

/// Places `maps` on the CPU path ([`crate::merge::many::run`]); `progress` hears (pairs done, pairs in all).
pub fn run_maps(
    names: Vec<String>,
    maps: &[OccupancyMap],
    options: &GlobalOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<SetResult> {
    let r = crate::merge::many::run(maps, options, &mut ReferenceBackend, progress)?;
    Ok(SetResult::of(names, r))
}

impl SetResult {
    /// A run's result under the maps' `names` (from [`crate::merge::many::run`] or its cached forms).
    pub fn of(names: Vec<String>, run: Run) -> SetResult {
        SetResult {
            names,
            pairwise: run.pairwise,
            placement: run.placement,
            timing: run.timing,
        }
    }

    /// The transform from map `src`'s pixels to map `dst`'s that the placement implies, when both are
    /// placed in one group.
    pub fn derived(&self, src: usize, dst: usize) -> Option<Rigid> {
        let (s, d) = (&self.placement.maps[src], &self.placement.maps[dst]);
        (s.group.is_some() && s.group == d.group).then(|| d.pose.inverse().after(&s.pose))
    }

    /// The transform from `src` to `dst` that the pair test alone accepted, when it did.
    pub fn pairwise_alone(&self, src: usize, dst: usize) -> Option<Rigid> {
        let (a, b) = (src.min(dst), src.max(dst));
        let v = self.pairwise.pairs.iter().find(|p| p.a == a && p.b == b)?;
        // The verdict maps b to a.
        v.accepted.then(|| {
            if dst == a {
                v.transform
            } else {
                v.transform.inverse()
            }
        })
    }

    fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }
}

/// How a set came out against its ground truth.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SetRow {
    /// What the set is.
    pub label: String,
    /// Maps given.
    pub maps: usize,
    /// Maps placed (in a group of two or more).
    pub placed: usize,
    /// Placed maps checked by an annotated pair with another map of their group and not placed wrongly.
    pub correct: usize,
    /// Placed maps blamed for the inaccurate annotated pairs of their group: the fewest maps that every
    /// such pair touches (a map placed wrongly makes all its pairs inaccurate; its partners are not
    /// blamed for it).
    pub wrong: usize,
    /// Groups formed.
    pub groups: usize,
    /// Maps placed into a group whose other maps are mostly of another building.
    pub foreign: usize,
    /// Annotated ordered pairs among the maps.
    pub pairs: usize,
    /// Of them: the placement's implied transform accurate, wrong, not given (not in one group).
    pub derived_accurate: usize,
    /// See `derived_accurate`.
    pub derived_wrong: usize,
    /// The same for the pair test's accepts chained along their maximum spanning tree (by rule value),
    /// as m-explore's map_merge chains its pairwise matches.
    pub chained_accurate: usize,
    /// See `chained_accurate`.
    pub chained_wrong: usize,
    /// The same for the pair test alone (one alignment per unordered pair).
    pub pairwise_accurate: usize,
    /// See `pairwise_accurate`.
    pub pairwise_wrong: usize,
    /// Accepted pairwise merges the placement dropped.
    pub dropped: usize,
    /// Pairs the placement rests on through a candidate the pair test did not accept (a cycle
    /// confirmed it).
    pub confirmed: usize,
    /// Pairs aligned.
    pub aligned: usize,
    /// Time.
    pub timing: Timing,
}

/// Scores `result` against `truths` (pairs of names; those naming maps not in the set are ignored) and
/// `building` (each map's building, for mixed sets).
pub fn score(
    label: &str,
    result: &SetResult,
    truths: &[TruePair],
    building: &dyn Fn(&str) -> String,
) -> SetRow {
    let n = result.names.len();
    let mut row = SetRow {
        label: label.to_string(),
        maps: n,
        groups: result.placement.groups.len(),
        dropped: result.placement.dropped.len(),
        confirmed: result
            .placement
            .kept
            .iter()
            .filter(|&&i| !result.pairwise.edges[i].accepted)
            .count(),
        aligned: result.pairwise.pairs.len(),
        timing: result.timing,
        ..SetRow::default()
    };
    // A group's building: the most frequent among its maps (ties: the first map's).
    let group_building = |members: &[usize]| {
        let names: Vec<String> = members
            .iter()
            .map(|&m| building(&result.names[m]))
            .collect();
        let count = |b: &String| names.iter().filter(|x| *x == b).count();
        let most = names.iter().map(count).max().unwrap_or(0);
        names
            .iter()
            .find(|b| count(b) == most)
            .cloned()
            .unwrap_or_default()
    };
    let mut inaccurate: Vec<(usize, usize)> = Vec::new();
    let mut checked = vec![false; n];
    let chained = chain(&result.pairwise);
    for t in truths {
        let (Some(s), Some(d)) = (result.index(&t.src), result.index(&t.dst)) else {
            continue;
        };
        row.pairs += 1;
        if let Some(est) = result.derived(s, d) {
            checked[s] = true;
            checked[d] = true;
            if t.accurate(&est) {
                row.derived_accurate += 1;
            } else {
                row.derived_wrong += 1;
                inaccurate.push((s, d));
            }
        }
        if let Some(est) = chained[s]
            .zip(chained[d])
            .and_then(|((gs, ps), (gd, pd))| (gs == gd).then(|| pd.inverse().after(&ps)))
        {
            if t.accurate(&est) {
                row.chained_accurate += 1;
            } else {
                row.chained_wrong += 1;
            }
        }
        if let Some(est) = result.pairwise_alone(s, d) {
            if t.accurate(&est) {
                row.pairwise_accurate += 1;
            } else {
                row.pairwise_wrong += 1;
            }
        }
    }
    let bad = blamed(&inaccurate, n);
    for (m, p) in result.placement.maps.iter().enumerate() {
        let Some(g) = p.group else { continue };
        row.placed += 1;
        // Placed with a map of its building that has no annotated pair with it: not checked.
        if bad[m] {
            row.wrong += 1;
        } else if checked[m] {
            row.correct += 1;
        }
        if building(&result.names[m]) != group_building(&result.placement.groups[g]) {
            row.foreign += 1;
        }
    }
    row
}

/// The maps to blame for the inaccurate pairs `wrong` (of `n` maps): the fewest that every such pair
/// touches, greedily (the map in most of the pairs left first, ties to the lower index, until none is
/// left). A map placed wrongly makes all its pairs inaccurate; its partners, placed right, are not blamed
/// for it, and a map placed between two wrongly placed ones is not either.
fn blamed(wrong: &[(usize, usize)], n: usize) -> Vec<bool> {
    let mut bad = vec![false; n];
    let mut left: Vec<(usize, usize)> = wrong.to_vec();
    while !left.is_empty() {
        let mut count = vec![0usize; n];
        for &(s, d) in &left {
            count[s] += 1;
            count[d] += 1;
        }
        let worst = (0..n)
            .max_by(|&x, &y| count[x].cmp(&count[y]).then(y.cmp(&x)))
            .unwrap_or(0);
        bad[worst] = true;
        left.retain(|&(s, d)| s != worst && d != worst);
    }
    bad
}

/// The table of [`SetRow`]s.
pub fn write_rows(out: &mut dyn Write, rows: &[SetRow]) -> io::Result<()> {
    writeln!(
        out,
        "| set | maps | placed | placed correctly | placed wrongly | groups | in another building's group | annotated pairs | derived: accurate | derived: wrong | chained accepts: accurate | chained accepts: wrong | pairwise alone: accurate | pairwise alone: wrong | accepted pairs dropped | unaccepted pairs used | pairs aligned | prepare s | align s | place s | total s |"
    )?;
    writeln!(
        out,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    )?;
    for r in rows {
        let pct = |k: usize| 100.0 * k as f64 / r.pairs.max(1) as f64;
        writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} ({:.1}%) | {} | {} ({:.1}%) | {} | {} ({:.1}%) | {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} |",
            crate::detect::output::md_cell(&r.label),
            r.maps,
            r.placed,
            r.correct,
            r.wrong,
            r.groups,
            r.foreign,
            r.pairs,
            r.derived_accurate,
            pct(r.derived_accurate),
            r.derived_wrong,
            r.chained_accurate,
            pct(r.chained_accurate),
            r.chained_wrong,
            r.pairwise_accurate,
            pct(r.pairwise_accurate),
            r.pairwise_wrong,
            r.dropped,
            r.confirmed,
            r.aligned,
            r.timing.prepare,
            r.timing.align,
            r.timing.place,
            r.timing.total()
        )?;
    }
    Ok(())
}

/// Where a suite's maps come from: named maps with their buildings.
pub struct Library {
    /// (name, building, map), in name order.
    pub maps: Vec<(String, String, OccupancyMap)>,
}

impl Library {
    fn of(&self, building: &str) -> Vec<usize> {
        (0..self.maps.len())
            .filter(|&i| self.maps[i].1 == building)
            .collect()
    }

    fn building_of(&self, name: &str) -> String {
        self.maps
            .iter()
            .find(|m| m.0 == name)
            .map_or_else(String::new, |m| m.1.clone())
    }
}

/// Sets of two maps of each of two buildings, at most, for each pair of buildings ([`suite`]).
pub const SMALL_MIXED: usize = 12;

/// The `--global` suite over a pair set's maps: each building alone; every two buildings together, and
/// all of them; two maps of each of two buildings ([`SMALL_MIXED`] sets a pair of buildings); the first 4
/// and 8 maps of the largest building (the cost as N grows); and a synthetic set of `synthetic.0` maps
/// cut from `synthetic.1` large synthetic offices (seeds `seed` on; [`synthetic_mixed`]) (exact truth,
/// the synthetic success test). `progress` hears what runs.
pub fn suite(
    lib: &Library,
    truths: &[TruePair],
    options: &GlobalOptions,
    synthetic: (usize, usize),
    seed: u64,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Vec<SetRow>> {
    let mut buildings: Vec<String> = Vec::new();
    for m in &lib.maps {
        if !buildings.contains(&m.1) {
            buildings.push(m.1.clone());
        }
    }
    let building = |name: &str| lib.building_of(name);
    let run = |label: &str, members: &[usize]| -> Result<SetRow> {
        let names = members.iter().map(|&i| lib.maps[i].0.clone()).collect();
        let maps: Vec<OccupancyMap> = members.iter().map(|&i| lib.maps[i].2.clone()).collect();
        let result = run_maps(names, &maps, options, &|k, n| progress(label, k, n))?;
        Ok(score(label, &result, truths, &building))
    };
    let mut rows = Vec::new();
    for b in &buildings {
        rows.push(run(b, &lib.of(b))?);
    }
    for (i, x) in buildings.iter().enumerate() {
        for y in &buildings[i + 1..] {
            let mut both = lib.of(x);
            both.extend(lib.of(y));
            both.sort_unstable();
            rows.push(run(&format!("{x} + {y}"), &both)?);
        }
    }
    // Small mixed sets, where two maps of one place give alike wrong answers for a map of another: two
    // maps of each of two buildings, every combination of their pairs up to SMALL_MIXED a pair of
    // buildings (evenly spread over them), summed into one row.
    let mut small = SetRow {
        label: String::new(),
        ..SetRow::default()
    };
    let mut sets = 0;
    for (i, x) in buildings.iter().enumerate() {
        for y in &buildings[i + 1..] {
            let two = |b: &str| -> Vec<(usize, usize)> {
                let m = lib.of(b);
                (0..m.len())
                    .flat_map(|p| (p + 1..m.len()).map(move |q| (p, q)))
                    .map(|(p, q)| (m[p], m[q]))
                    .collect()
            };
            let (px, py) = (two(x), two(y));
            let all = px.len() * py.len();
            let step = all.div_ceil(SMALL_MIXED).max(1);
            for k in (0..all).step_by(step) {
                let ((a, b), (c, d)) = (px[k / py.len()], py[k % py.len()]);
                let r = run(&format!("{x} + {y}, 2 + 2"), &[a, b, c, d])?;
                sets += 1;
                small.maps += r.maps;
                small.placed += r.placed;
                small.correct += r.correct;
                small.wrong += r.wrong;
                small.groups += r.groups;
                small.foreign += r.foreign;
                small.pairs += r.pairs;
                small.derived_accurate += r.derived_accurate;
                small.derived_wrong += r.derived_wrong;
                small.chained_accurate += r.chained_accurate;
                small.chained_wrong += r.chained_wrong;
                small.pairwise_accurate += r.pairwise_accurate;
                small.pairwise_wrong += r.pairwise_wrong;
                small.dropped += r.dropped;
                small.confirmed += r.confirmed;
                small.aligned += r.aligned;
                small.timing.prepare += r.timing.prepare;
                small.timing.align += r.timing.align;
                small.timing.place += r.timing.place;
            }
        }
    }
    if sets > 0 {
        small.label = format!("2 + 2 maps of two buildings ({sets} sets, summed)");
        rows.push(small);
    }
    if buildings.len() > 2 {
        let all: Vec<usize> = (0..lib.maps.len()).collect();
        rows.push(run("all buildings", &all)?);
    }
    if let Some(largest) = buildings.iter().max_by_key(|b| lib.of(b).len()) {
        let members = lib.of(largest);
        for k in [4, 8] {
            if members.len() > k {
                rows.push(run(&format!("{largest}, first {k}"), &members[..k])?);
            }
        }
    }
    let (names, maps, truths) = synthetic_mixed(synthetic.0, synthetic.1, seed)?;
    let label = synthetic_label(synthetic.0, synthetic.1);
    rows.push(score_maps(
        &label, names, &maps, &truths, options, progress,
    )?);
    Ok(rows)
}

/// The label of a synthetic set of `n` maps of `buildings` offices.
pub fn synthetic_label(n: usize, buildings: usize) -> String {
    if buildings <= 1 {
        format!("synthetic office, {n} maps")
    } else {
        format!("synthetic offices, {n} maps of {buildings} offices mixed")
    }
}

/// `n` maps cut from `buildings` synthetic offices ([`synthetic_maps`], seeds `seed`, `seed + 1`, ...),
/// as evenly as they divide (the first offices one more), named `oK-part-NN` for office K (`part-NN` for
/// one office), with every ordered pair of one office's truth (its building `oK`).
pub fn synthetic_mixed(
    n: usize,
    buildings: usize,
    seed: u64,
) -> Result<(Vec<String>, Vec<OccupancyMap>, Vec<TruePair>)> {
    if buildings <= 1 {
        return synthetic_maps(n, seed);
    }
    let (mut names, mut maps, mut truths) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..buildings {
        let count = n / buildings + usize::from(k < n % buildings);
        let (nm, mp, tr) = synthetic_maps(count, seed.wrapping_add(k as u64))?;
        let tag = |s: &str| format!("o{k}-{s}");
        names.extend(nm.iter().map(|s| tag(s)));
        maps.extend(mp);
        truths.extend(tr.into_iter().map(|mut t| {
            (t.src, t.dst, t.building) = (tag(&t.src), tag(&t.dst), format!("o{k}"));
            t
        }));
    }
    Ok((names, maps, truths))
}

/// Places `maps` and scores them against `truths`, labelled `label`; a map's building is its office's
/// tag in a mixed set (`oK` of `oK-part-NN`), else "synthetic".
pub fn score_maps(
    label: &str,
    names: Vec<String>,
    maps: &[OccupancyMap],
    truths: &[TruePair],
    options: &GlobalOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<SetRow> {
    let result = run_maps(names, maps, options, &|k, m| progress(label, k, m))?;
    let building = |name: &str| {
        name.split_once("-part-")
            .map_or("synthetic", |(office, _)| office)
            .to_string()
    };
    Ok(score(label, &result, truths, &building))
}

/// `n` maps cut from one synthetic office with every ordered pair's exact truth (the synthetic limits).
pub fn synthetic_maps(
    n: usize,
    seed: u64,
) -> Result<(Vec<String>, Vec<OccupancyMap>, Vec<TruePair>)> {
    // About 580 px a grid step: a 1044 px window each. The office is generated at half that size and
    // doubled, so its rooms and walls are as large in pixels as those of the real sensor maps (a 5 cm
    // grid); at its own scale a window would show a dense grid of small rooms.
    let cols = (n as f64 * 4.0 / 3.0).sqrt().round().max(1.0);
    let rows = (n as f64 / cols).ceil();
    let (w, h) = ((cols * 290.0) as u32, (rows * 290.0) as u32);
    let half = crate::map::synthetic::office_map(w.max(128), h.max(128), seed)?;
    let (w2, h2) = (half.width() * 2, half.height() * 2);
    let px = (0..h2)
        .flat_map(|y| (0..w2).map(move |x| (x, y)))
        .map(|(x, y)| half.get(x / 2, y / 2))
        .collect();
    let source = OccupancyMap::from_image(crate::map::MapImage::new(w2, h2, px)?);
    synthetic_maps_of(&source, n, seed)
}

/// `n` maps cut from `source` ([`synthetic_set`](crate::measure::synthetic::synthetic_set), no speckle)
/// with every ordered pair's exact truth (the synthetic limits), named `part-NN`.
pub fn synthetic_maps_of(
    source: &OccupancyMap,
    n: usize,
    seed: u64,
) -> Result<(Vec<String>, Vec<OccupancyMap>, Vec<TruePair>)> {
    use crate::measure::synthetic::synthetic_set;
    let crops = synthetic_set(source, n, 0.0, seed).ok_or_else(|| {
        crate::support::error::Error::invalid("the synthetic map is too small to cut a set from")
    })?;
    let names: Vec<String> = (0..n).map(|k| format!("part-{k:02}")).collect();
    let mut truths = Vec::new();
    for (s, cs) in crops.iter().enumerate() {
        for (d, cd) in crops.iter().enumerate() {
            if s == d {
                continue;
            }
            truths.push(cs.true_pair(cd, &names[s], &names[d]));
        }
    }
    Ok((names, crops.into_iter().map(|c| c.map).collect(), truths))
}

/// Each map's tree (by its first map) and pose in it, chaining the pair test's accepts along their
/// maximum spanning tree by rule value (Kruskal, then outward from each tree's first map); `None` for a
/// map in no accepted pair. The baseline the placement is measured against.
pub fn chain(pairwise: &Pairwise) -> Vec<Option<(usize, Rigid)>> {
    let accepted: Vec<(usize, usize, Rigid, f64)> = pairwise
        .pairs
        .iter()
        .filter(|p| p.accepted)
        .map(|p| (p.a, p.b, p.transform, p.score))
        .collect();
    let mut in_one = vec![false; pairwise.n];
    for &(a, b, _, _) in &accepted {
        (in_one[a], in_one[b]) = (true, true);
    }
    crate::merge::many::prescreen::forest(pairwise.n, &accepted)
        .into_iter()
        .zip(in_one)
        .map(|(tree, is)| is.then_some(tree))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::blamed;

    /// One map placed wrongly makes every pair with it inaccurate: it alone is blamed, not its partners.
    #[test]
    fn the_map_in_every_inaccurate_pair_is_blamed_not_its_partners() {
        let mut wrong = Vec::new();
        for x in [0, 1, 3, 4] {
            wrong.push((x, 2));
            wrong.push((2, x));
        }
        assert_eq!(blamed(&wrong, 5), vec![false, false, true, false, false]);
        assert_eq!(blamed(&[], 3), vec![false; 3]);
        // Two pairs with no map in common: one map of each is blamed.
        let two = blamed(&[(0, 1), (3, 4)], 5);
        assert_eq!(two.iter().filter(|&&b| b).count(), 2);
        assert!(two[0] != two[1] && two[3] != two[4], "{two:?}");
    }
}
