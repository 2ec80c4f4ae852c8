//! Synthetic pairs with exact truth, made from any map: two overlapping parts of it, one turned by a
//! random angle and shifted, with optional speckle. `merge-eval --synthetic` runs the merger over them,
//! and the tests use them as a property test.
//!
//! How a pair is cut: a random direction `u`; the known pixels' projections on `u` span `[lo, hi]`; A
//! keeps the pixels projecting below `lo + w`, B those above `hi - w`, with `w = (hi - lo) / (2 -
//! overlap)`, so the band both keep is `overlap` of each part's extent along `u`. A is cropped to its
//! known area; B is turned about its centre by a random angle into a square canvas with a random margin.
//! Both are written with map_server's values (0 occupied, 254 free, 205 unknown).
//!
//! Beside this file: the repetitive layouts (`layouts.rs`), the small windows (`crops.rs`), the symmetric
//! halls (`symmetric.rs`) and robots exploring a building (`explore.rs`).

mod crops;
mod explore;
mod layouts;
mod symmetric;

pub use crops::{synthetic_crops, CropSpec};
pub use explore::{explore, Exploration};
pub use layouts::{doors, grid_rooms, warehouse, Layout, LayoutKind};
pub use symmetric::{
    extra_room_door, extra_room_points, hall_pixel, symmetric_plan, SymmetricKind,
};

use crate::map::states::{CellState, ClassTable, FREE, OCCUPIED, UNKNOWN};
use crate::map::synthetic::Rng;
use crate::map::{MapImage, OccupancyMap};
use crate::measure::pairs::TruePair;
use crate::merge::transform::Rigid;

/// How to cut a pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SyntheticSpec {
    /// Share of each part's extent (along the cut direction) that the other part also holds, in (0, 1).
    pub overlap: f64,
    /// Probability that a free pixel of either part turns occupied (sensor speckle).
    pub noise: f64,
}

/// A pair cut from one map.
#[derive(Clone, Debug)]
pub struct SyntheticPair {
    /// The reference part.
    pub a: OccupancyMap,
    /// The moved part.
    pub b: OccupancyMap,
    /// B's pixels to A's, exact.
    pub truth: Rigid,
    /// Points of B where an estimate is checked (its known area's bounding box corners and centre; for
    /// a bent pair, points of the overlap).
    pub check_points: Vec<(f64, f64)>,
    /// Where the check points truly are in A (the truth applied to them, except in a bent pair).
    pub true_points: Vec<(f64, f64)>,
    /// Largest RMS error over the check points an accurate estimate may have, pixels.
    pub rms_limit_px: f64,
    /// With a lattice ([`PairShape::lattice`]): the fewest cells that contradict each other (a wall on
    /// free space) when B is misplaced by a shift of the lattice: 0 when nothing in the overlap breaks
    /// the period, so no merger can tell the true pose from a wrong one.
    pub alias_contradiction: Option<u64>,
    /// Where A's pixel (0, 0) lies in the map the pair was cut from: a point of the source is at
    /// `p - a_origin` in A, and at `truth`'s inverse of that in B.
    pub a_origin: (f64, f64),
}

/// How a pair is shaped beyond its cut ([`synthetic_pair_with`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PairShape {
    /// B bent as SLAM drift bends a map: its heading drifts by this many degrees per 1000 px along the cut
    /// direction, away from the overlap's centre (0: rigid).
    pub bend_deg_per_kpx: f64,
    /// The source's lattice of repeats (pixels), to measure [`SyntheticPair::alias_contradiction`].
    pub lattice: Vec<(f64, f64)>,
    /// Share of B's rooms left unexplored: discs of its known area turned unknown.
    pub unexplored: f64,
    /// Where each part lies along the cut direction, instead of the two ends overlapping by the spec's
    /// overlap: shares of the known area, in the order of the known pixels' projections.
    pub window: Option<Window>,
}

/// Two windows of a map's known area along the cut direction: each a range of shares (0 to 1) of the
/// known pixels in the order of their projections, so `(0.2, 0.7)` holds half the known area.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// A's range.
    pub a: (f64, f64),
    /// B's range.
    pub b: (f64, f64),
    /// A source pixel both ranges are counted from: each is shifted by the share of the known area
    /// before it, so `(-0.3, 0.2)` holds half the area with the pixel at three fifths of it.
    pub around: Option<(f64, f64)>,
}

impl Window {
    /// The share of the known area both windows hold.
    pub fn shared(&self) -> f64 {
        (self.a.1.min(self.b.1) - self.a.0.max(self.b.0)).max(0.0)
    }
}

