//! Loading robot maps: ROS `map_server` yaml files and their images (PGM, PNG).
//!
//! Pixel row 0 is the top of the map. The yaml origin is the pose of the lower-left pixel, as in ROS.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageFormat, ImageReader, Limits};
use serde_yaml::Value;

use crate::error::{Error, Result};

/// Largest decoded image the loader accepts, in bytes: a 65536 x 65536 8-bit map. Guards against a
/// header that claims an absurd size, which would otherwise abort the process when allocating.
pub const MAX_IMAGE_BYTES: u64 = 1 << 32;

/// An 8-bit greyscale map image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MapImage {
    width: u32,
    height: u32,
    pixels: Vec<u8>,
}

impl MapImage {
    /// Wraps `pixels` (row-major, `width * height` bytes). Fails on a zero-size map or a length mismatch.
    pub fn new(width: u32, height: u32, pixels: Vec<u8>) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!(
                "zero-size map ({width}x{height}): nothing to detect in"
            )));
        }
        let expected = width as u64 * height as u64;
        if pixels.len() as u64 != expected {
            return Err(Error::invalid(format!(
                "map of {width}x{height} needs {expected} pixels, got {}",
                pixels.len()
            )));
        }
        Ok(MapImage {
            width,
            height,
            pixels,
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
        &self.pixels
    }

    /// Mutable pixels, for building maps in memory.
    pub fn pixels_mut(&mut self) -> &mut [u8] {
        &mut self.pixels
    }

    /// The pixel at column `x`, row `y`. Panics when out of range, like slice indexing.
    pub fn get(&self, x: u32, y: u32) -> u8 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.pixels.len()
    }

    /// Always false: a `MapImage` has at least one pixel.
    pub fn is_empty(&self) -> bool {
        self.pixels.is_empty()
    }

    /// Writes the map as a binary PGM (P5).
    pub fn write_pgm(&self, path: &Path) -> Result<()> {
        let mut out = format!("P5\n{} {}\n255\n", self.width, self.height).into_bytes();
        out.extend_from_slice(&self.pixels);
        std::fs::write(path, out).map_err(|e| Error::output(path, e))
    }
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
        let [ox, oy, yaw] = self.origin;
        // Non-finite yaw (seen as `nan` in real yaml files) is treated as 0; the loader warns about it.
        let yaw = if yaw.is_finite() { yaw } else { 0.0 };
        let mx = (x as f64 + 0.5) * self.resolution;
        let my = ((height - 1 - y) as f64 + 0.5) * self.resolution;
        let (s, c) = yaw.sin_cos();
        (ox + c * mx - s * my, oy + s * mx + c * my)
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

    /// Loads a `.yaml` (and the image it names) or an image alone (with the ROS default thresholds).
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("yaml") | Some("yml") => Self::load_yaml(path),
            _ => {
                let image = load_image(path)?;
                Ok(OccupancyMap {
                    image_path: Some(path.to_path_buf()),
                    ..Self::from_image(image)
                })
            }
        }
    }

    /// Loads a ROS `map_server` yaml and the image it names (relative to the yaml's folder).
    pub fn load_yaml(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
        let meta = MapYaml::parse(&text).map_err(|m| Error::input(path, m))?;
        let image_path = if Path::new(&meta.image).is_absolute() {
            PathBuf::from(&meta.image)
        } else {
            path.parent()
                .unwrap_or_else(|| Path::new(""))
                .join(&meta.image)
        };
        let image = load_image(&image_path)?;
        let mut warnings = Vec::new();
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
            georef: Some(GeoRef {
                resolution: meta.resolution,
                origin: meta.origin,
            }),
            image_path: Some(image_path),
            yaml_path: Some(path.to_path_buf()),
            warnings,
        })
    }

    /// The file a user named for this map: the yaml if there was one, else the image.
    pub fn source(&self) -> Option<&Path> {
        self.yaml_path.as_deref().or(self.image_path.as_deref())
    }
}

/// The fields of a ROS `map_server` yaml that the detector uses.
#[derive(Clone, Debug, PartialEq)]
pub struct MapYaml {
    /// The image path as written in the yaml.
    pub image: String,
    /// Metres per pixel.
    pub resolution: f64,
    /// [x, y, yaw] of the lower-left pixel.
    pub origin: [f64; 3],
    /// negate, occupied_thresh, free_thresh.
    pub thresholds: Thresholds,
}

