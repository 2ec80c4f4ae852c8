//! What a merge will hold in memory, known before it allocates: each map at the reference resolution (a
//! resampled copy when its resolution differs) and each preparation over the map's explored part, so that
//! a run over its budget is refused with the estimate instead of aborting half way, and a huge canvas
//! holding one small room is not refused for the canvas.

use super::prepare::{crop_box, prepared_bytes, CROP_PAD};
use crate::error::{Error, Result};
use crate::map::OccupancyMap;

/// Most pixels a map resampled to another's resolution may have (4 Gi: an index past this would not fit
/// the 32-bit image sizes the tool uses).
pub const MAX_RESAMPLED: f64 = 4.0 * (1u64 << 30) as f64;

/// A map as the merge holds it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// The image as loaded, pixels.
    pub loaded: (u64, u64),
    /// At the reference resolution, pixels (the same as `loaded` when not resampled).
    pub width: u64,
    /// See `width`.
    pub height: u64,
    /// Its explored part there (with the preparation's margin), pixels.
    pub crop: (u64, u64),
    /// Whether it is resampled.
    pub resampled: bool,
}

impl Footprint {
    /// Bytes the merge holds for this map at once: the image, a resampled copy, the preparation of the
    /// explored part.
    pub fn bytes(&self) -> u64 {
        let loaded = self.loaded.0.saturating_mul(self.loaded.1);
        let copy = if self.resampled {
            self.width.saturating_mul(self.height)
        } else {
            0
        };
        let side = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        loaded
            .saturating_add(copy)
            .saturating_add(prepared_bytes(side(self.crop.0), side(self.crop.1)))
    }
}

/// The name a message gives `map`: its yaml, else its image, else "the map".
pub fn name_of(map: &OccupancyMap) -> String {
    map.yaml_path
        .as_deref()
        .or(map.image_path.as_deref())
        .map_or_else(|| "the map".to_string(), |p| p.display().to_string())
}

/// `map`'s footprint once brought to `resolution` (metres a pixel; `None`: kept as it is), as
/// [`at_resolution`](super::compose::at_resolution) would bring it. Refused, naming the map, both
/// resolutions and the size, when the resampled map would be over [`MAX_RESAMPLED`] pixels.
pub fn footprint(map: &OccupancyMap, resolution: Option<f64>) -> Result<Footprint> {
    let (w, h) = (u64::from(map.image.width()), u64::from(map.image.height()));
    let (x0, y0, x1, y1) = crop_box(map);
    let crop = ((x1 - x0) as u64, (y1 - y0) as u64);
    if let (Some(g), Some(r)) = (map.georef, resolution) {
        if (g.resolution - r).abs() > 1e-9 * r {
            let (nw, nh) = resampled_size(map, r)?;
            let k = g.resolution / r;
            // The explored part scaled, its margin kept, within the resampled map.
            let scaled = |v: u64, max: u64| {
                let inner = (v as f64 - 2.0 * CROP_PAD as f64).max(1.0) * k;
                (inner.ceil() as u64 + 2 * CROP_PAD as u64 + 2).min(max)
            };
            return Ok(Footprint {
                loaded: (w, h),
                width: nw,
                height: nh,
                crop: (scaled(crop.0, nw), scaled(crop.1, nh)),
                resampled: true,
            });
        }
    }
    Ok(Footprint {
        loaded: (w, h),
        width: w,
        height: h,
        crop,
        resampled: false,
    })
}