/// Fewest contradicting cells that count as breaking the period ([`SyntheticPair::alias_contradiction`]).
pub const MIN_ALIAS_CONTRADICTION: u64 = 40;

/// Smallest known extent (pixels, along the cut direction) a source must have.
pub const MIN_EXTENT: f64 = 64.0;

/// Largest canvas side of a part, pixels (B's canvas holds its part's diagonal).
pub const MAX_PART_SIDE: f64 = 16384.0;

/// A pair cut from `source` with `spec`, deterministic in `seed`; `None` when the map's known area is
/// too small (under [`MIN_EXTENT`] along the cut) or too large (a part over [`MAX_PART_SIDE`]).
pub fn synthetic_pair(
    source: &OccupancyMap,
    spec: &SyntheticSpec,
    seed: u64,
) -> Option<SyntheticPair> {
    synthetic_pair_with(source, spec, &PairShape::default(), seed)
}

/// [`synthetic_pair`], B bent and partly unexplored as `shape` says, and the pair's identifiability
/// measured against the source's lattice. A rigid pair with no lattice is exactly [`synthetic_pair`]'s.
pub fn synthetic_pair_with(
    source: &OccupancyMap,
    spec: &SyntheticSpec,
    shape: &PairShape,
    seed: u64,
) -> Option<SyntheticPair> {
    synthetic_pair_from(source, source, spec, shape, seed)
}

/// [`synthetic_pair_with`], B's part read from `copy`: the same place in the same frame (the same size)
/// seen another time, as a floor plan's furnished copy is; the cut and the truth are the source's. `None`
/// also when the two differ in size.
pub fn synthetic_pair_from(
    source: &OccupancyMap,
    copy: &OccupancyMap,
    spec: &SyntheticSpec,
    shape: &PairShape,
    seed: u64,
) -> Option<SyntheticPair> {
    let classes = ClassTable::new(&source.thresholds);
    let img = &source.image;
    let (w, h) = (img.width() as usize, img.height() as usize);
    if (copy.image.width(), copy.image.height()) != (img.width(), img.height()) {
        return None;
    }
    let state = |x: usize, y: usize| classes.state(img.pixels()[y * w + x]);
    let copy_classes = ClassTable::new(&copy.thresholds);
    let state_b = |x: usize, y: usize| copy_classes.state(copy.image.pixels()[y * w + x]);
    let mut rng = Rng::new(seed);
    let unit = |r: &mut Rng| f64::from(r.range(0, 1 << 24)) / f64::from(1u32 << 24);
    let phi = unit(&mut rng) * std::f64::consts::PI;
    let (su, cu) = phi.sin_cos();
    let proj = |x: f64, y: f64| x * cu + y * su;
    let (lo, hi) = known_extent(&state, (w, h), &proj);
    if hi - lo < MIN_EXTENT {
        return None;
    }
    let [a_lo, a_hi, b_lo, b_hi] = match &shape.window {
        None => {
            let overlap = spec.overlap.clamp(0.01, 0.99);
            let part = (hi - lo) / (2.0 - overlap);
            [f64::MIN, lo + part, hi - part, f64::MAX]
        }
        Some(win) => window_bounds(&state, (w, h), &proj, win)?,
    };
    let in_a = |x: usize, y: usize| (a_lo..a_hi).contains(&proj(x as f64, y as f64));
    let in_b = |x: usize, y: usize| (b_lo..b_hi).contains(&proj(x as f64, y as f64));
    let bbox = |keep: &dyn Fn(usize, usize) -> bool| {
        let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
        for y in 0..h {
            for x in 0..w {
                if keep(x, y) && state(x, y) != CellState::Unknown {
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
                }
            }
        }
        (x0, y0, x1.max(x0), y1.max(y0))
    };
    let value = |s: CellState, r: &mut Rng| written(s, spec.noise, r);
    // A: its part, cropped to its known area.
    let (ax0, ay0, ax1, ay1) = bbox(&in_a);
    let (aw, ah) = (ax1 - ax0, ay1 - ay0);
    if aw == 0 || ah == 0 || aw as f64 > MAX_PART_SIDE || ah as f64 > MAX_PART_SIDE {
        return None;
    }
    let mut a_px = vec![UNKNOWN; aw * ah];
    for y in 0..ah {
        for x in 0..aw {
            let (sx, sy) = (x + ax0, y + ay0);
            if in_a(sx, sy) {
                a_px[y * aw + x] = value(state(sx, sy), &mut rng);
            }
        }
    }
    // B: its part turned by theta about its centre into a square canvas, bent about the overlap's centre.
    let margin = f64::from(rng.range(4, 48));
    let theta = unit(&mut rng) * 360.0;
    let bend = shape.bend_deg_per_kpx.to_radians() / 1000.0;
    let centre = if bend != 0.0 {
        known_centre(&state, (w, h), &|x, y| in_a(x, y) && in_b(x, y))
    } else {
        (0.0, 0.0)
    };
    // The heading drifts with the distance along the cut from the overlap's centre: a turn about the
    // centre growing linearly, so the displacement grows with the square of the distance (as odometry
    // drift does).
    let warp = |p: (f64, f64)| {
        if bend == 0.0 {
            return p;
        }
        let d = (p.0 - centre.0, p.1 - centre.1);
        let (s, c) = (bend * (d.0 * cu + d.1 * su)).sin_cos();
        (centre.0 + c * d.0 - s * d.1, centre.1 + s * d.0 + c * d.1)
    };
    let (mut b_px, side, to_source, (kx0, ky0, kx1, ky1)) = turned(
        &state_b,
        (w, h),
        &in_b,
        bbox(&in_b),
        theta,
        margin,
        &warp,
        &mut |s| value(s, &mut rng),
    )?;
    if shape.unexplored > 0.0 {
        unexplore(&mut b_px, side, shape.unexplored, &mut rng);
    }
    let rigid = Rigid {
        tx: to_source.tx - ax0 as f64,
        ty: to_source.ty - ay0 as f64,
        ..to_source
    }
    .normalized();
    let (truth, check_points, true_points, rms_limit_px) = if bend == 0.0 {
        let check = box_points(kx0, ky0, kx1, ky1);
        let truth_points = check.iter().map(|&p| rigid.apply(p)).collect();
        (rigid, check, truth_points, SYNTHETIC_RMS_LIMIT_PX)
    } else {
        let b = (b_px.as_slice(), side);
        bent_truth(
            b,
            &|p| warp(to_source.apply(p)),
            &state,
            (w, h),
            &in_a,
            (ax0, ay0),
        )?
    };
    let alias_contradiction = (!shape.lattice.is_empty())
        .then(|| alias_contradiction(&state, (w, h), &in_a, &in_b, &shape.lattice));
    Some(SyntheticPair {
        a: map_of(aw, ah, a_px)?,
        b: map_of(side, side, b_px)?,
        truth,
        check_points,
        true_points,
        rms_limit_px,
        alias_contradiction,
        a_origin: (ax0 as f64, ay0 as f64),
    })
}

