//! Loading robot maps: ROS `map_server` yaml files and their images (PGM, PNG).
//!
//! Pixel row 0 is the top of the map. The yaml origin is the pose of the lower-left pixel, as in ROS.

mod find;
mod ros_grid;
mod rows;
mod save;
mod yaml;

use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::decode::{Decoder, ImageKind};
use crate::error::{Error, Result};
use crate::files;
use crate::memory::Budget;

pub use find::{find_maps, map_name, output_names, FoundMaps};
pub use ros_grid::{grid_image, GridThresholds, GRID_FREE, GRID_OCCUPIED, GRID_UNKNOWN};
pub use rows::{DecoderRows, MapRows};
pub use save::{merged_yaml_text, save_names, write_merged_pgm_to, yaml_text};
use yaml::read_yaml;
pub use yaml::{
    is_yaml, map_yaml_text, map_yaml_text_with, yaml_image, MapYaml, MAX_YAML_BYTES,
    MAX_YAML_NESTING,
};

/// Largest decoded image the loader accepts, in bytes: a 65536 x 65536 8-bit map. Guards against a
/// header that claims an absurd size, which would otherwise abort the process when allocating.
pub const MAX_IMAGE_BYTES: u64 = 1 << 32;

/// Pixels that live outside the library and are read in place, such as a numpy array handed in from
/// Python: the holder keeps them alive and unchanged for as long as it exists.
pub trait PixelSource: Send + Sync {
    /// The pixels, row-major, row 0 at the top.
    fn bytes(&self) -> &[u8];
}

impl PixelSource for Vec<u8> {
    fn bytes(&self) -> &[u8] {
        self
    }
}

/// Where a map's pixels are: owned, or read in place from a [`PixelSource`] (copied on first write).
#[derive(Clone)]
enum Pixels {
    Owned(Vec<u8>),
    Shared(Arc<dyn PixelSource>),
}

impl Pixels {
    fn bytes(&self) -> &[u8] {
        match self {
            Pixels::Owned(v) => v,
            Pixels::Shared(s) => s.bytes(),
        }
    }
}

/// An 8-bit greyscale map image, row-major, row 0 at the top.
#[derive(Clone)]
pub struct MapImage {
    width: u32,
    height: u32,
    pixels: Pixels,
}

impl PartialEq for MapImage {
    fn eq(&self, other: &Self) -> bool {
        (self.width, self.height) == (other.width, other.height) && self.pixels() == other.pixels()
    }
}

impl Eq for MapImage {}

impl std::fmt::Debug for MapImage {
    /// The size and where the pixels are, not the pixels.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = match self.pixels {
            Pixels::Owned(_) => "owned",
            Pixels::Shared(_) => "shared",
        };
        write!(f, "MapImage({}x{}, {kind})", self.width, self.height)
    }
}

impl MapImage {
    /// Wraps `pixels` (row-major, `width * height` bytes). Fails on a zero-size map or a length mismatch.
    pub fn new(width: u32, height: u32, pixels: Vec<u8>) -> Result<Self> {
        check_len(width, height, pixels.len())?;
        Ok(MapImage {
            width,
            height,
            pixels: Pixels::Owned(pixels),
        })
    }

    /// Wraps pixels read in place (`width * height` bytes from `source`), without a copy; the first
    /// [`MapImage::pixels_mut`] copies them. Fails as [`MapImage::new`] does.
    pub fn shared(width: u32, height: u32, source: Arc<dyn PixelSource>) -> Result<Self> {
        check_len(width, height, source.bytes().len())?;
        Ok(MapImage {
            width,
            height,
            pixels: Pixels::Shared(source),
        })
    }

    /// A map of one value everywhere.
    pub fn filled(width: u32, height: u32, value: u8) -> Result<Self> {
        Self::new(width, height, vec![value; width as usize * height as usize])
    }

    /// Width in pixels (at least 1).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels (at least 1).
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixels, row-major, row 0 at the top.
    pub fn pixels(&self) -> &[u8] {
        self.pixels.bytes()
    }

    /// Mutable pixels, for building maps in memory (pixels read in place are copied first).
    pub fn pixels_mut(&mut self) -> &mut [u8] {
        if let Pixels::Shared(s) = &self.pixels {
            self.pixels = Pixels::Owned(s.bytes().to_vec());
        }
        match &mut self.pixels {
            Pixels::Owned(v) => v,
            Pixels::Shared(_) => unreachable!("copied above"),
        }
    }

