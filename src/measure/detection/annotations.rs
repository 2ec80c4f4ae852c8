//! Recall of hand-marked corners: how many of the points a person clicked on a map have a keypoint near
//! them. The annotations are not exhaustive (a corner nobody clicked is no false detection), so this
//! measures recall, not precision; keypoints per map and recall at a fixed budget of keypoints (strongest
//! first) keep a detector from winning by firing everywhere.
//!
//! The file format is the one of `corners.json` in the shared merge-pairs data:
//! `{"maps": {"NAME": [[x, y], ...], ...}}`, pixel frame (x right, y down, pixel centres at integers),
//! NAME a map's file stem.

use std::collections::HashMap;
use std::io::{self, Write};
use std::path::Path;

use serde::Serialize;

use crate::backend::Keypoint;
use crate::detect::output::{csv_field, md_cell, TableFormat};
use crate::support::error::{Error, Result};

/// Largest annotation file read: the shared one is 20 KB.
pub const MAX_ANNOTATION_BYTES: u64 = 16 << 20;

/// The radii recall is reported at, pixels.
pub const RADII: [f64; 2] = [5.0, 10.0];

/// Keypoint budgets, as multiples of the number of marked points.
pub const BUDGETS: [usize; 2] = [1, 3];

/// Marked points per map name.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Annotations {
    maps: HashMap<String, Vec<(f64, f64)>>,
}

#[derive(serde::Deserialize)]
struct File {
    maps: Entries,
}

/// A JSON object's entries in file order, duplicates kept: a map named twice is an error, not the last
/// list silently winning.
struct Entries(Vec<(String, Vec<[f64; 2]>)>);

impl<'de> serde::Deserialize<'de> for Entries {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = Entries;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("an object of map names to lists of [x, y] points")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut m: A,
            ) -> std::result::Result<Entries, A::Error> {
                let mut v = Vec::new();
                while let Some(entry) = m.next_entry()? {
                    v.push(entry);
                }
                Ok(Entries(v))
            }
        }
        d.deserialize_map(Visit)
    }
}

impl Annotations {
    /// Reads an annotation file (bounded in size); every point must be finite.
    pub fn load(path: &Path) -> Result<Self> {
        let text = crate::support::files::read_small_text(
            path,
            MAX_ANNOTATION_BYTES,
            "an annotation file",
        )?;
        Self::parse(&text).map_err(|m| Error::input(path, m))
    }

    /// Parses the JSON text of an annotation file.
    pub fn parse(text: &str) -> std::result::Result<Self, String> {
        let f: File = serde_json::from_str(text).map_err(|e| {
            format!("not an annotation file ({{\"maps\": {{NAME: [[x, y], ...]}}}}): {e}")
        })?;
        let mut maps = HashMap::new();
        for (name, pts) in f.maps.0 {
            if let Some(p) = pts.iter().find(|p| !(p[0].is_finite() && p[1].is_finite())) {
                return Err(format!("{name}: point {p:?} is not finite"));
            }
            if maps.contains_key(&name) {
                return Err(format!(
                    "map {name:?} is listed twice (which list is meant cannot be told)"
                ));
            }
            maps.insert(name, pts.into_iter().map(|p| (p[0], p[1])).collect());
        }
        Ok(Annotations { maps })
    }

    /// Checks that every marked point of map `name` lies on its `width` x `height` pixels (pixel centres
    /// at integers, so from -0.5 to width - 0.5): a point off the map is a mistake in the file (another
    /// map's points, a swapped axis), and would silently count as missed.
    pub fn check_within(
        &self,
        name: &str,
        width: u32,
        height: u32,
    ) -> std::result::Result<(), String> {
        let (w, h) = (f64::from(width) - 0.5, f64::from(height) - 0.5);
        let off = self
            .points(name)
            .unwrap_or_default()
            .iter()
            .find(|&&(x, y)| !((-0.5..=w).contains(&x) && (-0.5..=h).contains(&y)));
        match off {
            Some((x, y)) => Err(format!(
                "{name}: the marked point [{x}, {y}] lies outside the {width}x{height} map"
            )),
            None => Ok(()),
        }
    }

    /// The marked points of map `name`, if it has any.
    pub fn points(&self, name: &str) -> Option<&[(f64, f64)]> {
        self.maps.get(name).map(Vec::as_slice)
    }

