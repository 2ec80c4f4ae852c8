//! The map's dominant wall direction, modulo 90 degrees: the angle at which the wall boundary pixels
//! line up best along rows and columns (a projection profile, as document-deskewing does).
//!
//! The boundary pixels are the occupied pixels with a free 4-neighbour; for each candidate angle they
//! are projected on both axes of the turned frame and binned, and the angle whose histograms have the
//! largest sum of squared counts wins (straight walls pile their pixels into a few bins). Host code,
//! shared by every backend, so the angle is the same whatever runs the kernels.

use rayon::prelude::*;

use crate::fast::bitplanes::{plane_row, words, ValueSet};
use crate::map::MapImage;
use crate::states::{CellState, ClassTable};

/// Boundary pixels used at most: a deterministic, evenly strided subset beyond this.
pub const MAX_POINTS: usize = 16384;

/// The dominant wall direction in degrees, in [-45, 45): the angle to turn the map by so that its walls
/// run along rows and columns. 0 when the map has no wall boundary.
pub fn dominant_angle(image: &MapImage, classes: &ClassTable) -> f64 {
    let points = boundary_points(image, classes);
    if points.is_empty() {
        return 0.0;
    }
    // 1-degree steps with 2-pixel bins find the basin; 0.1-degree steps with 1-pixel bins refine it.
    // Every angle on every core; the scores come back in angle order, so the choice is the same.
    let scores: Vec<(f64, f64)> = (-45..45)
        .into_par_iter()
        .map_init(Vec::new, |hist, d| {
            let d = f64::from(d);
            (d, profile(&points, d, 2.0, hist))
        })
        .collect();
    let coarse = scores
        .iter()
        .fold((f64::NAN, -1.0), |best, &(d, s)| pick(best, d, s))
        .0;
    let fine: Vec<(f64, f64)> = (-10..=10)
        .into_par_iter()
        .map_init(Vec::new, |hist, k| {
            let d = coarse + f64::from(k) / 10.0;
            (d, profile(&points, d, 1.0, hist))
        })
        .collect();
    // A wall of n pixels scores the same over about 1/n radians: take the middle of the plateau of
    // near-best angles around the best one, not its first angle.
    let best = fine
        .iter()
        .enumerate()
        .fold(0, |b, (i, f)| if f.1 > fine[b].1 { i } else { b });
    let near = |i: usize| fine[i].1 >= fine[best].1 * (1.0 - 1e-3);
    let (mut lo, mut hi) = (best, best);
    while lo > 0 && near(lo - 1) {
        lo -= 1;
    }
    while hi + 1 < fine.len() && near(hi + 1) {
        hi += 1;
    }
    let fine = (fine[lo].0 + fine[hi].0) / 2.0;
    // Back into [-45, 45).
    (fine + 45.0).rem_euclid(90.0) - 45.0
}

fn pick(best: (f64, f64), angle: f64, score: f64) -> (f64, f64) {
    if score > best.1 {
        (angle, score)
    } else {
        best
    }
}

/// Sum of squared bin counts of the points projected on both axes of the frame turned by `degrees`.
fn profile(points: &[(f64, f64)], degrees: f64, bin: f64, hist: &mut Vec<u32>) -> f64 {
    let (s, c) = degrees.to_radians().sin_cos();
    let mut total = 0.0;
    for axis in 0..2 {
        let proj = |&(x, y): &(f64, f64)| {
            if axis == 0 {
                x * c + y * s
            } else {
                -x * s + y * c
            }
        };
        let (lo, hi) = points
            .iter()
            .map(proj)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        hist.clear();
        hist.resize(((hi - lo) / bin) as usize + 2, 0);
        for pt in points {
            hist[((proj(pt) - lo) / bin) as usize] += 1;
        }
        total += hist
            .iter()
            .map(|&n| f64::from(n) * f64::from(n))
            .sum::<f64>();
    }
    total
}

/// The occupied pixels with a free 4-neighbour, at most [`MAX_POINTS`] of them, evenly strided.
fn boundary_points(image: &MapImage, classes: &ClassTable) -> Vec<(f64, f64)> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let occ = ValueSet::of(classes, &[CellState::Occupied]);
    let free = ValueSet::of(classes, &[CellState::Free]);
    let n = words(w);
    let row = |y: usize| &image.pixels()[y * w..(y + 1) * w];
    let mut planes = vec![vec![0u64; n]; 4]; // occupied of row y; free of rows y - 1, y, y + 1
    let mut visit = |f: &mut dyn FnMut(usize, usize)| {
        for p in planes.iter_mut().skip(1) {
            p.fill(0);
        }
        plane_row(&free, row(0), &mut planes[3]);
        for y in 0..h {
            plane_row(&occ, row(y), &mut planes[0]);
            planes[1..].rotate_left(1);
            if y + 1 < h {
                plane_row(&free, row(y + 1), &mut planes[3]);
            } else {
                planes[3].fill(0);
            }
            let (o, up, mid, down) = (&planes[0], &planes[1], &planes[2], &planes[3]);
            for k in 0..n {
                let left = (mid[k] << 1) | if k > 0 { mid[k - 1] >> 63 } else { 0 };
                let right = (mid[k] >> 1) | if k + 1 < n { mid[k + 1] << 63 } else { 0 };
                let mut b = o[k] & (up[k] | down[k] | left | right);
                while b != 0 {
                    let j = b.trailing_zeros() as usize;
                    b &= b - 1;
                    f(k * 64 + j, y);
                }
            }
        }
    };
    let mut count = 0usize;
    visit(&mut |_, _| count += 1);
    let stride = count.div_ceil(MAX_POINTS).max(1);
    let mut points = Vec::with_capacity(count.min(MAX_POINTS));
    let mut i = 0usize;
    visit(&mut |x, y| {
        if i % stride == 0 {
            points.push((x as f64, y as f64));
        }
        i += 1;
    });
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A room of `side` pixels turned by `degrees`: its walls' direction is what the estimate finds.
    fn turned_room(degrees: f64) -> MapImage {
        let n = 240u32;
        let (s, c) = degrees.to_radians().sin_cos();
        let mut px = vec![205u8; (n * n) as usize];
        for y in 0..n {
            for x in 0..n {
                let (dx, dy) = (f64::from(x) - 120.0, f64::from(y) - 120.0);
                let (u, v) = (dx * c + dy * s, -dx * s + dy * c);
                let m = u.abs().max(v.abs());
                px[(y * n + x) as usize] = if m < 70.0 {
                    254
                } else if m < 74.0 {
                    0
                } else {
                    205
                };
            }
        }
        MapImage::new(n, n, px).unwrap()
    }

    #[test]
    fn the_angle_of_a_turned_room_is_found_modulo_90_degrees() {
        for deg in [0.0, 7.0, -20.0, 33.3, 80.0] {
            let got = dominant_angle(&turned_room(deg), &ClassTable::default());
            let want = (deg + 45.0f64).rem_euclid(90.0) - 45.0;
            assert!((got - want).abs() <= 0.3, "{deg}: got {got}");
        }
        let blank = MapImage::filled(50, 40, 254).unwrap();
        assert_eq!(dominant_angle(&blank, &ClassTable::default()), 0.0);
    }
}
