//! ROS `map_server` yaml files: the fields the detector uses, parsed with bounds on size and nesting.

use std::path::{Path, PathBuf};

use serde_yaml::Value;

use super::Thresholds;
use crate::support::error::{Error, Result};
use crate::support::files;

/// The text of a ROS map_server yaml for image file `image` (a name beside the yaml), with the ROS
/// default thresholds, trinary mode and `resolution` and `origin` (a non-finite yaw written as 0). The
/// image name is written as a YAML scalar, quoted when it needs to be.
pub fn map_yaml_text(image: &str, resolution: f64, origin: [f64; 3]) -> String {
    map_yaml_text_with(image, resolution, origin, &Thresholds::default())
}

/// [`map_yaml_text`] with the given thresholds.
pub fn map_yaml_text_with(
    image: &str,
    resolution: f64,
    origin: [f64; 3],
    t: &Thresholds,
) -> String {
    let image = serde_yaml::to_string(image).unwrap_or_default();
    let yaw = if origin[2].is_finite() {
        origin[2]
    } else {
        0.0
    };
    format!(
        "image: {}\nresolution: {resolution:?}\norigin: [{:?}, {:?}, {yaw:?}]\nnegate: {}\n\
         occupied_thresh: {:?}\nfree_thresh: {:?}\nmode: trinary\n",
        image.trim_end(),
        origin[0],
        origin[1],
        u8::from(t.negate),
        t.occupied_thresh,
        t.free_thresh
    )
}

/// Deepest nesting of `[` and `{` a map yaml may have (a real one has 1: the origin list). The yaml
/// parser is quadratic in nesting depth, so deeper files are refused before parsing.
pub const MAX_YAML_NESTING: usize = 16;

/// Largest map yaml read, in bytes. A map yaml is a few hundred bytes; the bound keeps a hostile file
/// from being read whole or parsed for minutes.
pub const MAX_YAML_BYTES: u64 = 64 << 10;

/// Whether `path` names a yaml file (`.yaml` or `.yml`, any case): a map yaml, as opposed to an image.
pub fn is_yaml(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("yaml") || e.eq_ignore_ascii_case("yml"))
}

/// The image a valid map yaml at `path` names, if it is one and the image exists.
pub fn yaml_image(path: &Path) -> Option<PathBuf> {
    let (_, image) = read_yaml(path).ok()?;
    image.exists().then_some(image)
}

/// A map yaml's fields and the path of the image it names (relative to the yaml's folder).
pub(super) fn read_yaml(path: &Path) -> Result<(MapYaml, PathBuf)> {
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
    /// Where the map lies in the world, as the yaml says.
    pub fn georef(&self) -> super::GeoRef {
        super::GeoRef {
            resolution: self.resolution,
            origin: self.origin,
        }
    }

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
            // As written: a quoted name keeps its spaces, as ROS map_server keeps them (YAML already
            // trims an unquoted one).
            Some(Value::String(s)) if !s.trim().is_empty() => s.clone(),
            Some(_) => return Err("`image` must be a file name".into()),
            None => return Err("missing `image` (the map's image file)".into()),
        };
        let resolution = number(get("resolution"), "resolution")?
            .ok_or("missing `resolution` (metres per pixel)")?;
        if !(resolution.is_finite() && resolution > 0.0) {
            return Err(format!(
                "`resolution` must be a finite positive number, got {resolution}"
            ));
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
        let Ok(doc) = serde_yaml::from_str::<Value>(text) else {
            return meant_image_by_lines(text);
        };
        let map = doc.as_mapping()?;
        let has = |k: &str| map.contains_key(Value::String(k.to_string()));
        if !(has("resolution") || has("origin")) {
            return None;
        }
        map.get(Value::String("image".into()))?
            .as_str()
            .map(str::to_string)
    }
}

/// The `image` of yaml text that does not parse, read line by line: a top-level `image:` line beside a
/// top-level `resolution:` or `origin:` line is a map yaml with a typo (an unclosed bracket, a stray tab),
/// and the image it names must not then be read as a bare image.
fn meant_image_by_lines(text: &str) -> Option<String> {
    let value = |key: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(key)?.strip_prefix(':'))
            .map(str::trim)
    };
    if value("resolution").is_none() && value("origin").is_none() {
        return None;
    }
    let image = value("image")?;
    // A comment after the value, then the quotes around it.
    let image = match image.find(" #") {
        Some(i) => image[..i].trim_end(),
        None => image,
    };
    let unquoted = ['"', '\'']
        .iter()
        .find_map(|q| image.strip_prefix(*q)?.strip_suffix(*q))
        .unwrap_or(image);
    (!unquoted.trim().is_empty()).then(|| unquoted.to_string())
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

/// The deepest nesting of flow collections (`[`, `{`) in yaml text, counting every bracket, quoted or
/// not: an upper bound of what the parser will recurse into that no stray quote can hide.
pub(super) fn nesting_depth(text: &str) -> usize {
    let (mut depth, mut max) = (0usize, 0usize);
    for c in text.bytes() {
        match c {
            b'[' | b'{' => {
                depth += 1;
                max = max.max(depth);
            }
            b']' | b'}' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    max
}