    /// The annotated map names, sorted.
    pub fn names(&self) -> Vec<&str> {
        let mut v: Vec<&str> = self.maps.keys().map(String::as_str).collect();
        v.sort_unstable();
        v
    }
}

/// One detector on one map (or, with `map` "all", pooled over the maps).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RecallRecord {
    /// The map's name, or "all" for the pooled row.
    pub map: String,
    /// The detector's name.
    pub detector: &'static str,
    /// Marked points.
    pub marked: usize,
    /// Keypoints found.
    pub keypoints: usize,
    /// Marked points with a keypoint within 5 px, and within 10 px.
    pub hits_5: usize,
    /// See `hits_5`.
    pub hits_10: usize,
    /// Within 5 px, keeping only the strongest `marked` keypoints (1x); None when the detector has more
    /// keypoints than the budget and no strength to rank them by (the paper's OGM detector: every
    /// keypoint scores 0).
    pub hits_5_budget_1x: Option<usize>,
    /// Within 5 px, the strongest `3 * marked` keypoints (3x).
    pub hits_5_budget_3x: Option<usize>,
    /// Within 10 px, the strongest `marked` keypoints.
    pub hits_10_budget_1x: Option<usize>,
    /// Within 10 px, the strongest `3 * marked` keypoints.
    pub hits_10_budget_3x: Option<usize>,
}

impl RecallRecord {
    /// The share of marked points `hits` is; None for a map with no marked points (no recall to give).
    fn rate(&self, hits: usize) -> Option<f64> {
        (self.marked > 0).then(|| hits as f64 / self.marked as f64)
    }
}

/// Marked points within `radius` of some keypoint.
pub fn hits(points: &[(f64, f64)], keypoints: &[Keypoint], radius: f64) -> usize {
    let kps: Vec<(f64, f64)> = keypoints
        .iter()
        .map(|k| (f64::from(k.x), f64::from(k.y)))
        .collect();
    let grid = crate::measure::detection::PointGrid::new(&kps, radius);
    points
        .iter()
        .filter(|&&(x, y)| grid.has_within(x, y))
        .count()
}

/// The record of `detector`'s `keypoints` on map `map` with marked `points`.
pub fn recall(
    map: &str,
    detector: &'static str,
    points: &[(f64, f64)],
    keypoints: &[Keypoint],
) -> RecallRecord {
    let ranked = {
        let mut v = keypoints.to_vec();
        // Strongest first; ties in raster order, so the ranking is deterministic.
        v.sort_by(|a, b| b.score.cmp(&a.score).then((a.y, a.x).cmp(&(b.y, b.x))));
        v
    };
    let has_strength = keypoints.iter().any(|k| k.score != keypoints[0].score);
    let budget = |times: usize, radius: f64| {
        let n = times * points.len();
        (n >= ranked.len() || has_strength)
            .then(|| hits(points, &ranked[..n.min(ranked.len())], radius))
    };
    RecallRecord {
        map: map.to_string(),
        detector,
        marked: points.len(),
        keypoints: keypoints.len(),
        hits_5: hits(points, keypoints, RADII[0]),
        hits_10: hits(points, keypoints, RADII[1]),
        hits_5_budget_1x: budget(BUDGETS[0], RADII[0]),
        hits_5_budget_3x: budget(BUDGETS[1], RADII[0]),
        hits_10_budget_1x: budget(BUDGETS[0], RADII[1]),
        hits_10_budget_3x: budget(BUDGETS[1], RADII[1]),
    }
}

/// Per detector, the rows of every map summed into one "all" row (a budget is None when any map's is).
pub fn pooled(rows: &[RecallRecord]) -> Vec<RecallRecord> {
    let mut out: Vec<RecallRecord> = Vec::new();
    for r in rows {
        match out.iter_mut().find(|o| o.detector == r.detector) {
            Some(o) => {
                o.marked += r.marked;
                o.keypoints += r.keypoints;
                o.hits_5 += r.hits_5;
                o.hits_10 += r.hits_10;
                let add = |a: Option<usize>, b: Option<usize>| a.zip(b).map(|(a, b)| a + b);
                o.hits_5_budget_1x = add(o.hits_5_budget_1x, r.hits_5_budget_1x);
                o.hits_5_budget_3x = add(o.hits_5_budget_3x, r.hits_5_budget_3x);
                o.hits_10_budget_1x = add(o.hits_10_budget_1x, r.hits_10_budget_1x);
                o.hits_10_budget_3x = add(o.hits_10_budget_3x, r.hits_10_budget_3x);
            }
            None => out.push(RecallRecord {
                map: "all".to_string(),
                ..r.clone()
            }),
        }
    }
    out
}

