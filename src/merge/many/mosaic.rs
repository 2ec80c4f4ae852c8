//! The merged map of many maps placed in one frame (a group of [`crate::merge::many`]), and its picture with
//! every map in its own colour. The cell rule is the two-map one ([`crate::merge::compose::merge_cell`]):
//! occupied where any map says occupied, else free where any says free.

use crate::map::states::{CellState, ClassTable};
use crate::map::{MapImage, OccupancyMap, Thresholds};
use crate::merge::compose::{grown_georef, merge_cell};
use crate::merge::transform::Rigid;
use crate::support::error::{Error, Result};

/// The canvas holding every map's known area placed by its pose, in the frame's pixels: `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame {
    /// First column (the frame's pixels; 0 or negative when a map reaches left of the frame's origin).
    pub x0: i64,
    /// First row.
    pub y0: i64,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
}

impl Frame {
    /// A map's pose in the frame as a transform to the merged map's pixels.
    pub fn to_canvas(&self, pose: &Rigid) -> Rigid {
        Rigid {
            tx: pose.tx - self.x0 as f64,
            ty: pose.ty - self.y0 as f64,
            ..*pose
        }
    }
}

/// Largest merged canvas of many maps, pixels, relative to the maps together: a fleet's maps along a
/// diagonal corridor leave most of their box unknown (ten maps sharing a fifth of their width in a
/// diagonal line fill a sixth of it), but a placement that spreads maps further is not a merge of one
/// place. (Two maps: [`crate::merge::compose::MAX_CANVAS_FACTOR`].)
pub const MAX_MANY_CANVAS_FACTOR: u64 = 16;

/// Coordinates further than this from a frame's origin, pixels, are no placement of a map.
const MAX_COORDINATE: f64 = (1u64 << 40) as f64;

/// A box of a map's pixels, inclusive: first column, first row, last column, last row.
pub type PixelBox = (u32, u32, u32, u32);

/// The bounding box of a map's known pixels (inclusive), if it has any.
fn known_box(m: &OccupancyMap) -> Option<PixelBox> {
    let classes = ClassTable::new(&m.thresholds);
    let w = m.image.width() as usize;
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (y, row) in m.image.pixels().chunks(w.max(1)).enumerate() {
        let known = |v: &u8| classes.state(*v) != CellState::Unknown;
        if let (Some(a), Some(b)) = (row.iter().position(known), row.iter().rposition(known)) {
            (x0, x1) = (x0.min(a as u32), x1.max(b as u32));
            (y0, y1) = (y0.min(y as u32), y1.max(y as u32));
        }
    }
    (x0 <= x1).then_some((x0, y0, x1, y1))
}

/// The bounding box (inclusive, rounded) of the map box `b` placed by `pose`.
fn placed_box((bx0, by0, bx1, by1): PixelBox, pose: &Rigid) -> (i64, i64, i64, i64) {
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    let (bx0, by0, bx1, by1) = (
        f64::from(bx0),
        f64::from(by0),
        f64::from(bx1),
        f64::from(by1),
    );
    for p in [(bx0, by0), (bx1, by0), (bx0, by1), (bx1, by1)] {
        let (x, y) = pose.apply(p);
        x0 = x0.min(x.round());
        y0 = y0.min(y.round());
        x1 = x1.max(x.round());
        y1 = y1.max(y.round());
    }
    (x0 as i64, y0 as i64, x1 as i64, y1 as i64)
}

/// The canvas of the known areas of `maps` placed by `poses` (unknown margins around them are left out);
/// fails when none has a known cell, a pose is not finite, or the canvas would exceed
/// [`MAX_MANY_CANVAS_FACTOR`] times the maps together (a placement that spreads maps so far apart is not a
/// merge of one place).
pub fn frame(maps: &[&OccupancyMap], poses: &[Rigid]) -> Result<Frame> {
    let placed: Vec<(PixelBox, Rigid)> = maps
        .iter()
        .zip(poses)
        .filter_map(|(m, p)| known_box(m).map(|b| (b, *p)))
        .collect();
    let total = maps
        .iter()
        .map(|m| m.image.len() as u64)
        .fold(0, u64::saturating_add);
    frame_of(&placed, total)
}

/// Whether maps whose known areas lie within `boxes` (inclusive, their own pixels), placed by `poses`,
/// fit one canvas by [`frame`]'s limit, relative to `total` pixels of maps: what a join of groups is
/// checked against before it is made.
pub fn fits(boxes: &[PixelBox], poses: &[Rigid], total: u64) -> bool {
    let placed: Vec<(PixelBox, Rigid)> = boxes.iter().copied().zip(poses.iter().copied()).collect();
    frame_of(&placed, total).is_ok()
}

