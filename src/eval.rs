//! Repeatability (Schmid et al.): how many keypoints survive a known transform of the map.
//!
//! Detect on a map and on a transformed copy, map the first set through the known transform, and count the
//! keypoints within `tolerance` pixels of a keypoint of the second set, over the region both maps see,
//! divided by the smaller of the two counts in that region.

use crate::detector::{Detector, Keypoint};
use crate::error::Result;
use crate::map::{MapImage, OccupancyMap};
use crate::synth::{Rng, FREE, OCCUPIED, UNKNOWN};

/// A known change of a map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Transform {
    /// Turn by `k` quarter turns clockwise (exact).
    Rot90(u32),
    /// Mirror left to right (exact).
    Mirror,
    /// Rotate by `degrees` about the map centre, then shift by (tx, ty) pixels; nearest-neighbour
    /// resampling, unknown where the source is outside the map. Same size as the input.
    Rotate {
        /// Angle, degrees, clockwise in image coordinates (y down).
        degrees: f64,
        /// Shift right, pixels.
        tx: f64,
        /// Shift down, pixels.
        ty: f64,
    },
    /// SLAM-like noise: flip `speckle` of the free and occupied cells (free to occupied and back), and move
    /// `jitter` of the wall cells that touch free space by one pixel into it. Seeded.
    Noise {
        /// Fraction of free and occupied cells flipped.
        speckle: f64,
        /// Fraction of wall-boundary cells moved.
        jitter: f64,
        /// Seed of the noise.
        seed: u64,
    },
    /// Two crops of the map sharing `overlap` (0..1) of their width: the first is the left part, the second
    /// the right part. Keypoints are compared in the shared part.
    Overlap {
        /// Fraction of each crop's width that the other crop also sees.
        overlap: f64,
    },
}

/// The pair of maps to compare, and how points of the first map into the second.
pub struct Pair {
    /// The first map (the input, or its left crop).
    pub first: MapImage,
    /// The second map.
    pub second: MapImage,
    transform: Transform,
    w: u32,
    h: u32,
    shift: u32,
}

fn centre(p: &Keypoint) -> (f64, f64) {
    (p.x as f64 + 0.5, p.y as f64 + 0.5)
}

impl Pair {
    /// Applies `t` to `map`.
    pub fn new(map: &MapImage, t: Transform) -> Result<Self> {
        let (w, h) = (map.width(), map.height());
        let mut shift = 0;
        let (first, second) = match t {
            Transform::Rot90(k) => {
                let mut m = map.clone();
                for _ in 0..k % 4 {
                    m = rotate90(&m);
                }
                (map.clone(), m)
            }
            Transform::Mirror => (map.clone(), mirror(map)),
            Transform::Rotate { degrees, tx, ty } => (map.clone(), rotate(map, degrees, tx, ty)),
            Transform::Noise {
                speckle,
                jitter,
                seed,
            } => (map.clone(), noise(map, speckle, jitter, seed)),
            Transform::Overlap { overlap } => {
                let o = overlap.clamp(0.0, 1.0);
                let cw = ((f64::from(w) / (2.0 - o)).round() as u32).clamp(1, w);
                shift = w - cw;
                (crop(map, 0, cw)?, crop(map, shift, cw)?)
            }
        };
        Ok(Pair {
            first,
            second,
            transform: t,
            w,
            h,
            shift,
        })
    }

    /// Where a point (pixel-centre coordinates) of the first map lands in the second, if it does.
    pub fn forward(&self, (x, y): (f64, f64)) -> Option<(f64, f64)> {
        let (w, h) = (f64::from(self.w), f64::from(self.h));
        let p = match self.transform {
            Transform::Rot90(k) => {
                // One clockwise quarter turn of a W x H map: (x, y) -> (H - y, x) in an H x W map.
                let (mut x, mut y, mut ww, mut hh) = (x, y, w, h);
                for _ in 0..k % 4 {
                    (x, y) = (hh - y, x);
                    std::mem::swap(&mut ww, &mut hh);
                }
                (x, y)
            }
            Transform::Mirror => (w - x, y),
            Transform::Rotate { degrees, tx, ty } => {
                let (s, c) = degrees.to_radians().sin_cos();
                let (dx, dy) = (x - w / 2.0, y - h / 2.0);
                (
                    c * dx - s * dy + w / 2.0 + tx,
                    s * dx + c * dy + h / 2.0 + ty,
                )
            }
            Transform::Noise { .. } => (x, y),
            Transform::Overlap { .. } => (x - f64::from(self.shift), y),
        };
        let (sw, sh) = (
            f64::from(self.second.width()),
            f64::from(self.second.height()),
        );
        (p.0 >= 0.0 && p.1 >= 0.0 && p.0 < sw && p.1 < sh).then_some(p)
    }

