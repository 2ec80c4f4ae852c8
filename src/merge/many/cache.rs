//! What one placement of many maps can hand to the next: each map's preparation and each pair's
//! alignment, found again by the maps' content. A live merge (the ROS 2 node) places the same robots
//! every few seconds while one or two of their maps have changed: with the cache only the changed maps
//! are prepared again and only the pairs they are in are aligned again, and the result is the same, to the
//! bit, as placing every map afresh (preparation and alignment are pure functions of the pixels, the
//! thresholds and the options).
//!
//! Entries are matched by a hash of the pixels and confirmed by comparing the pixels themselves, so a
//! hash collision can never hand one map's preparation to another. The cache keeps only what the last
//! run used: its memory is one run's preparations and a copy of each map's pixels.
//!
//! An earlier run's pair alignments read from its `--poses` file can be carried in ([`Cache::carry`]):
//! they are matched by the maps' content ids alone ([`content_id`], 128 bits), and count as aligned.

use std::collections::HashMap;

use crate::map::{MapImage, OccupancyMap, Thresholds};
use crate::merge::many::prescreen::Signature;
use crate::merge::many::rounds::Aligned;
use crate::merge::many::{GlobalOptions, PairRecord};
use crate::merge::pair::align::Prepared;

/// A map's content id: XXH3-128 of its size, pixels and thresholds (a stable format, so ids written
/// to a file by one run are recognised by another).
pub type ContentId = u128;

/// `map`'s [`ContentId`].
pub fn content_id(map: &OccupancyMap) -> ContentId {
    use xxhash_rust::xxh3::Xxh3;
    let mut h = Xxh3::new();
    h.update(&map.image.width().to_le_bytes());
    h.update(&map.image.height().to_le_bytes());
    let t = &map.thresholds;
    h.update(&[u8::from(t.negate)]);
    h.update(&t.occupied_thresh.to_bits().to_le_bytes());
    h.update(&t.free_thresh.to_bits().to_le_bytes());
    h.update(map.image.pixels());
    h.digest128()
}

/// A map's preparation and, once a pre-screen needed it, its signature.
pub(super) type Kept = (Prepared, Option<Signature>);

/// A map's content as the cache recognises it.
#[derive(Clone)]
pub(super) struct Key {
    pub(super) hash: ContentId,
    /// Shared by every pair the map is in: one copy of its pixels, however many pairs are kept.
    image: std::sync::Arc<MapImage>,
    thresholds: Thresholds,
}

impl Key {
    pub(super) fn of(map: &OccupancyMap) -> Key {
        Key {
            hash: content_id(map),
            image: std::sync::Arc::new(map.image.clone()),
            thresholds: map.thresholds,
        }
    }

    fn same(&self, other: &Key) -> bool {
        self.hash == other.hash
            && self.thresholds == other.thresholds
            && (std::sync::Arc::ptr_eq(&self.image, &other.image) || self.image == other.image)
    }
}

/// How much of the last run came from the cache.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CacheUse {
    /// Maps whose preparation was reused.
    pub maps_reused: usize,
    /// Maps prepared.
    pub maps_prepared: usize,
    /// Pairs whose alignment was reused.
    pub pairs_reused: usize,
    /// Pairs aligned.
    pub pairs_aligned: usize,
    /// Pairs carried in from an earlier run whose records did not hold on the maps (aligned again when
    /// chosen).
    pub pairs_refused: usize,
}

/// Preparations and alignments kept between runs of [`crate::merge::many::run_cached`].
#[derive(Default)]
pub struct Cache {
    options: Option<GlobalOptions>,
    maps: Vec<(Key, Kept)>,
    /// By the two maps' hashes (reference, moved) and checked against their keys.
    pairs: HashMap<(ContentId, ContentId), (Key, Key, PairRecord)>,
    /// An earlier run's, by the two maps' content ids (reference, moved).
    carried: HashMap<(ContentId, ContentId), PairRecord>,
    used: CacheUse,
    /// The last run's carried pairs that did not hold on the maps (the maps' indices as given to it, and
    /// why).
    pub(super) refused: Vec<(usize, usize, String)>,
}

impl Cache {
    /// An empty cache.
    pub fn new() -> Cache {
        Cache::default()
    }

    /// How much of the last run came from the cache.
    pub fn last_use(&self) -> CacheUse {
        self.used
    }

    /// The pairs carried into the last run whose records did not hold on the maps ([`Cache::carry`]):
    /// the two maps' indices as given to it (reference, moved) and why.
    pub fn refused(&self) -> &[(usize, usize, String)] {
        &self.refused
    }

    /// Forgets everything kept under other options than `options` (which pairs a pre-screen chooses
    /// aside: a preparation and a pair's alignment do not depend on it).
    pub(super) fn start(&mut self, options: &GlobalOptions) {
        let options = GlobalOptions {
            prescreen: None,
            ..*options
        };
        if self.options.as_ref() != Some(&options) {
            self.maps.clear();
            self.pairs.clear();
            self.options = Some(options);
        }
        self.used = CacheUse::default();
        self.refused.clear();
    }

    /// The preparation (and signature) kept for `key`, taken out of the cache ([`Cache::keep`] puts it
    /// back).
    pub(super) fn take_map(&mut self, key: &Key) -> Option<Kept> {
        let i = self.maps.iter().position(|(k, _)| k.same(key))?;
        self.used.maps_reused += 1;
        Some(self.maps.swap_remove(i).1)
    }

    /// The alignment kept for the pair (`a` reference, `b` moved).
    pub(super) fn pair(&self, a: &Key, b: &Key) -> Option<PairRecord> {
        let (ka, kb, al) = self.pairs.get(&(a.hash, b.hash))?;
        (ka.same(a) && kb.same(b)).then(|| al.clone())
    }

    /// Takes up an earlier run's pair alignments (reference map's content id, moved map's, record):
    /// the next run counts those between its maps as aligned (in the same order of the two maps; a
    /// pair given the other way round is aligned again) and aligns only the pairs they leave. The run
    /// keeps them as its own; no later run carries them again.
    pub fn carry(&mut self, records: impl IntoIterator<Item = (ContentId, ContentId, PairRecord)>) {
        self.carried
            .extend(records.into_iter().map(|(a, b, r)| ((a, b), r)));
    }

    /// The carried pairs among the maps of `keys` (`a < b`), taken out of the cache.
    pub(super) fn carried(&mut self, keys: &[Key]) -> Aligned {
        let mut out = Aligned::new();
        if self.carried.is_empty() {
            return out;
        }
        for (a, ka) in keys.iter().enumerate() {
            for (b, kb) in keys.iter().enumerate().skip(a + 1) {
                if let Some(r) = self.carried.remove(&(ka.hash, kb.hash)) {
                    out.insert((a, b), r);
                }
            }
        }
        self.carried.clear();
        out
    }

    /// Keeps this run's maps and pairs, and only them.
    pub(super) fn keep(
        &mut self,
        maps: Vec<(Key, Kept)>,
        pairs: Vec<(usize, usize, PairRecord)>,
        used: CacheUse,
    ) {
        self.pairs = pairs
            .into_iter()
            .map(|(a, b, al)| {
                let (ka, kb) = (maps[a].0.clone(), maps[b].0.clone());
                ((ka.hash, kb.hash), (ka, kb, al))
            })
            .collect();
        self.maps = maps;
        self.used = used;
    }
}
