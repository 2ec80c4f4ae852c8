//! Loading robot maps: ROS `map_server` yaml files and their images (PGM, PNG).
//!
//! Pixel row 0 is the top of the map. The yaml origin is the pose of the lower-left pixel, as in ROS.

use std::collections::HashSet;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use serde_yaml::Value;

use crate::decode::{Decoder, ImageKind};
use crate::error::{Error, Result};
use crate::files::{self, FileId};
use crate::memory::Budget;

/// Largest decoded image the loader accepts, in bytes: a 65536 x 65536 8-bit map. Guards against a
/// header that claims an absurd size, which would otherwise abort the process when allocating.
pub const MAX_IMAGE_BYTES: u64 = 1 << 32;

/// Largest map yaml read, in bytes. A map yaml is a few hundred bytes; the bound keeps a hostile file
/// from being read whole or parsed for minutes.
pub const MAX_YAML_BYTES: u64 = 64 << 10;

/// Deepest nesting of `[` and `{` a map yaml may have (a real one has 1: the origin list). The yaml
/// parser is quadratic in nesting depth, so deeper files are refused before parsing.
pub const MAX_YAML_NESTING: usize = 16;

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

    /// Writes the map as a binary PGM (P5), atomically ([`files::write_atomic`]), without a second copy
    /// of the pixels.
    pub fn write_pgm(&self, path: &Path) -> Result<()> {
        files::write_atomic(path, |out| {
            write!(out, "P5\n{} {}\n255\n", self.width, self.height)?;
            out.write_all(&self.pixels)
        })
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
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        if matches!(ext.as_deref(), Some("yaml") | Some("yml")) {
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
        let georef = GeoRef {
            resolution: meta.resolution,
            origin: meta.origin,
        };
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
    /// without the pixels, and returns the map's size: to refuse a bad map before a long run starts.
    pub fn probe(path: &Path) -> Result<(u32, u32)> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        let (image_path, georef) = if matches!(ext.as_deref(), Some("yaml") | Some("yml")) {
            let (meta, image_path) = read_yaml(path)?;
            let georef = GeoRef {
                resolution: meta.resolution,
                origin: meta.origin,
            };
            (image_path, Some(georef))
        } else {
            (path.to_path_buf(), None)
        };
        let (file, len) = files::open_regular(&image_path)?;
        let dec = Decoder::new(
            BufReader::with_capacity(1 << 16, file),
            Some(len),
            kind_hint(&image_path),
            Budget::default().limit(),
        )
        .map_err(|m| Error::input(&image_path, m))?;
        let (w, h) = (dec.header().width, dec.header().height);
        if let Some(g) = georef {
            g.check_finite(w, h).map_err(|m| Error::input(path, m))?;
        }
        Ok((w, h))
    }

    /// The file a user named for this map: the yaml if there was one, else the image.
    pub fn source(&self) -> Option<&Path> {
        self.yaml_path.as_deref().or(self.image_path.as_deref())
    }
}

/// A map yaml's fields and the path of the image it names (relative to the yaml's folder).
fn read_yaml(path: &Path) -> Result<(MapYaml, PathBuf)> {
    let text = files::read_small_text(path, MAX_YAML_BYTES, "a map yaml")?;
    let meta = MapYaml::parse(&text).map_err(|m| Error::input(path, m))?;
    let image_path = if Path::new(&meta.image).is_absolute() {
        PathBuf::from(&meta.image)
    } else {
        path.parent()
            .unwrap_or_else(|| Path::new(""))
            .join(&meta.image)
    };
    Ok((meta, image_path))
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
        // Editors on Windows start UTF-8 files with a byte-order mark; it is not part of the yaml.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        if text.len() as u64 > MAX_YAML_BYTES {
            return Err(format!(
                "{} bytes is too large for a map yaml (at most {MAX_YAML_BYTES})",
                text.len()
            ));
        }
        let depth = nesting_depth(text);
        if depth > MAX_YAML_NESTING {
            return Err(format!(
                "nested {depth} levels deep; a map yaml is a flat list of keys (at most {MAX_YAML_NESTING} levels)"
            ));
        }
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