    /// The same image with its pixels behind a reference count, so that its clones share them (the maps
    /// a Python program passes around).
    pub fn into_shared(self) -> MapImage {
        match self.pixels {
            Pixels::Owned(v) => MapImage {
                pixels: Pixels::Shared(Arc::new(v)),
                ..self
            },
            Pixels::Shared(_) => self,
        }
    }

    /// Whether the pixels are read in place from a [`PixelSource`] rather than owned.
    pub fn is_shared(&self) -> bool {
        matches!(self.pixels, Pixels::Shared(_))
    }

    /// The pixel at column `x`, row `y`. Panics when out of range, like slice indexing.
    pub fn get(&self, x: u32, y: u32) -> u8 {
        self.pixels()[y as usize * self.width as usize + x as usize]
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.pixels().len()
    }

    /// Always false: a `MapImage` has at least one pixel.
    pub fn is_empty(&self) -> bool {
        self.pixels().is_empty()
    }

    /// Writes the map as a binary PGM (P5), atomically ([`files::write_atomic`]), without a second copy
    /// of the pixels.
    pub fn write_pgm(&self, path: &Path) -> Result<()> {
        files::write_atomic(path, |out| self.write_pgm_to(out))
    }

    /// The image as a binary PGM (P5, maxval 255) into `out`.
    pub fn write_pgm_to(&self, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        write_pgm_header(out, self.width, self.height)?;
        out.write_all(self.pixels())
    }
}

/// The header of a binary PGM (P5, maxval 255) of `width` x `height`; the raster follows it.
pub fn write_pgm_header(
    out: &mut dyn std::io::Write,
    width: u32,
    height: u32,
) -> std::io::Result<()> {
    write_pgm_header_with(out, width, height, None)
}

/// [`write_pgm_header`] with a comment line after the magic number (which every PGM reader skips).
pub fn write_pgm_header_with(
    out: &mut dyn std::io::Write,
    width: u32,
    height: u32,
    comment: Option<&str>,
) -> std::io::Result<()> {
    out.write_all(b"P5\n")?;
    if let Some(c) = comment {
        writeln!(out, "# {c}")?;
    }
    write!(out, "{width} {height}\n255\n")
}

/// Refuses a zero-size map or a pixel count other than `width * height`.
fn check_len(width: u32, height: u32, len: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::invalid(format!(
            "zero-size map ({width}x{height}): nothing to detect in"
        )));
    }
    let expected = width as u64 * height as u64;
    if len as u64 != expected {
        return Err(Error::invalid(format!(
            "map of {width}x{height} needs {expected} pixels, got {len}"
        )));
    }
    Ok(())
}

/// How pixel values map to occupancy, as in ROS `map_server`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thresholds {
    /// When true, p = v / 255 (white is occupied); otherwise p = (255 - v) / 255.
    pub negate: bool,
    /// Occupied when p > occupied_thresh.
    pub occupied_thresh: f64,
    /// Free when p < free_thresh.
    pub free_thresh: f64,
}

impl Default for Thresholds {
    /// The ROS defaults: negate 0, occupied_thresh 0.65, free_thresh 0.196.
    fn default() -> Self {
        Thresholds {
            negate: false,
            occupied_thresh: 0.65,
            free_thresh: 0.196,
        }
    }
}

impl Thresholds {
    /// Checks both thresholds lie in [0, 1] and free_thresh does not exceed occupied_thresh.
    pub fn validate(&self) -> std::result::Result<(), String> {
        for (name, v) in [
            ("occupied_thresh", self.occupied_thresh),
            ("free_thresh", self.free_thresh),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(format!("{name} must lie in [0, 1], got {v}"));
            }
        }
        if self.free_thresh > self.occupied_thresh {
            return Err(format!(
                "free_thresh ({}) is above occupied_thresh ({})",
                self.free_thresh, self.occupied_thresh
            ));
        }
        Ok(())
    }
}

/// Where the map lies in the world: the yaml's resolution and origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeoRef {
    /// Metres per pixel.
    pub resolution: f64,
    /// Pose of the lower-left pixel's outer corner: x, y in metres, yaw in radians.
    pub origin: [f64; 3],
}

