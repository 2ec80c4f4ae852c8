//! Repeatability (Schmid et al.): how many keypoints survive a known transform of the map.
//!
//! Detect on a map and on a transformed copy, map the first set through the known transform, and count the
//! keypoints within `tolerance` pixels of a keypoint of the second set, over the region both maps see,
//! divided by the smaller of the two counts in that region.
//!
//! This file holds repeatability, its table and plots; `annotations.rs`, the recall of annotated corners;
//! `page.rs`, the `eval` page.

pub mod annotations;
pub mod page;

use std::io::{self, Write};

use image::{Rgb, RgbImage};
use serde::Serialize;

use crate::detect::detector::{DetectOptions, Detector, DetectorKind, Keypoint};
use crate::detect::output::{csv_field, md_cell, TableFormat};
use crate::map::synthetic::{Rng, FREE, OCCUPIED, UNKNOWN};
use crate::map::{GeoRef, MapImage, OccupancyMap};
use crate::support::error::{Error, Result};

/// Most random trials per condition `evaluate` runs (each trial is a transformed copy of the map).
pub const MAX_TRIALS: u32 = 1000;

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

impl Pair {
    /// The two maps as a user has them: two crops share the map's world frame (as a cropped map's yaml,
    /// or a SLAM map grown at its edges, keeps it: a pixel a metre, origin at the first crop's lower left
    /// corner); the other transforms make maps of their own, without one.
    pub fn maps(&self) -> (OccupancyMap, OccupancyMap) {
        let mut a = OccupancyMap::from_image(self.first.clone());
        let mut b = OccupancyMap::from_image(self.second.clone());
        if let Transform::Overlap { .. } = self.transform {
            let frame = |x: u32| GeoRef {
                resolution: 1.0,
                origin: [f64::from(x), 0.0, 0.0],
            };
            a.georef = Some(frame(0));
            b.georef = Some(frame(self.shift));
        }
        (a, b)
    }
}

/// Repeatability of `detector` under `pair`, or `None` when the shared region holds no keypoint.
pub fn repeatability(detector: &mut Detector, pair: &Pair, tolerance: f64) -> Result<Option<f64>> {
    let (first, second) = pair.maps();
    let a = detector.detect(&first)?.keypoints;
    let b = detector.detect(&second)?.keypoints;
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
    let grid = PointGrid::new(&b, tolerance);
    let matched = mapped
        .iter()
        .filter(|&&(x, y)| grid.has_within(x, y))
        .count();
    Some(matched.min(n) as f64 / n as f64)
}

/// Points in a grid of cells at least `radius` wide, to ask whether any lies within `radius` of a place:
/// such a point is in the 3 x 3 cells around it, so dense sets cost linear time, not all pairs.
pub(crate) struct PointGrid {
    cell: f64,
    r2: f64,
    cells: std::collections::HashMap<(i64, i64), Vec<(f64, f64)>>,
}

impl PointGrid {
    pub(crate) fn new(points: &[(f64, f64)], radius: f64) -> Self {
        let mut g = PointGrid {
            cell: radius.max(1.0),
            r2: radius * radius,
            cells: Default::default(),
        };
        for &(x, y) in points {
            let k = g.key(x, y);
            g.cells.entry(k).or_default().push((x, y));
        }
        g
    }

    fn key(&self, x: f64, y: f64) -> (i64, i64) {
        (
            (x / self.cell).floor() as i64,
            (y / self.cell).floor() as i64,
        )
    }

    /// Whether some point lies within the radius of (x, y).
    pub(crate) fn has_within(&self, x: f64, y: f64) -> bool {
        let (cx, cy) = self.key(x, y);
        (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                self.cells
                    .get(&(cx.saturating_add(dx), cy.saturating_add(dy)))
                    .is_some_and(|v| {
                        v.iter()
                            .any(|&(px, py)| (px - x).powi(2) + (py - y).powi(2) <= self.r2)
                    })
            })
        })
    }
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

