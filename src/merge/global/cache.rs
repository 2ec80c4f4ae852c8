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

use std::collections::HashMap;
use std::hash::{Hash, Hasher};

use super::GlobalOptions;
use crate::map::{MapImage, OccupancyMap, Thresholds};
use crate::merge::align::{Alignment, Prepared};
use crate::merge::prescreen::Signature;

/// A map's preparation and, once a pre-screen needed it, its signature.
pub(super) type Kept = (Prepared, Option<Signature>);

/// A map's content as the cache recognises it.
#[derive(Clone)]
pub(super) struct Key {
    hash: u64,
    image: MapImage,
    thresholds: Thresholds,
}

impl Key {
    pub(super) fn of(map: &OccupancyMap) -> Key {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        (map.image.width(), map.image.height()).hash(&mut h);
        map.image.pixels().hash(&mut h);
        let t = &map.thresholds;
        (
            t.negate,
            t.occupied_thresh.to_bits(),
            t.free_thresh.to_bits(),
        )
            .hash(&mut h);
        Key {
            hash: h.finish(),
            image: map.image.clone(),
            thresholds: map.thresholds,
        }
    }

    fn same(&self, other: &Key) -> bool {
        self.hash == other.hash && self.thresholds == other.thresholds && self.image == other.image
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
}

/// Preparations and alignments kept between runs of [`super::run_cached`].
#[derive(Default)]
pub struct Cache {
    options: Option<GlobalOptions>,
    maps: Vec<(Key, Kept)>,
    /// By the two maps' hashes (reference, moved) and checked against their keys.
    pairs: HashMap<(u64, u64), (Key, Key, Alignment)>,
    used: CacheUse,
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
    }

    /// The preparation (and signature) kept for `key`, taken out of the cache ([`Cache::keep`] puts it
    /// back).
    pub(super) fn take_map(&mut self, key: &Key) -> Option<Kept> {
        let i = self.maps.iter().position(|(k, _)| k.same(key))?;
        self.used.maps_reused += 1;
        Some(self.maps.swap_remove(i).1)
    }

    /// The alignment kept for the pair (`a` reference, `b` moved).
    pub(super) fn pair(&self, a: &Key, b: &Key) -> Option<Alignment> {
        let (ka, kb, al) = self.pairs.get(&(a.hash, b.hash))?;
        (ka.same(a) && kb.same(b)).then(|| al.clone())
    }

    /// Keeps this run's maps and pairs, and only them.
    pub(super) fn keep(
        &mut self,
        maps: Vec<(Key, Kept)>,
        pairs: Vec<(usize, usize, Alignment)>,
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