/// Shares of the known area each part of a plan-vs-furnished pair holds ([`furnished_pair`]).
pub const FURNISHED_PART: (f64, f64) = (0.36, 0.64);

/// Least share of the known area both parts of a plan-vs-furnished pair hold.
pub const FURNISHED_MIN_SHARED: f64 = 0.15;

/// A plan-vs-furnished pair: A a window of `plan`, B a window of `furnished` (the same place in the same
/// frame with furniture drawn in: a second session whose appearance changed), each holding 36 to 64% of
/// the known area along a random direction and both at least 15% of it, B turned by a random angle;
/// deterministic in `seed`, the truth exact (both share one frame). `None` as [`synthetic_pair_from`].
pub fn furnished_pair(
    plan: &OccupancyMap,
    furnished: &OccupancyMap,
    noise: f64,
    seed: u64,
) -> Option<SyntheticPair> {
    let mut rng = Rng::new(seed ^ 0x5eed_f00d);
    let mut unit = || f64::from(rng.range(0, 1 << 24)) / f64::from(1u32 << 24);
    let (lo, hi) = FURNISHED_PART;
    let (fa, fb) = (lo + unit() * (hi - lo), lo + unit() * (hi - lo));
    let a0 = unit() * (1.0 - fa);
    // B placed at random until the two share enough; else B from where A starts.
    let window = (0..64)
        .map(|_| unit() * (1.0 - fb))
        .map(|b0| Window {
            a: (a0, a0 + fa),
            b: (b0, b0 + fb),
            around: None,
        })
        .find(|w| w.shared() >= FURNISHED_MIN_SHARED)
        .unwrap_or(Window {
            a: (a0, a0 + fa),
            b: (a0, a0 + fb),
            around: None,
        });
    let shape = PairShape {
        window: Some(window),
        ..PairShape::default()
    };
    let spec = SyntheticSpec {
        overlap: window.shared(),
        noise,
    };
    synthetic_pair_from(plan, furnished, &spec, &shape, seed)
}