/// One row of the evaluation: a detector's mean repeatability on a map under one condition.
#[derive(Serialize, Debug, Clone, PartialEq)]
pub struct EvalRecord {
    /// The map, as named by the caller.
    pub map: String,
    /// The detector's name.
    pub detector: &'static str,
    /// The condition's name ([`Condition::name`]).
    pub condition: &'static str,
    /// The condition's level ([`Condition::level`]).
    pub level: f64,
    /// Mean over the trials that had keypoints in the shared region; None when none had.
    pub repeatability: Option<f64>,
    /// Trials run.
    pub trials: u32,
}

/// Every detector of `kinds` (with the options of `base` otherwise) on `map` under every condition:
/// `trials` random trials per random condition, one per exact one. One transformed pair is in memory at
/// a time.
#[allow(clippy::too_many_arguments)]
pub fn evaluate(
    detector: &mut Detector,
    name: &str,
    map: &MapImage,
    kinds: &[DetectorKind],
    base: &DetectOptions,
    trials: u32,
    seed: u64,
    tolerance: f64,
) -> Result<Vec<EvalRecord>> {
    if !(1..=MAX_TRIALS).contains(&trials) {
        return Err(Error::invalid(format!(
            "trials must lie in 1..={MAX_TRIALS}, got {trials}"
        )));
    }
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        return Err(Error::invalid(format!(
            "tolerance must be >= 0, got {tolerance}"
        )));
    }
    let (w, h) = (map.width(), map.height());
    let mut rows = Vec::new();
    for cond in conditions() {
        let trials = if cond.is_exact() { 1 } else { trials };
        let mut scores: Vec<Vec<f64>> = vec![Vec::new(); kinds.len()];
        for t in 0..trials {
            let pair = Pair::new(map, cond.transform(w, h, seed, u64::from(t)))?;
            for (kind, s) in kinds.iter().zip(&mut scores) {
                detector.set_options(DetectOptions {
                    detector: *kind,
                    ..*base
                });
                s.extend(repeatability(detector, &pair, tolerance)?);
            }
        }
        for (kind, s) in kinds.iter().zip(scores) {
            rows.push(EvalRecord {
                map: name.to_string(),
                detector: kind.name(),
                condition: cond.name,
                level: cond.level,
                repeatability: (!s.is_empty()).then(|| s.iter().sum::<f64>() / s.len() as f64),
                trials,
            });
        }
    }
    Ok(rows)
}

/// Bytes [`evaluate`] allocates for a `width` x `height` map beyond the map and the detector: a pair of
/// transformed maps and the copies the detector reads.
pub fn evaluate_bytes(width: u32, height: u32) -> u64 {
    (u64::from(width) * u64::from(height)).saturating_mul(4)
}

/// Writes the rows as a Markdown table, CSV or JSON.
pub fn write_table(
    out: &mut dyn Write,
    format: TableFormat,
    rows: &[EvalRecord],
) -> io::Result<()> {
    match format {
        TableFormat::Json => {
            serde_json::to_writer_pretty(&mut *out, &rows)?;
            writeln!(out)?;
        }
        TableFormat::Csv => {
            writeln!(out, "map,detector,condition,level,repeatability,trials")?;
            for r in rows {
                let rep = r.repeatability.map_or(String::new(), |v| format!("{v:.4}"));
                writeln!(
                    out,
                    "{},{},{},{},{rep},{}",
                    csv_field(&r.map),
                    r.detector,
                    r.condition,
                    r.level,
                    r.trials
                )?;
            }
        }
        TableFormat::Md => {
            writeln!(
                out,
                "| map | detector | condition | level | repeatability | trials |"
            )?;
            writeln!(out, "|---|---|---|---|---|---|")?;
            for r in rows {
                let rep = r
                    .repeatability
                    .map_or("n/a".to_string(), |v| format!("{:.1}%", 100.0 * v));
                writeln!(
                    out,
                    "| {} | {} | {} | {} | {rep} | {} |",
                    md_cell(&r.map),
                    r.detector,
                    r.condition,
                    r.level,
                    r.trials
                )?;
            }
        }
    }
    out.flush()
}

