//! An earlier run's `--poses` file taken up again: the maps it placed and every pair it aligned, so that
//! new maps are added to a merge without aligning the old pairs again (`merge --from FILE NEW...`).
//! The old pairs count as aligned ([`super::Cache::carry`]); the new maps are screened against all
//! maps and the placement is made afresh over every pair, old and new: the same placement a full run
//! would make from those pairs (a full run may align fewer: it never aligned the old set's closing
//! pairs against a smaller set).

use serde::Deserialize;

use super::{report, Cache, ContentId, GlobalOptions, PairRecord};
use crate::error::{Error, Result};

/// What a run reads of an earlier run's `--poses` file.
#[derive(Clone, Debug)]
pub struct Previous {
    /// Its maps, as it names them (paths as given to it), in its order.
    pub maps: Vec<String>,
    /// Each aligned pair: the two maps' content ids (reference, moved) and the record.
    pub records: Vec<(ContentId, ContentId, PairRecord)>,
    /// [`report::options_id`] of the run that made them.
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
    /// Reads a `--poses` document (`what` names it in errors).
    pub fn parse(text: &str, what: &str) -> Result<Previous> {
        let bad = |why: String| Error::invalid(format!("{what}: {why}"));
        let doc: Doc = serde_json::from_str(text)
            .map_err(|e| bad(format!("not a `merge --poses` document: {e}")))?;
        let mut ids = std::collections::HashMap::new();
        for m in &doc.maps {
            let Some(hex) = &m.content else {
                return Err(bad(format!(
                    "map {:?} has no content id (written by an older version: merge the maps afresh)",
                    m.map
                )));
            };
            let id = (hex.len() == 32)
                .then(|| u128::from_str_radix(hex, 16).ok())
                .flatten()
                .ok_or_else(|| {
                    bad(format!(
                        "map {:?}: content id {hex:?} is not 32 hex digits",
                        m.map
                    ))
                })?;
            ids.insert(m.map.as_str(), id);
        }
        let records = doc
            .alignments
            .into_iter()
            .map(|p| {
                let id = |name: &str| {
                    ids.get(name).copied().ok_or_else(|| {
                        bad(format!(
                            "an alignment names map {name:?}, which it does not list"
                        ))
                    })
                };
                Ok((id(&p.a)?, id(&p.b)?, p.alignment))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Previous {
            maps: doc.maps.into_iter().map(|m| m.map).collect(),
            records,
            options: doc.alignments_of.unwrap_or_default(),
        })
    }

    /// Whether its alignments were made by this build with `options` (else none is taken up).
    pub fn fits(&self, options: &GlobalOptions) -> bool {
        self.options == report::options_id(options)
    }

    /// A cache holding its alignments, when they [`Previous::fits`] `options` (an empty one else).
    pub fn cache(self, options: &GlobalOptions) -> Cache {
        let mut cache = Cache::new();
        if self.fits(options) {
            cache.carry(self.records);
        }
        cache
    }
}
