//! Keypoint lists as CSV or JSON.

use std::io::Write;

use serde::Serialize;

use crate::detector::{DetectOptions, Detection, DetectorKind};
use crate::map::OccupancyMap;

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

/// A Markdown table cell: `|` escaped and line breaks made spaces, so a file name cannot break the table.
pub fn md_cell(s: &str) -> String {
    s.replace('|', "\\|").replace(['\n', '\r'], " ")
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

/// Writes the keypoints of `det` (found in `map`) in `format`.
pub fn write_keypoints(
    out: &mut dyn Write,
    format: Format,
    map: &OccupancyMap,
    det: &Detection,
    options: &DetectOptions,
    backend: &str,
) -> std::io::Result<()> {
    match format {
        Format::Csv => write_csv(out, map, det, options.detector),
        Format::Json => write_json(out, map, det, options, backend),
    }
}

/// CSV: `x,y,rule,code` for the OGM detector, `x,y,score,scale,convex,rule,code` for the robust one
/// (score: its strength in pixels), `x,y,score` for the baselines, plus `world_x,world_y` in metres when
/// the map has a yaml.
pub fn write_csv(
    out: &mut dyn Write,
    map: &OccupancyMap,
    det: &Detection,
    detector: DetectorKind,
) -> std::io::Result<()> {
    let header = match detector {
        DetectorKind::Ogm => "x,y,rule,code",
        DetectorKind::OgmRobust => "x,y,score,scale,convex,rule,code",
        DetectorKind::Baseline(_) => "x,y,score",
    };
    write!(out, "{header}")?;
    writeln!(
        out,
        "{}",
        if map.georef.is_some() {
            ",world_x,world_y"
        } else {
            ""
        }
    )?;
    for k in &det.keypoints {
        match detector {
            DetectorKind::Ogm => write!(out, "{},{},{},{}", k.x, k.y, k.rule, k.code)?,
            DetectorKind::OgmRobust => write!(
                out,
                "{},{},{},{},{},{},{}",
                k.x, k.y, k.score, k.scale, k.convex, k.rule, k.code
            )?,
            DetectorKind::Baseline(_) => write!(out, "{},{},{}", k.x, k.y, k.score)?,
        }
        if let Some(g) = &map.georef {
            let (wx, wy) = g.pixel_to_world(k.x, k.y, det.height);
            write!(out, ",{wx:.6},{wy:.6}")?;
        }
        writeln!(out)?;
    }
    Ok(())
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
struct JsonDetection<'a> {
    map: Option<String>,
    width: u32,
    height: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    resolution: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    origin: Option<[Option<f64>; 3]>,
    detector: &'a str,
    rules: &'a str,
    unknown_as_occupied: bool,
    /// The robust detector's grid angle, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    angle_deg: Option<f64>,
    backend: &'a str,
    count: usize,
    keypoints: JsonKeypoints<'a>,
}

/// The keypoint list, serialised one by one as it is written: no second copy of a long list in memory.
struct JsonKeypoints<'a> {
    det: &'a Detection,
    georef: Option<crate::map::GeoRef>,
    detector: DetectorKind,
}

impl Serialize for JsonKeypoints<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        let mut seq = s.serialize_seq(Some(self.det.keypoints.len()))?;
        for k in &self.det.keypoints {
            let (ogm, robust) = (
                self.detector == DetectorKind::Ogm,
                self.detector == DetectorKind::OgmRobust,
            );
            seq.serialize_element(&JsonKeypoint {
                x: k.x,
                y: k.y,
                rule: (ogm || robust).then_some(k.rule),
                code: (ogm || robust).then_some(k.code),
                score: (!ogm).then_some(k.score),
                scale: robust.then_some(k.scale),
                convex: robust.then_some(k.convex),
                world: self.georef.map(|g| {
                    let (wx, wy) = g.pixel_to_world(k.x, k.y, self.det.height);
                    [wx, wy]
                }),
            })?;
        }
        seq.end()
    }
}

/// JSON: `{"map", "width", "height", ["resolution", "origin",] "detector", "rules", "unknown_as_occupied",
/// ["angle_deg",] "backend", "count", "keypoints": [{"x", "y", ["rule", "code",] ["score",] ["scale",
/// "convex",] ["world": [x, y]]}]}` (the fields each detector has, as in the CSV).
pub fn write_json(
    out: &mut dyn Write,
    map: &OccupancyMap,
    det: &Detection,
    options: &DetectOptions,
    backend: &str,
) -> std::io::Result<()> {
    let doc = JsonDetection {
        map: map.source().map(|p| p.display().to_string()),
        width: det.width,
        height: det.height,
        resolution: map.georef.map(|g| g.resolution),
        // JSON has no NaN: a non-finite yaw is written as null.
        origin: map
            .georef
            .map(|g| g.origin.map(|v| v.is_finite().then_some(v))),
        detector: options.detector.name(),
        rules: options.rules.name(),
        unknown_as_occupied: options.unknown_as_occupied,
        angle_deg: det.robust.map(|r| r.angle),
        backend,
        count: det.keypoints.len(),
        keypoints: JsonKeypoints {
            det,
            georef: map.georef,
            detector: options.detector,
        },
    };
    serde_json::to_writer_pretty(&mut *out, &doc)?;
    writeln!(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_cells_keep_their_columns() {
        assert_eq!(csv_field("map"), "map");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\"\n"), "\"say \"\"hi\"\"\n\"");
        assert_eq!(md_cell("a|b\nc"), "a\\|b c");
    }
}