impl MapYaml {
    /// The `image` of yaml text that is meant as a map yaml (a mapping with `image` and `resolution` or
    /// `origin`) whether or not it is a valid one; None for other yaml (a ROS parameter file).
    pub fn meant_image(text: &str) -> Option<String> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        if text.len() as u64 > MAX_YAML_BYTES || nesting_depth(text) > MAX_YAML_NESTING {
            return None;
        }
        let doc: Value = serde_yaml::from_str(text).ok()?;
        let map = doc.as_mapping()?;
        let has = |k: &str| map.contains_key(Value::String(k.to_string()));
        if !(has("resolution") || has("origin")) {
            return None;
        }
        map.get(Value::String("image".into()))?
            .as_str()
            .map(|s| s.trim().to_string())
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

/// The deepest nesting of flow collections (`[`, `{`) in yaml text, outside quotes and comments: an upper
/// bound of what the parser will recurse into.
fn nesting_depth(text: &str) -> usize {
    let (mut depth, mut max) = (0usize, 0usize);
    let mut quote: Option<char> = None;
    let mut comment = false;
    let mut prev = '\n';
    for c in text.chars() {
        if comment {
            comment = c != '\n';
        } else if let Some(q) = quote {
            if c == q {
                quote = None;
            }
        } else {
            match c {
                '"' | '\'' => quote = Some(c),
                '#' if prev.is_whitespace() => comment = true,
                '[' | '{' => {
                    depth += 1;
                    max = max.max(depth);
                }
                ']' | '}' => depth = depth.saturating_sub(1),
                _ => {}
            }
        }
        prev = c;
    }
    max
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
    let (file, len) = files::open_regular(path)?;
    let reader = BufReader::with_capacity(1 << 16, file);
    decode_within(reader, len, kind_hint(path), budget, extra, check)
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

/// The one decoding path of files and bytes: header, checks, budget, then the rows.
fn decode_within<R: std::io::BufRead>(
    reader: R,
    len: u64,
    hint: Option<ImageKind>,
    budget: &Budget,
    extra: &dyn Fn(u32, u32) -> u64,
    check: Option<SizeCheck>,
) -> Result<(MapImage, Vec<String>)> {
    let mut dec = Decoder::new(reader, Some(len), hint, budget.limit()).map_err(Error::invalid)?;
    let (w, h) = (dec.header().width, dec.header().height);
    if let Some(check) = check {
        check(w, h)?;
    }
    let need = (u64::from(w) * u64::from(h))
        .saturating_add(dec.header().decoder_bytes)
        .saturating_add(extra(w, h));
    budget.check(format_args!("a {w}x{h} map"), need)?;
    let mut pixels = vec![0u8; w as usize * h as usize];
    for row in pixels.chunks_exact_mut(w as usize) {
        dec.read_row(row).map_err(Error::invalid)?;
    }
    let warnings = dec.finish().map_err(Error::invalid)?;
    Ok((MapImage::new(w, h, pixels)?, warnings))
}

/// Decodes image bytes in memory; `hint` is the format the file name suggests, used when the content
/// does not say. Refuses images over the machine's memory budget ([`Budget::machine`]) from the header.
pub fn decode_image(
    bytes: &[u8],
    hint: Option<ImageKind>,
) -> std::result::Result<MapImage, String> {
    decode_within(
        bytes,
        bytes.len() as u64,
        hint,
        &Budget::default(),
        &|_, _| 0,
        None,
    )
    .map(|(img, _)| img)
    .map_err(|e| e.to_string())
}

/// What [`find_maps`] found.
#[derive(Debug, Default)]
pub struct FoundMaps {
    /// The maps, files as given and then each folder's in path order.
    pub maps: Vec<PathBuf>,
    /// Things left out on purpose, for information: yaml files that are not maps, links back into a
    /// folder already searched.
    pub notes: Vec<String>,
    /// Entries that could not be read (an unreadable folder or yaml, a fifo named like a map, a folder
    /// with no map): skipped so the rest is processed, but the run should end with an error.
    pub problems: Vec<String>,
}

/// The maps named by `inputs`: files as given, and for each folder (searched recursively, in path order,
/// hidden entries left out, each real folder once however many links lead to it) every ROS map yaml plus
/// every PGM/PNG image that no yaml there names. A yaml that is not a map (ROS packages keep other yaml
/// files beside their maps) is left out with a note. Unreadable entries are reported in
/// [`FoundMaps::problems`] and skipped; they never stop the search.
pub fn find_maps(inputs: &[PathBuf]) -> FoundMaps {
    let mut found = FoundMaps::default();
    let mut seen_dirs: HashSet<FileId> = HashSet::new();
    let mut seen_files: HashSet<FileId> = HashSet::new();
    for input in inputs {
        if !input.is_dir() {
            found.maps.push(input.clone());
            continue;
        }
        let before = found.maps.len();
        let files = walk(input, &mut seen_dirs, &mut seen_files, &mut found);
        let ext = |p: &Path| {
            p.extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
                .unwrap_or_default()
        };
        // The images the yamls name, compared as file identities (links and spellings alike).
        let mut named = HashSet::new();
        for y in files
            .iter()
            .filter(|p| matches!(ext(p).as_str(), "yaml" | "yml"))
        {
            let text = match files::read_small_text(y, MAX_YAML_BYTES, "a map yaml") {
                Ok(t) => t,
                Err(e) if e.to_string().contains("too large") => {
                    found
                        .notes
                        .push(format!("skipped {}: not a map yaml: {e}", y.display()));
                    continue;
                }
                Err(e) => {
                    found.problems.push(format!("skipped {e}"));
                    continue;
                }
            };
            let dir = y.parent().unwrap_or(Path::new(""));
            match MapYaml::parse(&text) {
                Ok(meta) => {
                    named.extend(FileId::of(&dir.join(meta.image)));
                    found.maps.push(y.clone());
                }
                // A broken map yaml is an error, and its image is not read as a bare image either: that
                // would detect with the wrong thresholds and no world coordinates.
                Err(e) => match MapYaml::meant_image(&text) {
                    Some(image) => {
                        named.extend(FileId::of(&dir.join(image)));
                        found.problems.push(format!("skipped {}: {e}", y.display()));
                    }
                    None => found
                        .notes
                        .push(format!("skipped {}: not a map yaml: {e}", y.display())),
                },
            }
        }
        for p in &files {
            if matches!(ext(p).as_str(), "pgm" | "png")
                && !FileId::of(p).is_some_and(|id| named.contains(&id))
            {
                found.maps.push(p.clone());
            }
        }
        if found.maps.len() == before {
            found.problems.push(format!(
                "{}: no maps in this folder (looked for .yaml, .pgm and .png files)",
                input.display()
            ));
        }
    }
    found
}

/// The regular files under `root`, sorted, each real folder and file visited once.
fn walk(
    root: &Path,
    seen_dirs: &mut HashSet<FileId>,
    seen_files: &mut HashSet<FileId>,
    found: &mut FoundMaps,
) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let Some(id) = FileId::of(&dir) else {
            found
                .problems
                .push(format!("skipped {}: cannot read the folder", dir.display()));
            continue;
        };
        if !seen_dirs.insert(id) {
            if dir != root {
                found.notes.push(format!(
                    "skipped {}: a link to a folder already searched",
                    dir.display()
                ));
            }
            continue;
        }
        let entries = match std::fs::read_dir(&dir) {
            Ok(e) => e,
            Err(e) => {
                found.problems.push(format!(
                    "skipped {}: cannot list the folder: {e}",
                    dir.display()
                ));
                continue;
            }
        };
        for entry in entries {
            let p = match entry {
                Ok(e) => e.path(),
                Err(e) => {
                    found
                        .problems
                        .push(format!("skipped an entry of {}: {e}", dir.display()));
                    continue;
                }
            };
            let hidden = p
                .file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with('.'));
            if hidden {
                continue;
            }
            let is_map_name = p
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
                .is_some_and(|e| matches!(e.as_str(), "yaml" | "yml" | "pgm" | "png"));
            match std::fs::metadata(&p) {
                Ok(m) if m.is_dir() => stack.push(p),
                Ok(m) if m.is_file() => {
                    if seen_files.insert(FileId::from_meta(&p, &m)) {
                        files.push(p);
                    }
                }
                Ok(m) if is_map_name => found.problems.push(format!(
                    "skipped {}: not a regular file ({})",
                    p.display(),
                    files::kind_of(&m)
                )),
                Ok(_) => {}
                Err(e) if is_map_name => found
                    .problems
                    .push(format!("skipped {}: cannot read: {e}", p.display())),
                // A broken link or unreadable entry that is no map is none of our business.
                Err(_) => {}
            }
        }
    }
    files.sort();
    files
}
