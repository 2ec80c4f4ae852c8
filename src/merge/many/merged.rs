//! Many maps merged end to end: every map brought to one resolution, placed ([`crate::merge::many::run`]), each
//! group's canvas and the report of every map's pose; each group's merged map and picture on demand
//! (what `merge A B C ...` and the Python `merge_many` do).

use std::borrow::Cow;
use std::time::Instant;

use crate::backend::Backend;
use crate::map::OccupancyMap;
use crate::merge::many::mosaic::{self, Frame};
use crate::merge::many::poses::{self, Poses};
use crate::merge::many::{Cache, GlobalOptions, Run};
use crate::merge::{resample, Rigid};
use crate::support::error::Result;

/// Many maps placed, with what it takes to draw each group.
#[derive(Clone, Debug)]
pub struct ManyMerge {
    /// The maps as placed: each at the first georeferenced map's resolution.
    pub maps: Vec<OccupancyMap>,
    /// Each map's resolution over that reference resolution, where it differs ([`poses::MapEntry::scale`]).
    pub scales: Vec<Option<f64>>,
    /// The placement and every pair's verdict.
    pub run: Run,
    /// Each group's canvas in its first map's frame.
    pub frames: Vec<Frame>,
    /// The report: each map's pose in its group's merged map, the groups, the dropped merges.
    pub report: Poses,
}

/// Places `maps` (named `names` in the report): each brought to the first georeferenced map's resolution,
/// then [`crate::merge::many::run`] (`backend` scores the dense checks, `progress` hears pairs done and in all).
pub fn merge_maps(
    maps: Vec<OccupancyMap>,
    names: &[String],
    options: &GlobalOptions,
    backend: &mut dyn Backend,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<ManyMerge> {
    merge_maps_cached(maps, names, options, backend, progress, &mut Cache::new())
}

/// [`merge_maps`] keeping each map's preparation and each pair's alignment in `cache` for the next call
/// ([`crate::merge::many::run_cached`]): a live merge where few maps change between calls redoes only their part.
pub fn merge_maps_cached(
    maps: Vec<OccupancyMap>,
    names: &[String],
    options: &GlobalOptions,
    backend: &mut dyn Backend,
    progress: &(dyn Fn(usize, usize) + Sync),
    cache: &mut Cache,
) -> Result<ManyMerge> {
    merge_maps_with(
        maps,
        names,
        options,
        backend,
        progress,
        cache,
        &mut crate::merge::many::Local,
    )
}

/// [`merge_maps_cached`] with what the cache does not hold prepared and aligned by `engine`
/// ([`crate::merge::many::run_with`]).
pub fn merge_maps_with(
    mut maps: Vec<OccupancyMap>,
    names: &[String],
    options: &GlobalOptions,
    backend: &mut dyn Backend,
    progress: &(dyn Fn(usize, usize) + Sync),
    cache: &mut Cache,
    engine: &mut dyn crate::merge::many::Engine,
) -> Result<ManyMerge> {
    let start = Instant::now();
    let mut scales = vec![None; maps.len()];
    if let Some(res) = maps.iter().find_map(|m| m.georef).map(|g| g.resolution) {
        for (m, s) in maps.iter_mut().zip(&mut scales) {
            crate::support::stop::check()?;
            let (at, scale) = resample::at_resolution(m, res)?;
            if let Cow::Owned(resampled) = at {
                (*m, *s) = (resampled, scale);
            }
        }
    }
    let run = crate::merge::many::run_with(&maps, options, backend, progress, cache, engine)?;
    let frames = (0..run.placement.groups.len())
        .map(|g| {
            let (ms, ps) = group_of(&maps, &run, g);
            mosaic::frame(&ms, &ps)
        })
        .collect::<Result<Vec<_>>>()?;
    let seconds = start.elapsed().as_secs_f64();
    let report = poses::poses(names, &maps, &scales, &run, &frames, seconds, options);
    Ok(ManyMerge {
        maps,
        scales,
        run,
        frames,
        report,
    })
}

/// Group `g`'s maps and their poses in its frame.
fn group_of<'m>(
    maps: &'m [OccupancyMap],
    run: &Run,
    g: usize,
) -> (Vec<&'m OccupancyMap>, Vec<Rigid>) {
    run.placement.groups[g]
        .iter()
        .map(|&m| (&maps[m], run.placement.maps[m].pose))
        .unzip()
}

impl ManyMerge {
    /// The number of groups (maps placed together; none when no two maps could be).
    pub fn groups(&self) -> usize {
        self.run.placement.groups.len()
    }

    /// Group `g`'s maps and their poses in its frame.
    pub fn group(&self, g: usize) -> (Vec<&OccupancyMap>, Vec<Rigid>) {
        group_of(&self.maps, &self.run, g)
    }

    /// Group `g`'s merged map ([`mosaic::compose_many`]).
    pub fn merged(&self, g: usize) -> Result<OccupancyMap> {
        let (ms, ps) = self.group(g);
        mosaic::compose_many(&ms, &ps).map(|(m, _)| m)
    }

    /// Group `g`'s picture, every map's walls in its own colour ([`mosaic::overlay_many`]).
    pub fn overlay(&self, g: usize) -> Result<image::RgbImage> {
        let (ms, ps) = self.group(g);
        mosaic::overlay_many(&ms, &ps)
    }

    /// Group `g`'s maps (as the report names them) and their wall colours in its picture.
    pub fn legend(&self, g: usize) -> Vec<(&str, image::Rgb<u8>)> {
        self.report.groups[g]
            .maps
            .iter()
            .enumerate()
            .map(|(k, m)| {
                (
                    m.as_str(),
                    image::Rgb(mosaic::MAP_COLOURS[k % mosaic::MAP_COLOURS.len()]),
                )
            })
            .collect()
    }

    /// [`ManyMerge::overlay`] with its [`ManyMerge::legend`] drawn below it (each map by its short name).
    pub fn overlay_with_legend(&self, g: usize) -> Result<image::RgbImage> {
        let entries: Vec<(String, image::Rgb<u8>)> = self
            .legend(g)
            .into_iter()
            .map(|(m, c)| (crate::map::map_name(std::path::Path::new(m)), c))
            .collect();
        Ok(crate::support::plot::with_legend(
            &self.overlay(g)?,
            &entries,
        ))
    }
}