impl MapYaml {
    /// Parses the yaml text; the error is a one-line description of the first problem found.
    pub fn parse(text: &str) -> std::result::Result<Self, String> {
        let doc: Value =
            serde_yaml::from_str(text).map_err(|e| format!("broken yaml: {}", one_line(&e)))?;
        let map = match &doc {
            Value::Mapping(m) => m,
            Value::Null => return Err("empty yaml: expected image, resolution and origin".into()),
            _ => return Err("yaml is not a mapping of keys to values".into()),
        };
        let get = |k: &str| map.get(Value::String(k.to_string()));
        let image = match get("image") {
            Some(Value::String(s)) if !s.trim().is_empty() => s.trim().to_string(),
            Some(_) => return Err("`image` must be a file name".into()),
            None => return Err("missing `image` (the map's image file)".into()),
        };
        let resolution = number(get("resolution"), "resolution")?
            .ok_or("missing `resolution` (metres per pixel)")?;
        if !(resolution.is_finite() && resolution > 0.0) {
            return Err(format!("`resolution` must be positive, got {resolution}"));
        }
        let origin = match get("origin") {
            Some(Value::Sequence(seq)) if seq.len() == 3 || seq.len() == 2 => {
                let mut o = [0.0; 3];
                for (i, v) in seq.iter().enumerate() {
                    o[i] = number(Some(v), "origin")?.ok_or("`origin` holds an empty value")?;
                }
                if !(o[0].is_finite() && o[1].is_finite()) {
                    return Err(format!("`origin` x and y must be finite, got {o:?}"));
                }
                o
            }
            Some(_) => return Err("`origin` must be a list [x, y, yaw]".into()),
            None => return Err("missing `origin` ([x, y, yaw] of the lower-left pixel)".into()),
        };
        let negate = match get("negate") {
            None => false,
            Some(Value::Bool(b)) => *b,
            Some(v) => match number(Some(v), "negate")? {
                Some(0.0) => false,
                Some(1.0) => true,
                _ => return Err("`negate` must be 0 or 1".into()),
            },
        };
        let d = Thresholds::default();
        let thresholds = Thresholds {
            negate,
            occupied_thresh: number(get("occupied_thresh"), "occupied_thresh")?
                .unwrap_or(d.occupied_thresh),
            free_thresh: number(get("free_thresh"), "free_thresh")?.unwrap_or(d.free_thresh),
        };
        thresholds.validate()?;
        match get("mode") {
            None => {}
            Some(Value::String(m)) => match m.trim() {
                // Scale mode differs from trinary only in the values between the thresholds, which the
                // three-state detector reads as unknown either way.
                "trinary" | "scale" => {}
                other => {
                    return Err(format!(
                        "unsupported mode `{other}`: the detector needs a trinary (or scale) map"
                    ))
                }
            },
            Some(_) => return Err("`mode` must be trinary or scale".into()),
        }
        Ok(MapYaml {
            image,
            resolution,
            origin,
            thresholds,
        })
    }
}

/// A yaml number; also accepts numbers written as strings (real maps contain `nan`).
fn number(v: Option<&Value>, key: &str) -> std::result::Result<Option<f64>, String> {
    match v {
        None | Some(Value::Null) => Ok(None),
        Some(Value::Number(n)) => n
            .as_f64()
            .map(Some)
            .ok_or_else(|| format!("`{key}` is not a number")),
        Some(Value::String(s)) => s
            .trim()
            .parse::<f64>()
            .map(Some)
            .map_err(|_| format!("`{key}` is not a number: {s:?}")),
        Some(_) => Err(format!("`{key}` is not a number")),
    }
}

fn one_line(e: &impl std::fmt::Display) -> String {
    e.to_string().replace('\n', " ")
}

