//! Writing a map as ROS `map_server` reads it: `NAME.yaml` with `NAME.pgm` beside it, or the image alone.

use std::path::{Path, PathBuf};

use super::{map_yaml_text_with, OccupancyMap};
use crate::support::error::{Error, Result};
use crate::support::files;

/// The files a map is written to for `path`: `NAME.yaml` gives the yaml and `NAME.pgm`; `NAME.pgm` the
/// image alone; anything else is refused.
pub fn save_names(o: Option<&Path>) -> Result<(Option<PathBuf>, Option<PathBuf>)> {
    match o {
        Some(o)
            if o.extension().is_some_and(|e| {
                e.eq_ignore_ascii_case("yaml") || e.eq_ignore_ascii_case("yml")
            }) =>
        {
            Ok((Some(o.to_path_buf()), Some(o.with_extension("pgm"))))
        }
        Some(o) if o.extension().is_some_and(|e| e.eq_ignore_ascii_case("pgm")) => {
            Ok((None, Some(o.to_path_buf())))
        }
        Some(o) => Err(Error::invalid(format!(
            "{}: the map is written as NAME.yaml or NAME.yml (with NAME.pgm) or NAME.pgm",
            o.display()
        ))),
        None => Ok((None, None)),
    }
}

/// The yaml text of `map` with its image `pgm` beside it; `reference` names the map whose frame it keeps,
/// for the placeholder comment when that map had no georeference.
pub fn yaml_text(pgm: &Path, map: &OccupancyMap, reference: &str) -> String {
    let image = pgm
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    match map.georef {
        Some(g) => map_yaml_text_with(&image, g.resolution, g.origin, &map.thresholds),
        None => format!(
            "# {reference} had no yaml: resolution 1 and origin 0 are placeholders.\n{}",
            map_yaml_text_with(&image, 1.0, [0.0; 3], &map.thresholds)
        ),
    }
}

/// The text of a merged map's yaml: [`yaml_text`] opened by the comment that tells a later folder run it
/// is the tool's output, not a robot's map ([`crate::support::marks`]).
pub fn merged_yaml_text(pgm: &Path, map: &OccupancyMap, reference: &str) -> String {
    crate::support::marks::merged_yaml_comment() + &yaml_text(pgm, map, reference)
}

/// A merged map's image as a binary PGM into `out`, its header carrying the merged map's mark (a comment,
/// which every PGM reader skips).
pub fn write_merged_pgm_to(
    map: &OccupancyMap,
    out: &mut dyn std::io::Write,
) -> std::io::Result<()> {
    let image = &map.image;
    super::write_pgm_header_with(
        out,
        image.width(),
        image.height(),
        Some(crate::support::marks::MERGED_MAP),
    )?;
    out.write_all(image.pixels())
}

impl OccupancyMap {
    /// Writes the map to `NAME.yaml` (and `NAME.pgm` beside it) or `NAME.pgm` alone, both renamed into
    /// place together when complete: a failure leaves neither. The image is written as it is, the yaml
    /// with the map's thresholds, so the map loads back the same.
    pub fn save(&self, path: &Path) -> Result<()> {
        let (yaml, pgm) = save_names(Some(path))?;
        let pgm = pgm.expect("save_names gives an image for a path");
        let mut staged = files::Staged::default();
        staged.write(&pgm, |out| self.image.write_pgm_to(out))?;
        if let Some(yaml) = &yaml {
            let text = yaml_text(&pgm, self, "the map");
            staged.write(yaml, |out| out.write_all(text.as_bytes()))?;
        }
        staged.commit()
    }
}
