//! A robot's map as loaded: ROS `map_server` yaml files and their images (PGM, PNG), the thresholds
//! that read the pixels as occupancy, and where the map lies.
//!
//! Pixel row 0 is the top of the map. The yaml origin is the pose of the lower-left pixel, as in ROS.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use super::yaml::{is_yaml, read_yaml};
use super::MapImage;
use crate::map::decode::{Decoder, ImageKind};
use crate::support::error::{Error, Result};
use crate::support::files;
use crate::support::memory::Budget;

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
        crate::map::decode::check_in_memory(w, h).map_err(|m| Error::input(&image_path, m))?;
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
/// ROS does for trinary maps. See [`crate::map::decode`] for what is refused.
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
pub(super) fn open_image_with(
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
    crate::map::decode::check_in_memory(w, h).map_err(Error::invalid)?;
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
