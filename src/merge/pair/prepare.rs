//! A map prepared for alignment, once however many maps it is aligned with: its known area's bounding
//! box (plus 8 px), wall pixels, dominant wall direction, distance maps, the scoring kernel's flags, and
//! the coarse masks of the correlation.

use crate::backend::{ScoreTarget, FLAG_DEEP, FLAG_INSIDE, FLAG_NEAR};
use crate::map::states::{CellState, ClassTable};
use crate::map::OccupancyMap;
use crate::merge::pair::distance::{edt, edt_distance};

/// Coarse cell sides the correlation may use, pixels: per pair, the finest whose FFT stays small (so a
/// small map is correlated at 4 px, the 1585 px maps of the real pairs at 16).
pub const CELLS: [usize; 3] = [4, 8, 16];
/// Wall pixels a map screens the coarse hypotheses with (at most about).
pub const SCREEN_POINTS: usize = 1500;
/// Free pixels a map's free-space agreement is measured with (at most about).
pub const FREE_POINTS: usize = 4000;
/// Margin around the known area, pixels.
const PAD: usize = 8;

/// Bytes [`Prepared`] holds for a `width` x `height` map, and its transforms' buffers (at most): two
/// distance maps with their nearest pixels, the flag bytes, the masks, and the transform's row buffers;
/// plus what aligning it takes at most: the coarse correlation's buffers (three n x n complex spectra for
/// each of up to 10 rotation pairs at once, and the reference map's, n of its coarsest cells and another
/// map's diagonal, at most the correlation's limit).
pub fn prepared_bytes(width: u32, height: u32) -> u64 {
    preparing_bytes(width, height)
        .saturating_add((3 * rotation_tasks() + 3) * spectrum_bytes(width, height))
}

/// Bytes a `width` x `height` map's preparation holds while it is made: 42 a pixel (two distance maps
/// with their nearest pixels, the flag bytes, the masks, the transform's row buffers).
pub fn preparing_bytes(width: u32, height: u32) -> u64 {
    (u64::from(width) * u64::from(height)).saturating_mul(42)
}

/// A pair's coarse rotations that run at once: one a core, at most 10 (20 rotations, two a task).
pub fn rotation_tasks() -> u64 {
    rayon::current_num_threads().clamp(1, 10) as u64
}

/// Bytes of one n x n complex spectrum of the coarse correlation of a `width` x `height` map with
/// another (n of its coarsest cells and another map's diagonal, at most the correlation's limit).
pub fn spectrum_bytes(width: u32, height: u32) -> u64 {
    let side = u64::from(width.max(height)).div_ceil(CELLS[CELLS.len() - 1] as u64);
    let n = (side * 5 / 2 + 2)
        .next_power_of_two()
        .min(crate::merge::pair::fft::MAX_FFT as u64);
    n * n * 8
}

/// Bytes a [`Prepared`] keeps for a `width` x `height` crop once made, about 12 a pixel: its nearest
/// wall pixels (4), four flag targets (4), its walls and coarse masks. The rest of
/// [`prepared_bytes`] is working memory, held only while it is prepared or aligned. (Measured: 200 maps
/// of about 1476^2 px prepared and aligned together peaked at 6.4 GB with their images.)
pub fn kept_bytes(width: u32, height: u32) -> u64 {
    (u64::from(width) * u64::from(height)).saturating_mul(12)
}

/// Flag bit of [`Prepared::flags_fine`]: within 1.5 px of an occupied pixel (the local fit's test of a wall
/// landing on a wall). The scoring kernel reads only the three lower bits, so it rides along in a byte
/// the preparation keeps anyway, instead of a distance map of 4 bytes a pixel.
pub(in crate::merge) const FLAG_TOUCH: u8 = 8;
/// Flag bit of [`Prepared::flags_fine`] on a map's own occupied pixels: clutter, an occupied 8-connected
/// component whose bounding box is at most [`CLUTTER_PX`] a side (speckle, a chair, a person, a box):
/// what a second robot, another day, need not see, so its walls on the other map's free space are
/// the map's own noise, not a contradiction of the pose. Read by the local fit for the
/// building-independent measures only (`merge::pair::evidence`); the scoring kernel does not read it.
pub(in crate::merge) const FLAG_NOISE: u8 = 16;
/// An occupied component at most this many pixels a side is clutter ([`FLAG_NOISE`]): 0.8 m at the usual
/// 0.05 m a cell, what a person, a chair or a bin spans, and any speckle; a wall or a room's furniture
/// along it spans more. (Measured, the share of the walls it marks: the Halmstad sensor maps 0-8%, the
/// drawn floor plans 0%, their furnished copies up to 40% in an overlap; at 48 px it marks 2-16% of
/// the Halmstad maps' walls and excuses hardly more of their right poses' conflicts.)
pub const CLUTTER_PX: usize = 16;

