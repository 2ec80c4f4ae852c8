//! What a merge will hold in memory, known before it allocates: each map at the reference resolution (a
//! resampled copy when its resolution differs) and each preparation over the map's explored part, so that
//! a run over its budget is refused with the estimate instead of aborting half way, and a huge canvas
//! holding one small room is not refused for the canvas.

use crate::map::OccupancyMap;
use crate::merge::compose::Canvas;
use crate::merge::pair::prepare::{
    crop_box, kept_bytes, prepared_bytes, preparing_bytes, rotation_tasks, spectrum_bytes, CROP_PAD,
};
use crate::merge::resample::resampled_size;
use crate::merge::transform::Rigid;
use crate::support::error::Result;

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

    /// Bytes a set of maps keeps for this map while the others are prepared and aligned: the image, a
    /// resampled copy, what its preparation keeps ([`kept_bytes`]).
    pub fn kept(&self) -> u64 {
        let side = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        let (c0, c1) = (side(self.crop.0), side(self.crop.1));
        self.bytes() - prepared_bytes(c0, c1) + kept_bytes(c0, c1).min(prepared_bytes(c0, c1))
    }

    /// Working memory while this map is prepared, or a pair with it aligned, in a set that runs one a
    /// core: its preparation's temporaries, or the pair's coarse correlation: its own four spectra and
    /// three for each rotation task it may have running (up to one a core: a core waiting on its own
    /// pair's tasks takes up another pair's).
    pub fn working(&self) -> u64 {
        let side = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        let (c0, c1) = (side(self.crop.0), side(self.crop.1));
        let correlation = (4 + 3 * rotation_tasks()) * spectrum_bytes(c0, c1);
        let temporaries = preparing_bytes(c0, c1).saturating_sub(kept_bytes(c0, c1));
        temporaries.max(correlation)
    }
}

/// Bytes a set holds at once: what every map keeps, and the working memory of as many pairs as run at
/// once (one a core), each as large as the largest map's: every pair with the largest map needs its
/// working memory (a pair's correlation is sized by its larger map), and several of them may run
/// together.
pub fn set_bytes(kept: impl IntoIterator<Item = (u64, u64)>) -> u64 {
    let (mut held, mut most) = (0u64, 0u64);
    for (k, w) in kept {
        held = held.saturating_add(k);
        most = most.max(w);
    }
    let at_once = rayon::current_num_threads().max(1) as u64;
    held.saturating_add(most.saturating_mul(at_once))
}

/// `map`'s footprint once brought to `resolution` (metres a pixel; `None`: kept as it is), as
/// [`at_resolution`](crate::merge::resample::at_resolution) would bring it. Refused, naming the map, both
/// resolutions and the size, when the resampled map would be over [`MAX_RESAMPLED`](crate::merge::resample::MAX_RESAMPLED) pixels.
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

/// The two maps of a two-map merge as it holds them: A as it is, B brought to A's cells.
pub fn pair(a: &OccupancyMap, b: &OccupancyMap) -> Result<(Footprint, Footprint)> {
    Ok((
        footprint(a, None)?,
        footprint(b, a.georef.map(|g| g.resolution))?,
    ))
}

/// Bytes a many-map merge holds at once: every map at the first georeferenced map's cells (the
/// resolution [`merge_maps`](crate::merge::many::merge_maps) brings them to) with what its preparation keeps,
/// and the working memory of the maps prepared and aligned at once ([`set_bytes`]).
pub fn many_bytes<'m>(maps: impl IntoIterator<Item = &'m OccupancyMap> + Clone) -> Result<u64> {
    let resolution = maps
        .clone()
        .into_iter()
        .find_map(|m| m.georef)
        .map(|g| g.resolution);
    let prints = maps
        .into_iter()
        .map(|m| footprint(m, resolution))
        .collect::<Result<Vec<_>>>()?;
    // A run keeps a copy of each map's pixels at that resolution to recognise it again (its cache).
    Ok(set_bytes(prints.iter().map(|f| {
        (
            f.kept().saturating_add(f.width.saturating_mul(f.height)),
            f.working(),
        )
    })))
}

/// The merged canvas of `a` and B (`b`: B's footprint at A's cells, from [`pair`]) placed by `t`,
/// known before anything is drawn on it; refused as [`Canvas::of`] refuses.
pub fn canvas(a: &OccupancyMap, b: &Footprint, t: &Rigid) -> Result<Canvas> {
    let side = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
    Canvas::of(
        a.image.width(),
        a.image.height(),
        side(b.width),
        side(b.height),
        t,
    )
}

/// Refuses, before anything is prepared, two maps whose explored parts are too large to align with each
/// other (the correlation's limit, as the alignment would find it after preparing both).
pub fn check_alignable(a: &Footprint, b: &Footprint) -> Result<()> {
    let side = |v: u64| usize::try_from(v).unwrap_or(usize::MAX);
    crate::merge::pair::coarse::check_size(
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