impl GeoRef {
    /// World coordinates (metres) of the centre of pixel (x, y), where y counts down from the top row of a
    /// map `height` pixels high. ROS convention: the origin is the pose of the lower-left pixel's corner.
    pub fn pixel_to_world(&self, x: u32, y: u32, height: u32) -> (f64, f64) {
        self.point_to_world((f64::from(x), f64::from(y)), height)
    }

    /// [`GeoRef::pixel_to_world`] of a fractional pixel position (pixel centres at integers).
    pub fn point_to_world(&self, (x, y): (f64, f64), height: u32) -> (f64, f64) {
        let [ox, oy, _] = self.origin;
        let mx = (x + 0.5) * self.resolution;
        let my = (f64::from(height) - 1.0 - y + 0.5) * self.resolution;
        let (s, c) = self.yaw_sin_cos();
        (ox + c * mx - s * my, oy + s * mx + c * my)
    }

    /// The position in pixels (pixel centres at integers) of world point `(wx, wy)` in a map `height`
    /// pixels high: the inverse of [`GeoRef::point_to_world`].
    pub fn world_to_point(&self, (wx, wy): (f64, f64), height: u32) -> (f64, f64) {
        let [ox, oy, _] = self.origin;
        let (s, c) = self.yaw_sin_cos();
        let (dx, dy) = (wx - ox, wy - oy);
        let (mx, my) = (c * dx + s * dy, -s * dx + c * dy);
        (
            mx / self.resolution - 0.5,
            f64::from(height) - 0.5 - my / self.resolution,
        )
    }

    /// Sine and cosine of the origin's yaw; a non-finite yaw (seen as `nan` in real yaml files) is treated as
    /// 0, and the loader warns about it.
    fn yaw_sin_cos(&self) -> (f64, f64) {
        let yaw = self.origin[2];
        if yaw.is_finite() { yaw } else { 0.0 }.sin_cos()
    }

    /// Checks that every pixel of a `width` x `height` map has finite world coordinates (a resolution of
    /// 1e308 or an origin of 1e308 would make them infinite or NaN).
    pub fn check_finite(&self, width: u32, height: u32) -> std::result::Result<(), String> {
        let extent = self.resolution * f64::from(width.max(height));
        let corners = [
            (0, 0),
            (width - 1, 0),
            (0, height - 1),
            (width - 1, height - 1),
        ];
        let finite = extent.is_finite()
            && corners.iter().all(|&(x, y)| {
                let (wx, wy) = self.pixel_to_world(x, y, height);
                wx.is_finite() && wy.is_finite()
            });
        if finite {
            Ok(())
        } else {
            Err(format!(
                "resolution {} and origin [{}, {}] give non-finite world coordinates for a {width}x{height} map",
                self.resolution, self.origin[0], self.origin[1]
            ))
        }
    }
}

/// A map ready for detection: the image, how to read its pixels, and (from a yaml) where it lies.
#[derive(Clone, Debug)]
pub struct OccupancyMap {
    /// The greyscale image.
    pub image: MapImage,
    /// How pixel values become occupied / unknown / free.
    pub thresholds: Thresholds,
    /// Resolution and origin, when the map came with a yaml.
    pub georef: Option<GeoRef>,
    /// The image file the pixels came from, if any.
    pub image_path: Option<PathBuf>,
    /// The yaml file, if any.
    pub yaml_path: Option<PathBuf>,
    /// Things a user should know that do not stop loading (for example a `nan` yaw).
    pub warnings: Vec<String>,
}

impl OccupancyMap {
    /// The files the map was read from: its yaml and its image (none for a map made in memory).
    pub fn files(&self) -> impl Iterator<Item = &Path> {
        [self.yaml_path.as_deref(), self.image_path.as_deref()]
            .into_iter()
            .flatten()
    }

    /// A map from an image in memory, with the ROS default thresholds and no georeference.
    pub fn from_image(image: MapImage) -> Self {
        OccupancyMap {
            image,
            thresholds: Thresholds::default(),
            georef: None,
            image_path: None,
            yaml_path: None,
            warnings: Vec::new(),
        }
    }

