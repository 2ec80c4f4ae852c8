//! The pre-screen of a large set of maps: which pairs are worth the full alignment.
//!
//! Aligning every pair of N maps costs N(N-1)/2 alignments of tens of milliseconds each. Most pairs of a
//! fleet's maps do not overlap, and a map that overlaps many others needs only a few of them to be placed
//! and checked around cycles. So each map gets a compact signature, computed once, every two signatures
//! are compared (microseconds a pair), and only each map's most similar maps go through the alignment.
//!
//! The signature: the map's corners (the robust detector's, on its known area) taken two at a time. For
//! two corners up to [`REACH`] px apart, their offset in the detector's turned grid, the two corners'
//! opening directions, and whether each is convex make a term. The grid turns with the map's walls, and
//! the offset is turned by the quarter turn that brings it into one quadrant (the corners' directions with
//! it), so a term does not change when the map is turned or shifted. A corner pair two maps share
//! (their overlap) gives both the same term; a pair of one map alone is one the other lacks. Offsets are
//! binned at [`BIN`] px with bilinear weights, so that a corner a few pixels off still meets its twin.
//! Terms every map has (a door's width, a corridor's) say little: they are weighted by their rarity in
//! the set (tf-idf), and two signatures' similarity is the cosine of their weighted terms.

use std::collections::{BTreeSet, HashMap};

use rayon::prelude::*;

use crate::backend::FLAG_INSIDE;
use crate::backend::{DetectOptions, DetectorKind};
use crate::detect::detector::Detector;
use crate::map::{MapImage, OccupancyMap};
use crate::merge::pair::prepare::Prepared;
use crate::merge::transform::Rigid;
use crate::support::error::Result;

/// Corner pairs farther apart than this (pixels) make no term.
pub const REACH: f64 = 320.0;
/// The offsets' bin, pixels.
pub const BIN: f64 = 8.0;
/// The strongest corners a signature is made of, at most.
pub const MAX_CORNERS: usize = 400;

/// How a large set is screened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Prescreen {
    /// Each map is aligned with this many of its most similar maps (and any map that chose it).
    pub partners: usize,
    /// Sets of at most this many maps align every pair.
    pub above: usize,
    /// Rounds of closing cycles ([`closing_pairs`]) after the first alignments.
    pub rounds: usize,
    /// New pairs a map may get in one round of closing cycles.
    pub per_round: usize,
}

impl Default for Prescreen {
    fn default() -> Self {
        Prescreen {
            partners: 3,
            above: 12,
            rounds: 3,
            per_round: 4,
        }
    }
}

/// A corner as a signature sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corner {
    /// Its position in the turned grid's axes, pixels.
    pub p: f64,
    /// See `p`.
    pub q: f64,
    /// The quadrant its walls are in, turning with the grid: 0 (+p +q), 1 (-p +q), 2 (-p -q), 3 (+p -q);
    /// 4 when its code names none.
    pub dir: u8,
    /// A convex corner.
    pub convex: bool,
}

/// A map's pre-screen signature: its weighted terms, sorted by term.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Signature {
    /// (term, weight), terms ascending.
    pub terms: Vec<(u32, f32)>,
    /// Corners it was made of.
    pub corners: usize,
}

/// The quadrant of an 8-neighbour code's occupied cells: the one whose three cells (its diagonal and the
/// two beside it) hold the most, when one does.
pub fn quadrant(code: u8) -> u8 {
    // Bit order of crate::backend::rules: Q (-1,-1), B (0,-1), P (1,-1), A (1,0), Q' (1,1), B' (0,1), P' (-1,1),
    // A' (-1,0). Quadrant 0 is +p +q: A, Q', B'.
    const CELLS: [[u8; 3]; 4] = [[3, 4, 5], [5, 6, 7], [7, 0, 1], [1, 2, 3]];
    let counts = CELLS.map(|c| c.iter().filter(|&&b| (code >> b) & 1 == 1).count());
    let most = *counts.iter().max().unwrap_or(&0);
    let at: Vec<usize> = (0..4).filter(|&i| counts[i] == most).collect();
    if most == 0 || at.len() != 1 {
        4
    } else {
        at[0] as u8
    }
}