/// Marks [`FLAG_NOISE`] in `flags` (a `w` x `h` crop's fine flags) on every pixel of each occupied
/// 8-connected component of `occ` whose bounding box is at most [`CLUTTER_PX`] a side. Each fill
/// stops as soon as it spans more or reaches a pixel settled before (a small component touches none),
/// so it holds at most a [`CLUTTER_PX`]-square's pixels, and the pass is linear in the crop.
fn mark_clutter(occ: Vec<bool>, w: usize, h: usize, flags: &mut [u8]) {
    // Each pixel: not occupied (0), occupied and not yet reached, in the current fill, settled.
    let mut state: Vec<u8> = occ.into_iter().map(u8::from).collect();
    let (mut stack, mut fill) = (Vec::new(), Vec::new());
    for start in 0..w * h {
        if state[start] != OPEN {
            continue;
        }
        stack.clear();
        fill.clear();
        state[start] = FILLING;
        stack.push(start);
        let small = fill_small(&mut state, w, h, &mut stack, &mut fill);
        for &i in fill.iter().chain(&stack) {
            state[i] = SETTLED;
            if small {
                flags[i] |= FLAG_NOISE;
            }
        }
    }
}

/// [`mark_clutter`]'s states of an occupied pixel: not yet reached, in the current fill, settled.
const OPEN: u8 = 1;
const FILLING: u8 = 2;
const SETTLED: u8 = 3;

/// Grows the fill from `stack` (its pixels moved into `fill` as they are reached) over the occupied
/// 8-neighbours: whether the whole component was reached within [`CLUTTER_PX`] a side (clutter); false
/// as soon as it spans more or touches a pixel settled before (then it is part of a larger one).
fn fill_small(
    state: &mut [u8],
    w: usize,
    h: usize,
    stack: &mut Vec<usize>,
    fill: &mut Vec<usize>,
) -> bool {
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    while let Some(i) = stack.pop() {
        fill.push(i);
        let (x, y) = (i % w, i / w);
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
        if (x1 - x0).max(y1 - y0) >= CLUTTER_PX {
            return false;
        }
        for yy in y.saturating_sub(1)..(y + 2).min(h) {
            for xx in x.saturating_sub(1)..(x + 2).min(w) {
                let j = yy * w + xx;
                match state[j] {
                    OPEN => {
                        state[j] = FILLING;
                        stack.push(j);
                    }
                    SETTLED => return false,
                    _ => {}
                }
            }
        }
    }
    true
}

/// The share of a prepared map's wall pixels that are clutter ([`FLAG_NOISE`]): its own noise level,
/// from the map alone.
pub(in crate::merge) fn clutter_share(p: &Prepared) -> f64 {
    if p.flags_fine.flags.len() != p.w * p.h {
        return 0.0;
    }
    let noisy = p
        .walls
        .iter()
        .filter(|&&(x, y)| p.flags_fine.flags[y as usize * p.w + x as usize] & FLAG_NOISE != 0)
        .count();
    noisy as f64 / p.walls.len().max(1) as f64
}

/// The part of `map` a preparation holds: its known area's bounding box plus [`PAD`] px, within the map
/// (the whole map when nothing is known), as (x0, y0, x1, y1), ends exclusive.
pub fn crop_box(map: &OccupancyMap) -> (usize, usize, usize, usize) {
    let classes = ClassTable::new(&map.thresholds);
    let img = &map.image;
    let (fw, fh) = (img.width() as usize, img.height() as usize);
    let (mut x0, mut y0, mut x1, mut y1) = (fw, fh, 0, 0);
    for (y, row) in img.pixels().chunks_exact(fw.max(1)).enumerate() {
        let known = |v: &u8| classes.state(*v) != CellState::Unknown;
        let (Some(first), Some(last)) = (row.iter().position(known), row.iter().rposition(known))
        else {
            continue;
        };
        (x0, y0, x1, y1) = (x0.min(first), y0.min(y), x1.max(last + 1), y1.max(y + 1));
    }
    if x1 <= x0 {
        return (0, 0, fw, fh);
    }
    (
        x0.saturating_sub(PAD),
        y0.saturating_sub(PAD),
        (x1 + PAD).min(fw),
        (y1 + PAD).min(fh),
    )
}

