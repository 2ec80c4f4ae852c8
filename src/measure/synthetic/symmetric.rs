//! Symmetric buildings for the hard synthetic suite: a hall with 2 to 8 identical wings around it (the
//! plan turns onto itself by a whole wing), each wing mirrored about its axis (rooms on both sides) or not
//! (rooms on one side); and the variant whose only asymmetric part is one extra room at the end of one
//! wing. A pair cut from such a plan can be placed wrongly by a turn of the building's symmetry with
//! nearly every wall on a wall: only the extra room, or what the windows leave out, tells the turns apart.
//!
//! Drawn as a union of free rectangles (corridors, rooms, doors) and a regular polygon (the hall); walls
//! are what is not free within [`WALL`] px of free space, the rest unknown, as a floor plan's map.

use crate::map::states::{FREE, OCCUPIED, UNKNOWN};
use crate::map::synthetic::Rng;
use crate::map::MapImage;
use crate::support::error::Result;

/// Wall thickness, pixels.
const WALL: f64 = 3.0;
/// Margin of unknown around the plan, pixels.
const MARGIN: f64 = 12.0;

/// A symmetric plan: a hall with `wings` identical wings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SymmetricKind {
    /// Wings around the hall, 2 to 8: the plan turns onto itself by 360 / wings degrees.
    pub wings: u8,
    /// Rooms on both sides of each wing's corridor (the wing mirrored about its axis), or on one side.
    pub mirrored: bool,
    /// One more room at the end of the first wing: the one detail that tells the turns apart.
    pub extra_room: bool,
    /// Each wing after the first turned back by this many more degrees (0: none): with two wings bent
    /// by 7, the second wing lies 173 degrees from the first, so a wing matches the other under a turn
    /// near, not at, a half turn (a building mapped bent, or built so), while the hall still turns onto
    /// itself by a half turn.
    pub bend_deg: u8,
}

impl SymmetricKind {
    /// A plan of `wings` wings, mirrored, with no extra room and no bend.
    pub fn plain(wings: u8) -> SymmetricKind {
        SymmetricKind {
            wings,
            mirrored: true,
            extra_room: false,
            bend_deg: 0,
        }
    }

    /// The kinds of the suite: 2 to 8 mirrored wings; 3 and 5 wings not mirrored; 4 and 6 with one
    /// extra room; 2 wings bent by 7 degrees.
    pub fn suite() -> Vec<SymmetricKind> {
        let kind = |wings, mirrored, extra_room| SymmetricKind {
            mirrored,
            extra_room,
            ..SymmetricKind::plain(wings)
        };
        (2..=8)
            .map(|k| kind(k, true, false))
            .chain([kind(3, false, false), kind(5, false, false)])
            .chain([kind(4, true, true), kind(6, true, true)])
            .chain([SymmetricKind {
                bend_deg: 7,
                ..SymmetricKind::plain(2)
            }])
            .collect()
    }

    /// Its name in reports: `5 wings`, `3 wings, not mirrored`, `4 wings, one extra room`, `2 wings,
    /// bent 7 deg`.
    pub fn name(self) -> String {
        let mut s = format!("{} wings", self.wings);
        if !self.mirrored {
            s += ", not mirrored";
        }
        if self.extra_room {
            s += ", one extra room";
        }
        if self.bend_deg > 0 {
            s += &format!(", bent {} deg", self.bend_deg);
        }
        s
    }
}

/// A rectangle in plan coordinates: centre, half sizes, turned by `angle` radians.
#[derive(Clone, Copy, Debug)]
struct Rect {
    cx: f64,
    cy: f64,
    hx: f64,
    hy: f64,
    angle: f64,
}

impl Rect {
    /// Whether `(x, y)` lies inside, given `self.angle.sin_cos()` (worked out once a rectangle, not
    /// once a pixel: the plan's drawing spent most of its time there).
    fn contains(&self, (s, c): (f64, f64), x: f64, y: f64) -> bool {
        let (dx, dy) = (x - self.cx, y - self.cy);
        let (u, v) = (c * dx + s * dy, -s * dx + c * dy);
        u.abs() <= self.hx && v.abs() <= self.hy
    }
}