/// The canvas of boxes placed by poses, limited relative to `total` pixels of maps.
fn frame_of(placed: &[(PixelBox, Rigid)], total: u64) -> Result<Frame> {
    let (mut x0, mut y0, mut x1, mut y1) = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
    for (b, p) in placed {
        let finite = [p.theta_deg, p.tx, p.ty]
            .iter()
            .all(|v| v.is_finite() && v.abs() < MAX_COORDINATE);
        if !finite {
            return Err(Error::invalid(format!(
                "a map's pose ({}, {}, {}) is no placement",
                p.theta_deg, p.tx, p.ty
            )));
        }
        let q = placed_box(*b, p);
        x0 = x0.min(q.0);
        y0 = y0.min(q.1);
        x1 = x1.max(q.2);
        y1 = y1.max(q.3);
    }
    if x0 > x1 {
        return Err(Error::invalid("no map to merge has a known cell"));
    }
    let (w, h) = ((x1 - x0 + 1) as u64, (y1 - y0 + 1) as u64);
    if w.saturating_mul(h) > total.saturating_mul(MAX_MANY_CANVAS_FACTOR)
        || w > u64::from(u32::MAX)
        || h > u64::from(u32::MAX)
    {
        return Err(Error::invalid(format!(
            "the merged map would be {w}x{h}: the maps land far apart"
        )));
    }
    Ok(Frame {
        x0,
        y0,
        width: w as u32,
        height: h as u32,
    })
}

/// Visits every canvas cell each map covers: `visit(canvas index, map number, state)`.
fn for_each_cell(
    maps: &[&OccupancyMap],
    poses: &[Rigid],
    f: &Frame,
    mut visit: impl FnMut(usize, usize, CellState),
) -> Result<()> {
    for (k, (m, pose)) in maps.iter().zip(poses).enumerate() {
        // Map by map, a raised stop (Ctrl-C in Python) ends the drawing.
        crate::support::stop::check()?;
        let classes = ClassTable::new(&m.thresholds);
        let (w, h) = (m.image.width(), m.image.height());
        let Some(known) = known_box(m) else { continue };
        // Clipped to the canvas: rounding may put a corner a pixel past it.
        let b = placed_box(known, pose);
        let inv = pose.inverse().applier();
        let (fx1, fy1) = (
            f.x0 + i64::from(f.width) - 1,
            f.y0 + i64::from(f.height) - 1,
        );
        for y in b.1.max(f.y0)..=b.3.min(fy1) {
            let cy = (y - f.y0) as usize;
            for x in b.0.max(f.x0)..=b.2.min(fx1) {
                let (mx, my) = inv.apply((x as f64, y as f64));
                let (mx, my) = (mx.round(), my.round());
                if mx < 0.0 || my < 0.0 || mx >= f64::from(w) || my >= f64::from(h) {
                    continue;
                }
                let state = classes.state(m.image.get(mx as u32, my as u32));
                visit(cy * f.width as usize + (x - f.x0) as usize, k, state);
            }
        }
    }
    Ok(())
}

/// The merged map of `maps` placed by `poses` (each map's pixels to the frame of the first map, whose
/// georeference it keeps, grown so that the first map's cells keep their world coordinates), and the
/// canvas.
pub fn compose_many(maps: &[&OccupancyMap], poses: &[Rigid]) -> Result<(OccupancyMap, Frame)> {
    let f = frame(maps, poses)?;
    let mut cells = vec![CellState::Unknown; f.width as usize * f.height as usize];
    for_each_cell(maps, poses, &f, |i, _, s| {
        cells[i] = merge_cell(cells[i], s)
    })?;
    let image = MapImage::new(
        f.width,
        f.height,
        cells.iter().map(|s| s.map_server_value()).collect(),
    )?;
    let georef = maps[0]
        .georef
        .map(|g| grown_georef(&g, maps[0].image.height(), f.x0, f.y0 + i64::from(f.height)));
    Ok((
        OccupancyMap {
            image,
            thresholds: Thresholds::default(),
            georef,
            image_path: None,
            yaml_path: None,
            warnings: Vec::new(),
        },
        f,
    ))
}

