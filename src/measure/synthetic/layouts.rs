//! Repetitive layouts for the hard synthetic suites: a grid of equal rooms, warehouse aisles, and a
//! corridor of identical offices. Each comes with its lattice (the shifts under which it repeats), so a
//! pair cut from it can be told to be identifiable (something in the overlap breaks the period) or not.
//!
//! What breaks the period is what real buildings have: the outer walls against the unknown outside, a
//! few walls left out, a few cabinets, a missing door. Everything else repeats exactly.

use crate::map::states::{FREE, OCCUPIED, UNKNOWN};
use crate::map::synthetic::Rng;
use crate::map::MapImage;
use crate::support::error::Result;

/// A generated layout: the map and the basis of its lattice of repeats (pixels).
#[derive(Clone, Debug)]
pub struct Layout {
    /// The map (map_server values).
    pub image: MapImage,
    /// Shifts under which the layout repeats away from what breaks the period: every integer combination
    /// of them is a way to misplace a part of it.
    pub lattice: Vec<(f64, f64)>,
}

/// The repetitive families.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutKind {
    /// Equal rooms on a regular grid, walls across the whole floor, each room's doors in the same place.
    GridRooms,
    /// Long parallel racks with cross-aisles at a fixed spacing.
    Warehouse,
    /// A long corridor between two rows of identical offices, one door each.
    Doors,
}

impl LayoutKind {
    /// Every kind.
    pub const ALL: [LayoutKind; 3] = [
        LayoutKind::GridRooms,
        LayoutKind::Warehouse,
        LayoutKind::Doors,
    ];

    /// Its name in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            LayoutKind::GridRooms => "grid-rooms",
            LayoutKind::Warehouse => "warehouse",
            LayoutKind::Doors => "doors",
        }
    }

    /// The layout of this kind for `seed`.
    pub fn make(self, seed: u64) -> Result<Layout> {
        match self {
            LayoutKind::GridRooms => grid_rooms(seed),
            LayoutKind::Warehouse => warehouse(seed),
            LayoutKind::Doors => doors(seed),
        }
    }
}

/// A map being drawn.
struct Draw {
    w: usize,
    h: usize,
    px: Vec<u8>,
}

impl Draw {
    fn new(w: usize, h: usize) -> Draw {
        Draw {
            w,
            h,
            px: vec![UNKNOWN; w * h],
        }
    }

    /// Fills [x0, x1) x [y0, y1), clipped to the map.
    fn fill(&mut self, x0: usize, y0: usize, x1: usize, y1: usize, v: u8) {
        for y in y0.min(self.h)..y1.min(self.h) {
            self.px[y * self.w + x0.min(self.w)..y * self.w + x1.min(self.w)].fill(v);
        }
    }

    /// A building: free inside, walls `t` thick around, unknown outside, `m` px of margin.
    fn building(&mut self, m: usize, t: usize) {
        let (w, h) = (self.w, self.h);
        self.fill(m, m, w - m, h - m, OCCUPIED);
        self.fill(m + t, m + t, w - m - t, h - m - t, FREE);
    }

    fn image(self) -> Result<MapImage> {
        MapImage::new(self.w as u32, self.h as u32, self.px)
    }
}

/// Margin of unknown around each layout, and wall thickness, pixels.
const MARGIN: usize = 12;
const WALL: usize = 3;

/// Equal rooms of `px` x `py` (not square, so a quarter turn does not repeat them) on a grid of 8 x 8,
/// walls across the whole floor, each wall with a door at the same place; two walls left out and two
/// cabinets at random.
pub fn grid_rooms(seed: u64) -> Result<Layout> {
    let mut rng = Rng::new(seed);
    let px = rng.range(104, 136) as usize;
    let py = rng.range(68, 92) as usize;
    let (nx, ny) = (8, 8);
    let (w, h) = (nx * px + 2 * MARGIN + WALL, ny * py + 2 * MARGIN + WALL);
    let mut d = Draw::new(w, h);
    d.building(MARGIN, WALL);
    let (x0, y0) = (MARGIN, MARGIN);
    let door = 18;
    let (dx, dy) = (
        rng.range(10, (px - door - 10) as u32) as usize,
        rng.range(10, (py - door - 10) as u32) as usize,
    );
    let skip: Vec<(usize, usize, bool)> = (0..2)
        .map(|_| {
            (
                rng.range(1, nx as u32) as usize,
                rng.range(1, ny as u32) as usize,
                rng.chance(0.5),
            )
        })
        .collect();
    // Interior walls: vertical at every column boundary, horizontal at every row boundary, a door in
    // each room's stretch of wall.
    for i in 1..nx {
        for j in 0..ny {
            if skip.contains(&(i, j, true)) {
                continue;
            }
            let (x, y) = (x0 + i * px, y0 + j * py);
            d.fill(x, y, x + WALL, y + py + WALL, OCCUPIED);
            d.fill(x, y + dy, x + WALL, y + dy + door, FREE);
        }
    }
    for j in 1..ny {
        for i in 0..nx {
            if skip.contains(&(i, j, false)) {
                continue;
            }
            let (x, y) = (x0 + i * px, y0 + j * py);
            d.fill(x, y, x + px + WALL, y + WALL, OCCUPIED);
            d.fill(x + dx, y, x + dx + door, y + WALL, FREE);
        }
    }
    for _ in 0..2 {
        let (i, j) = (
            rng.range(0, nx as u32) as usize,
            rng.range(0, ny as u32) as usize,
        );
        let (x, y) = (x0 + i * px + 20, y0 + j * py + 20);
        d.fill(x, y, x + 24, y + 12, OCCUPIED);
    }
    Ok(Layout {
        image: d.image()?,
        lattice: vec![(px as f64, 0.0), (0.0, py as f64)],
    })
}

