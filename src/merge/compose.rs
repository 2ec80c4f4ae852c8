//! The merged map: A's frame, its canvas grown to hold B, every cell from both maps.
//!
//! Cell rule: a cell known in one map takes that map's state; known in both, occupied if either says
//! occupied (a wall one robot saw is not erased by the other's free space: the conservative choice for
//! planning), else free. B's cells are read by nearest neighbour through the inverse transform. Written with
//! ROS map_server's values (0 occupied, 254 free, 205 unknown), and, when A has a georeference, with the
//! origin moved so that every cell of A keeps its world coordinates.

use crate::map::states::{CellState, ClassTable};
use crate::map::{GeoRef, MapImage, OccupancyMap, Thresholds};
use crate::merge::transform::{Applier, Rigid};
use crate::support::error::{Error, Result};

/// Largest merged canvas, pixels, relative to the two maps together: a transform that would grow the
/// canvas beyond this is not a merge of maps of one place.
pub const MAX_CANVAS_FACTOR: u64 = 4;

/// The canvas of the merge, in A's pixel frame: `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Canvas {
    /// First column, in A's pixels (0 or negative).
    pub x0: i64,
    /// First row.
    pub y0: i64,
    /// One past the last column.
    pub x1: i64,
    /// One past the last row.
    pub y1: i64,
}

impl Canvas {
    /// The canvas holding A (`wa` x `ha`) and B (`wb` x `hb`) placed by `t`. Refused when `t` is not
    /// finite or the canvas would be wider or higher than a map can be (B placed absurdly far from A).
    pub fn of(wa: u32, ha: u32, wb: u32, hb: u32, t: &Rigid) -> Result<Canvas> {
        if !(t.theta_deg.is_finite() && t.tx.is_finite() && t.ty.is_finite()) {
            return Err(Error::invalid(format!(
                "the transform ({} deg, {}, {}) is not a placement: it must be finite",
                t.theta_deg, t.tx, t.ty
            )));
        }
        // The canvas pixels are those whose centres B's pixel centres reach (nearest neighbour).
        let (mut x0, mut y0, mut x1, mut y1) =
            (0f64, 0f64, f64::from(wa) - 1.0, f64::from(ha) - 1.0);
        let (bw, bh) = (f64::from(wb.max(1)) - 1.0, f64::from(hb.max(1)) - 1.0);
        for (x, y) in [(0.0, 0.0), (bw, 0.0), (0.0, bh), (bw, bh)] {
            let (px, py) = t.apply((x, y));
            x0 = x0.min(px.round());
            y0 = y0.min(py.round());
            x1 = x1.max(px.round());
            y1 = y1.max(py.round());
        }
        // Both spans hold 0, so a span within u32 keeps every bound well inside i64.
        let (w, h) = (x1 - x0 + 1.0, y1 - y0 + 1.0);
        if w > f64::from(u32::MAX) || h > f64::from(u32::MAX) {
            return Err(Error::invalid(format!(
                "the merged map would be {w:.3e} x {h:.3e} pixels: B lands far from A"
            )));
        }
        Ok(Canvas {
            x0: x0 as i64,
            y0: y0 as i64,
            x1: x1 as i64 + 1,
            y1: y1 as i64 + 1,
        })
    }

    /// Pixels, width times height.
    pub fn pixels(&self) -> u64 {
        self.width().saturating_mul(self.height())
    }

    /// Width, pixels.
    pub fn width(&self) -> u64 {
        (self.x1 - self.x0) as u64
    }

    /// Height, pixels.
    pub fn height(&self) -> u64 {
        (self.y1 - self.y0) as u64
    }
}

/// Both maps read in A's pixel frame on the merged canvas: A directly, B by nearest neighbour through the
/// inverse transform; unknown outside either.
struct Placed<'a> {
    a: &'a MapImage,
    b: &'a MapImage,
    ca: ClassTable,
    cb: ClassTable,
    /// The inverse transform, its sine and cosine computed once for every pixel.
    inv: Applier,
    canvas: Canvas,
}

impl<'a> Placed<'a> {
    /// Fails when the transform is not finite or the canvas would be larger than [`MAX_CANVAS_FACTOR`]
    /// times the two maps.
    fn new(a: &'a OccupancyMap, b: &'a OccupancyMap, t: &Rigid) -> Result<Self> {
        let (ia, ib) = (&a.image, &b.image);
        let canvas = Canvas::of(ia.width(), ia.height(), ib.width(), ib.height(), t)?;
        let limit = (ia.len() as u64 + ib.len() as u64).saturating_mul(MAX_CANVAS_FACTOR);
        if canvas.pixels() > limit {
            return Err(Error::invalid(format!(
                "the merged map would be {}x{}: B lands far from A",
                canvas.width(),
                canvas.height()
            )));
        }
        Ok(Placed {
            a: ia,
            b: ib,
            ca: ClassTable::new(&a.thresholds),
            cb: ClassTable::new(&b.thresholds),
            inv: t.inverse().applier(),
            canvas,
        })
    }