    /// Whether a point of the second map was seen by the first (its pre-image lies inside the first map).
    pub fn seen_by_first(&self, (x, y): (f64, f64)) -> bool {
        let (w, h) = (f64::from(self.w), f64::from(self.h));
        match self.transform {
            Transform::Rotate { degrees, tx, ty } => {
                let (s, c) = degrees.to_radians().sin_cos();
                let (dx, dy) = (x - w / 2.0 - tx, y - h / 2.0 - ty);
                let (sx, sy) = (c * dx + s * dy + w / 2.0, -s * dx + c * dy + h / 2.0);
                sx >= 0.0 && sy >= 0.0 && sx < w && sy < h
            }
            Transform::Overlap { .. } => x + f64::from(self.shift) < f64::from(self.first.width()),
            _ => true,
        }
    }
}

/// Repeatability of `detector` under `pair`, or `None` when the shared region holds no keypoint.
pub fn repeatability(detector: &mut Detector, pair: &Pair, tolerance: f64) -> Result<Option<f64>> {
    let a = detector
        .detect(&OccupancyMap::from_image(pair.first.clone()))?
        .keypoints;
    let b = detector
        .detect(&OccupancyMap::from_image(pair.second.clone()))?
        .keypoints;
    Ok(score(pair, &a, &b, tolerance))
}

/// The repeatability of keypoint sets `a` (first map) and `b` (second map).
pub fn score(pair: &Pair, a: &[Keypoint], b: &[Keypoint], tolerance: f64) -> Option<f64> {
    let mapped: Vec<(f64, f64)> = a.iter().filter_map(|k| pair.forward(centre(k))).collect();
    let b: Vec<(f64, f64)> = b
        .iter()
        .map(centre)
        .filter(|&p| pair.seen_by_first(p))
        .collect();
    let n = mapped.len().min(b.len());
    if n == 0 {
        return None;
    }
    let t2 = tolerance * tolerance;
    let matched = mapped
        .iter()
        .filter(|&&(x, y)| {
            b.iter()
                .any(|&(bx, by)| (bx - x).powi(2) + (by - y).powi(2) <= t2)
        })
        .count();
    Some(matched.min(n) as f64 / n as f64)
}

/// Turns a map 90 degrees clockwise: pixel (x, y) goes to (h - 1 - y, x).
pub fn rotate90(img: &MapImage) -> MapImage {
    let (w, h) = (img.width(), img.height());
    let mut px = vec![0; img.len()];
    for y in 0..h {
        for x in 0..w {
            px[(x * h + (h - 1 - y)) as usize] = img.get(x, y);
        }
    }
    MapImage::new(h, w, px).expect("same pixel count")
}

/// Mirrors a map left to right.
pub fn mirror(img: &MapImage) -> MapImage {
    let (w, h) = (img.width(), img.height());
    let px = (0..h)
        .flat_map(|y| (0..w).rev().map(move |x| (x, y)))
        .map(|(x, y)| img.get(x, y))
        .collect();
    MapImage::new(w, h, px).expect("same pixel count")
}

fn rotate(img: &MapImage, degrees: f64, tx: f64, ty: f64) -> MapImage {
    let (w, h) = (img.width(), img.height());
    let (fw, fh) = (f64::from(w), f64::from(h));
    let (s, c) = degrees.to_radians().sin_cos();
    let mut px = Vec::with_capacity(img.len());
    for y in 0..h {
        for x in 0..w {
            // Inverse map of the output pixel's centre; nearest source pixel.
            let (dx, dy) = (
                f64::from(x) + 0.5 - fw / 2.0 - tx,
                f64::from(y) + 0.5 - fh / 2.0 - ty,
            );
            let (sx, sy) = (c * dx + s * dy + fw / 2.0, -s * dx + c * dy + fh / 2.0);
            px.push(if sx >= 0.0 && sy >= 0.0 && sx < fw && sy < fh {
                img.get(sx as u32, sy as u32)
            } else {
                UNKNOWN
            });
        }
    }
    MapImage::new(w, h, px).expect("same size")
}