/// Loads a PGM (P2/P5, 8 or 16 bit) or PNG (grey, grey+alpha, RGB, RGBA) as 8-bit grey.
///
/// 16-bit images are scaled to 8 bits; colour images are converted by luminance; alpha is ignored, as
/// ROS does for trinary maps.
pub fn load_image(path: &Path) -> Result<MapImage> {
    let bytes = std::fs::read(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    decode_image(&bytes, ImageFormat::from_path(path).ok()).map_err(|m| Error::input(path, m))
}

/// Decodes image bytes; `hint` is the format the file name suggests, used when the content does not say.
pub fn decode_image(
    bytes: &[u8],
    hint: Option<ImageFormat>,
) -> std::result::Result<MapImage, String> {
    if bytes.is_empty() {
        return Err("empty file".into());
    }
    let mut reader = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot read: {e}"))?;
    if reader.format().is_none() {
        if let Some(h) = hint {
            reader.set_format(h);
        }
    }
    let format = match reader.format() {
        Some(f @ (ImageFormat::Png | ImageFormat::Pnm)) => f,
        Some(f) => {
            return Err(format!(
                "unsupported image format {f:?}: expected PGM (P2/P5) or PNG"
            ))
        }
        None => return Err("unknown image format: expected PGM (P2/P5) or PNG".into()),
    };
    let mut limits = Limits::default();
    limits.max_alloc = Some(MAX_IMAGE_BYTES);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| {
        let name = if format == ImageFormat::Png {
            "PNG"
        } else {
            "PGM"
        };
        format!(
            "cannot decode {name} image (truncated or corrupt?): {}",
            one_line(&e)
        )
    })?;
    let (w, h) = (img.width(), img.height());
    if w == 0 || h == 0 {
        return Err(format!("zero-size image ({w}x{h})"));
    }
    let grey = match img {
        DynamicImage::ImageLuma8(g) => g.into_raw(),
        // to_luma8 scales 16-bit values and takes luminance of colour; it drops alpha.
        other => other.to_luma8().into_raw(),
    };
    MapImage::new(w, h, grey).map_err(|e| e.to_string())
}

/// The maps named by `inputs`: files as given, and for each folder (searched recursively, in path order,
/// hidden entries left out) every ROS map yaml plus every PGM/PNG image that no yaml there names. A yaml
/// that is not a map (ROS packages keep other yaml files beside their maps) is left out with a note in the
/// second list. A folder with no map is an error rather than a silently empty batch.
pub fn find_maps(inputs: &[PathBuf]) -> Result<(Vec<PathBuf>, Vec<String>)> {
    let (mut maps, mut notes) = (Vec::new(), Vec::new());
    for input in inputs {
        if !input.is_dir() {
            maps.push(input.clone());
            continue;
        }
        let mut files = Vec::new();
        let mut stack = vec![input.clone()];
        while let Some(dir) = stack.pop() {
            let list_err =
                |e: std::io::Error| Error::input(&dir, format!("cannot list the folder: {e}"));
            for entry in std::fs::read_dir(&dir).map_err(list_err)? {
                let p = entry.map_err(list_err)?.path();
                let hidden = p
                    .file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.starts_with('.'));
                if hidden {
                    continue;
                } else if p.is_dir() {
                    stack.push(p);
                } else {
                    files.push(p);
                }
            }
        }
        files.sort();
        let ext = |p: &Path| {
            p.extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
                .unwrap_or_default()
        };
        let canon = |p: &Path| p.canonicalize().unwrap_or_else(|_| p.to_path_buf());
        let before = maps.len();
        // The images the yamls name, compared as canonical paths.
        let mut named = Vec::new();
        for y in files
            .iter()
            .filter(|p| matches!(ext(p).as_str(), "yaml" | "yml"))
        {
            let text = std::fs::read_to_string(y)
                .map_err(|e| Error::input(y, format!("cannot read: {e}")))?;
            match MapYaml::parse(&text) {
                Ok(meta) => {
                    named.push(canon(&y.parent().unwrap_or(Path::new("")).join(meta.image)));
                    maps.push(y.clone());
                }
                Err(e) => notes.push(format!("skipped {}: not a map yaml: {e}", y.display())),
            }
        }
        for p in &files {
            if matches!(ext(p).as_str(), "pgm" | "png") && !named.contains(&canon(p)) {
                maps.push(p.clone());
            }
        }
        if maps.len() == before {
            return Err(Error::input(
                input,
                "no maps in this folder (looked for .yaml, .pgm and .png files)",
            ));
        }
    }
    Ok((maps, notes))
}