    /// A's state at A pixel (x, y).
    #[inline]
    fn a(&self, x: i64, y: i64) -> CellState {
        if x >= 0 && y >= 0 && x < i64::from(self.a.width()) && y < i64::from(self.a.height()) {
            self.ca.state(self.a.get(x as u32, y as u32))
        } else {
            CellState::Unknown
        }
    }

    /// B's state under A pixel (x, y).
    #[inline]
    fn b(&self, x: i64, y: i64) -> CellState {
        let (bx, by) = self.inv.apply((x as f64, y as f64));
        let (bx, by) = (bx.round(), by.round());
        if bx < 0.0
            || by < 0.0
            || bx >= f64::from(self.b.width())
            || by >= f64::from(self.b.height())
        {
            return CellState::Unknown;
        }
        self.cb.state(self.b.get(bx as u32, by as u32))
    }

    /// Whether `state` has an occupied cell within 2 px of (x, y).
    fn occupied_near(&self, x: i64, y: i64, state: impl Fn(i64, i64) -> CellState) -> bool {
        (-2..=2).any(|dy| (-2..=2).any(|dx| state(x + dx, y + dy) == CellState::Occupied))
    }
}

/// The merge cell rule.
#[inline]
pub fn merge_cell(a: CellState, b: CellState) -> CellState {
    match (a, b) {
        (CellState::Occupied, _) | (_, CellState::Occupied) => CellState::Occupied,
        (CellState::Free, _) | (_, CellState::Free) => CellState::Free,
        _ => CellState::Unknown,
    }
}

/// The merged map of `a` and `b`, B placed by `t` (B's pixels to A's). Fails when `t` is not finite or
/// the canvas would be larger than [`MAX_CANVAS_FACTOR`] times the two maps.
pub fn compose(a: &OccupancyMap, b: &OccupancyMap, t: &Rigid) -> Result<OccupancyMap> {
    let placed = Placed::new(a, b, t)?;
    let canvas = placed.canvas;
    let (w, h) = (canvas.width() as u32, canvas.height() as u32);
    let mut out = Vec::with_capacity(w as usize * h as usize);
    for cy in 0..h {
        let y = i64::from(cy) + canvas.y0;
        for cx in 0..w {
            let x = i64::from(cx) + canvas.x0;
            out.push(merge_cell(placed.a(x, y), placed.b(x, y)).map_server_value());
        }
    }
    let image = MapImage::new(w, h, out)?;
    let georef = a
        .georef
        .map(|g| grown_georef(&g, a.image.height(), canvas.x0, canvas.y1));
    Ok(OccupancyMap {
        image,
        thresholds: Thresholds::default(),
        georef,
        image_path: None,
        yaml_path: None,
        warnings: Vec::new(),
    })
}

/// Colours of the merge overlay: walls of A only, of B only, of both; free space of both; of one only;
/// conflicts (a wall of one map on the other's free space).
pub const OVERLAY_COLOURS: [(&str, [u8; 3]); 6] = [
    ("walls of A only", [30, 90, 220]),
    ("walls of B only", [230, 120, 0]),
    ("walls of both (within 2 px)", [0, 0, 0]),
    ("free in both", [255, 255, 255]),
    ("free in one", [215, 215, 215]),
    (
        "a wall on the other map's free space, no wall of it within 2 px",
        [220, 0, 180],
    ),
];

/// [`OVERLAY_COLOURS`] with labels short enough for the legend drawn into a picture.
pub fn overlay_legend() -> Vec<(&'static str, image::Rgb<u8>)> {
    let short = [
        "WALLS OF A ONLY",
        "WALLS OF B ONLY",
        "WALLS OF BOTH",
        "FREE IN BOTH",
        "FREE IN ONE",
        "CONFLICT: A WALL ON FREE SPACE",
    ];
    short
        .into_iter()
        .zip(OVERLAY_COLOURS)
        .map(|(l, (_, c))| (l, image::Rgb(c)))
        .collect()
}

/// Colour of the merge overlay where neither map knows anything.
pub const OVERLAY_UNKNOWN: image::Rgb<u8> = image::Rgb([150, 150, 150]);

/// The picture of a merge: both maps on the merged canvas in the [`OVERLAY_COLOURS`], so a person sees at
/// a glance whether walls line up (black), or one map's walls cross the other's free space (magenta).
pub fn overlay(a: &OccupancyMap, b: &OccupancyMap, t: &Rigid) -> Result<image::RgbImage> {
    let placed = Placed::new(a, b, t)?;
    let canvas = placed.canvas;
    let c = |i: usize| image::Rgb(OVERLAY_COLOURS[i].1);
    let unknown = OVERLAY_UNKNOWN;
    Ok(image::RgbImage::from_fn(
        canvas.width() as u32,
        canvas.height() as u32,
        |cx, cy| {
            let (x, y) = (i64::from(cx) + canvas.x0, i64::from(cy) + canvas.y0);
            let (sa, sb) = (placed.a(x, y), placed.b(x, y));
            // Walls within 2 px of the other map's walls agree: maps of one place differ by a pixel or two.
            let a_near = || placed.occupied_near(x, y, |x, y| placed.a(x, y));
            let b_near = || placed.occupied_near(x, y, |x, y| placed.b(x, y));
            use CellState::*;
            match (sa, sb) {
                (Occupied, _) if b_near() => c(2),
                (_, Occupied) if a_near() => c(2),
                (Occupied, Occupied) => c(2),
                (Occupied, Free) | (Free, Occupied) => c(5),
                (Occupied, Unknown) => c(0),
                (Unknown, Occupied) => c(1),
                (Free, Free) => c(3),
                (Free, Unknown) | (Unknown, Free) => c(4),
                (Unknown, Unknown) => unknown,
            }
        },
    ))
}

