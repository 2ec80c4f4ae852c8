//! An earlier run's `--poses` file taken up again: the maps it placed and every pair it aligned, so that
//! new maps are added to a merge without aligning the old pairs again (`merge --from FILE NEW...`).
//! The old pairs count as aligned ([`crate::merge::many::Cache::carry`]); the new maps are screened against all
//! maps and the placement is made afresh over every pair, old and new: the same placement a full run
//! would make from those pairs (a full run may align fewer: it never aligned the old set's closing
//! pairs against a smaller set).

use std::collections::HashMap;

use serde::Deserialize;

use crate::merge::many::{poses, Cache, ContentId, GlobalOptions, PairRecord};
use crate::support::error::{Error, Result};

/// What a run reads of an earlier run's `--poses` file.
#[derive(Clone, Debug)]
pub struct Previous {
    /// Its maps, as it names them (paths as given to it), in its order.
    pub maps: Vec<String>,
    /// Each map's content id as the file gives it.
    pub ids: Vec<ContentId>,
    /// Each aligned pair: the two maps' indices in [`Previous::maps`] (reference, moved) and the record.
    pub records: Vec<(usize, usize, PairRecord)>,
    /// [`poses::options_id`] of the run that made them.
    pub options: String,
}

#[derive(Deserialize)]
struct Doc {
    maps: Vec<MapDoc>,
    #[serde(default)]
    alignments: Vec<AlignmentDoc>,
    #[serde(default)]
    alignments_of: Option<String>,
}

#[derive(Deserialize)]
struct MapDoc {
    map: String,
    #[serde(default)]
    content: Option<String>,
}

#[derive(Deserialize)]
struct AlignmentDoc {
    a: String,
    b: String,
    alignment: PairRecord,
}

impl Previous {
    /// Reads a `--poses` document (`what` names it in errors). Two alignments of the same two maps'
    /// contents (a content id given to two maps) are an error: which maps they belong to is not known.
    pub fn parse(text: &str, what: &str) -> Result<Previous> {
        let bad = |why: String| Error::invalid(format!("{what}: {why}"));
        let doc: Doc = serde_json::from_str(text)
            .map_err(|e| bad(format!("not a `merge --poses` document: {e}")))?;
        let mut index = HashMap::new();
        let mut ids = Vec::with_capacity(doc.maps.len());
        for (i, m) in doc.maps.iter().enumerate() {
            let Some(hex) = &m.content else {
                return Err(bad(format!(
                    "map {:?} has no content id (written by an older version: merge the maps afresh)",
                    m.map
                )));
            };
            let id = parse_id(hex).ok_or_else(|| {
                bad(format!(
                    "map {:?}: content id {hex:?} is not 32 hex digits",
                    m.map
                ))
            })?;
            // A map given twice is one map: its alignments name its first listing.
            index.entry(m.map.as_str()).or_insert(i);
            ids.push(id);
        }
        let mut claimed = HashMap::new();
        let mut records = Vec::with_capacity(doc.alignments.len());
        for p in doc.alignments {
            let at = |name: &str| {
                index.get(name).copied().ok_or_else(|| {
                    bad(format!(
                        "an alignment names map {name:?}, which it does not list"
                    ))
                })
            };
            let (a, b) = (at(&p.a)?, at(&p.b)?);
            if let Some((x, y)) = claimed.insert((ids[a], ids[b]), (a, b)) {
                return Err(bad(format!(
                    "the alignments of {:?} onto {:?} and of {:?} onto {:?} are of the same two maps' \
                     contents (a content id given twice): which maps they belong to is not known",
                    doc.maps[b].map, doc.maps[a].map, doc.maps[y].map, doc.maps[x].map
                )));
            }
            records.push((a, b, p.alignment));
        }
        Ok(Previous {
            maps: doc.maps.into_iter().map(|m| m.map).collect(),
            ids,
            records,
            options: doc.alignments_of.unwrap_or_default(),
        })
    }

    /// Whether its alignments were made by this build with `options` (else none is taken up).
    pub fn fits(&self, options: &GlobalOptions) -> bool {
        self.options == poses::options_id(options)
    }

    /// A cache holding its alignments, when they [`Previous::fits`] `options` (an empty one else).
    pub fn cache(self, options: &GlobalOptions) -> Cache {
        let mut cache = Cache::new();
        if self.fits(options) {
            let ids = self.ids;
            cache.carry(
                self.records
                    .into_iter()
                    .map(|(a, b, r)| (ids[a], ids[b], r)),
            );
        }
        cache
    }
}

/// A content id: exactly 32 hex digits (no sign).
fn parse_id(hex: &str) -> Option<ContentId> {
    (hex.len() == 32 && hex.bytes().all(|c| c.is_ascii_hexdigit()))
        .then(|| u128::from_str_radix(hex, 16).ok())
        .flatten()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_content_id_is_32_hex_digits_and_no_sign() {
        assert_eq!(
            parse_id(&"0f".repeat(16)),
            Some(0x0f0f_0f0f_0f0f_0f0f_0f0f_0f0f_0f0f_0f0f)
        );
        assert_eq!(parse_id(&format!("+{}", "a".repeat(31))), None);
        assert_eq!(parse_id(&format!("-{}", "a".repeat(31))), None);
        assert_eq!(parse_id(&"a".repeat(31)), None);
        assert_eq!(parse_id(&"g".repeat(32)), None);
    }

    fn doc(ids: [&str; 3]) -> String {
        let record = r#"{"accepted":false,"transform":{"theta_deg":0.0,"tx":0.0,"ty":0.0},"score":"-inf","reason":"x","edges":[]}"#;
        format!(
            r#"{{"maps":[{{"map":"a","content":"{}"}},{{"map":"b","content":"{}"}},{{"map":"c","content":"{}"}}],
               "alignments":[{{"a":"a","b":"c","alignment":{record}}},{{"a":"b","b":"c","alignment":{record}}}]}}"#,
            ids[0], ids[1], ids[2]
        )
    }

    #[test]
    fn a_content_id_given_to_two_maps_whose_alignments_collide_is_an_error() {
        let (x, y, z) = ("1".repeat(32), "2".repeat(32), "3".repeat(32));
        let p = Previous::parse(&doc([&x, &y, &z]), "f").unwrap();
        assert_eq!(p.records.len(), 2);
        let e = Previous::parse(&doc([&x, &x, &z]), "f")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("content id given twice") && e.starts_with("f: "),
            "{e}"
        );
    }
}