/// A pair of a symmetric plan ([`symmetric_plan`]): two windows that both hold its hall, each 45-70% of
/// the known area with the hall's centre a quarter to three quarters of the way across it, B turned by a
/// random angle; deterministic in `seed`. `None` as [`synthetic_pair_with`].
pub fn hall_pair(kind: SymmetricKind, seed: u64) -> Option<SyntheticPair> {
    let (image, hall) = symmetric_plan(kind, seed).ok()?;
    let plan = OccupancyMap::from_image(image);
    let mut rng = Rng::new(seed ^ 0x4a11_5eed);
    let mut unit = || f64::from(rng.range(0, 1 << 24)) / f64::from(1u32 << 24);
    let mut part = || {
        let (f, r) = (0.45 + 0.25 * unit(), 0.25 + 0.5 * unit());
        (-r * f, (1.0 - r) * f)
    };
    let window = Window {
        a: part(),
        b: part(),
        around: Some(hall),
    };
    let shape = PairShape {
        window: Some(window),
        ..PairShape::default()
    };
    let spec = SyntheticSpec {
        overlap: window.shared(),
        noise: 0.0,
    };
    synthetic_pair_with(&plan, &spec, &shape, seed)
}

/// A [`hall_pair`] of a plan with an extra room whose two windows both hold the room whole
/// ([`extra_room_in_both`]): the first of the seeds drawn from `seed` that gives one (a few dozen at
/// most), with the seed it was drawn with. `None` without an extra room or when none of them does.
pub fn hall_pair_holding_room(kind: SymmetricKind, seed: u64) -> Option<(SyntheticPair, u64)> {
    if !kind.extra_room {
        return None;
    }
    (0..64u64)
        .map(|i| seed.wrapping_add(i.wrapping_mul(0x9e37_79b9)))
        .find_map(|s| {
            hall_pair(kind, s)
                .filter(|p| extra_room_in_both(kind, s, p))
                .map(|p| (p, s))
        })
}

/// Whether both windows of `pair`, a [`hall_pair`] of `kind` and `seed`, hold the plan's extra room
/// whole ([`extra_room_points`] all free in A and in B): the pairs whose one asymmetric detail lies in
/// the overlap, which a merger can tell from their turns. `false` without an extra room.
pub fn extra_room_in_both(kind: SymmetricKind, seed: u64, pair: &SyntheticPair) -> bool {
    let Some(points) = extra_room_points(kind, seed) else {
        return false;
    };
    let to_b = pair.truth.inverse();
    let free = |m: &OccupancyMap, p: (f64, f64)| state_at(m, p) == Some(CellState::Free);
    points.iter().all(|&p| {
        let in_a = plan_in_a(kind, seed, pair, p);
        free(&pair.a, in_a) && free(&pair.b, to_b.apply(in_a))
    })
}

/// The state of `m`'s pixel nearest `(x, y)`; `None` outside the map.
fn state_at(m: &OccupancyMap, (x, y): (f64, f64)) -> Option<CellState> {
    let (x, y) = (x.round(), y.round());
    let inside =
        x >= 0.0 && y >= 0.0 && x < f64::from(m.image.width()) && y < f64::from(m.image.height());
    inside.then(|| ClassTable::new(&m.thresholds).state(m.image.get(x as u32, y as u32)))
}

/// Where a point of `kind`'s plan for `seed` (from the hall's centre, as [`extra_room_points`] gives
/// it) lies in `pair`'s window A.
fn plan_in_a(
    kind: SymmetricKind,
    seed: u64,
    pair: &SyntheticPair,
    (u, v): (f64, f64),
) -> (f64, f64) {
    let hall = hall_pixel(kind, seed);
    (hall.0 + u - pair.a_origin.0, hall.1 + v - pair.a_origin.1)
}

/// Whether every turn of `pair`'s plan by a whole wing lays the extra room's door where the other
/// window has seen ([`extra_room_door`]): A has seen the door's place turned by the wing, or B the
/// place turned back. Only then do the maps themselves contradict each turned pose. Where neither
/// has, the turned pose lays each map's room on the other's unknown, and the pair is exactly what a
/// building with a room at both places would give: no merger can tell its poses apart. `false`
/// without an extra room.
pub fn extra_room_turns_seen(kind: SymmetricKind, seed: u64, pair: &SyntheticPair) -> bool {
    let Some(door) = extra_room_door(kind, seed) else {
        return false;
    };
    let to_b = pair.truth.inverse();
    let seen =
        |m: &OccupancyMap, p: (f64, f64)| state_at(m, p).is_some_and(|s| s != CellState::Unknown);
    let in_a = |p: (f64, f64)| plan_in_a(kind, seed, pair, p);
    let turned = |a: f64| {
        let (s, c) = a.sin_cos();
        (c * door.0 - s * door.1, s * door.0 + c * door.1)
    };
    let n = usize::from(kind.wings.clamp(2, 8));
    (1..n).all(|j| {
        let a = std::f64::consts::TAU * j as f64 / n as f64;
        seen(&pair.a, in_a(turned(a))) || seen(&pair.b, to_b.apply(in_a(turned(-a))))
    })
}