/// The corners of `map` for its signature: the robust detector's on the map's known area, strongest
/// first, at most [`MAX_CORNERS`].
pub fn corners(map: &OccupancyMap) -> Result<Vec<Corner>> {
    let (x0, y0, x1, y1) = crate::merge::pair::prepare::crop_box(map);
    let (fw, w) = (map.image.width() as usize, x1 - x0);
    let px: Vec<u8> = map
        .image
        .pixels()
        .chunks_exact(fw.max(1))
        .skip(y0)
        .take(y1 - y0)
        .flat_map(|row| row[x0..x1].iter().copied())
        .collect();
    let crop = OccupancyMap {
        image: MapImage::new(w as u32, (y1 - y0) as u32, px)?,
        thresholds: map.thresholds,
        georef: None,
        image_path: None,
        yaml_path: None,
        warnings: Vec::new(),
    };
    let mut detector = Detector::new(DetectOptions {
        detector: DetectorKind::OgmRobust,
        ..DetectOptions::default()
    });
    let found = detector.detect(&crop)?;
    let angle = found.robust.map_or(0.0, |r| r.angle);
    let (s, c) = angle.to_radians().sin_cos();
    let mut k = found.keypoints;
    k.sort_by(|a, b| b.score.cmp(&a.score).then(a.cmp(b)));
    Ok(k.iter()
        .take(MAX_CORNERS)
        .map(|k| {
            let (x, y) = (f64::from(k.x), f64::from(k.y));
            Corner {
                p: x * c + y * s,
                q: -x * s + y * c,
                dir: quadrant(k.code),
                convex: k.convex,
            }
        })
        .collect())
}

impl Signature {
    /// The signature of `map` ([`corners`]).
    pub fn of(map: &OccupancyMap) -> Result<Signature> {
        Ok(Signature::from_corners(&corners(map)?))
    }

    /// The signature of a map with `corners`: its terms' counts (not yet weighted by rarity).
    pub fn from_corners(corners: &[Corner]) -> Signature {
        let span = (REACH / BIN).ceil() as i64 + 2;
        let mut acc: HashMap<u32, f32> = HashMap::new();
        for (i, a) in corners.iter().enumerate() {
            for (j, b) in corners.iter().enumerate() {
                if i == j {
                    continue;
                }
                let (mut dp, mut dq) = (b.p - a.p, b.q - a.q);
                if dp * dp + dq * dq > REACH * REACH {
                    continue;
                }
                // The quarter turns (p, q) -> (-q, p) that bring the offset into p > 0, q >= 0; each
                // turns a quadrant index by one.
                let mut turns = 0u8;
                while !(dp > 0.0 && dq >= 0.0) && turns < 4 {
                    (dp, dq) = (-dq, dp);
                    turns += 1;
                }
                if turns == 4 {
                    continue; // the same point twice
                }
                let dir = |d: u8| if d == 4 { 4 } else { (d + turns) % 4 };
                let kind = u32::from(dir(a.dir)) * 5 + u32::from(dir(b.dir));
                let kind = kind * 4 + u32::from(a.convex) * 2 + u32::from(b.convex);
                let (u, v) = (dp / BIN, dq / BIN);
                let (bu, bv) = (u.floor(), v.floor());
                let (fu, fv) = ((u - bu) as f32, (v - bv) as f32);
                for (du, wu) in [(0i64, 1.0 - fu), (1, fu)] {
                    for (dv, wv) in [(0i64, 1.0 - fv), (1, fv)] {
                        let (cu, cv) = (bu as i64 + du, bv as i64 + dv);
                        let cell = (cu.clamp(0, span) * (span + 1) + cv.clamp(0, span)) as u32;
                        *acc.entry(cell * 100 + kind).or_insert(0.0) += wu * wv;
                    }
                }
            }
        }
        let mut terms: Vec<(u32, f32)> = acc.into_iter().collect();
        terms.sort_unstable_by_key(|t| t.0);
        Signature {
            terms,
            corners: corners.len(),
        }
    }
}

