//! Keypoint lists as CSV or JSON.

use std::io::Write;

use serde::Serialize;

use crate::detect::detector::{DetectOptions, Detection, DetectorKind, Keypoint};
use crate::map::{GeoRef, OccupancyMap};

/// Formats of the tables `eval` and `compare` print.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableFormat {
    /// A Markdown table.
    Md,
    /// CSV with a header line.
    Csv,
    /// Pretty-printed JSON.
    Json,
}

/// A CSV field as RFC 4180 writes it: quoted (quotes doubled) when it holds a comma, a quote or a line
/// break, as a map's file name may.
pub fn csv_field(s: &str) -> std::borrow::Cow<'_, str> {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\"")).into()
    } else {
        s.into()
    }
}

/// A Markdown table cell: `|` escaped, line breaks made spaces and other control characters written
/// escaped (`\u{1b}`), so a file name can neither break the table nor send escape sequences to a terminal.
pub fn md_cell(s: &str) -> String {
    crate::support::error::one_line(&s.replace('|', "\\|").replace(['\n', '\r'], " "))
}

/// Output formats of `detect`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// A header line `x,y,rule,code[,world_x,world_y]` (robust detector: `x,y,score,scale,convex,rule,code`;
    /// baselines: `x,y,score`), then one keypoint a line.
    Csv,
    /// One object with the map's size and the keypoint list.
    Json,
}

/// Writes the keypoints of `det` (found in `map`) in `format`: [`KeypointWriter`] with all of them at once.
pub fn write_keypoints(
    out: &mut dyn Write,
    format: Format,
    map: &OccupancyMap,
    det: &Detection,
    options: &DetectOptions,
    backend: &str,
) -> std::io::Result<()> {
    let about = About {
        map: map.source().map(|p| p.display().to_string()),
        width: det.width,
        height: det.height,
        georef: map.georef,
        options: *options,
        backend: backend.to_string(),
        angle_deg: det.robust.map(|r| r.angle),
        anchor_px: det.robust.map(|r| [r.anchor.0, r.anchor.1]),
    };
    let mut w = KeypointWriter::begin(out, format, &about)?;
    w.push(&det.keypoints)?;
    w.end()
}

/// What a keypoint file says about its map and its detection, before the keypoints.
#[derive(Clone, Debug)]
pub struct About {
    /// The file the user named (yaml or image).
    pub map: Option<String>,
    /// Map width in pixels.
    pub width: u32,
    /// Map height in pixels.
    pub height: u32,
    /// Resolution and origin, when the map has a yaml: keypoints get world coordinates.
    pub georef: Option<GeoRef>,
    /// How the keypoints were found.
    pub options: DetectOptions,
    /// The backend's name.
    pub backend: String,
    /// The robust detector's grid angle, degrees.
    pub angle_deg: Option<f64>,
    /// The robust detector's grid anchor, map pixels.
    pub anchor_px: Option<[f64; 2]>,
}

/// Writes keypoints as they come, in (y, x) order, so that a streamed detection never holds its list:
/// [`KeypointWriter::begin`], [`KeypointWriter::push`] as often as needed, then [`KeypointWriter::end`].
///
/// CSV: a header line `x,y,rule,code` for the OGM detector, `x,y,score,scale,convex,rule,code` for the
/// robust one (score: its strength in pixels), `x,y,score` for the baselines, plus `world_x,world_y` in
/// metres when the map has a yaml; then one keypoint a line.
///
/// JSON: `{"map", "width", "height", ["resolution", "origin",] "detector", "rules",
/// "unknown_as_occupied", ["angle_deg", "anchor_px",] "backend", "keypoints": [{"x", "y", ["rule", "code",]
/// ["score",] ["scale", "convex",] ["world": [x, y]]}], "count"}`: the fields each detector has, as in the
/// CSV, one keypoint a line; the count comes last, once known.
pub struct KeypointWriter<'a> {
    out: &'a mut dyn Write,
    format: Format,
    detector: DetectorKind,
    georef: Option<GeoRef>,
    height: u32,
    count: u64,
}

#[derive(Serialize)]
struct JsonKeypoint {
    x: u32,
    y: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    rule: Option<u8>,
    #[serde(skip_serializing_if = "Option::is_none")]
    code: Option<u8>,
    #[serde(skip_serializing_if = "Option::is_none")]
    score: Option<i64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    scale: Option<u8>,
    #[serde(skip_serializing_if = "Option::is_none")]
    convex: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    world: Option<[f64; 2]>,
}

#[derive(Serialize)]
struct JsonHead<'a> {
    map: &'a Option<String>,
    width: u32,
    height: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    resolution: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    origin: Option<[Option<f64>; 3]>,
    detector: &'a str,
    rules: &'a str,
    unknown_as_occupied: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    angle_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    anchor_px: Option<[f64; 2]>,
    backend: &'a str,
}