/// The projections bounding `win`'s two windows: `[a_lo, a_hi, b_lo, b_hi]`, from the known pixels'
/// projections in order (a window reaching share 0 or 1 is open at that end). `None` when there are too
/// few known pixels to split.
fn window_bounds(
    state: &dyn Fn(usize, usize) -> CellState,
    (w, h): (usize, usize),
    proj: &dyn Fn(f64, f64) -> f64,
    win: &Window,
) -> Option<[f64; 4]> {
    let mut p: Vec<f64> = Vec::new();
    for y in 0..h {
        for x in 0..w {
            if state(x, y) != CellState::Unknown {
                p.push(proj(x as f64, y as f64));
            }
        }
    }
    if p.len() < 64 {
        return None;
    }
    p.sort_unstable_by(f64::total_cmp);
    let origin = win.around.map_or(0.0, |(x, y)| {
        p.partition_point(|&v| v < proj(x, y)) as f64 / p.len() as f64
    });
    let at = |q: f64| match q + origin {
        q if q <= 0.0 => f64::MIN,
        q if q >= 1.0 => f64::MAX,
        q => p[((q * p.len() as f64) as usize).min(p.len() - 1)],
    };
    Some([at(win.a.0), at(win.a.1), at(win.b.0), at(win.b.1)])
}

/// Turns discs of the known area of a `side` x `side` canvas unknown until about `share` of it is:
/// rooms a robot has not entered yet.
fn unexplore(px: &mut [u8], side: usize, share: f64, rng: &mut Rng) {
    let known: Vec<usize> = (0..px.len()).filter(|&i| px[i] != UNKNOWN).collect();
    let target = (share * known.len() as f64) as usize;
    let mut erased = 0usize;
    for _ in 0..64 {
        if erased >= target || known.is_empty() {
            break;
        }
        let c = known[rng.range(0, known.len() as u32) as usize];
        let (cx, cy) = ((c % side) as i64, (c / side) as i64);
        let r = i64::from(rng.range(20, 50));
        for y in (cy - r).max(0)..(cy + r + 1).min(side as i64) {
            for x in (cx - r).max(0)..(cx + r + 1).min(side as i64) {
                let i = y as usize * side + x as usize;
                if (x - cx).pow(2) + (y - cy).pow(2) <= r * r && px[i] != UNKNOWN {
                    px[i] = UNKNOWN;
                    erased += 1;
                }
            }
        }
    }
}

/// The fewest cells of B's part and A's part that contradict each other (one occupied, the other free)
/// when B is misplaced by a combination of the lattice (up to 3 steps of each vector) that keeps at
/// least a quarter of the true overlap: 0 when some misplacement contradicts nothing.
fn alias_contradiction(
    state: &dyn Fn(usize, usize) -> CellState,
    (w, h): (usize, usize),
    in_a: &dyn Fn(usize, usize) -> bool,
    in_b: &dyn Fn(usize, usize) -> bool,
    lattice: &[(f64, f64)],
) -> u64 {
    let count = |dx: i64, dy: i64| {
        let (mut overlap, mut contra) = (0u64, 0u64);
        for y in 0..h as i64 {
            let ty = y + dy;
            if ty < 0 || ty >= h as i64 {
                continue;
            }
            for x in 0..w as i64 {
                let tx = x + dx;
                if tx < 0 || tx >= w as i64 || !in_b(x as usize, y as usize) {
                    continue;
                }
                let (sb, ta) = (tx as usize, ty as usize);
                if !in_a(sb, ta) {
                    continue;
                }
                let (b, a) = (state(x as usize, y as usize), state(sb, ta));
                if b == CellState::Unknown || a == CellState::Unknown {
                    continue;
                }
                overlap += 1;
                contra += u64::from(b != a);
            }
        }
        (overlap, contra)
    };
    let (true_overlap, _) = count(0, 0);
    let steps: Vec<i64> = (-3..=3).collect();
    let mut shifts: Vec<(i64, i64)> = Vec::new();
    let (l1, l2) = (lattice[0], lattice.get(1).copied().unwrap_or((0.0, 0.0)));
    for &i in &steps {
        for &j in &steps {
            if (i, j) == (0, 0) || (lattice.len() < 2 && j != 0) {
                continue;
            }
            let d = (
                (i as f64 * l1.0 + j as f64 * l2.0).round() as i64,
                (i as f64 * l1.1 + j as f64 * l2.1).round() as i64,
            );
            shifts.push(d);
        }
    }
    shifts
        .iter()
        .filter_map(|&(dx, dy)| {
            let (overlap, contra) = count(dx, dy);
            (4 * overlap >= true_overlap).then_some(contra)
        })
        .min()
        .unwrap_or(u64::MAX)
}