/// Every two of `signatures` compared: the cosine of their terms weighted by rarity in the set (idf),
/// row by row (the diagonal 0).
pub fn similarities<S: std::borrow::Borrow<Signature> + Sync>(signatures: &[S]) -> Vec<Vec<f64>> {
    let n = signatures.len();
    let mut df: HashMap<u32, u32> = HashMap::new();
    for s in signatures {
        for &(t, _) in &s.borrow().terms {
            *df.entry(t).or_insert(0) += 1;
        }
    }
    let idf = |t: u32| ((n as f64 + 1.0) / (f64::from(df[&t]) + 0.5)).ln();
    let weighted: Vec<Vec<(u32, f64)>> = signatures
        .iter()
        .map(|s| {
            let w: Vec<(u32, f64)> = s
                .borrow()
                .terms
                .iter()
                .map(|&(t, c)| (t, f64::from(c).sqrt() * idf(t)))
                .collect();
            let norm = w.iter().map(|x| x.1 * x.1).sum::<f64>().sqrt().max(1e-12);
            w.into_iter().map(|(t, x)| (t, x / norm)).collect()
        })
        .collect();
    (0..n)
        .into_par_iter()
        .map(|a| {
            (0..n)
                .map(|b| {
                    if a == b {
                        0.0
                    } else {
                        dot(&weighted[a], &weighted[b])
                    }
                })
                .collect()
        })
        .collect()
}

fn dot(x: &[(u32, f64)], y: &[(u32, f64)]) -> f64 {
    let (mut i, mut j, mut s) = (0, 0, 0.0);
    while i < x.len() && j < y.len() {
        match x[i].0.cmp(&y[j].0) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                s += x[i].1 * y[j].1;
                i += 1;
                j += 1;
            }
        }
    }
    s
}

/// The pairs (a < b) to align: each map with its `k` most similar maps (ties to the lower index). Maps
/// whose signature shares nothing with a map tell nothing about it: where a map has fewer than `k` maps
/// it shares terms with, the rest of its `k` are the maps nearest it in the set's order (robots' maps are
/// often listed as they were made) and nearest in size (`sizes`: its wall pixels), taken in turn. So
/// every map has at most `k` partners of its own, and the pairs are at most `k` a map whatever the set.
pub fn pairs(similar: &[Vec<f64>], sizes: &[f64], k: usize) -> Vec<(usize, usize)> {
    let n = similar.len();
    let mut keep = BTreeSet::new();
    for (a, row) in similar.iter().enumerate() {
        let mut alike: Vec<usize> = (0..n).filter(|&b| b != a && row[b] > 0.0).collect();
        alike.sort_by(|&x, &y| row[y].total_cmp(&row[x]).then(x.cmp(&y)));
        let rest = k.saturating_sub(alike.len());
        let fallback = if rest > 0 {
            nearest_in_turn(a, n, sizes, &alike)
        } else {
            Vec::new()
        };
        for &b in alike.iter().take(k).chain(fallback.iter().take(rest)) {
            keep.insert((a.min(b), a.max(b)));
        }
    }
    keep.into_iter().collect()
}

/// The maps other than `a` and those of `taken`, nearest `a` in the set's order and nearest in size
/// (`sizes`, compared by their ratio), in turn: the first of each order, then the second, and so on.
fn nearest_in_turn(a: usize, n: usize, sizes: &[f64], taken: &[usize]) -> Vec<usize> {
    let others: Vec<usize> = (0..n).filter(|&b| b != a && !taken.contains(&b)).collect();
    let by_order = {
        let mut o = others.clone();
        o.sort_by_key(|&b| (b.abs_diff(a), b));
        o
    };
    let by_size = {
        let size = |b: usize| sizes.get(b).copied().unwrap_or(1.0).max(1.0).ln();
        let mut o = others;
        o.sort_by(|&x, &y| {
            let (dx, dy) = ((size(x) - size(a)).abs(), (size(y) - size(a)).abs());
            dx.total_cmp(&dy).then(x.cmp(&y))
        });
        o
    };
    let mut out: Vec<usize> = Vec::with_capacity(by_order.len());
    for (x, y) in by_order.into_iter().zip(by_size) {
        for b in [x, y] {
            if !out.contains(&b) {
                out.push(b);
            }
        }
    }
    out
}

