//! Replays every input the fuzzers keep (`fuzz/corpus/TARGET`, minimised) and every crash they ever
//! found (`fuzz/regressions/TARGET`) through the same harness the fuzz targets run, so a bug found once by
//! `scripts/fuzz.sh` stays fixed in the ordinary test suite.

#[path = "../../fuzz/harness.rs"]
mod harness;

use std::path::Path;

/// A fuzz target's body.
type Harness = fn(&[u8]);

fn replay(target: &str, run: Harness) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut n = 0;
    for dir in ["corpus", "regressions"] {
        let d = root.join(dir).join(target);
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        let mut files: Vec<_> = entries.map(|e| e.unwrap().path()).collect();
        files.sort();
        for f in files.into_iter().filter(|f| !f.ends_with("README")) {
            // (A fuzzer running beside the tests replaces corpus files as it minimises them.)
            let Ok(data) = std::fs::read(&f) else {
                continue;
            };
            // A panic names the input, so the failure can be reproduced with `cargo fuzz run`.
            let r = std::panic::catch_unwind(|| run(&data));
            assert!(r.is_ok(), "fuzz input {} fails again", f.display());
            n += 1;
        }
    }
    // The seeds are committed: an empty replay means the corpus went missing.
    assert!(
        n >= 5,
        "only {n} inputs for {target} under {}",
        root.display()
    );
}

#[test]
fn decode_corpus_and_regressions() {
    replay("decode", harness::decode);
}

#[test]
fn yaml_corpus_and_regressions() {
    replay("yaml", harness::yaml);
}

#[test]
fn detect_corpus_and_regressions() {
    replay("detect", harness::detect);
}

#[test]
fn merge_corpus_and_regressions() {
    replay("merge", harness::merge);
}

#[test]
fn pairs_corpus_and_regressions() {
    replay("pairs", harness::pairs);
}

#[test]
fn grid_corpus_and_regressions() {
    replay("grid", harness::grid);
}