/// A wing along +u from `start` to `start + len` (before turning by `angle` about the origin, then
/// shifting by `at`): a corridor `corridor` wide with `rooms` rooms on each of `sides` (-1, 1: both), each
/// with a door.
#[allow(clippy::too_many_arguments)]
fn wing(
    out: &mut Vec<Rect>,
    at: (f64, f64),
    angle: f64,
    start: f64,
    len: f64,
    corridor: f64,
    rooms: usize,
    depth: f64,
    sides: &[f64],
) {
    let (s, c) = angle.sin_cos();
    let place = |u: f64, v: f64, hx: f64, hy: f64| Rect {
        cx: at.0 + c * u - s * v,
        cy: at.1 + s * u + c * v,
        hx,
        hy,
        angle,
    };
    out.push(place(start + len / 2.0, 0.0, len / 2.0, corridor / 2.0));
    let pitch = len / rooms as f64;
    for k in 0..rooms {
        let u = start + pitch * (k as f64 + 0.5);
        for &side in sides {
            let v = side * (corridor / 2.0 + 2.0 * WALL + depth / 2.0);
            out.push(place(u, v, pitch / 2.0 - 2.0 * WALL, depth / 2.0));
            // The door through the wall between room and corridor.
            out.push(place(u, side * (corridor / 2.0 + WALL), 6.0, WALL + 1.0));
        }
    }
}

/// The drawn sizes of a plan, from its seed.
struct Sizes {
    corridor: f64,
    depth: f64,
    rooms: usize,
    len: f64,
    turn0: f64,
    radius: f64,
}

impl Sizes {
    fn draw(kind: SymmetricKind, seed: u64) -> Sizes {
        let mut rng = Rng::new(seed);
        let corridor = f64::from(rng.range(18, 28));
        let depth = f64::from(rng.range(40, 64));
        let rooms = rng.range(3, 6) as usize;
        let len = rooms as f64 * f64::from(rng.range(48, 64));
        let turn0 = f64::from(rng.range(0, 360)).to_radians();
        // A hall wide enough that neighbouring wings' rooms do not meet (a square one for two wings).
        let corners = hall_corners(kind);
        let reach = corridor / 2.0 + 2.0 * WALL + depth;
        let radius = reach / (std::f64::consts::PI / corners as f64).tan() + 2.0 * WALL;
        Sizes {
            corridor,
            depth,
            rooms,
            len,
            turn0,
            radius,
        }
    }

    /// The extra room's centre along the first wing (from the hall's centre).
    fn room_at(&self) -> f64 {
        self.radius * 0.9 + self.len + 2.0 * WALL + self.depth / 2.0
    }
}

/// The hall's corners: one a wing, four for two wings.
fn hall_corners(kind: SymmetricKind) -> usize {
    let n = usize::from(kind.wings.clamp(2, 8));
    if n < 3 {
        4
    } else {
        n
    }
}

/// The plan of `kind` for `seed` (map_server values), a few hundred px a side, and the hall's centre in
/// its pixels.
pub fn symmetric_plan(kind: SymmetricKind, seed: u64) -> Result<(MapImage, (f64, f64))> {
    let (rects, hub) = plan_rects(kind, seed);
    draw(&rects, hub)
}

/// Where [`symmetric_plan`] puts the hall's centre in its pixels, without drawing the plan.
pub fn hall_pixel(kind: SymmetricKind, seed: u64) -> (f64, f64) {
    let (rects, (_, r, _)) = plan_rects(kind, seed);
    let (x0, y0, _, _) = canvas(&rects, r);
    (-x0 - 0.5, -y0 - 0.5)
}

/// The plan's free rectangles and its hall (corners, circumradius, turn), about the hall's centre.
fn plan_rects(kind: SymmetricKind, seed: u64) -> (Vec<Rect>, (usize, f64, f64)) {
    let z = Sizes::draw(kind, seed);
    let n = usize::from(kind.wings.clamp(2, 8));
    let sides: &[f64] = if kind.mirrored { &[-1.0, 1.0] } else { &[1.0] };
    let mut rects = Vec::new();
    for k in 0..n {
        let a = z.turn0 + std::f64::consts::TAU * k as f64 / n as f64
            - (f64::from(kind.bend_deg) * k as f64).to_radians();
        wing(
            &mut rects,
            (0.0, 0.0),
            a,
            z.radius * 0.9,
            z.len,
            z.corridor,
            z.rooms,
            z.depth,
            sides,
        );
    }
    if kind.extra_room {
        // One more room at the end of the first wing, with its door.
        let (s, c) = z.turn0.sin_cos();
        let u = z.room_at();
        rects.push(Rect {
            cx: c * u,
            cy: s * u,
            hx: z.depth / 2.0,
            hy: z.depth / 2.0,
            angle: z.turn0,
        });
        rects.push(Rect {
            cx: c * (u - z.depth / 2.0 - WALL),
            cy: s * (u - z.depth / 2.0 - WALL),
            hx: WALL + 1.0,
            hy: 6.0,
            angle: z.turn0,
        });
    }
    // The hall's polygon turned with the wings, so that the whole plan turns onto itself.
    (rects, (hall_corners(kind), z.radius, z.turn0))
}

