//! A map opened to be read row by row ([`OccupancyMap::open_rows`]), for streamed detection
//! ([`crate::map::stream`]): the yaml and the image header are read and checked, the pixels stay in the file.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use super::occupancy::open_image_with;
use super::yaml::is_yaml;
use super::yaml::read_yaml;
use super::{GeoRef, OccupancyMap, Thresholds};
use crate::map::decode::Decoder;
use crate::support::error::{Error, Result};
use crate::support::memory::Budget;

impl OccupancyMap {
    /// Opens a map (a `.yaml` and its image, or an image alone) to be read row by row
    /// ([`crate::map::stream`]): the yaml and the image header are read and checked, no pixel is.
    pub fn open_rows(path: &Path) -> Result<MapRows> {
        let (meta, image_path, yaml_path) = if is_yaml(path) {
            let (meta, image_path) = read_yaml(path)?;
            (Some(meta), image_path, Some(path.to_path_buf()))
        } else {
            (None, path.to_path_buf(), None)
        };
        let dec = open_image_with(&image_path, &Budget::default(), 1 << 20)?;
        let (w, h) = (dec.header().width, dec.header().height);
        let mut warnings = Vec::new();
        if let Some(meta) = &meta {
            meta.georef()
                .check_finite(w, h)
                .map_err(|m| Error::input(path, m))?;
            if !meta.origin[2].is_finite() {
                warnings.push(format!(
                    "{}: origin yaw is {}; world coordinates use yaw 0",
                    path.display(),
                    meta.origin[2]
                ));
            }
        }
        Ok(MapRows {
            thresholds: meta
                .as_ref()
                .map_or_else(Thresholds::default, |m| m.thresholds),
            georef: meta.map(|m| m.georef()),
            source: DecoderRows {
                decoder: Some(dec),
                path: image_path.clone(),
            },
            image_path,
            yaml_path,
            warnings,
        })
    }
}

/// A map opened to be read row by row ([`OccupancyMap::open_rows`]): what [`OccupancyMap`] holds, with
/// the rows still in the file.
pub struct MapRows {
    /// The rows, to be read once ([`crate::map::stream::RowSource`]).
    pub source: DecoderRows,
    /// How pixel values become occupied / unknown / free.
    pub thresholds: Thresholds,
    /// Resolution and origin, when the map came with a yaml.
    pub georef: Option<GeoRef>,
    /// The image file.
    pub image_path: PathBuf,
    /// The yaml file, if any.
    pub yaml_path: Option<PathBuf>,
    /// Things a user should know that do not stop loading.
    pub warnings: Vec<String>,
}

impl MapRows {
    /// The file a user named for this map: the yaml if there was one, else the image.
    pub fn source_path(&self) -> &Path {
        self.yaml_path.as_deref().unwrap_or(&self.image_path)
    }

    /// The header's size.
    pub fn size(&self) -> (u32, u32) {
        (self.source.width(), self.source.height())
    }

    /// Bytes the decoder allocates beyond the rows it hands out (see [`crate::map::decode::Header`]).
    pub fn decoder_bytes(&self) -> u64 {
        self.source
            .decoder
            .as_ref()
            .map_or(0, |d| d.header().decoder_bytes)
    }

    /// Whether the image is an interlaced PNG, whose decoding holds the whole image.
    pub fn holds_whole_image(&self) -> bool {
        self.source
            .decoder
            .as_ref()
            .is_some_and(|d| d.header().whole_image)
    }
}

/// An image file's rows through its decoder, errors naming the file.
pub struct DecoderRows {
    decoder: Option<Decoder<BufReader<std::fs::File>>>,
    path: PathBuf,
}

// The stream module makes this a `RowSource`; the map module stays below it.
impl DecoderRows {
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.decoder.as_ref().map_or(0, |d| d.header().width)
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.decoder.as_ref().map_or(0, |d| d.header().height)
    }

    /// Fills `out` (whole rows) with the next rows.
    pub fn read_rows(&mut self, out: &mut [u8]) -> Result<()> {
        let dec = self
            .decoder
            .as_mut()
            .ok_or_else(|| Error::Internal("rows read after the end".into()))?;
        dec.read_rows(out).map_err(|m| Error::input(&self.path, m))
    }

    /// The image file and the byte offset of its raster, when the raster is the rows as they are (see
    /// [`Decoder::raw_raster`]).
    pub fn raw_file(&self) -> Option<(PathBuf, u64)> {
        let at = self.decoder.as_ref()?.raw_raster()?;
        Some((self.path.clone(), at))
    }

    /// The rows were read from [`DecoderRows::raw_file`] by the caller.
    pub fn raw_read(&mut self) {
        if let Some(d) = self.decoder.as_mut() {
            d.raster_read_elsewhere();
        }
    }

    /// After the last row: the decoder's warnings, naming the file.
    pub fn finish(&mut self) -> Result<Vec<String>> {
        let Some(dec) = self.decoder.take() else {
            return Ok(Vec::new());
        };
        let warnings = dec.finish().map_err(|m| Error::input(&self.path, m))?;
        Ok(warnings
            .into_iter()
            .map(|m| format!("{}: {m}", self.path.display()))
            .collect())
    }
}