/// The files [`repeatability_plots`] makes.
pub const PLOT_FILES: [&str; 2] = ["repeatability-noise.png", "repeatability-rotation.png"];

/// Plots of repeatability against noise and rotation, averaged over the maps, a line per detector:
/// `(file name, picture)` for `repeatability-noise.png` and `repeatability-rotation.png`.
pub fn repeatability_plots(rows: &[EvalRecord]) -> Vec<(&'static str, RgbImage)> {
    use crate::support::plot::{line_plot, Series};
    let mut plots = Vec::new();
    let colours = [
        ("ogm", Rgb([220, 20, 20])),
        ("ogm-robust", Rgb([130, 0, 160])),
        ("harris", Rgb([30, 90, 220])),
        ("shi-tomasi", Rgb([20, 160, 60])),
        ("trajkovic", Rgb([240, 140, 0])),
    ];
    for (cond, file, x_label, x_scale) in [
        (
            "noise",
            PLOT_FILES[0],
            "NOISE % (SPECKLE AND WALL JITTER)",
            100.0,
        ),
        (
            "rotation",
            PLOT_FILES[1],
            "ROTATION (DEGREES) WITH RANDOM SHIFT",
            1.0,
        ),
    ] {
        let series: Vec<Series> = colours
            .iter()
            .map(|(det, colour)| {
                let mut levels: Vec<f64> = rows
                    .iter()
                    .filter(|r| r.condition == cond && r.detector == *det)
                    .map(|r| r.level)
                    .collect();
                levels.sort_by(f64::total_cmp);
                levels.dedup();
                let points = levels
                    .into_iter()
                    .filter_map(|lv| {
                        let v: Vec<f64> = rows
                            .iter()
                            .filter(|r| r.condition == cond && r.detector == *det && r.level == lv)
                            .filter_map(|r| r.repeatability)
                            .collect();
                        (!v.is_empty())
                            .then(|| (lv * x_scale, v.iter().sum::<f64>() / v.len() as f64))
                    })
                    .collect();
                Series {
                    label: det.to_uppercase(),
                    colour: *colour,
                    points,
                }
            })
            .collect();
        let maps = rows
            .iter()
            .map(|r| &r.map)
            .collect::<std::collections::BTreeSet<_>>()
            .len();
        let title = format!("REPEATABILITY VS {} ({maps} MAPS)", cond.to_uppercase());
        plots.push((file, line_plot(&title, x_label, &series, 900, 520)));
    }
    plots
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid search finds exactly the matches of the all-pairs search it replaced.
    #[test]
    fn grid_matching_equals_all_pairs() {
        let mut rng = Rng::new(7);
        let map = MapImage::filled(64, 48, FREE).unwrap();
        let pair = Pair::new(&map, Transform::Mirror).unwrap();
        for tolerance in [0.0, 0.5, 1.0, 2.0, 3.7, 10.0, 1e300] {
            let pts = |rng: &mut Rng, n: u32| -> Vec<Keypoint> {
                (0..n)
                    .map(|_| Keypoint::scored(rng.range(0, 64), rng.range(0, 48), 0))
                    .collect()
            };
            let (a, b) = (pts(&mut rng, 200), pts(&mut rng, 150));
            let mapped: Vec<(f64, f64)> =
                a.iter().filter_map(|k| pair.forward(centre(k))).collect();
            let bs: Vec<(f64, f64)> = b
                .iter()
                .map(centre)
                .filter(|&p| pair.seen_by_first(p))
                .collect();
            let t2 = tolerance * tolerance;
            let brute = mapped
                .iter()
                .filter(|&&(x, y)| {
                    bs.iter()
                        .any(|&(bx, by)| (bx - x).powi(2) + (by - y).powi(2) <= t2)
                })
                .count();
            let n = mapped.len().min(bs.len());
            assert_eq!(
                score(&pair, &a, &b, tolerance),
                Some(brute.min(n) as f64 / n as f64),
                "tolerance {tolerance}"
            );
        }
    }
}