/// The margin a preparation keeps around a map's known area, pixels.
pub const CROP_PAD: usize = PAD;

/// A map prepared for alignment.
pub struct Prepared {
    /// Crop origin in the map, pixels.
    pub(in crate::merge) off: (f64, f64),
    pub(in crate::merge) w: usize,
    pub(in crate::merge) h: usize,
    /// Wall pixels, crop coordinates.
    pub(in crate::merge) walls: Vec<(f64, f64)>,
    /// The same, as the scoring kernel takes them.
    pub(in crate::merge) wall_points: Vec<[u32; 2]>,
    /// An even sample of them (at most [`SCREEN_POINTS`]), for screening many coarse hypotheses.
    pub(in crate::merge) screen_points: Vec<[u32; 2]>,
    /// What another map's walls landing on each pixel count as (the scoring kernel's target): inside
    /// (known, or within 5 px of a wall), near a wall (within 5 px), deep in free space (over 20 px).
    pub(in crate::merge) flags: ScoreTarget,
    /// The same at a finer tolerance: near = on an occupied pixel (the sub-pixel polish), deep over 3 px
    /// (the contradiction veto); and [`FLAG_TOUCH`] and [`FLAG_NOISE`], which the scoring kernel does
    /// not read.
    pub(in crate::merge) flags_fine: ScoreTarget,
    /// The screening's target: near within 5 px, deep over 20 px, and (the inside bit) over 8 px deep (a
    /// wall landing in a room's free space away from its walls: what tells a wrong placement in a building
    /// of many like rooms).
    pub(in crate::merge) flags_screen: ScoreTarget,
    /// An even sample of the free pixels (at most [`FREE_POINTS`]).
    pub(in crate::merge) free_points: Vec<[u32; 2]>,
    /// What another map's free pixels landing on each pixel count as: known, free, occupied.
    pub(in crate::merge) flags_free: ScoreTarget,
    /// The nearest wall pixel (crop index; `u32::MAX` without walls), ICP's target.
    pub(in crate::merge) nearest: Vec<u32>,
    /// Wall bounding box corners and centroid.
    pub(in crate::merge) reference: [(f64, f64); 5],
    /// Dominant wall direction, degrees in [0, 90).
    pub(in crate::merge) angle: f64,
    /// Corners for corner hypotheses (crop coordinates), when prepared with them.
    pub(in crate::merge) corners: Option<Vec<(f64, f64)>>,
    /// Its self-symmetry, once measured (the aligner's `self_symmetry`).
    pub(crate) symmetry: std::sync::OnceLock<Symmetry>,
    /// The coarse masks, one level per cell side of [`CELLS`]: the coarsest always, a finer one when
    /// this map is small enough for it to be chosen.
    pub(in crate::merge) levels: Vec<Option<Coarse>>,
}

/// How a map matches itself: its best self-match other than the identity, and the transforms (its pixels
/// to its own) under which it matches itself well enough to misplace another map by them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Symmetry {
    /// the aligner's `self_symmetry`.
    pub value: f64,
    /// Its best self-match under a shift (turned by under 10 degrees): how well the map repeats itself.
    pub repeat: f64,
    /// Self-transforms with a self-match of at least the aligner's `ALIAS_SELF_MATCH`.
    pub transforms: Vec<crate::merge::transform::Rigid>,
    /// Time its measurement took, milliseconds: `merge-eval` reports it per map, apart from the time
    /// of the pair whose alignment first needed it.
    pub ms: f64,
}

/// A map's coarse masks at one cell side.
pub(in crate::merge) struct Coarse {
    /// Cell side, pixels.
    pub(in crate::merge) cell: usize,
    /// Cells across and down.
    pub(in crate::merge) cw: usize,
    pub(in crate::merge) ch: usize,
    /// Cells with a wall pixel that is not speckle.
    pub(in crate::merge) cwall: Vec<f32>,
    /// The same dilated by a cell.
    pub(in crate::merge) cwall_dil: Vec<f32>,
    /// Cells mostly free and at least a cell from any wall cell.
    pub(in crate::merge) cfree: Vec<f32>,
}

