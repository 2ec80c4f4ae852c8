//! Small partial maps: two square windows of one map, as two robots' maps are early in an exploration,
//! overlapping by a share of their side or apart (then any merge of them is wrong).

use crate::map::states::{CellState, ClassTable, UNKNOWN};
use crate::map::synthetic::Rng;
use crate::map::{MapImage, OccupancyMap};
use crate::measure::synthetic::{
    box_points, turned, written, SyntheticPair, SYNTHETIC_RMS_LIMIT_PX,
};
use crate::merge::transform::Rigid;

/// How to cut two small windows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CropSpec {
    /// The windows' side, pixels (at least 32).
    pub side: u32,
    /// Share of the side the windows share along the axis they are offset on; `None`: apart, by 8 to 40 px.
    pub overlap: Option<f64>,
    /// Speckle probability of free pixels.
    pub noise: f64,
}

/// Two windows of `source` as [`CropSpec`] says, B turned by a random angle into a square canvas;
/// deterministic in `seed`. `None` when no place in 40 tries gives two windows at least half known.
pub fn synthetic_crops(source: &OccupancyMap, spec: &CropSpec, seed: u64) -> Option<SyntheticPair> {
    let classes = ClassTable::new(&source.thresholds);
    let img = &source.image;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let state = |x: usize, y: usize| classes.state(img.pixels()[y * w + x]);
    let side = spec.side.max(32) as usize;
    let mut rng = Rng::new(seed);
    let known = |x0: usize, y0: usize| {
        let mut n = 0usize;
        for y in (y0..y0 + side).step_by(4) {
            for x in (x0..x0 + side).step_by(4) {
                n += usize::from(state(x, y) != CellState::Unknown);
            }
        }
        n as f64 / ((side / 4) * (side / 4)).max(1) as f64
    };
    for _ in 0..40 {
        let d = match spec.overlap {
            Some(o) => (side as f64 * (1.0 - o.clamp(0.05, 0.95))).round() as i64,
            None => (side + rng.range(8, 41) as usize) as i64,
        };
        let (dx, dy) = match rng.range(0, 4) {
            0 => (d, 0),
            1 => (-d, 0),
            2 => (0, d),
            _ => (0, -d),
        };
        let span = |len: usize, off: i64| {
            let lo = (-off).max(0);
            let hi = len as i64 - side as i64 - off.max(0);
            (hi > lo).then_some((lo, hi))
        };
        let (Some((xl, xh)), Some((yl, yh))) = (span(w, dx), span(h, dy)) else {
            return None;
        };
        let ax = rng.range(xl as u32, xh as u32) as usize;
        let ay = rng.range(yl as u32, yh as u32) as usize;
        let (bx, by) = ((ax as i64 + dx) as usize, (ay as i64 + dy) as usize);
        if known(ax, ay) < 0.5 || known(bx, by) < 0.5 {
            continue;
        }
        // A: its window cropped to its known area.
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for y in ay..ay + side {
            for x in ax..ax + side {
                if state(x, y) != CellState::Unknown {
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
                }
            }
        }
        let (aw, ah) = (x1 - x0, y1 - y0);
        let mut a_px = vec![UNKNOWN; aw * ah];
        for y in 0..ah {
            for x in 0..aw {
                a_px[y * aw + x] = written(state(x + x0, y + y0), spec.noise, &mut rng);
            }
        }
        let keep = |x: usize, y: usize| x >= bx && x < bx + side && y >= by && y < by + side;
        let margin = f64::from(rng.range(4, 24));
        let theta = f64::from(rng.range(0, 1 << 24)) / f64::from(1u32 << 24) * 360.0;
        let (b_px, bside, to_source, (kx0, ky0, kx1, ky1)) = turned(
            &state,
            (w, h),
            &keep,
            (bx, by, bx + side, by + side),
            theta,
            margin,
            &|p| p,
            &mut |s| written(s, spec.noise, &mut rng),
        )?;
        let truth = Rigid {
            tx: to_source.tx - x0 as f64,
            ty: to_source.ty - y0 as f64,
            ..to_source
        }
        .normalized();
        let check_points = box_points(kx0, ky0, kx1, ky1);
        let true_points = check_points.iter().map(|&p| truth.apply(p)).collect();
        let make = |w: usize, h: usize, px: Vec<u8>| {
            MapImage::new(w as u32, h as u32, px)
                .ok()
                .map(OccupancyMap::from_image)
        };
        return Some(SyntheticPair {
            a: make(aw, ah, a_px)?,
            b: make(bside, bside, b_px)?,
            truth,
            check_points,
            true_points,
            rms_limit_px: SYNTHETIC_RMS_LIMIT_PX,
            alias_contradiction: None,
            a_origin: (x0 as f64, y0 as f64),
        });
    }
    None
}