/// The accepted pairs' forest: each map's component (by its lowest map) and its pose there (its pixels to
/// the component root's), chained along the accepted pairs of highest rule value first (a maximum
/// spanning forest). `accepted` holds (a, b, b's pixels to a's, rule value).
pub fn forest(n: usize, accepted: &[(usize, usize, Rigid, f64)]) -> Vec<(usize, Rigid)> {
    let mut order: Vec<usize> = (0..accepted.len()).collect();
    order.sort_by(|&x, &y| {
        accepted[y]
            .3
            .total_cmp(&accepted[x].3)
            .then((accepted[x].0, accepted[x].1).cmp(&(accepted[y].0, accepted[y].1)))
    });
    let mut root: Vec<usize> = (0..n).collect();
    fn find(root: &mut [usize], mut i: usize) -> usize {
        while root[i] != i {
            root[i] = root[root[i]];
            i = root[i];
        }
        i
    }
    // tree[u]: (v, v's pixels to u's).
    let mut tree: Vec<Vec<(usize, Rigid)>> = vec![Vec::new(); n];
    for i in order {
        let (a, b, t, _) = accepted[i];
        let (ra, rb) = (find(&mut root, a), find(&mut root, b));
        if ra != rb {
            root[ra.max(rb)] = ra.min(rb);
            tree[a].push((b, t));
            tree[b].push((a, t.inverse()));
        }
    }
    let mut out: Vec<Option<(usize, Rigid)>> = vec![None; n];
    for start in 0..n {
        if out[start].is_some() {
            continue;
        }
        out[start] = Some((start, Rigid::IDENTITY));
        let mut stack = vec![start];
        while let Some(u) = stack.pop() {
            let pu = out[u].expect("visited").1;
            for &(v, t) in &tree[u] {
                if out[v].is_none() {
                    out[v] = Some((start, pu.after(&t)));
                    stack.push(v);
                }
            }
        }
    }
    out.into_iter()
        .map(|p| p.expect("every map visited"))
        .collect()
}

/// The pairs that close the cycles of the accepted pairs: two maps of one component of the accepted
/// pairs ([`forest`]) not yet aligned whose poses there make them overlap: `share(u, v, v's pixels to
/// u's)` ([`predicted_overlap`]) at least [`CLOSE_OVERLAP`]. At most `per_map` new pairs a map, the
/// largest predicted overlaps first (ties to the lower indices); pairs `a < b`, ascending.
pub fn closing_pairs(
    forest: &[(usize, Rigid)],
    aligned: &BTreeSet<(usize, usize)>,
    share: &(dyn Fn(usize, usize, &Rigid) -> f64 + Sync),
    per_map: usize,
) -> Vec<(usize, usize)> {
    let n = forest.len();
    let mut ranked: Vec<((usize, usize), f64)> = (0..n)
        .into_par_iter()
        .flat_map_iter(|u| {
            (u + 1..n)
                .filter(move |&v| forest[u].0 == forest[v].0 && !aligned.contains(&(u, v)))
                .filter_map(move |v| {
                    // v's pixels to u's through the component's root.
                    let v_to_u = forest[u].1.inverse().after(&forest[v].1);
                    let s = share(u, v, &v_to_u);
                    (s >= CLOSE_OVERLAP).then_some(((u, v), s))
                })
        })
        .collect();
    ranked.sort_by(|x, y| y.1.total_cmp(&x.1).then(x.0.cmp(&y.0)));
    capped(ranked.into_iter().map(|r| r.0), n, per_map)
}

/// How much two prepared maps overlap when `v_to_u` (v's pixels to u's) places them: the larger of the
/// shares of each map's walls (its screening sample) that land on the other's known area.
pub fn predicted_overlap(u: &Prepared, v: &Prepared, v_to_u: &Rigid) -> f64 {
    // Boxes apart: nothing to count.
    if overlap(&u.bounds_in_map(), &v.bounds_in_map(), v_to_u) <= 0.0 {
        return 0.0;
    }
    walls_on(u, v, v_to_u).max(walls_on(v, u, &v_to_u.inverse()))
}

/// The share of `v`'s screening walls that `v_to_u` puts on `u`'s known area (or near its walls).
fn walls_on(u: &Prepared, v: &Prepared, v_to_u: &Rigid) -> f64 {
    let t = v_to_u.applier();
    let inside = v
        .screen_points
        .iter()
        .filter(|&&[x, y]| {
            let (mx, my) = t.apply((f64::from(x) + v.off.0, f64::from(y) + v.off.1));
            u.index(mx - u.off.0, my - u.off.1)
                .is_some_and(|i| u.flags.flags[i] & FLAG_INSIDE != 0)
        })
        .count();
    inside as f64 / v.screen_points.len().max(1) as f64
}