impl<'a> KeypointWriter<'a> {
    /// Writes the header (CSV) or the fields before the list (JSON).
    pub fn begin(out: &'a mut dyn Write, format: Format, about: &About) -> std::io::Result<Self> {
        let detector = about.options.detector;
        match format {
            Format::Csv => {
                let header = match detector {
                    DetectorKind::Ogm => "x,y,rule,code",
                    DetectorKind::OgmRobust => "x,y,score,scale,convex,rule,code",
                    DetectorKind::Baseline(_) => "x,y,score",
                };
                let world = if about.georef.is_some() {
                    ",world_x,world_y"
                } else {
                    ""
                };
                writeln!(out, "{header}{world}")?;
            }
            Format::Json => {
                let head = JsonHead {
                    map: &about.map,
                    width: about.width,
                    height: about.height,
                    resolution: about.georef.map(|g| g.resolution),
                    // JSON has no NaN: a non-finite yaw is written as null.
                    origin: about
                        .georef
                        .map(|g| g.origin.map(|v| v.is_finite().then_some(v))),
                    detector: detector.name(),
                    rules: about.options.rules.name(),
                    unknown_as_occupied: about.options.unknown_as_occupied,
                    angle_deg: about.angle_deg,
                    anchor_px: about.anchor_px,
                    backend: &about.backend,
                };
                let text = serde_json::to_string_pretty(&head)?;
                // The object stays open for the list: everything but its closing brace.
                let open = text
                    .trim_end()
                    .strip_suffix('}')
                    .unwrap_or(&text)
                    .trim_end();
                write!(out, "{open},\n  \"keypoints\": [")?;
            }
        }
        Ok(KeypointWriter {
            out,
            format,
            detector,
            georef: about.georef,
            height: about.height,
            count: 0,
        })
    }

    /// Writes keypoints, after those written before.
    pub fn push(&mut self, keypoints: &[Keypoint]) -> std::io::Result<()> {
        let (ogm, robust) = (
            self.detector == DetectorKind::Ogm,
            self.detector == DetectorKind::OgmRobust,
        );
        for k in keypoints {
            let world = self.georef.map(|g| g.pixel_to_world(k.x, k.y, self.height));
            match self.format {
                Format::Csv => {
                    let out = &mut self.out;
                    match self.detector {
                        DetectorKind::Ogm => write!(out, "{},{},{},{}", k.x, k.y, k.rule, k.code)?,
                        DetectorKind::OgmRobust => write!(
                            out,
                            "{},{},{},{},{},{},{}",
                            k.x, k.y, k.score, k.scale, k.convex, k.rule, k.code
                        )?,
                        DetectorKind::Baseline(_) => write!(out, "{},{},{}", k.x, k.y, k.score)?,
                    }
                    if let Some((wx, wy)) = world {
                        write!(out, ",{wx:.6},{wy:.6}")?;
                    }
                    writeln!(out)?;
                }
                Format::Json => {
                    let sep = if self.count == 0 { "" } else { "," };
                    write!(self.out, "{sep}\n    ")?;
                    serde_json::to_writer(
                        &mut *self.out,
                        &JsonKeypoint {
                            x: k.x,
                            y: k.y,
                            rule: (ogm || robust).then_some(k.rule),
                            code: (ogm || robust).then_some(k.code),
                            score: (!ogm).then_some(k.score),
                            scale: robust.then_some(k.scale),
                            convex: robust.then_some(k.convex),
                            world: world.map(|(x, y)| [x, y]),
                        },
                    )?;
                }
            }
            self.count += 1;
        }
        Ok(())
    }

    /// Closes the document (JSON: the list and the count).
    pub fn end(self) -> std::io::Result<()> {
        if self.format == Format::Json {
            let close = if self.count == 0 { "" } else { "\n  " };
            writeln!(self.out, "{close}],\n  \"count\": {}\n}}", self.count)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The JSON written piece by piece is one valid document, empty or not.
    #[test]
    fn streamed_json_is_one_document() {
        let about = About {
            map: Some("a \"b\".yaml".into()),
            width: 10,
            height: 8,
            georef: Some(GeoRef {
                resolution: 0.5,
                origin: [1.0, 2.0, f64::NAN],
            }),
            options: DetectOptions::default(),
            backend: "cpu".into(),
            angle_deg: None,
            anchor_px: None,
        };
        for n in [0usize, 1, 3] {
            let mut text = Vec::new();
            let mut w = KeypointWriter::begin(&mut text, Format::Json, &about).unwrap();
            for i in 0..n {
                w.push(&[Keypoint::ogm(i as u32, 2, 4, 7)]).unwrap();
            }
            w.end().unwrap();
            let v: serde_json::Value = serde_json::from_slice(&text).unwrap();
            assert_eq!(v["count"], n);
            assert_eq!(v["keypoints"].as_array().unwrap().len(), n);
            assert_eq!(v["map"], "a \"b\".yaml");
            assert!(v["origin"][2].is_null());
            if n > 0 {
                assert_eq!(v["keypoints"][0]["world"][0], 1.25);
            }
        }
    }

    #[test]
    fn table_cells_keep_their_columns() {
        assert_eq!(csv_field("map"), "map");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\"\n"), "\"say \"\"hi\"\"\n\"");
        assert_eq!(md_cell("a|b\nc"), "a\\|b c");
        assert_eq!(md_cell("x\u{1b}[31m\r"), "x\\u{1b}[31m ");
    }
}