/// Wall colours of the maps, in turn (distinct on white and grey; the 13th map takes the first again).
pub const MAP_COLOURS: [[u8; 3]; 12] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [23, 190, 207],
    [188, 189, 34],
    [0, 0, 128],
    [128, 0, 0],
    [0, 100, 0],
];

/// The picture of a merge of many maps: unknown grey, free white, each wall pixel in the colour of the
/// first map (in the given order) with a wall there.
pub fn overlay_many(maps: &[&OccupancyMap], poses: &[Rigid]) -> Result<image::RgbImage> {
    let f = frame(maps, poses)?;
    const NONE: u16 = u16::MAX;
    const FREE: u16 = u16::MAX - 1;
    let mut owner = vec![NONE; f.width as usize * f.height as usize];
    for_each_cell(maps, poses, &f, |i, k, s| match s {
        CellState::Occupied if owner[i] >= FREE => owner[i] = k as u16,
        CellState::Free if owner[i] == NONE => owner[i] = FREE,
        _ => {}
    })?;
    Ok(image::RgbImage::from_fn(
        f.width,
        f.height,
        |x, y| match owner[y as usize * f.width as usize + x as usize] {
            NONE => crate::merge::compose::OVERLAY_UNKNOWN,
            FREE => image::Rgb([255, 255, 255]),
            k => image::Rgb(MAP_COLOURS[k as usize % MAP_COLOURS.len()]),
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::states::{FREE, OCCUPIED, UNKNOWN};
    use crate::map::GeoRef;

    #[test]
    fn the_first_map_keeps_its_world_frame_and_walls_win() {
        let mut a = MapImage::filled(10, 10, 254).unwrap();
        a.pixels_mut()[0] = 0;
        let a = OccupancyMap {
            georef: Some(GeoRef {
                resolution: 0.05,
                origin: [1.0, 2.0, 0.0],
            }),
            ..OccupancyMap::from_image(a)
        };
        let b = OccupancyMap::from_image(MapImage::filled(4, 4, 0).unwrap());
        let c = OccupancyMap::from_image(MapImage::filled(3, 3, 254).unwrap());
        let poses = [
            Rigid::IDENTITY,
            Rigid {
                theta_deg: 0.0,
                tx: -2.0,
                ty: 8.0,
            },
            Rigid {
                theta_deg: 90.0,
                tx: 12.0,
                ty: 0.0,
            },
        ];
        let (m, f) = compose_many(&[&a, &b, &c], &poses).unwrap();
        assert_eq!((f.x0, f.y0, f.width, f.height), (-2, 0, 15, 12));
        let (g, ga) = (m.georef.unwrap(), a.georef.unwrap());
        let (p, q) = (
            g.pixel_to_world(2, 0, m.image.height()),
            ga.pixel_to_world(0, 0, 10),
        );
        assert!(
            (p.0 - q.0).abs() < 1e-9 && (p.1 - q.1).abs() < 1e-9,
            "{p:?} {q:?}"
        );
        assert_eq!(m.image.get(2, 0), OCCUPIED); // a's wall
        assert_eq!(m.image.get(2, 9), OCCUPIED); // b over a's free space
        assert_eq!(m.image.get(5, 5), FREE);
        assert_eq!(m.image.get(14, 1), FREE); // c, turned
        assert_eq!(m.image.get(14, 5), UNKNOWN);
        let pic = overlay_many(&[&a, &b, &c], &poses).unwrap();
        assert_eq!(pic.get_pixel(2, 0).0, MAP_COLOURS[0]);
        assert_eq!(pic.get_pixel(0, 11).0, MAP_COLOURS[1]);
        assert_eq!(pic.get_pixel(14, 1).0, [255, 255, 255]);
        let far = [
            Rigid::IDENTITY,
            Rigid {
                tx: 1e5,
                ..Rigid::IDENTITY
            },
        ];
        assert!(compose_many(&[&a, &b], &far).is_err());
        let nan = [
            Rigid::IDENTITY,
            Rigid {
                theta_deg: f64::NAN,
                ..Rigid::IDENTITY
            },
        ];
        assert!(compose_many(&[&a, &b], &nan).is_err());
        // A long line of maps fits while the canvas stays within the factor.
        let line: Vec<Rigid> = (0..3)
            .map(|k| Rigid {
                tx: 8.0 * f64::from(k),
                ty: 8.0 * f64::from(k),
                ..Rigid::IDENTITY
            })
            .collect();
        assert!(compose_many(&[&a, &a, &a], &line).is_ok());
    }
}