/// The pairs that may join two components of the accepted pairs ([`forest`]): each map with the map of
/// another component most similar to it, not yet aligned, when that similarity is at least
/// [`JOIN_SHARE`] of the highest it has with a map of its own component or one it was already aligned
/// with (accepted or not: a map as alike as one that did not match is no better a candidate). Pairs
/// `a < b`, ascending.
pub fn joining_pairs(
    similar: &[Vec<f64>],
    forest: &[(usize, Rigid)],
    aligned: &BTreeSet<(usize, usize)>,
) -> Vec<(usize, usize)> {
    let n = similar.len();
    let mut out = BTreeSet::new();
    for u in 0..n {
        let key = |v: usize| (u.min(v), u.max(v));
        let own = (0..n)
            .filter(|&v| v != u && (forest[v].0 == forest[u].0 || aligned.contains(&key(v))))
            .map(|v| similar[u][v])
            .fold(0.0, f64::max);
        let best = (0..n)
            .filter(|&v| forest[v].0 != forest[u].0 && !aligned.contains(&key(v)))
            .max_by(|&x, &y| similar[u][x].total_cmp(&similar[u][y]).then(y.cmp(&x)));
        if let Some(v) = best {
            if similar[u][v] > 0.0 && similar[u][v] >= JOIN_SHARE * own {
                out.insert(key(v));
            }
        }
    }
    out.into_iter().collect()
}

/// The share of a map's best similarity within its component that a map of another component must reach
/// to be aligned with it in a joining round.
pub const JOIN_SHARE: f64 = 0.75;

/// `ranked` pairs kept in order while neither map has `per_map` yet; ascending.
fn capped(
    ranked: impl Iterator<Item = (usize, usize)>,
    n: usize,
    per_map: usize,
) -> Vec<(usize, usize)> {
    let mut count = vec![0usize; n];
    let mut out = Vec::new();
    for (a, b) in ranked {
        if count[a] < per_map && count[b] < per_map {
            count[a] += 1;
            count[b] += 1;
            out.push((a, b));
        }
    }
    out.sort_unstable();
    out
}

/// The share of the smaller of two boxes they have in common, once `v`'s is moved by `v_to_u`.
fn overlap(u: &[(f64, f64); 4], v: &[(f64, f64); 4], v_to_u: &Rigid) -> f64 {
    let bbox = |pts: &mut dyn Iterator<Item = (f64, f64)>| {
        pts.fold(
            (f64::MAX, f64::MAX, f64::MIN, f64::MIN),
            |(x0, y0, x1, y1), (x, y)| (x0.min(x), y0.min(y), x1.max(x), y1.max(y)),
        )
    };
    let bu = bbox(&mut u.iter().copied());
    let bv = bbox(&mut v.iter().map(|&p| v_to_u.apply(p)));
    let area = |b: (f64, f64, f64, f64)| (b.2 - b.0).max(0.0) * (b.3 - b.1).max(0.0);
    let common = (
        bu.0.max(bv.0),
        bu.1.max(bv.1),
        bu.2.min(bv.2),
        bu.3.min(bv.3),
    );
    let smaller = area(bu).min(area(bv));
    if smaller <= 0.0 {
        return 0.0;
    }
    area(common) / smaller
}