    /// Loads a `.yaml` (and the image it names) or an image alone (with the ROS default thresholds), within
    /// the machine's memory budget ([`Budget::machine`]).
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        Self::load_within(path.as_ref(), &Budget::default(), &|_, _| 0)
    }

    /// [`OccupancyMap::load`], refusing before the pixels are allocated when the map (`width * height`
    /// bytes, plus the decoder's buffers, plus `extra(width, height)`: what the caller will allocate for
    /// it, such as a detector's working memory) would exceed `budget`.
    pub fn load_within(
        path: &Path,
        budget: &Budget,
        extra: &dyn Fn(u32, u32) -> u64,
    ) -> Result<Self> {
        if is_yaml(path) {
            return Self::load_yaml_within(path, budget, extra);
        }
        let (image, warnings) = load_image_within(path, budget, extra, None)?;
        Ok(OccupancyMap {
            image_path: Some(path.to_path_buf()),
            warnings,
            ..Self::from_image(image)
        })
    }

    /// Loads a ROS `map_server` yaml and the image it names (relative to the yaml's folder).
    pub fn load_yaml(path: &Path) -> Result<Self> {
        Self::load_yaml_within(path, &Budget::default(), &|_, _| 0)
    }

    fn load_yaml_within(
        path: &Path,
        budget: &Budget,
        extra: &dyn Fn(u32, u32) -> u64,
    ) -> Result<Self> {
        let (meta, image_path) = read_yaml(path)?;
        let georef = meta.georef();
        let check = |w: u32, h: u32| georef.check_finite(w, h).map_err(|m| Error::input(path, m));
        let (image, mut warnings) = load_image_within(&image_path, budget, extra, Some(&check))?;
        if !meta.origin[2].is_finite() {
            warnings.push(format!(
                "{}: origin yaw is {}; world coordinates use yaw 0",
                path.display(),
                meta.origin[2]
            ));
        }
        Ok(OccupancyMap {
            image,
            thresholds: meta.thresholds,
            georef: Some(georef),
            image_path: Some(image_path),
            yaml_path: Some(path.to_path_buf()),
            warnings,
        })
    }

    /// Reads what loading `path` reads up to the image header (the yaml and its checks, the header),
    /// without the pixels, and returns the map's size and its image file: to refuse a bad map, and to
    /// protect its image from the run's outputs, before a long run starts.
    pub fn probe(path: &Path) -> Result<(u32, u32, PathBuf)> {
        let (image_path, georef) = if is_yaml(path) {
            let (meta, image_path) = read_yaml(path)?;
            (image_path, Some(meta.georef()))
        } else {
            (path.to_path_buf(), None)
        };
        let dec = open_image(&image_path, &Budget::default())?;
        let (w, h) = (dec.header().width, dec.header().height);
        // Its callers hold maps whole: a map too large for that is refused now, not when its turn comes.
        crate::decode::check_in_memory(w, h).map_err(|m| Error::input(&image_path, m))?;
        if let Some(g) = georef {
            g.check_finite(w, h).map_err(|m| Error::input(path, m))?;
        }
        Ok((w, h, image_path))
    }

    /// The file a user named for this map: the yaml if there was one, else the image.
    pub fn source(&self) -> Option<&Path> {
        self.yaml_path.as_deref().or(self.image_path.as_deref())
    }
}

/// Loads a PGM (P2/P5, 8 or 16 bit) or PNG (grey, grey+alpha, RGB, RGBA, palette) as 8-bit grey, within
/// the machine's memory budget.
///
/// 16-bit images are scaled to 8 bits; colour images are converted by luminance; alpha is ignored, as
/// ROS does for trinary maps. See [`crate::decode`] for what is refused.
pub fn load_image(path: &Path) -> Result<MapImage> {
    load_image_within(path, &Budget::default(), &|_, _| 0, None).map(|(img, _)| img)
}

/// The image kind a file name suggests.
fn kind_hint(path: &Path) -> Option<ImageKind> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("png") => Some(ImageKind::Png),
        Some("pgm" | "pnm") => Some(ImageKind::Pgm),
        _ => None,
    }
}

/// A check of the header's size before any pixel is read (the yaml's world coordinates).
type SizeCheck<'a> = &'a dyn Fn(u32, u32) -> Result<()>;

/// Reads the header, checks the size against `budget` (map + decoder buffers + `extra`) and `check`,
/// then decodes row by row into one buffer: about 1x the map in memory. Returns the image and warnings
/// (such as trailing bytes ignored).
pub fn load_image_within(
    path: &Path,
    budget: &Budget,
    extra: &dyn Fn(u32, u32) -> u64,
    check: Option<SizeCheck>,
) -> Result<(MapImage, Vec<String>)> {
    let dec = open_image(path, budget)?;
    decode_rows(dec, budget, extra, check)
        .map_err(|e| match e {
            Error::Input {
                path: None,
                message,
            } => Error::input(path, message),
            other => other,
        })
        .map(|(img, warnings)| {
            let named = warnings
                .into_iter()
                .map(|m| format!("{}: {m}", path.display()))
                .collect();
            (img, named)
        })
}