/// Points of the extra room of `kind`'s plan for `seed` (`None` without one), from the hall's centre
/// (add the hall's pixel, [`hall_pixel`]): its centre and four points a few px inside
/// its corners, so that a window holding all five holds the whole room.
pub fn extra_room_points(kind: SymmetricKind, seed: u64) -> Option<[(f64, f64); 5]> {
    if !kind.extra_room {
        return None;
    }
    let z = Sizes::draw(kind, seed);
    let (s, c) = z.turn0.sin_cos();
    let u = z.room_at();
    let r = z.depth / 2.0 - 2.0;
    let at = |du: f64, dv: f64| (c * (u + du) - s * dv, s * (u + du) + c * dv);
    Some([at(0.0, 0.0), at(-r, -r), at(-r, r), at(r, -r), at(r, r)])
}

/// The extra room's door of `kind`'s plan for `seed` (`None` without one), from the hall's centre: the
/// middle of the gap it cuts in the first wing's end wall (half a wall in from the wall's outer face,
/// where the room's own wall begins). The plan turned by a whole wing lays it on another wing's closed
/// end wall, the one place where a turn of the plan contradicts the plan.
pub fn extra_room_door(kind: SymmetricKind, seed: u64) -> Option<(f64, f64)> {
    if !kind.extra_room {
        return None;
    }
    let z = Sizes::draw(kind, seed);
    let (s, c) = z.turn0.sin_cos();
    let u = z.room_at() - z.depth / 2.0 - 1.5 * WALL;
    Some((c * u, s * u))
}

/// The canvas that holds `rects` and a hall of circumradius `r` about the origin with a margin: where
/// its pixel (0, 0) lies (its corner, in plan coordinates) and its size.
fn canvas(rects: &[Rect], r: f64) -> (f64, f64, usize, usize) {
    // The extent: every rectangle's corners and the hall.
    let (mut lo, mut hi) = ((-r, -r), (r, r));
    for r in rects {
        let reach = r.hx.hypot(r.hy);
        lo = (lo.0.min(r.cx - reach), lo.1.min(r.cy - reach));
        hi = (hi.0.max(r.cx + reach), hi.1.max(r.cy + reach));
    }
    let pad = MARGIN + WALL + 2.0;
    (
        lo.0 - pad,
        lo.1 - pad,
        (hi.0 - lo.0 + 2.0 * pad).ceil() as usize,
        (hi.1 - lo.1 + 2.0 * pad).ceil() as usize,
    )
}