impl Coarse {
    fn new(solid: &[bool], free: &[bool], w: usize, h: usize, cell: usize) -> Coarse {
        let (cw, ch) = (w.div_ceil(cell), h.div_ceil(cell));
        let mut cwall = vec![0f32; cw * ch];
        let mut n_free = vec![0usize; cw * ch];
        for y in 0..h {
            for x in 0..w {
                let c = (y / cell) * cw + x / cell;
                if solid[y * w + x] {
                    cwall[c] = 1.0;
                }
                n_free[c] += usize::from(free[y * w + x]);
            }
        }
        let cwall_dil = morph(&cwall, cw, ch, true);
        let cfree = (0..cw * ch)
            .map(|c| {
                f32::from(u8::from(
                    n_free[c] * 2 >= cell * cell && cwall_dil[c] == 0.0,
                ))
            })
            .collect();
        Coarse {
            cell,
            cw,
            ch,
            cwall,
            cwall_dil,
            cfree,
        }
    }
}

impl Prepared {
    /// Prepares `map` (read with its thresholds).
    pub fn new(map: &OccupancyMap) -> Prepared {
        let classes = ClassTable::new(&map.thresholds);
        let img = &map.image;
        let fw = img.width() as usize;
        let state = |x: usize, y: usize| classes.state(img.pixels()[y * fw + x]);
        let (x0, y0, x1, y1) = crop_box(map);
        let (w, h) = (x1 - x0, y1 - y0);
        let mut occ = vec![false; w * h];
        let mut free = vec![false; w * h];
        let mut known = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let s = state(x + x0, y + y0);
                occ[y * w + x] = s == CellState::Occupied;
                free[y * w + x] = s == CellState::Free;
                known[y * w + x] = s != CellState::Unknown;
            }
        }
        // Row by row on every core, in row order.
        let walls: Vec<(f64, f64)> = {
            use rayon::prelude::*;
            (0..h)
                .into_par_iter()
                .flat_map_iter(|y| {
                    let (occ, free) = (&occ, &free);
                    (0..w).filter_map(move |x| {
                        let touches_free = occ[y * w + x]
                            && (y.saturating_sub(1)..(y + 2).min(h)).any(|yy| {
                                (x.saturating_sub(1)..(x + 2).min(w)).any(|xx| free[yy * w + xx])
                            });
                        touches_free.then_some((x as f64, y as f64))
                    })
                })
                .collect()
        };
        // ICP pulls walls onto the other map's nearest wall pixel (occupied, next to free space): inside a
        // thick wall every occupied pixel is its own nearest, which would hold an estimate off by a pixel.
        let mut boundary = vec![false; w * h];
        for &(x, y) in &walls {
            boundary[y as usize * w + x as usize] = true;
        }
        let not_free: Vec<bool> = free.iter().map(|&f| !f).collect();
        // The three distance maps at once (on every core).
        let (dist, ((_, nearest), free_depth)) = rayon::join(
            || edt_distance(&occ, w, h),
            || rayon::join(|| edt(&boundary, w, h), || edt_distance(&not_free, w, h)),
        );
        let angle = dominant_angle(&walls);
        let reference = reference_points(&walls);
        let wall_points: Vec<[u32; 2]> = walls.iter().map(|&(x, y)| [x as u32, y as u32]).collect();
        let screen_points = wall_points
            .iter()
            .step_by(wall_points.len().div_ceil(SCREEN_POINTS).max(1))
            .copied()
            .collect();
        // The scoring kernel's four flag targets, a byte a pixel: (inside, near, deep) bits as each
        // probe reads them.
        let inside = |i: usize| u8::from(known[i] || dist[i] <= 5.0) * FLAG_INSIDE;
        // Verification: inside, near a wall within 5 px, over 20 px deep.
        let verification = |i: usize| {
            inside(i)
                + u8::from(dist[i] <= 5.0) * FLAG_NEAR
                + u8::from(free_depth[i] > 20.0) * FLAG_DEEP
        };
        // The polish and the veto: inside, on an occupied pixel, over 3 px deep.
        let fine = |i: usize| {
            inside(i)
                + u8::from(occ[i]) * FLAG_NEAR
                + u8::from(free_depth[i] > 3.0) * FLAG_DEEP
                + u8::from(dist[i] <= 1.5) * FLAG_TOUCH
        };
        // The screening's own bits: near (within 5 px), deep (over 20 px), and in the place of inside,
        // over 8 px deep.
        let screening = |i: usize| {
            u8::from(free_depth[i] > 8.0) * FLAG_INSIDE
                + u8::from(dist[i] <= 5.0) * FLAG_NEAR
                + u8::from(free_depth[i] > 20.0) * FLAG_DEEP
        };
        // Free space: known, free, occupied.
        let free_space = |i: usize| {
            u8::from(known[i]) * FLAG_INSIDE
                + u8::from(free[i]) * FLAG_NEAR
                + u8::from(occ[i]) * FLAG_DEEP
        };
        let specs: [&(dyn Fn(usize) -> u8 + Sync); 4] =
            [&verification, &fine, &screening, &free_space];
        // The crop is at most MAX_FFT cells a side wherever it is aligned; a larger one is refused there.
        let target = |f: &&(dyn Fn(usize) -> u8 + Sync)| ScoreTarget {
            width: w as u32,
            height: h as u32,
            flags: (0..w * h).map(f).collect(),
        };
        // The targets and the coarse levels are independent: built on every core.
        let (targets, levels) = rayon::join(
            || {
                use rayon::prelude::*;
                specs.par_iter().map(target).collect::<Vec<_>>()
            },
            || coarse_levels(&occ, &free, w, h),
        );
        let Ok([flags, mut flags_fine, flags_screen, flags_free]) =
            <[ScoreTarget; 4]>::try_from(targets)
        else {
            unreachable!("four specs make four targets");
        };
        mark_clutter(occ, w, h, &mut flags_fine.flags);
        let n_free = free.iter().filter(|&&f| f).count();
        let free_points = (0..w * h)
            .filter(|&i| free[i])
            .step_by(n_free.div_ceil(FREE_POINTS).max(1))
            .map(|i| [(i % w) as u32, (i / w) as u32])
            .collect();
        Prepared {
            off: (x0 as f64, y0 as f64),
            w,
            h,
            walls,
            wall_points,
            screen_points,
            flags,
            flags_fine,
            flags_screen,
            free_points,
            flags_free,
            nearest,
            reference,
            angle,
            corners: None,
            symmetry: std::sync::OnceLock::new(),
            levels,
        }
    }

    /// [`Prepared::new`] with `detector`'s corners for corner hypotheses.
    pub fn with_corners(
        map: &OccupancyMap,
        detector: crate::backend::DetectorKind,
    ) -> crate::support::error::Result<Prepared> {
        let mut p = Prepared::new(map);
        let (ox, oy) = p.off;
        p.corners = Some(
            crate::merge::pair::hypotheses::corners(map, detector)?
                .into_iter()
                .map(|(x, y)| (x - ox, y - oy))
                .filter(|&(x, y)| x >= 0.0 && y >= 0.0 && x < p.w as f64 && y < p.h as f64)
                .collect(),
        );
        Ok(p)
    }

    /// Its wall bounding box corners and centroid (the centroid last), in the map's own pixels.
    pub(in crate::merge) fn reference_in_map(&self) -> [(f64, f64); 5] {
        self.reference
            .map(|(x, y)| (x + self.off.0, y + self.off.1))
    }

    /// The corners of its known area's bounding box (plus the margin), in the map's own pixels.
    pub(in crate::merge) fn bounds_in_map(&self) -> [(f64, f64); 4] {
        let (x0, y0) = self.off;
        let (x1, y1) = (x0 + self.w as f64 - 1.0, y0 + self.h as f64 - 1.0);
        [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
    }

    /// Whether it holds what aligning reads (a preparation read in its placement form does not:
    /// [`crate::merge::many::codec::Form::Placement`]).
    pub(in crate::merge) fn can_align(&self) -> bool {
        self.nearest.len() == self.w * self.h && !self.levels.is_empty()
    }

    /// Whether it has enough walls next to free space to be aligned at all.
    pub(in crate::merge) fn alignable(&self) -> bool {
        self.walls.len() >= 20
    }

    /// Crop index of the pixel nearest to (x, y), if inside the crop.
    #[inline]
    pub(in crate::merge) fn index(&self, x: f64, y: f64) -> Option<usize> {
        // Rounding half up by truncation, which is floor for the non-negative values kept (`f64::round`
        // is a libm call, and this runs millions of times a pair).
        let (x, y) = (x + 0.5, y + 0.5);
        (x >= 0.0 && y >= 0.0 && x < self.w as f64 && y < self.h as f64)
            .then(|| y as usize * self.w + x as usize)
    }
}

