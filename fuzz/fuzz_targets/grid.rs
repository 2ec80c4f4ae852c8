//! Fuzz target `grid`: see [`harness::grid`] (shared with the regression test that replays the corpus).
#![no_main]

#[path = "../harness.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::grid(data));