/// The size of `map` resampled to `resolution`, refused (naming the map, both resolutions and the size in
/// plain units) when over [`MAX_RESAMPLED`] pixels or not a resolution.
pub fn resampled_size(map: &OccupancyMap, resolution: f64) -> Result<(u64, u64)> {
    let name = name_of(map);
    let Some(g) = map.georef else {
        return Ok((u64::from(map.image.width()), u64::from(map.image.height())));
    };
    if !(resolution.is_finite() && resolution > 0.0) {
        return Err(Error::invalid(format!(
            "{name}: cannot be brought to a resolution of {resolution} m a pixel"
        )));
    }
    let k = g.resolution / resolution;
    let (w, h) = (map.image.width(), map.image.height());
    let (nw, nh) = (
        (f64::from(w) * k).round().max(1.0),
        (f64::from(h) * k).round().max(1.0),
    );
    let px = nw * nh;
    if px.is_nan() || px > MAX_RESAMPLED {
        return Err(Error::invalid(format!(
            "{name}: its cells are {} m; brought to the {} m cells of the map it is merged with, this \
             {w}x{h} map would be {} x {} pixels, over the {} pixels a map may have; resample it to \
             a resolution nearer {} m first",
            short(g.resolution),
            short(resolution),
            count(nw),
            count(nh),
            count(MAX_RESAMPLED),
            short(resolution)
        )));
    }
    Ok((nw as u64, nh as u64))
}

/// A count for people: an integer up to a trillion, else in powers of ten (`3.1e+15`).
fn count(v: f64) -> String {
    if v < 1e12 {
        format!("{v:.0}")
    } else {
        format!("{v:.1e}")
    }
}

/// A resolution for people: up to six significant digits, no trailing zeros, powers of ten when tiny or
/// huge.
fn short(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e6).contains(&v.abs()) {
        return format!("{v:.3e}");
    }
    let s = format!("{v:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Refuses, before anything is prepared, two maps whose explored parts are too large to align with each
/// other (the correlation's limit, as the alignment would find it after preparing both).
pub fn check_alignable(a: &Footprint, b: &Footprint) -> Result<()> {
    let side = |v: u64| usize::try_from(v).unwrap_or(usize::MAX);
    super::coarse::check_size(
        (side(b.crop.0), side(b.crop.1)),
        (side(a.crop.0), side(a.crop.1)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::{GeoRef, MapImage};

    fn map(w: u32, h: u32, resolution: f64, room: Option<(u32, u32, u32)>) -> OccupancyMap {
        let mut px = vec![205u8; (w * h) as usize];
        if let Some((x0, y0, side)) = room {
            for y in y0..y0 + side {
                for x in x0..x0 + side {
                    px[(y * w + x) as usize] = 254;
                }
            }
        }
        let mut m = OccupancyMap::from_image(MapImage::new(w, h, px).unwrap());
        m.georef = Some(GeoRef {
            resolution,
            origin: [0.0; 3],
        });
        m
    }

    #[test]
    fn a_coarse_map_brought_to_fine_cells_counts_its_resampled_copy_and_explored_part() {
        let m = map(100, 80, 0.5, Some((10, 10, 20)));
        let f = footprint(&m, Some(0.05)).unwrap();
        assert_eq!((f.width, f.height), (1000, 800));
        assert!(f.resampled);
        // The 20 px room (36 px with the margins) at ten times the cells: about 200 px and the margins.
        assert!((200..=230).contains(&f.crop.0), "{f:?}");
        assert!(f.bytes() > 1000 * 800 && f.bytes() < 1000 * 800 + 100 * 80 + 200 * 1000 * 42);
        let same = footprint(&m, Some(0.5)).unwrap();
        assert!(!same.resampled && same.crop == (36, 36));
    }

    #[test]
    fn a_resampled_size_past_the_limit_is_refused_in_plain_words() {
        let m = map(2000, 2000, 2.0, None);
        let e = footprint(&m, Some(0.0001)).unwrap_err().to_string();
        assert!(
            e.contains("2 m") && e.contains("0.0001 m") && e.contains("40000000 x"),
            "{e}"
        );
        let far = map(2000, 2000, 1e9, None);
        let e = footprint(&far, Some(0.0001)).unwrap_err().to_string();
        assert!(e.contains("e16 x") && e.contains("1.000e9 m"), "{e}");
        assert!(e.len() < 400, "{e}");
    }
}