fn noise(img: &MapImage, speckle: f64, jitter: f64, seed: u64) -> MapImage {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let src = img.pixels();
    let mut px = src.to_vec();
    let mut rng = Rng::new(seed);
    for (i, &v) in src.iter().enumerate() {
        let (x, y) = (i % w, i / w);
        if (v == FREE || v == OCCUPIED) && rng.chance(speckle) {
            px[i] = if v == FREE { OCCUPIED } else { FREE };
            continue;
        }
        if v == OCCUPIED && jitter > 0.0 {
            let free_nb: Vec<usize> = [(0i64, -1i64), (1, 0), (0, 1), (-1, 0)]
                .iter()
                .filter_map(|&(dx, dy)| {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    (nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h)
                        .then(|| ny as usize * w + nx as usize)
                })
                .filter(|&j| src[j] == FREE)
                .collect();
            if !free_nb.is_empty() && rng.chance(jitter) {
                // The wall cell moves one pixel into free space.
                let j = free_nb[rng.range(0, free_nb.len() as u32) as usize];
                px[j] = OCCUPIED;
                px[i] = FREE;
            }
        }
    }
    MapImage::new(img.width(), img.height(), px).expect("same size")
}

fn crop(img: &MapImage, x0: u32, cw: u32) -> Result<MapImage> {
    let px = (0..img.height())
        .flat_map(|y| (x0..x0 + cw).map(move |x| (x, y)))
        .map(|(x, y)| img.get(x, y))
        .collect();
    MapImage::new(cw, img.height(), px)
}

/// One measured condition of `eval`: a family of transforms at one level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Condition {
    /// `rot90`, `rot180`, `rot270`, `mirror`, `rotation`, `noise` or `overlap`.
    pub name: &'static str,
    /// Degrees for `rotation`, the noise fraction for `noise`, the shared fraction for `overlap`; 0 else.
    pub level: f64,
}

/// The conditions `eval` measures: exact turns and mirror, rotations with translation, noise levels,
/// partial overlaps.
pub fn conditions() -> Vec<Condition> {
    let mut v: Vec<Condition> = ["rot90", "rot180", "rot270", "mirror"]
        .into_iter()
        .map(|name| Condition { name, level: 0.0 })
        .collect();
    v.extend([15.0, 30.0, 45.0, 60.0, 75.0].map(|level| Condition {
        name: "rotation",
        level,
    }));
    v.extend([0.001, 0.005, 0.01, 0.02, 0.05].map(|level| Condition {
        name: "noise",
        level,
    }));
    v.extend([0.3, 0.5, 0.7].map(|level| Condition {
        name: "overlap",
        level,
    }));
    v
}

impl Condition {
    /// Whether every trial is the same transform (so one trial suffices).
    pub fn is_exact(&self) -> bool {
        matches!(
            self.name,
            "rot90" | "rot180" | "rot270" | "mirror" | "overlap"
        )
    }

    /// The transform of trial `trial` (seeded: the same seed and trial give the same transform).
    pub fn transform(&self, w: u32, h: u32, seed: u64, trial: u64) -> Transform {
        let mut rng = Rng::new(seed ^ trial.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        match self.name {
            "rot90" => Transform::Rot90(1),
            "rot180" => Transform::Rot90(2),
            "rot270" => Transform::Rot90(3),
            "mirror" => Transform::Mirror,
            "rotation" => {
                // A shift of up to a tenth of the map's size either way.
                let mut shift =
                    |n: u32| (f64::from(rng.range(0, 2001)) / 1000.0 - 1.0) * f64::from(n) / 10.0;
                let (tx, ty) = (shift(w), shift(h));
                Transform::Rotate {
                    degrees: self.level,
                    tx,
                    ty,
                }
            }
            "noise" => Transform::Noise {
                speckle: self.level,
                jitter: self.level,
                seed: rng.next_u64(),
            },
            _ => Transform::Overlap {
                overlap: self.level,
            },
        }
    }
}