/// The before/after picture of one annotated map: the paper's detector's keypoints, and the robust
/// detector's strongest three per marked point (the 3x budget), the marked points ringed in green on both.
pub fn marked_sheet(
    name: &str,
    map: &crate::OccupancyMap,
    points: &[(f64, f64)],
    paper: &[Keypoint],
    robust: &[Keypoint],
) -> image::RgbImage {
    let budget = BUDGETS[1] * points.len();
    let strongest =
        crate::detect::detector::strongest(robust.to_vec(), budget, crate::DetectorKind::OgmRobust)
            .unwrap_or_default();
    let panels = [
        (format!("PAPER OGM: {} KEYPOINTS", paper.len()), paper),
        (
            format!("OGM-ROBUST: STRONGEST {}", strongest.len()),
            &strongest[..],
        ),
    ];
    crate::measure::compare::labelled_sheet(
        &format!("{name}: {} MARKED POINTS (GREEN RINGS)", points.len()),
        map,
        &panels,
        points,
    )
}

/// Bytes of [`marked_sheet`]'s picture, for memory budgets.
pub const MARKED_SHEET_BYTES: u64 = crate::measure::compare::sheet_bytes(2);

/// The file [`marked_sheet`] is written to in a `--plot` folder, for map `name`.
pub fn marked_sheet_file(name: &str) -> String {
    format!("{name}-marked.png")
}

/// The rows as the `--html` page's table (`id="recall"`), the pooled rows in bold colours.
pub fn html_table(rows: &[RecallRecord]) -> crate::support::report::Table {
    use crate::support::report::{Cell, Table};
    let mut t = Table::new(
        "recall",
        "Hand-marked corners found: recall within 5 and 10 px, and at a budget of the strongest 1x and 3x as many keypoints as marked points",
        &[
            ("map", false),
            ("detector", false),
            ("marked", true),
            ("keypoints", true),
            ("within 5 px %", true),
            ("within 10 px %", true),
            ("5 px, 1x %", true),
            ("5 px, 3x %", true),
            ("10 px, 1x %", true),
            ("10 px, 3x %", true),
        ],
    );
    for r in rows {
        let pct = |h: Option<usize>| Cell::opt(h.and_then(|h| r.rate(h)).map(|v| 100.0 * v), 1);
        t.row_with(
            vec![
                Cell::text(&r.map),
                Cell::text(r.detector),
                Cell::int(r.marked as i128),
                Cell::int(r.keypoints as i128),
                pct(Some(r.hits_5)),
                pct(Some(r.hits_10)),
                pct(r.hits_5_budget_1x),
                pct(r.hits_5_budget_3x),
                pct(r.hits_10_budget_1x),
                pct(r.hits_10_budget_3x),
            ],
            (r.map == "all").then_some("good"),
        );
    }
    t
}