/// The share of a map's walls that must be predicted to fall on the other map for a closing pair.
pub const CLOSE_OVERLAP: f64 = 0.2;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::OccupancyMap;

    /// Bits of the neighbours named (crate::backend::rules' order: Q B P A Q' B' P' A').
    fn code(bits: &[u8]) -> u8 {
        bits.iter().fold(0, |c, &b| c | (1 << b))
    }

    #[test]
    fn a_corner_code_names_the_quadrant_of_its_walls() {
        // Walls along the top row and the right column: the +p -q quadrant.
        assert_eq!(quadrant(code(&[0, 1, 2, 3, 4])), 3);
        // Along the bottom row and the left column: -p +q.
        assert_eq!(quadrant(code(&[4, 5, 6, 7, 0])), 1);
        assert_eq!(quadrant(code(&[3, 4, 5])), 0);
        assert_eq!(quadrant(code(&[7, 0, 1])), 2);
        // Every side alike, or nothing: no quadrant.
        assert_eq!(quadrant(0xff), 4);
        assert_eq!(quadrant(0), 4);
    }

    /// The map turned by a quarter turn clockwise, its pixels exactly.
    fn quarter_turn(map: &OccupancyMap) -> OccupancyMap {
        let (w, h) = (map.image.width(), map.image.height());
        let px = (0..w)
            .flat_map(|y| (0..h).map(move |x| (x, y)))
            .map(|(x, y)| map.image.get(y, h - 1 - x))
            .collect();
        OccupancyMap::from_image(MapImage::new(h, w, px).unwrap())
    }

    /// The signature is the map's, not its frame's: a quarter turn and a shift keep most of it (its
    /// corner pairs are the same), another office's shares almost nothing with it.
    #[test]
    fn a_turned_and_shifted_map_keeps_its_signature_and_another_office_does_not() {
        let a = OccupancyMap::from_image(crate::map::synthetic::office_map(360, 280, 3).unwrap());
        let turned = quarter_turn(&a);
        // Shifted: 40 unknown columns on its left.
        let (w, h) = (turned.image.width(), turned.image.height());
        let px = (0..h)
            .flat_map(|y| (0..w + 40).map(move |x| (x, y)))
            .map(|(x, y)| {
                if x < 40 {
                    205
                } else {
                    turned.image.get(x - 40, y)
                }
            })
            .collect();
        let moved = OccupancyMap::from_image(MapImage::new(w + 40, h, px).unwrap());
        let other =
            OccupancyMap::from_image(crate::map::synthetic::office_map(360, 280, 11).unwrap());
        let sigs: Vec<Signature> = [&a, &moved, &other]
            .iter()
            .map(|m| Signature::of(m).unwrap())
            .collect();
        assert!(sigs[0].corners >= 20, "{} corners", sigs[0].corners);
        let s = similarities(&sigs);
        // Measured 0.80 and 0.01: not 1, since the detector's grid is anchored at the middle of each
        // map's known area, which the shift's margin moves by a few pixels, and a few corners change.
        assert!(s[0][1] > 0.6, "turned and shifted: {:.3}", s[0][1]);
        assert!(s[0][2] < 0.2 * s[0][1], "{:.3} vs {:.3}", s[0][2], s[0][1]);
        assert_eq!(s[0][1], s[1][0]);
        assert_eq!(s[2][2], 0.0);
    }

    #[test]
    fn each_map_keeps_its_most_similar_maps() {
        let s = vec![
            vec![0.0, 0.9, 0.1, 0.2],
            vec![0.9, 0.0, 0.3, 0.1],
            vec![0.1, 0.3, 0.0, 0.8],
            vec![0.2, 0.1, 0.8, 0.0],
        ];
        let sizes = [1.0; 4];
        assert_eq!(pairs(&s, &sizes, 1), vec![(0, 1), (2, 3)]);
        assert_eq!(pairs(&s, &sizes, 2), vec![(0, 1), (0, 3), (1, 2), (2, 3)]);
        assert_eq!(pairs(&s, &sizes, 9).len(), 6);
    }

    #[test]
    fn a_map_that_shares_nothing_gets_its_neighbours_in_order_and_in_size_not_every_map() {
        // Map 3 shares nothing with any of 8 maps: not all of them, but its neighbour in the set's order
        // (2 or 4) and the map nearest its size (7), in turn.
        let n = 8;
        let mut s: Vec<Vec<f64>> = (0..n)
            .map(|a: usize| {
                (0..n)
                    .map(|b| {
                        if a != b && a != 3 && b != 3 {
                            1.0 / (1.0 + a.abs_diff(b) as f64)
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect();
        let sizes = [500.0, 600.0, 700.0, 5000.0, 800.0, 900.0, 1000.0, 4000.0];
        let of3: Vec<(usize, usize)> = pairs(&s, &sizes, 3)
            .into_iter()
            .filter(|p| p.0 == 3 || p.1 == 3)
            .collect();
        assert_eq!(of3, vec![(2, 3), (3, 4), (3, 7)]);
        // A map sharing terms with only one map: that one first, then the nearest in turn.
        s[3][6] = 0.5;
        s[6][3] = 0.5;
        let of3: Vec<(usize, usize)> = pairs(&s, &sizes, 3)
            .into_iter()
            .filter(|p| p.0 == 3 || p.1 == 3)
            .collect();
        assert_eq!(of3, vec![(2, 3), (3, 6), (3, 7)]);
    }

    proptest::proptest! {
        /// Whatever the similarities (maps that share nothing, ties, a few alike) and sizes, at most
        /// `k` pairs a map are chosen, each of two distinct maps, and every map has one when it can.
        #[test]
        fn the_first_round_is_at_most_k_pairs_a_map(
            n in 2usize..40,
            k in 1usize..6,
            seed in 0u64..1000,
            zero_share in 0.0f64..1.0,
        ) {
            let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let mut next = || {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64
            };
            let mut s = vec![vec![0.0; n]; n];
            let pairs_of: Vec<(usize, usize)> =
                (0..n).flat_map(|a| (a + 1..n).map(move |b| (a, b))).collect();
            for (a, b) in pairs_of {
                let v = if next() < zero_share { 0.0 } else { next() };
                (s[a][b], s[b][a]) = (v, v);
            }
            let sizes: Vec<f64> = (0..n).map(|_| 1.0 + 1e4 * next()).collect();
            let chosen = pairs(&s, &sizes, k);
            proptest::prop_assert!(chosen.len() <= k * n, "{} pairs for {n} maps", chosen.len());
            proptest::prop_assert!(chosen.iter().all(|&(a, b)| a < b && b < n));
            for m in 0..n {
                proptest::prop_assert!(chosen.iter().any(|&(a, b)| a == m || b == m));
            }
        }
    }

    fn shift(tx: f64, ty: f64) -> Rigid {
        Rigid {
            theta_deg: 0.0,
            tx,
            ty,
        }
    }

    /// 0-1 and 1-2 accepted put 2 beside 0: that pair closes the cycle; a pair already aligned, a map of
    /// another component or one predicted apart does not, and no map takes more than its share.
    #[test]
    fn the_pairs_that_close_cycles_are_those_the_accepted_ones_make_overlap() {
        // b's pixels to a's: map 1 lies 100 px right of map 0, map 2 100 px right of map 1.
        let accepted = [
            (0, 1, shift(100.0, 0.0), 5.0),
            (1, 2, shift(100.0, 0.0), 5.0),
            (3, 4, shift(0.0, 0.0), 5.0),
        ];
        let forest = forest(6, &accepted);
        assert_eq!(forest[2].0, 0);
        assert_eq!(forest[4].0, 3);
        assert_eq!(forest[5].0, 5);
        // Map 2 in map 0's pixels: 200 px right.
        let p = forest[0].1.inverse().after(&forest[2].1);
        assert!((p.tx - 200.0).abs() < 1e-9 && p.ty.abs() < 1e-9, "{p:?}");
        // Overlap: maps 300 px wide, so within 300 px of each other.
        let share = |u: usize, v: usize, t: &Rigid| {
            let _ = (u, v);
            (1.0 - t.tx.abs() / 300.0).max(0.0)
        };
        let aligned: BTreeSet<(usize, usize)> = [(0, 1), (1, 2), (3, 4)].into_iter().collect();
        assert_eq!(closing_pairs(&forest, &aligned, &share, 4), vec![(0, 2)]);
        assert!(closing_pairs(&forest, &aligned, &share, 0).is_empty());
        let mut all = aligned.clone();
        all.insert((0, 2));
        assert!(closing_pairs(&forest, &all, &share, 4).is_empty());
        // Predicted apart.
        let far = [
            (0, 1, shift(280.0, 0.0), 5.0),
            (1, 2, shift(280.0, 0.0), 5.0),
        ];
        assert!(closing_pairs(&super::forest(3, &far), &aligned, &share, 4).is_empty());
    }

    #[test]
    fn a_map_is_joined_with_its_most_similar_map_of_another_component_only_when_alike_enough() {
        // Maps 0-1 one component, 2 and 3 alone.
        let forest = forest(4, &[(0, 1, shift(0.0, 0.0), 5.0)]);
        let aligned: BTreeSet<(usize, usize)> = [(0, 1)].into_iter().collect();
        let s = vec![
            vec![0.0, 0.4, 0.35, 0.1],
            vec![0.4, 0.0, 0.1, 0.05],
            vec![0.35, 0.1, 0.0, 0.0],
            vec![0.1, 0.05, 0.0, 0.0],
        ];
        // 0: 0.35 >= 0.75 * 0.4 -> (0, 2); 1: 0.1 < 0.3 -> nothing; 2: its best (0) -> (0, 2);
        // 3: best 0.1 with nothing of its own to compare -> (0, 3).
        assert_eq!(joining_pairs(&s, &forest, &aligned), vec![(0, 2), (0, 3)]);
    }
}
