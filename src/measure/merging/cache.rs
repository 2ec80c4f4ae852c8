//! What `merge-eval` measured, kept on disk: each pair's alignment (its candidates and every feature the
//! acceptance test reads), keyed by the two maps' contents, the merger's options and the build that
//! measures them ([`MEASURE_ID`]). A refit or a re-judgement of the same pairs (`--cross-validate` again,
//! another `--only`) reads them back instead of aligning again; any change to a map, an option or the code
//! that measures finds nothing and measures anew.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::map::OccupancyMap;
use crate::merge::many::{content_id, ContentId};
use crate::merge::pair::align::{Alignment, MergeOptions};
use crate::support::error::Result;

/// The code that measures an alignment, as the build saw it: the crate's version and a hash of every
/// source but the command line and this harness (`build.rs`).
pub const MEASURE_ID: &str = env!("OGM_MEASURE_ID");

/// Largest cache entry read: an alignment with its dozen candidates is a few kilobytes.
const MAX_ENTRY_BYTES: u64 = 1 << 20;

/// One pair's measurement as kept.
#[derive(Serialize, Deserialize)]
struct Entry {
    /// The build that measured it, again (the key holds it too; a reader checks both).
    measure: String,
    alignment: Alignment,
    /// Time of the alignment when it was measured, milliseconds.
    ms: f64,
}

/// A folder of kept measurements, and how the last runs used it.
#[derive(Debug)]
pub struct RecordCache {
    dir: PathBuf,
    measure: String,
    /// Pairs read from the folder.
    pub hits: usize,
    /// Pairs measured (and written to it).
    pub misses: usize,
    /// Why the folder could not be written, when it could not (then nothing more is written to it).
    pub unwritable: Option<String>,
}

impl RecordCache {
    /// The cache in `dir` (made when the first entry is written), for this build.
    pub fn new(dir: &Path) -> RecordCache {
        Self::for_build(dir, MEASURE_ID)
    }

    /// The cache in `dir` as the build `measure` keeps it: a cache written by another build is not read.
    pub fn for_build(dir: &Path, measure: &str) -> RecordCache {
        RecordCache {
            dir: dir.to_path_buf(),
            measure: measure.to_string(),
            hits: 0,
            misses: 0,
            unwritable: None,
        }
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The key of aligning map `b` onto map `a` (their content ids) with `options`.
    pub fn key(&self, a: ContentId, b: ContentId, options: &MergeOptions) -> String {
        use xxhash_rust::xxh3::Xxh3;
        let mut h = Xxh3::new();
        h.update(self.measure.as_bytes());
        h.update(format!("{options:?}").as_bytes());
        h.update(&a.to_le_bytes());
        h.update(&b.to_le_bytes());
        format!("{:032x}", h.digest128())
    }

    /// The key of aligning `b` onto `a` with `options`.
    pub fn key_of(&self, a: &OccupancyMap, b: &OccupancyMap, options: &MergeOptions) -> String {
        self.key(content_id(a), content_id(b), options)
    }

    fn path(&self, key: &str) -> PathBuf {
        self.dir.join(format!("{key}.json"))
    }

    /// The alignment kept under `key`, with its time, counted as a hit; None (counted as nothing) when
    /// there is none, or it cannot be read, or another build wrote it.
    pub fn get(&mut self, key: &str) -> Option<(Alignment, f64)> {
        let text = crate::support::files::read_small_text(
            &self.path(key),
            MAX_ENTRY_BYTES,
            "a cache entry",
        )
        .ok()?;
        let entry: Entry = serde_json::from_str(&text).ok()?;
        if entry.measure != self.measure {
            return None;
        }
        self.hits += 1;
        Some((entry.alignment, entry.ms))
    }

    /// Keeps `alignment` (measured in `ms`) under `key`, counted as a miss. A failure to write is kept in
    /// [`RecordCache::unwritable`], not returned: the run has its result either way.
    pub fn put(&mut self, key: &str, alignment: &Alignment, ms: f64) {
        self.misses += 1;
        if self.unwritable.is_some() {
            return;
        }
        if let Err(e) = self.write(key, alignment, ms) {
            self.unwritable = Some(e.to_string());
        }
    }

    fn write(&self, key: &str, alignment: &Alignment, ms: f64) -> Result<()> {
        crate::support::files::create_dir(&self.dir)?;
        let entry = Entry {
            measure: self.measure.clone(),
            alignment: alignment.clone(),
            ms,
        };
        let text = serde_json::to_string(&entry)
            .map_err(|e| crate::support::error::Error::Internal(e.to_string()))?;
        crate::support::files::write_atomic(&self.path(key), |w| w.write_all(text.as_bytes()))
    }
}

/// The default cache folder: `$OGM_CORNERS_CACHE`, else `$XDG_CACHE_HOME/ogm-corners/merge-eval`, else
/// `~/.cache/ogm-corners/merge-eval`; None when none can be told.
pub fn default_dir() -> Option<PathBuf> {
    let var = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    if let Some(d) = var("OGM_CORNERS_CACHE") {
        return Some(d);
    }
    let base = var("XDG_CACHE_HOME").or_else(|| var("HOME").map(|h| h.join(".cache")))?;
    Some(base.join("ogm-corners").join("merge-eval"))
}