/// The free union of `rects` and a regular polygon (corners, circumradius, turn) about the origin, walls
/// around, unknown beyond, on a canvas that holds it with a margin; with the origin in its pixels.
fn draw(rects: &[Rect], (n, r, turn): (usize, f64, f64)) -> Result<(MapImage, (f64, f64))> {
    // The hall's sides as half-planes, and each rectangle's turn, worked out once.
    let sides: Vec<(f64, f64)> = (0..n)
        .map(|k| {
            let a = turn + std::f64::consts::TAU * (k as f64 + 0.5) / n as f64;
            (a.cos(), a.sin())
        })
        .collect();
    let apothem = r * (std::f64::consts::PI / n as f64).cos();
    let in_hub = |x: f64, y: f64| sides.iter().all(|&(c, s)| x * c + y * s <= apothem);
    let turns: Vec<(f64, f64)> = rects.iter().map(|r| r.angle.sin_cos()).collect();
    let free_at = |x: f64, y: f64| {
        in_hub(x, y) || rects.iter().zip(&turns).any(|(r, &t)| r.contains(t, x, y))
    };
    let (x0, y0, w, h) = canvas(rects, r);
    let mut free = vec![false; w * h];
    for (i, f) in free.iter_mut().enumerate() {
        let (x, y) = ((i % w) as f64 + x0 + 0.5, (i / w) as f64 + y0 + 0.5);
        *f = free_at(x, y);
    }
    let t = WALL as isize;
    let mut px = vec![UNKNOWN; w * h];
    for y in 0..h as isize {
        for x in 0..w as isize {
            let i = y as usize * w + x as usize;
            if free[i] {
                px[i] = FREE;
                continue;
            }
            let near = (-t..=t).any(|dy| {
                (-t..=t).any(|dx| {
                    let (u, v) = (x + dx, y + dy);
                    u >= 0
                        && v >= 0
                        && (u as usize) < w
                        && (v as usize) < h
                        && free[v as usize * w + u as usize]
                })
            });
            if near {
                px[i] = OCCUPIED;
            }
        }
    }
    Ok((
        MapImage::new(w as u32, h as u32, px)?,
        (-x0 - 0.5, -y0 - 0.5),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_plan_is_drawn_with_walls_between_free_and_unknown() {
        for kind in SymmetricKind::suite() {
            let (img, (cx, cy)) = symmetric_plan(kind, 3).unwrap();
            let px = img.pixels();
            let count = |v: u8| px.iter().filter(|&&p| p == v).count();
            assert!(count(FREE) > 10_000, "{kind:?}");
            assert!(count(OCCUPIED) > 2_000, "{kind:?}");
            assert!(count(UNKNOWN) > 0, "{kind:?}");
            assert!(img.width() < 2400 && img.height() < 2400, "{kind:?}");
            // The hall's centre is free.
            assert_eq!(
                img.get(cx.round() as u32, cy.round() as u32),
                FREE,
                "{kind:?}"
            );
        }
    }

    /// The door of the extra room is free in the plan, and every turn of it by a whole wing lies on
    /// another wing's closed end wall: the pixel a turned pose contradicts.
    #[test]
    fn the_extra_rooms_door_turned_by_a_wing_lies_on_a_closed_end_wall() {
        for kind in SymmetricKind::suite().into_iter().filter(|k| k.extra_room) {
            for seed in 1..=4u64 {
                let (img, c) = symmetric_plan(kind, seed).unwrap();
                let (u, v) = extra_room_door(kind, seed).unwrap();
                let at = |(x, y): (f64, f64)| {
                    img.get((c.0 + x).round() as u32, (c.1 + y).round() as u32)
                };
                assert_eq!(at((u, v)), FREE, "{kind:?} {seed}");
                let n = f64::from(kind.wings);
                for j in 1..kind.wings {
                    let (s, co) = (std::f64::consts::TAU * f64::from(j) / n).sin_cos();
                    let turned = (co * u - s * v, s * u + co * v);
                    assert_eq!(at(turned), OCCUPIED, "{kind:?} {seed}: wing {j}");
                }
            }
        }
    }

    /// The share of the free pixels that land on free pixels when the plan is turned by `deg` about
    /// the hall's centre.
    fn agree(kind: SymmetricKind, deg: f64) -> f64 {
        let (img, c) = symmetric_plan(kind, 4).unwrap();
        let (w, h) = (img.width() as usize, img.height() as usize);
        let px = img.pixels();
        let free: Vec<(usize, usize)> = (0..w * h)
            .filter(|&i| px[i] == FREE)
            .map(|i| (i % w, i / w))
            .step_by(7)
            .collect();
        let (s, co) = deg.to_radians().sin_cos();
        let hits = free
            .iter()
            .filter(|p| {
                let (dx, dy) = (p.0 as f64 - c.0, p.1 as f64 - c.1);
                let (x, y) = (c.0 + co * dx - s * dy, c.1 + s * dx + co * dy);
                let (x, y) = (x.round() as isize, y.round() as isize);
                x >= 0
                    && y >= 0
                    && (x as usize) < w
                    && (y as usize) < h
                    && px[y as usize * w + x as usize] == FREE
            })
            .count();
        hits as f64 / free.len() as f64
    }

    #[test]
    fn a_k_wing_plan_turns_onto_itself_by_a_whole_wing_and_not_by_half_of_one() {
        for kind in SymmetricKind::suite() {
            let k = f64::from(kind.wings);
            if kind.bend_deg > 0 {
                // Bent: the plan turns onto itself neither by the whole wing nor by the wings' angle
                // apart, though each lays most of it on itself (the hall, or the wings): 0.74 and 0.80.
                for deg in [360.0 / k, 360.0 / k - f64::from(kind.bend_deg)] {
                    let share = agree(kind, deg);
                    assert!(share > 0.6 && share < 0.9, "{kind:?}, {deg} deg: {share}");
                }
                continue;
            }
            let whole = agree(kind, 360.0 / k);
            let half = agree(kind, 180.0 / k);
            if kind.extra_room {
                // The extra room breaks it, a little.
                assert!(whole > 0.9 && whole < 0.995, "{kind:?}: {whole}");
            } else {
                assert!(whole > 0.98, "{kind:?}: {whole}");
            }
            assert!(half < 0.75, "{kind:?}: {half}");
        }
    }
}