/// Writes the rows (per map, then the pooled rows) as Markdown, CSV or JSON.
pub fn write_table(
    out: &mut dyn Write,
    format: TableFormat,
    rows: &[RecallRecord],
) -> io::Result<()> {
    let pct = |r: &RecallRecord, h: Option<usize>| {
        h.and_then(|h| r.rate(h))
            .map_or("n/a".to_string(), |v| format!("{:.1}%", 100.0 * v))
    };
    match format {
        TableFormat::Json => {
            serde_json::to_writer_pretty(&mut *out, rows)?;
            writeln!(out)?;
        }
        TableFormat::Csv => {
            writeln!(
                out,
                "map,detector,marked,keypoints,hits_5,hits_10,hits_5_budget_1x,hits_5_budget_3x,\
                 hits_10_budget_1x,hits_10_budget_3x"
            )?;
            let opt = |h: Option<usize>| h.map_or(String::new(), |h| h.to_string());
            for r in rows {
                writeln!(
                    out,
                    "{},{},{},{},{},{},{},{},{},{}",
                    csv_field(&r.map),
                    r.detector,
                    r.marked,
                    r.keypoints,
                    r.hits_5,
                    r.hits_10,
                    opt(r.hits_5_budget_1x),
                    opt(r.hits_5_budget_3x),
                    opt(r.hits_10_budget_1x),
                    opt(r.hits_10_budget_3x)
                )?;
            }
        }
        TableFormat::Md => {
            writeln!(out, "| map | detector | marked | keypoints | within 5 px | within 10 px | 5 px, 1x budget | 5 px, 3x budget | 10 px, 1x budget | 10 px, 3x budget |")?;
            writeln!(out, "|---|---|---|---|---|---|---|---|---|---|")?;
            for r in rows {
                writeln!(
                    out,
                    "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                    md_cell(&r.map),
                    r.detector,
                    r.marked,
                    r.keypoints,
                    pct(r, Some(r.hits_5)),
                    pct(r, Some(r.hits_10)),
                    pct(r, r.hits_5_budget_1x),
                    pct(r, r.hits_5_budget_3x),
                    pct(r, r.hits_10_budget_1x),
                    pct(r, r.hits_10_budget_3x)
                )?;
            }
        }
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recall_counts_points_near_keypoints_and_budgets_take_the_strongest() {
        let points = [(10.0, 10.0), (50.0, 50.0), (100.2, 100.0)];
        let kps = [
            Keypoint::scored(13, 10, 1),   // 3 px from the first point
            Keypoint::scored(57, 50, 9),   // 7 px from the second
            Keypoint::scored(300, 300, 5), // near nothing
        ];
        let r = recall("m", "harris", &points, &kps);
        assert_eq!((r.hits_5, r.hits_10), (1, 2));
        // 1x budget: the 3 strongest of 3 keypoints; 3x: all.
        assert_eq!(r.hits_10_budget_1x, Some(2));
        let r = recall("m", "harris", &points[..1], &kps);
        // Budget 1: only the strongest (score 9, near the second point, not marked here).
        assert_eq!(r.hits_10_budget_1x, Some(0));
        assert_eq!(r.hits_10_budget_3x, Some(1));
        // No strength and more keypoints than the budget: not measurable.
        let flat = [Keypoint::scored(13, 10, 0), Keypoint::scored(0, 0, 0)];
        assert_eq!(
            recall("m", "ogm", &points[..1], &flat).hits_10_budget_1x,
            None
        );
        assert_eq!(
            recall("m", "ogm", &points[..1], &flat).hits_10_budget_3x,
            Some(1)
        );
        assert_eq!(recall("m", "ogm", &points, &[]).hits_10, 0);
    }

    #[test]
    fn the_file_format_parses_and_bad_points_are_refused() {
        let a = Annotations::parse(
            r#"{"convention": "x right", "maps": {"F5_01": [[1.5, 2], [3, 4]]}}"#,
        )
        .unwrap();
        assert_eq!(a.points("F5_01"), Some(&[(1.5, 2.0), (3.0, 4.0)][..]));
        assert_eq!(a.names(), ["F5_01"]);
        assert!(Annotations::parse(r#"{"maps": {"a": [[1e999, 0]]}}"#).is_err());
        assert!(Annotations::parse("[]").is_err());
        let twice = Annotations::parse(r#"{"maps": {"a": [[1, 1]], "a": [[2, 2]]}}"#);
        assert!(twice.unwrap_err().contains("listed twice"));
        let a = Annotations::parse(r#"{"maps": {"a": [[-0.5, 9.5]], "b": [[1e300, 0]]}}"#).unwrap();
        assert!(a.check_within("a", 10, 10).is_ok());
        assert!(a.check_within("a", 10, 9).is_err());
        assert!(a.check_within("b", 10, 10).unwrap_err().contains("outside"));
    }

    #[test]
    fn a_map_with_no_marked_points_has_no_recall_rather_than_none_found() {
        let r = recall("m", "harris", &[], &[]);
        let mut md = Vec::new();
        write_table(&mut md, TableFormat::Md, &[r]).unwrap();
        let md = String::from_utf8(md).unwrap();
        assert!(md.contains("n/a") && !md.contains("0.0%"), "{md}");
    }

    #[test]
    fn pooled_rows_sum_the_maps() {
        let kps = [Keypoint::scored(0, 0, 1)];
        let rows = [
            recall("a", "harris", &[(0.0, 0.0)], &kps),
            recall("b", "harris", &[(50.0, 50.0), (0.0, 1.0)], &kps),
        ];
        let p = pooled(&rows);
        assert_eq!(p.len(), 1);
        assert_eq!((p[0].marked, p[0].hits_10, p[0].keypoints), (3, 2, 2));
    }
}