/// Racks `rt` thick every `pitch` px across the hall, cut by cross-aisles `gap` wide every `bay` px; one
/// rack shortened and a pallet at random.
pub fn warehouse(seed: u64) -> Result<Layout> {
    let mut rng = Rng::new(seed);
    let pitch = rng.range(44, 60) as usize;
    let bay = rng.range(180, 240) as usize;
    let (rt, gap) = (10, 30);
    let (nr, nb) = (14, 6);
    let (w, h) = (
        nb * bay + gap + 2 * MARGIN + 2 * WALL,
        nr * pitch + 2 * MARGIN + 2 * WALL,
    );
    let mut d = Draw::new(w, h);
    d.building(MARGIN, WALL);
    let (x0, y0) = (MARGIN + WALL, MARGIN + WALL);
    let short = rng.range(1, nr as u32 - 1) as usize;
    for r in 1..nr {
        let y = y0 + r * pitch - rt / 2;
        for b in 0..nb {
            let x = x0 + gap + b * bay;
            let end = if r == short && b == nb - 1 {
                x + bay / 2
            } else {
                x + bay - gap
            };
            d.fill(x, y, end, y + rt, OCCUPIED);
        }
    }
    let (pxl, pyl) = (
        x0 + gap + rng.range(0, (nb * bay) as u32) as usize,
        y0 + rng.range(2, nr as u32 - 1) as usize * pitch + rt,
    );
    d.fill(pxl, pyl + 6, pxl + 16, pyl + 20, OCCUPIED);
    Ok(Layout {
        image: d.image()?,
        lattice: vec![(bay as f64, 0.0), (0.0, pitch as f64)],
    })
}

/// A corridor `cw` wide along the whole floor between two rows of offices `ow` wide and `od` deep, each
/// with one door onto the corridor at the same place; one door walled up.
pub fn doors(seed: u64) -> Result<Layout> {
    let mut rng = Rng::new(seed);
    let ow = rng.range(70, 96) as usize;
    let od = rng.range(80, 110) as usize;
    let cw = rng.range(30, 44) as usize;
    let n = 16;
    let (w, h) = (
        n * ow + WALL + 2 * MARGIN,
        2 * od + cw + 3 * WALL + 2 * MARGIN,
    );
    let mut d = Draw::new(w, h);
    d.building(MARGIN, WALL);
    let (x0, y0) = (MARGIN, MARGIN);
    let door = 16;
    let dx = rng.range(8, (ow - door - 8) as u32) as usize;
    let closed = rng.range(1, 2 * n as u32 - 1) as usize;
    // The corridor's two walls, then the offices' partitions and doors.
    let top = y0 + WALL + od;
    let bottom = top + WALL + cw;
    d.fill(x0, top, w - MARGIN, top + WALL, OCCUPIED);
    d.fill(x0, bottom, w - MARGIN, bottom + WALL, OCCUPIED);
    for i in 0..n {
        let x = x0 + i * ow;
        if i > 0 {
            d.fill(x, y0, x + WALL, top, OCCUPIED);
            d.fill(x, bottom, x + WALL, h - MARGIN, OCCUPIED);
        }
        for (k, y) in [(2 * i, top), (2 * i + 1, bottom)] {
            if k != closed {
                d.fill(x + dx, y, x + dx + door, y + WALL, FREE);
            }
        }
    }
    Ok(Layout {
        image: d.image()?,
        lattice: vec![(ow as f64, 0.0)],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::states::{CellState, ClassTable};
    use crate::map::Thresholds;

    /// Away from the outer walls and the few breakers, each layout repeats under its lattice.
    #[test]
    fn layouts_repeat_under_their_lattice() {
        let classes = ClassTable::new(&Thresholds::default());
        for kind in LayoutKind::ALL {
            let l = kind.make(3).unwrap();
            let (w, h) = (l.image.width() as usize, l.image.height() as usize);
            let px = l.image.pixels();
            for &(sx, sy) in &l.lattice {
                let (sx, sy) = (sx as usize, sy as usize);
                let (mut same, mut known) = (0usize, 0usize);
                for y in 0..h - sy {
                    for x in 0..w - sx {
                        let (a, b) = (
                            classes.state(px[y * w + x]),
                            classes.state(px[(y + sy) * w + x + sx]),
                        );
                        if a != CellState::Unknown && b != CellState::Unknown {
                            known += 1;
                            same += usize::from(a == b);
                        }
                    }
                }
                let share = same as f64 / known as f64;
                assert!(share > 0.97 && share < 1.0, "{}: {share}", kind.name());
            }
        }
    }
}