/// A cell's value as written (map_server's), a free cell turned occupied with probability `noise`.
fn written(s: CellState, noise: f64, rng: &mut Rng) -> u8 {
    match s {
        CellState::Free if noise > 0.0 && rng.chance(noise) => OCCUPIED,
        CellState::Free => FREE,
        CellState::Occupied => OCCUPIED,
        CellState::Unknown => UNKNOWN,
    }
}

/// A box's corners and centre: where estimates are checked.
fn box_points(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<(f64, f64)> {
    vec![
        (x0, y0),
        (x1, y0),
        (x0, y1),
        (x1, y1),
        ((x0 + x1) / 2.0, (y0 + y1) / 2.0),
    ]
}

/// The pixels of a `w` x `h` source for which `keep` holds, within the box `(x0, y0, x1, y1)`, turned by
/// `theta` degrees about the box's centre into a square canvas holding its diagonal and `margin` on each
/// side (each canvas point's source point passed through `warp`: the identity for a rigid cut), each
/// cell's value from its state by `value`: the canvas, its side, the transform from its pixels
/// to the source's, and its known area's bounding box (`None` when it holds nothing known or is too large).
// The cut's geometry, the warp and the value of a cell are each the caller's: one function for the
// pairs, the bent pairs, the small windows and the sets.
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
fn turned(
    state: &dyn Fn(usize, usize) -> CellState,
    (w, h): (usize, usize),
    keep: &dyn Fn(usize, usize) -> bool,
    (bx0, by0, bx1, by1): (usize, usize, usize, usize),
    theta: f64,
    margin: f64,
    warp: &dyn Fn((f64, f64)) -> (f64, f64),
    value: &mut dyn FnMut(CellState) -> u8,
) -> Option<(Vec<u8>, usize, Rigid, (f64, f64, f64, f64))> {
    let cb = (
        (bx0 + bx1) as f64 / 2.0 - 0.5,
        (by0 + by1) as f64 / 2.0 - 0.5,
    );
    let diag = ((bx1 - bx0) as f64).hypot((by1 - by0) as f64);
    let side = (diag + 2.0 * margin).ceil();
    if side > MAX_PART_SIDE {
        return None;
    }
    let side = side as usize;
    let cq = ((side as f64 - 1.0) / 2.0, (side as f64 - 1.0) / 2.0);
    // The canvas pixel q lies at source point R(theta) (q - cq) + cb.
    let rot = Rigid {
        theta_deg: theta,
        tx: 0.0,
        ty: 0.0,
    };
    let r_cq = rot.apply(cq);
    let to_source = Rigid {
        theta_deg: theta,
        tx: cb.0 - r_cq.0,
        ty: cb.1 - r_cq.1,
    };
    let mut px = vec![UNKNOWN; side * side];
    let (mut kx0, mut ky0, mut kx1, mut ky1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for y in 0..side {
        for x in 0..side {
            let (sx, sy) = warp(to_source.apply((x as f64, y as f64)));
            let (sx, sy) = (sx.round(), sy.round());
            if sx < 0.0 || sy < 0.0 || sx >= w as f64 || sy >= h as f64 {
                continue;
            }
            let (sx, sy) = (sx as usize, sy as usize);
            if keep(sx, sy) {
                let s = state(sx, sy);
                px[y * side + x] = value(s);
                if s != CellState::Unknown {
                    let (fx, fy) = (x as f64, y as f64);
                    (kx0, ky0, kx1, ky1) = (kx0.min(fx), ky0.min(fy), kx1.max(fx), ky1.max(fy));
                }
            }
        }
    }
    (kx1 >= kx0).then_some((px, side, to_source, (kx0, ky0, kx1, ky1)))
}

/// One map of a synthetic set: a window of the source turned and shifted, with its exact pose.
#[derive(Clone, Debug)]
pub struct SyntheticCrop {
    /// The map.
    pub map: OccupancyMap,
    /// Its pixels to the source's, exact.
    pub pose: Rigid,
    /// Points of it (its known area's bounding box corners and centre) where an estimate is checked.
    pub check_points: Vec<(f64, f64)>,
}

/// `n` overlapping maps cut from `source`, deterministic in `seed`: windows on a jittered grid over its
/// known area (each about 1.8 grid steps across, so neighbours share about 45% of a window), each turned
/// by a random angle into a square canvas with a random margin, with speckle at `noise`. `None` when `n`
/// is 0, the source's known area is under [`MIN_EXTENT`] across, a window holds nothing known or would
/// exceed [`MAX_PART_SIDE`].
pub fn synthetic_set(
    source: &OccupancyMap,
    n: usize,
    noise: f64,
    seed: u64,
) -> Option<Vec<SyntheticCrop>> {
    let classes = ClassTable::new(&source.thresholds);
    let img = &source.image;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let state = |x: usize, y: usize| classes.state(img.pixels()[y * w + x]);
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for y in 0..h {
        for x in 0..w {
            if state(x, y) != CellState::Unknown {
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
            }
        }
    }
    if n == 0 || x1 < x0 + MIN_EXTENT as usize || y1 < y0 + MIN_EXTENT as usize {
        return None;
    }
    let (ew, eh) = ((x1 - x0) as f64, (y1 - y0) as f64);
    let cols = ((n as f64 * ew / eh).sqrt().round() as usize).clamp(1, n);
    let rows = n.div_ceil(cols);
    let (sx, sy) = (ew / cols as f64, eh / rows as f64);
    let mut rng = Rng::new(seed);
    let unit = |r: &mut Rng| f64::from(r.range(0, 1 << 24)) / f64::from(1u32 << 24);
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let (c, r) = (k % cols, k / cols);
        // The window's centre jittered by up to a fifth of a step.
        let cx = x0 as f64 + (c as f64 + 0.5 + 0.4 * (unit(&mut rng) - 0.5)) * sx;
        let cy = y0 as f64 + (r as f64 + 0.5 + 0.4 * (unit(&mut rng) - 0.5)) * sy;
        let (hw, hh) = (0.9 * sx.max(sy), 0.9 * sx.max(sy));
        let clampu = |v: f64, hi: usize| v.clamp(0.0, hi as f64) as usize;
        let b = (
            clampu(cx - hw, w),
            clampu(cy - hh, h),
            clampu(cx + hw, w),
            clampu(cy + hh, h),
        );
        let keep = |x: usize, y: usize| x >= b.0 && x < b.2 && y >= b.1 && y < b.3;
        let margin = f64::from(rng.range(4, 48));
        let theta = unit(&mut rng) * 360.0;
        let value = &mut |s: CellState| written(s, noise, &mut rng);
        let (px, side, pose, (kx0, ky0, kx1, ky1)) =
            turned(&state, (w, h), &keep, b, theta, margin, &|p| p, value)?;
        out.push(SyntheticCrop {
            map: OccupancyMap::from_image(MapImage::new(side as u32, side as u32, px).ok()?),
            pose: pose.normalized(),
            check_points: box_points(kx0, ky0, kx1, ky1),
        });
    }
    Some(out)
}

impl SyntheticCrop {
    /// This map onto `dst`, another of its set, as a pair set's entry named `src` -> `dst_name`: the
    /// exact transform between their poses, the synthetic limits, and this map's check points with where
    /// the truth puts them.
    pub fn true_pair(&self, dst: &SyntheticCrop, src: &str, dst_name: &str) -> TruePair {
        let t = dst.pose.inverse().after(&self.pose);
        TruePair {
            src: src.to_string(),
            dst: dst_name.to_string(),
            building: "synthetic".to_string(),
            theta_deg: t.theta_deg,
            tx: t.tx,
            ty: t.ty,
            rms_limit_px: SYNTHETIC_RMS_LIMIT_PX,
            rot_limit_deg: SYNTHETIC_ROT_LIMIT_DEG,
            src_points: self.check_points.iter().map(|p| [p.0, p.1]).collect(),
            dst_points: self
                .check_points
                .iter()
                .map(|&p| {
                    let q = t.apply(p);
                    [q.0, q.1]
                })
                .collect(),
        }
    }
}

impl SyntheticPair {
    /// The pair as a pair set's entry: its truth, the success test's limits ([`SYNTHETIC_ROT_LIMIT_DEG`],
    /// [`SYNTHETIC_RMS_LIMIT_PX`]) and the check points in B with where the truth puts them in A.
    pub fn true_pair(&self, src: &str, dst: &str, building: &str) -> TruePair {
        TruePair {
            src: src.to_string(),
            dst: dst.to_string(),
            building: building.to_string(),
            theta_deg: self.truth.theta_deg,
            tx: self.truth.tx,
            ty: self.truth.ty,
            rms_limit_px: self.rms_limit_px,
            rot_limit_deg: SYNTHETIC_ROT_LIMIT_DEG,
            src_points: self.check_points.iter().map(|p| [p.0, p.1]).collect(),
            dst_points: self.true_points.iter().map(|q| [q.0, q.1]).collect(),
        }
    }

    /// The estimate's rotation error (degrees) and RMS error over [`SyntheticPair::check_points`]
    /// (pixels), as [`TruePair::errors`] measures them.
    pub fn errors(&self, estimate: &Rigid) -> (f64, f64) {
        self.true_pair("", "", "").errors(estimate)
    }

    /// Whether the estimate passes the success test.
    pub fn accurate(&self, estimate: &Rigid) -> bool {
        self.true_pair("", "", "").accurate(estimate)
    }
}

/// Rotation error a synthetic estimate may have to count as accurate, degrees.
pub const SYNTHETIC_ROT_LIMIT_DEG: f64 = 1.0;
/// RMS error over the check points a synthetic estimate may have, pixels.
pub const SYNTHETIC_RMS_LIMIT_PX: f64 = 3.0;

/// A `w` x `h` map of pixels `px`.
fn map_of(w: usize, h: usize, px: Vec<u8>) -> Option<OccupancyMap> {
    MapImage::new(w as u32, h as u32, px)
        .ok()
        .map(OccupancyMap::from_image)
}

/// The least and greatest of `proj` over the known pixels of a `w` x `h` map.
fn known_extent(
    state: &dyn Fn(usize, usize) -> CellState,
    (w, h): (usize, usize),
    proj: &dyn Fn(f64, f64) -> f64,
) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for y in 0..h {
        for x in 0..w {
            if state(x, y) != CellState::Unknown {
                let p = proj(x as f64, y as f64);
                (lo, hi) = (lo.min(p), hi.max(p));
            }
        }
    }
    (lo, hi)
}

