//! Synthetic maps: a seeded office generator for the demo, tests and benchmarks, and a small PRNG.
//!
//! The project ships no real maps; everything it needs to show or measure is generated here.

use crate::map::MapImage;
use crate::support::error::{Error, Result};

pub use crate::map::states::{FREE, OCCUPIED, UNKNOWN};

/// SplitMix64: small, fast and stable across versions, so a seed always gives the same map.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x5DEE_CE66_D1CE_4E5B)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A value in `lo..hi` (`lo` when the range is empty).
    pub fn range(&mut self, lo: u32, hi: u32) -> u32 {
        if hi <= lo {
            return lo;
        }
        lo + (((self.next_u64() >> 32) * u64::from(hi - lo)) >> 32) as u32
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        ((self.next_u64() >> 11) as f64) < p * (1u64 << 53) as f64
    }
}

/// Smallest side the office generator accepts.
pub const MIN_OFFICE_SIDE: u32 = 32;

/// A half-open rectangle [x0, x1) x [y0, y1).
#[derive(Clone, Copy, Debug)]
struct Rect {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl Rect {
    fn w(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }
    fn h(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }
}

struct Canvas {
    w: u32,
    px: Vec<u8>,
}

impl Canvas {
    fn fill(&mut self, r: Rect, v: u8) {
        for y in r.y0..r.y1 {
            let row = (y * self.w) as usize;
            self.px[row + r.x0 as usize..row + r.x1 as usize].fill(v);
        }
    }
}

/// Room sizes in pixels (about 1.2 m to 9 m at 0.05 m/px).
const MIN_ROOM: u32 = 24;

/// Checks that [`office_map`] can make a `width` x `height` map: each side at least [`MIN_OFFICE_SIDE`],
/// at most [`crate::map::MAX_IMAGE_BYTES`] pixels. (It allocates the map once, `width * height` bytes;
/// [`OfficeRows`] makes larger maps row by row.)
pub fn check_office_size(width: u32, height: u32) -> Result<()> {
    if width < MIN_OFFICE_SIDE || height < MIN_OFFICE_SIDE {
        return Err(Error::invalid(format!(
            "synthetic office map of {width}x{height} is too small: each side needs at least {MIN_OFFICE_SIDE} px"
        )));
    }
    if width as u64 * height as u64 > crate::map::MAX_IMAGE_BYTES {
        return Err(Error::invalid(format!(
            "synthetic map of {width}x{height} exceeds {} pixels",
            crate::map::MAX_IMAGE_BYTES
        )));
    }
    Ok(())
}

/// Maps above this many pixels are made by [`office_map_parallel`] in the tools that time them.
pub const PARALLEL_PIXELS: u64 = 1 << 28;
/// Side of the offices [`office_map_parallel`] tiles a large map with.
const PARALLEL_TILE: u32 = 8192;
/// Side of the offices [`OfficeRows::new`] tiles a map above [`PARALLEL_PIXELS`] with: a strip of them is
/// 1024 to 2047 rows, what the generator holds.
pub const STREAM_TILE: u32 = 1024;

/// A large synthetic map made on all threads: a grid of independent offices of about 8192 x 8192 (the
/// last row and column absorb the remainder), each [`office_map`] with its own seed derived from `seed`
/// and its place. Deterministic; for maps whose single-threaded drawing would dominate a benchmark
/// (65536 x 65536 is 4 GiB). The rows of [`OfficeRows::with_tile`] with tiles of 8192.
pub fn office_map_parallel(width: u32, height: u32, seed: u64) -> Result<MapImage> {
    check_office_size(width, height)?;
    let rows = OfficeRows::with_tile(width, height, seed, PARALLEL_TILE)?;
    let w = width as usize;
    let mut px = vec![0u8; w * height as usize];
    // Each strip drawn straight into its rows of the map: no strip buffer beside it.
    for (ty, &(y0, y1)) in rows.ys.iter().enumerate() {
        rows.draw_strip(ty, &mut px[y0 as usize * w..y1 as usize * w])?;
    }
    MapImage::new(width, height, px)
}

/// Where the tiles of a side of `n` pixels start and end: `n / tile` tiles (at least one), the last
/// absorbing the remainder.
fn cuts(n: u32, tile: u32) -> Vec<(u32, u32)> {
    let k = (n / tile).max(1);
    (0..k)
        .map(|i| (i * tile, if i + 1 == k { n } else { (i + 1) * tile }))
        .collect()
}

/// A synthetic office map of any size made row by row, holding one strip of tiles at a time: a grid of
/// independent [`office_map`]s with seeds derived from `seed` and their place (as
/// [`office_map_parallel`]), each strip drawn on all threads. Deterministic.
pub struct OfficeRows {
    width: u32,
    height: u32,
    seed: u64,
    xs: Vec<(u32, u32)>,
    ys: Vec<(u32, u32)>,
    /// The strip being handed out, its index and the next row in it.
    strip: Vec<u8>,
    strip_i: usize,
    next: u32,
}

impl OfficeRows {
    /// The map `demo` and `bench` write: up to [`PARALLEL_PIXELS`] one office (exactly [`office_map`]),
    /// above it offices of [`STREAM_TILE`].
    pub fn new(width: u32, height: u32, seed: u64) -> Result<Self> {
        let tile = if u64::from(width) * u64::from(height) <= PARALLEL_PIXELS {
            width.max(height)
        } else {
            STREAM_TILE
        };
        Self::with_tile(width, height, seed, tile)
    }