/// The image file at `path` (a regular file), its header read.
fn open_image(path: &Path, budget: &Budget) -> Result<Decoder<BufReader<std::fs::File>>> {
    open_image_with(path, budget, 1 << 16)
}

/// [`open_image`] reading `buffer` bytes at a time (a streamed map reads megabytes: fewer system calls).
fn open_image_with(
    path: &Path,
    budget: &Budget,
    buffer: usize,
) -> Result<Decoder<BufReader<std::fs::File>>> {
    let (file, len) = files::open_regular(path)?;
    #[cfg(target_os = "linux")]
    if buffer > 1 << 16 {
        // Read front to back once: a larger read-ahead. Only advice; a failure changes nothing.
        let _ = rustix::fs::fadvise(&file, 0, None, rustix::fs::Advice::Sequential);
    }
    let reader = BufReader::with_capacity(buffer, file);
    Decoder::new(reader, Some(len), kind_hint(path), budget.limit())
        .map_err(|m| Error::input(path, m))
}

/// The one decoding path of files and bytes once the header is read: checks, budget, then the rows.
fn decode_rows<R: std::io::BufRead>(
    mut dec: Decoder<R>,
    budget: &Budget,
    extra: &dyn Fn(u32, u32) -> u64,
    check: Option<SizeCheck>,
) -> Result<(MapImage, Vec<String>)> {
    let (w, h) = (dec.header().width, dec.header().height);
    crate::decode::check_in_memory(w, h).map_err(Error::invalid)?;
    if let Some(check) = check {
        check(w, h)?;
    }
    let need = (u64::from(w) * u64::from(h))
        .saturating_add(dec.header().decoder_bytes)
        .saturating_add(extra(w, h));
    budget.check(format_args!("a {w}x{h} map"), need)?;
    let mut pixels = vec![0u8; w as usize * h as usize];
    dec.read_rows(&mut pixels).map_err(Error::invalid)?;
    let warnings = dec.finish().map_err(Error::invalid)?;
    Ok((MapImage::new(w, h, pixels)?, warnings))
}

/// Decodes image bytes in memory; `hint` is the format the file name suggests, used when the content
/// does not say. Refuses images over the machine's memory budget ([`Budget::machine`]) from the header.
pub fn decode_image(
    bytes: &[u8],
    hint: Option<ImageKind>,
) -> std::result::Result<MapImage, String> {
    let budget = Budget::default();
    let dec = Decoder::new(bytes, Some(bytes.len() as u64), hint, budget.limit())?;
    decode_rows(dec, &budget, &|_, _| 0, None)
        .map(|(img, _)| img)
        .map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_pixels_are_read_in_place_and_copied_on_write() {
        let source: Arc<dyn PixelSource> = Arc::new(vec![1u8, 2, 3, 4, 5, 6]);
        let img = MapImage::shared(3, 2, source.clone()).unwrap();
        assert!(img.is_shared());
        assert_eq!(img.pixels().as_ptr(), source.bytes().as_ptr());
        assert_eq!(img.get(2, 1), 6);
        // A clone shares the pixels; a write copies them first and leaves the source alone.
        let mut copy = img.clone();
        assert_eq!(copy.pixels().as_ptr(), source.bytes().as_ptr());
        copy.pixels_mut()[0] = 9;
        assert!(!copy.is_shared());
        assert_eq!(source.bytes()[0], 1);
        assert_ne!(copy, img);
        assert_eq!(MapImage::new(3, 2, vec![1, 2, 3, 4, 5, 6]).unwrap(), img);
        assert!(MapImage::shared(4, 2, source).is_err());
        // An owned image made shared keeps its pixels and shares them from then on.
        let owned = MapImage::new(2, 1, vec![7, 8]).unwrap().into_shared();
        assert!(owned.is_shared() && owned.pixels() == [7, 8]);
        assert_eq!(owned.clone().pixels().as_ptr(), owned.pixels().as_ptr());
    }
}