/// The centre of the known pixels `keep` keeps.
fn known_centre(
    state: &dyn Fn(usize, usize) -> CellState,
    (w, h): (usize, usize),
    keep: &dyn Fn(usize, usize) -> bool,
) -> (f64, f64) {
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            if keep(x, y) && state(x, y) != CellState::Unknown {
                (sx, sy, n) = (sx + x as f64, sy + y as f64, n + 1.0);
            }
        }
    }
    (sx / f64::max(n, 1.0), sy / f64::max(n, 1.0))
}

/// A pair's truth: the transform, the points it is checked at in B and where they truly lie in A, and
/// the limit of the RMS error there, pixels.
type Truth = (Rigid, Vec<(f64, f64)>, Vec<(f64, f64)>, f64);

/// A bent pair's truth: the rigid fit from B's known pixels (`b_px`, `side` square) to where they truly
/// lie in A (`source_of`, then less A's corner `a0`), over those whose source is known and in A's part;
/// with those points and the limit (twice the fit's residual, as the real pairs' success test has it).
/// `None` where fewer than four such pixels are found.
fn bent_truth(
    (b_px, side): (&[u8], usize),
    source_of: &dyn Fn((f64, f64)) -> (f64, f64),
    state: &dyn Fn(usize, usize) -> CellState,
    (w, h): (usize, usize),
    in_a: &dyn Fn(usize, usize) -> bool,
    (ax0, ay0): (usize, usize),
) -> Option<Truth> {
    // Checked where the maps overlap, as annotated real pairs are: B's known pixels whose source
    // lies in A's part; the truth is the rigid fit to where they truly are, and the limit twice its
    // residual, as the real pairs' success test has it.
    let step = (side / 16).max(4);
    let (mut from, mut to) = (Vec::new(), Vec::new());
    for y in (step / 2..side).step_by(step) {
        for x in (step / 2..side).step_by(step) {
            if b_px[y * side + x] == UNKNOWN {
                continue;
            }
            let s = source_of((x as f64, y as f64));
            let (sx, sy) = (s.0.round(), s.1.round());
            if sx < 0.0 || sy < 0.0 || sx >= w as f64 || sy >= h as f64 {
                continue;
            }
            if in_a(sx as usize, sy as usize)
                && state(sx as usize, sy as usize) != CellState::Unknown
            {
                from.push((x as f64, y as f64));
                to.push((s.0 - ax0 as f64, s.1 - ay0 as f64));
            }
        }
    }
    if from.len() < 4 {
        return None;
    }
    let fit = crate::merge::transform::fit_rigid(&from, &to);
    let rms = (from
        .iter()
        .zip(&to)
        .map(|(&p, q)| {
            let r = fit.apply(p);
            (r.0 - q.0).powi(2) + (r.1 - q.1).powi(2)
        })
        .sum::<f64>()
        / from.len() as f64)
        .sqrt();
    Some((
        fit.normalized(),
        from,
        to,
        (2.0 * rms).max(SYNTHETIC_RMS_LIMIT_PX),
    ))
}