/// The coarse levels of [`CELLS`] a `w` x `h` map may use: the coarsest always, a finer one when the map
/// spans at most [`crate::merge::pair::fft::FINE_FFT`] of its cells. Their walls leave out speckle (an occupied pixel
/// with no occupied 8-neighbour).
fn coarse_levels(occ: &[bool], free: &[bool], w: usize, h: usize) -> Vec<Option<Coarse>> {
    let mut solid = vec![false; w * h];
    for y in 0..h {
        let rows = y.saturating_sub(1)..(y + 2).min(h);
        for x in (0..w).filter(|&x| occ[y * w + x]) {
            let cols = x.saturating_sub(1)..(x + 2).min(w);
            solid[y * w + x] = rows.clone().any(|yy| {
                cols.clone()
                    .any(|xx| (xx, yy) != (x, y) && occ[yy * w + xx])
            });
        }
    }
    CELLS
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            let usable = w.max(h).div_ceil(c) <= crate::merge::pair::fft::FINE_FFT;
            (usable || i == CELLS.len() - 1).then(|| Coarse::new(&solid, free, w, h, c))
        })
        .collect()
}

/// 3 x 3 dilation (max) or erosion (min) of a coarse mask; outside the mask does not count.
fn morph(m: &[f32], w: usize, h: usize, dilate: bool) -> Vec<f32> {
    let mut out = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut v = m[y * w + x];
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    v = if dilate {
                        v.max(m[yy * w + xx])
                    } else {
                        v.min(m[yy * w + xx])
                    };
                }
            }
            out[y * w + x] = v;
        }
    }
    out
}

