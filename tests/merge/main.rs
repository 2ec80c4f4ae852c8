//! Merging: two maps, cut pairs, the hard synthetic families, the symmetric halls' property test, many
//! maps, records, the merge surfaces' reliability, transforms (the many-map merge's memory bound is
//! `tests/merge_memory.rs`, a binary of its own).
//!
//! One binary a layer: linking one test binary, not one a file, is most of the build. Run one
//! file's tests with a filter: `cargo test --test merge -- cut_pairs::`.

#[path = "../common/mod.rs"]
mod common;
mod cut_pairs;
mod families;
mod many;
mod pair;
mod records;
mod reliability;
mod symmetry;
mod transform;