    /// Offices of about `tile` pixels a side.
    pub fn with_tile(width: u32, height: u32, seed: u64, tile: u32) -> Result<Self> {
        if width < MIN_OFFICE_SIDE || height < MIN_OFFICE_SIDE {
            check_office_size(width, height)?;
        }
        let tile = tile.max(MIN_OFFICE_SIDE);
        Ok(OfficeRows {
            width,
            height,
            seed,
            xs: cuts(width, tile),
            ys: cuts(height, tile),
            strip: Vec::new(),
            strip_i: usize::MAX,
            next: 0,
        })
    }

    /// Bytes the generator holds: its largest strip, and an office per thread while drawing it.
    pub fn bytes(&self) -> u64 {
        let tall = self.ys.iter().map(|&(a, b)| b - a).max().unwrap_or(0);
        let wide = self.xs.iter().map(|&(a, b)| b - a).max().unwrap_or(0);
        // An office per thread at most, and no more than the strip has.
        let drawn = rayon::current_num_threads().min(self.xs.len()) as u64;
        u64::from(tall) * (u64::from(self.width) + drawn * u64::from(wide))
    }

    /// Draws strip `ty` (its rows, `width` bytes each) into `out`, as many offices at a time as there are
    /// threads.
    fn draw_strip(&self, ty: usize, out: &mut [u8]) -> Result<()> {
        use rayon::prelude::*;
        let (y0, y1) = self.ys[ty];
        let w = self.width as usize;
        let places: Vec<(usize, (u32, u32))> = self.xs.iter().copied().enumerate().collect();
        for group in places.chunks(rayon::current_num_threads().max(1)) {
            let offices: Vec<MapImage> = group
                .par_iter()
                .map(|&(tx, (x0, x1))| {
                    let s = self.seed
                        ^ (((ty as u64) << 32) | tx as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
                    office_map(x1 - x0, y1 - y0, s)
                })
                .collect::<Result<_>>()?;
            for (t, &(_, (x0, _))) in offices.iter().zip(group) {
                let tw = t.width() as usize;
                for (r, row) in t.pixels().chunks_exact(tw).enumerate() {
                    let at = r * w + x0 as usize;
                    out[at..at + tw].copy_from_slice(row);
                }
            }
        }
        Ok(())
    }

    /// Writes the next row into `out` (`width` bytes).
    pub fn next_row(&mut self, out: &mut [u8]) -> Result<()> {
        let y = self.next;
        if y >= self.height {
            return Err(Error::Internal("read past the last row".into()));
        }
        let ty = self
            .ys
            .iter()
            .position(|&(a, b)| (a..b).contains(&y))
            .unwrap_or(0);
        let (y0, y1) = self.ys[ty];
        if self.strip_i != ty {
            let mut strip = std::mem::take(&mut self.strip);
            strip.resize((y1 - y0) as usize * self.width as usize, 0);
            self.draw_strip(ty, &mut strip)?;
            self.strip = strip;
            self.strip_i = ty;
        }
        let w = self.width as usize;
        let r = (y - y0) as usize;
        out.copy_from_slice(&self.strip[r * w..(r + 1) * w]);
        self.next += 1;
        Ok(())
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
}

/// A synthetic office floor as a SLAM map would show it: rooms from recursive splits, corridors, doors,
/// walls 1-3 px thick, furniture, a few unexplored rooms, sensor speckle and ragged walls, and unknown space
/// outside the building. The same (size, seed) always gives the same map.
pub fn office_map(width: u32, height: u32, seed: u64) -> Result<MapImage> {
    check_office_size(width, height)?;
    let n = width as u64 * height as u64;
    let mut rng = Rng::new(seed);
    let mut c = Canvas {
        w: width,
        px: vec![UNKNOWN; n as usize],
    };
    let margin = (width.min(height) / 20).max(4);
    let building = Rect {
        x0: margin,
        y0: margin,
        x1: width - margin,
        y1: height - margin,
    };
    c.fill(building, FREE);
    let t = rng.range(2, 4);
    for r in [
        Rect {
            y1: building.y0 + t,
            ..building
        },
        Rect {
            y0: building.y1 - t,
            ..building
        },
        Rect {
            x1: building.x0 + t,
            ..building
        },
        Rect {
            x0: building.x1 - t,
            ..building
        },
    ] {
        c.fill(r, OCCUPIED);
    }
    let inner = Rect {
        x0: building.x0 + t,
        y0: building.y0 + t,
        x1: building.x1 - t,
        y1: building.y1 - t,
    };
    let mut rooms = Vec::new();
    split(&mut c, &mut rng, inner, 0, &mut rooms);
    for room in rooms {
        furnish(&mut c, &mut rng, room);
    }
    add_noise(&mut c, &mut rng, width, height);
    MapImage::new(width, height, c.px)
}

/// [`office_map`] with furniture: occupied boxes of 6-40 px at seeded random free places, so that the
/// map does not look the same turned by 180 degrees (the bare office's grid of rooms nearly does), and
/// its top-right corner unexplored, so that its known area has no symmetry either: a map with one right
/// pose onto a part of itself, as the merger's tests want. The same (size, seed) always gives the same
/// map.
pub fn cluttered_office(width: u32, height: u32, seed: u64) -> Result<MapImage> {
    let mut img = office_map(width, height, seed)?;
    let mut rng = Rng::new(seed ^ 0x5eed);
    for _ in 0..(width * height / 4000).max(4) {
        let (bw, bh) = (rng.range(6, 40), rng.range(6, 40));
        if bw >= width || bh >= height {
            continue;
        }
        let (x0, y0) = (rng.range(0, width - bw), rng.range(0, height - bh));
        if img.get(x0, y0) != FREE || img.get(x0 + bw - 1, y0 + bh - 1) != FREE {
            continue;
        }
        for y in y0..y0 + bh {
            for x in x0..x0 + bw {
                img.pixels_mut()[(y * width + x) as usize] = OCCUPIED;
            }
        }
    }
    for y in 0..height * 2 / 5 {
        for x in width * 3 / 5..width {
            img.pixels_mut()[(y * width + x) as usize] = UNKNOWN;
        }
    }
    Ok(img)
}

/// Splits `r` with a wall (or, near the top of the tree, a corridor between two walls) and recurses;
/// collects the leaves as rooms.
fn split(c: &mut Canvas, rng: &mut Rng, r: Rect, depth: u32, rooms: &mut Vec<Rect>) {
    let vertical = r.w() >= r.h(); // a vertical wall splits the longer side
    let long = r.w().max(r.h());
    let max_room = rng.range(70, 180);
    if long < 2 * MIN_ROOM + 6 || (r.w() <= max_room && r.h() <= max_room) {
        rooms.push(r);
        return;
    }
    let (lo, hi) = if vertical { (r.x0, r.x1) } else { (r.y0, r.y1) };
    let band = |a: u32, b: u32| {
        if vertical {
            Rect { x0: a, x1: b, ..r }
        } else {
            Rect { y0: a, y1: b, ..r }
        }
    };
    let corridor = depth <= 1 && long > 4 * MIN_ROOM + 40 && rng.chance(0.6);
    if corridor {
        let cw = rng.range(8, 15);
        let (t1, t2) = (rng.range(1, 4), rng.range(1, 4));
        let pos = rng.range(lo + MIN_ROOM + t1, hi - MIN_ROOM - cw - t2);
        wall_with_doors(c, rng, band(pos - t1, pos), vertical);
        wall_with_doors(c, rng, band(pos + cw, pos + cw + t2), vertical);
        split(c, rng, band(lo, pos - t1), depth + 1, rooms);
        split(c, rng, band(pos + cw + t2, hi), depth + 1, rooms);
    } else {
        let t = rng.range(1, 4);
        let pos = rng.range(lo + MIN_ROOM, hi - MIN_ROOM - t);
        wall_with_doors(c, rng, band(pos, pos + t), vertical);
        split(c, rng, band(lo, pos), depth + 1, rooms);
        split(c, rng, band(pos + t, hi), depth + 1, rooms);
    }
}

/// Fills `wall` as occupied, then opens one or two doors along it.
fn wall_with_doors(c: &mut Canvas, rng: &mut Rng, wall: Rect, vertical: bool) {
    c.fill(wall, OCCUPIED);
    let (lo, hi) = if vertical {
        (wall.y0, wall.y1)
    } else {
        (wall.x0, wall.x1)
    };
    let doors = if hi - lo > 120 { 2 } else { 1 };
    for _ in 0..doors {
        let dw = rng.range(6, 12);
        if hi - lo < dw + 8 {
            return;
        }
        let at = rng.range(lo + 4, hi - 4 - dw);
        let door = if vertical {
            Rect {
                y0: at,
                y1: at + dw,
                ..wall
            }
        } else {
            Rect {
                x0: at,
                x1: at + dw,
                ..wall
            }
        };
        c.fill(door, FREE);
    }
}

/// Furniture in a room, or leaves it unexplored (unknown inside its walls).
fn furnish(c: &mut Canvas, rng: &mut Rng, room: Rect) {
    if rng.chance(0.1) {
        c.fill(room, UNKNOWN);
        return;
    }
    for _ in 0..rng.range(0, 4) {
        let (fw, fh) = (rng.range(3, 13), rng.range(3, 13));
        if room.w() < fw + 10 || room.h() < fh + 10 {
            continue;
        }
        let x0 = rng.range(room.x0 + 5, room.x1 - 5 - fw);
        let y0 = rng.range(room.y0 + 5, room.y1 - 5 - fh);
        c.fill(
            Rect {
                x0,
                y0,
                x1: x0 + fw,
                y1: y0 + fh,
            },
            OCCUPIED,
        );
    }
}

/// Sensor speckle in free space, bumps and gaps along walls. Each decision reads the map as it was
/// before any noise; only the original of the rows above and at the current one is kept (the row below is
/// still untouched), so a 16384^2 map does not need a second copy.
fn add_noise(c: &mut Canvas, rng: &mut Rng, w: u32, h: u32) {
    if h < 3 {
        return;
    }
    let wu = w as usize;
    let mut above = c.px[..wu].to_vec();
    let mut here = c.px[wu..2 * wu].to_vec();
    for y in 1..h - 1 {
        let row = y as usize * wu;
        let (head, below) = c.px.split_at_mut(row + wu);
        let out = &mut head[row..];
        let below = &below[..wu];
        for x in 1..wu - 1 {
            let v = here[x];
            let near =
                |s: u8| here[x - 1] == s || here[x + 1] == s || above[x] == s || below[x] == s;
            if v == FREE {
                if near(OCCUPIED) && rng.chance(0.03) {
                    out[x] = OCCUPIED; // a bump on a wall
                } else if rng.chance(0.001) {
                    out[x] = OCCUPIED; // a spurious return
                } else if rng.chance(0.001) {
                    out[x] = UNKNOWN; // a cell no beam crossed
                }
            } else if v == OCCUPIED && near(FREE) && rng.chance(0.01) {
                out[x] = FREE; // a missed return in a wall
            }
        }
        std::mem::swap(&mut above, &mut here);
        here.copy_from_slice(below);
    }
}