fn reference_points(walls: &[(f64, f64)]) -> [(f64, f64); 5] {
    if walls.is_empty() {
        return [(0.0, 0.0); 5];
    }
    let (mut lo, mut hi, mut sum) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN), (0.0, 0.0));
    for &(x, y) in walls {
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
        sum = (sum.0 + x, sum.1 + y);
    }
    let n = walls.len() as f64;
    [lo, hi, (lo.0, hi.1), (hi.0, lo.1), (sum.0 / n, sum.1 / n)]
}

/// Dominant wall direction in [0, 90): the angle maximising the sum of squared 1-px histogram counts of
/// the wall pixels projected on both axes (1-degree steps, then 0.1 around the best).
fn dominant_angle(walls: &[(f64, f64)]) -> f64 {
    if walls.is_empty() {
        return 0.0;
    }
    let score = |deg: f64| {
        let (s, c) = deg.to_radians().sin_cos();
        let mut total = 0.0;
        for axis in 0..2 {
            // Rounded to the nearest integer by truncating a positive value (`round` is a libm call).
            const OFFSET: f64 = (1u64 << 40) as f64;
            let proj = |&(x, y): &(f64, f64)| -> i64 {
                let v = if axis == 0 {
                    x * c + y * s
                } else {
                    -x * s + y * c
                };
                (v + 0.5 + OFFSET) as i64 - (1i64 << 40)
            };
            let lo = walls.iter().map(proj).min().unwrap_or(0);
            let hi = walls.iter().map(proj).max().unwrap_or(0);
            let mut hist = vec![0u32; (hi - lo + 1) as usize];
            for p in walls {
                hist[(proj(p) - lo) as usize] += 1;
            }
            total += hist
                .iter()
                .map(|&n| f64::from(n) * f64::from(n))
                .sum::<f64>();
        }
        total
    };
    // The 90 whole degrees on every core; the first best kept, as a loop in order would.
    let scores: Vec<f64> = {
        use rayon::prelude::*;
        (0..90)
            .into_par_iter()
            .map(|d| score(f64::from(d)))
            .collect()
    };
    let mut best = (-1.0, 0.0);
    for (d, &v) in scores.iter().enumerate() {
        if v > best.0 {
            best = (v, d as f64);
        }
    }
    let a0 = best.1;
    for k in -10..=10 {
        let d = a0 + f64::from(k) / 10.0;
        let v = score(d);
        if v > best.0 {
            best = (v, d);
        }
    }
    best.1.rem_euclid(90.0)
}