/// A reference map's georeference for a grown canvas whose first column is `x0` and whose row after its
/// last is `y1` (in the reference map's pixels; `h0` its height): the origin (the pose of the lower-left
/// corner) moves to the canvas's lower-left corner, so the reference map's cells keep their world
/// coordinates.
pub(super) fn grown_georef(g: &GeoRef, h0: u32, x0: i64, y1: i64) -> GeoRef {
    let [ox, oy, yaw] = g.origin;
    let yaw_used = if yaw.is_finite() { yaw } else { 0.0 };
    // In the map frame (before yaw): the canvas's lower-left corner is x0 columns left and (y1 - h0)
    // rows below the reference map's lower-left corner.
    let dx = x0 as f64 * g.resolution;
    let dy = -((y1 - i64::from(h0)) as f64) * g.resolution;
    let (s, c) = yaw_used.sin_cos();
    GeoRef {
        resolution: g.resolution,
        origin: [ox + c * dx - s * dy, oy + s * dx + c * dy, yaw],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::states::{FREE, OCCUPIED, UNKNOWN};

    #[test]
    fn a_cells_keep_their_world_coordinates_and_the_rule_is_conservative() {
        let mut ia = MapImage::filled(20, 10, 254).unwrap();
        ia.pixels_mut()[0] = 0;
        let a = OccupancyMap {
            georef: Some(GeoRef {
                resolution: 0.1,
                origin: [-1.0, 2.0, 0.0],
            }),
            ..OccupancyMap::from_image(ia)
        };
        // B: all occupied, placed 5 px left and 3 px up of A's origin.
        let b = OccupancyMap::from_image(MapImage::filled(8, 8, 0).unwrap());
        let t = Rigid {
            theta_deg: 0.0,
            tx: -5.0,
            ty: -3.0,
        };
        let m = compose(&a, &b, &t).unwrap();
        assert_eq!((m.image.width(), m.image.height()), (25, 13));
        let (g, ga) = (m.georef.unwrap(), a.georef.unwrap());
        // A's pixel (0, 0) is canvas pixel (5, 3): same world position.
        assert_eq!(
            g.pixel_to_world(5, 3, m.image.height()),
            ga.pixel_to_world(0, 0, 10)
        );
        assert_eq!(m.image.get(5, 3), OCCUPIED); // A occupied
        assert_eq!(m.image.get(6, 4), OCCUPIED); // A free, B occupied: occupied
        assert_eq!(m.image.get(20, 10), FREE); // A free, outside B
        assert_eq!(m.image.get(0, 12), UNKNOWN); // neither
        assert!(compose(
            &a,
            &b,
            &Rigid {
                tx: 1e6,
                ..Rigid::IDENTITY
            }
        )
        .is_err());
    }

    #[test]
    fn a_transform_not_finite_or_past_any_canvas_is_refused_not_overflowed() {
        let a = OccupancyMap::from_image(MapImage::filled(20, 10, 254).unwrap());
        let b = OccupancyMap::from_image(MapImage::filled(8, 8, 0).unwrap());
        for (theta_deg, tx, ty) in [
            (f64::NAN, 0.0, 0.0),
            (0.0, f64::NAN, 0.0),
            (0.0, 0.0, f64::INFINITY),
            (f64::INFINITY, 0.0, 0.0),
            (0.0, 1e19, 0.0),
            (0.0, -1e300, 1e300),
            (0.0, 9.3e18, 0.0),
            (0.0, f64::from(u32::MAX), 0.0),
        ] {
            let t = Rigid { theta_deg, tx, ty };
            let e = compose(&a, &b, &t).unwrap_err().to_string();
            assert!(
                e.contains("finite") || e.contains("far from A"),
                "{t:?}: {e}"
            );
            assert!(overlay(&a, &b, &t).is_err(), "{t:?}");
            assert!(Canvas::of(20, 10, 8, 8, &t).is_err(), "{t:?}");
        }
        // The largest span a canvas may have is still a canvas (refused later for its size alone).
        let c = Canvas::of(
            1,
            1,
            1,
            1,
            &Rigid {
                tx: f64::from(u32::MAX) - 1.0,
                ..Rigid::IDENTITY
            },
        )
        .unwrap();
        assert_eq!(c.width(), u64::from(u32::MAX));
    }
}
