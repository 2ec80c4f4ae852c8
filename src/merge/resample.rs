//! Bringing a map to another's resolution: the nearest-neighbour resampling the two-map and many-map
//! merges apply to every map whose cells differ from the reference map's, and the size it would have,
//! refused in plain words before anything is allocated.

use crate::map::{GeoRef, MapImage, OccupancyMap};
use crate::support::error::{Error, Result};

/// Most pixels a map resampled to another's resolution may have (4 Gi: an index past this would not fit
/// the 32-bit image sizes the tool uses).
pub const MAX_RESAMPLED: f64 = 4.0 * (1u64 << 30) as f64;

/// The name a message gives `map`: its yaml, else its image, else "the map".
pub fn name_of(map: &OccupancyMap) -> String {
    map.yaml_path
        .as_deref()
        .or(map.image_path.as_deref())
        .map_or_else(|| "the map".to_string(), |p| p.display().to_string())
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

/// `map` at `resolution` (metres a pixel): resampled ([`resample`]) when it is georeferenced at another
/// resolution, with its resolution over the new one; otherwise as it is, with `None`. How the two-map and
/// the many-map merges bring every map to the reference map's resolution.
pub fn at_resolution(
    map: &OccupancyMap,
    resolution: f64,
) -> Result<(std::borrow::Cow<'_, OccupancyMap>, Option<f64>)> {
    use std::borrow::Cow;
    match map.georef {
        Some(g) if (g.resolution - resolution).abs() > 1e-9 * resolution => Ok((
            Cow::Owned(resample(map, resolution)?),
            Some(g.resolution / resolution),
        )),
        _ => Ok((Cow::Borrowed(map), None)),
    }
}

/// `map` resampled by nearest neighbour to `resolution` (metres a pixel), keeping its origin: how a map
/// of another resolution is brought to the reference map's before aligning.
pub fn resample(map: &OccupancyMap, resolution: f64) -> Result<OccupancyMap> {
    let Some(g) = map.georef else {
        return Ok(map.clone());
    };
    let k = g.resolution / resolution; // new pixels per old pixel
    let (w, h) = (map.image.width(), map.image.height());
    // Refused, in plain words, past the largest map; the caller's budget counted it before.
    let (nw, nh) = resampled_size(map, resolution)?;
    let (nw, nh) = (nw as u32, nh as u32);
    let mut px = Vec::with_capacity(nw as usize * nh as usize);
    for y in 0..nh {
        // Pixel centres: old = (new + 0.5) / k - 0.5, rows counted from the bottom so the origin stays.
        let from_bottom = f64::from(nh - 1 - y);
        let oy = ((from_bottom + 0.5) / k - 0.5)
            .round()
            .clamp(0.0, f64::from(h - 1)) as u32;
        let sy = h - 1 - oy;
        for x in 0..nw {
            let sx = ((f64::from(x) + 0.5) / k - 0.5)
                .round()
                .clamp(0.0, f64::from(w - 1)) as u32;
            px.push(map.image.get(sx, sy));
        }
    }
    Ok(OccupancyMap {
        image: MapImage::new(nw, nh, px)?,
        georef: Some(GeoRef { resolution, ..g }),
        ..map.clone()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resampling_to_a_finer_resolution_keeps_the_world_frame() {
        let mut img = MapImage::filled(10, 6, 254).unwrap();
        img.pixels_mut()[2 * 10 + 3] = 0; // pixel (3, 2)
        let m = OccupancyMap {
            georef: Some(GeoRef {
                resolution: 0.1,
                origin: [1.0, -2.0, 0.0],
            }),
            ..OccupancyMap::from_image(img)
        };
        let r = resample(&m, 0.05).unwrap();
        assert_eq!((r.image.width(), r.image.height()), (20, 12));
        let (g, gr) = (m.georef.unwrap(), r.georef.unwrap());
        assert_eq!(gr.origin, g.origin);
        // The occupied pixel's world centre falls in one of the four fine pixels it became.
        let (wx, wy) = g.pixel_to_world(3, 2, 6);
        let (fx, fy) = (
            ((wx - gr.origin[0]) / 0.05).floor() as u32,
            (12.0 - (wy - gr.origin[1]) / 0.05).floor() as u32,
        );
        assert_eq!(r.image.get(fx, fy), 0);
        assert_eq!(r.image.pixels().iter().filter(|&&v| v == 0).count(), 4);
        assert!(resample(&m, f64::NAN).is_err());
    }
}
