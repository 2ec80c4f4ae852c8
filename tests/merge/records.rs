//! Pair records that did not come from this process's own alignment are claims, checked against the
//! maps before a placement uses them: an earlier run's `--poses` file taken up by `merge --from` (edited,
//! damaged, or another set's) and an executor's answers in a distributed run (wrong, swollen, the wrong
//! way round). A record that does not hold is aligned again (`--from`) or refuses the run (an engine);
//! no edit places a map elsewhere than the maps themselves put it.

use ogm_corners::backend::reference::ReferenceBackend;
use ogm_corners::measure::merging::many::synthetic_maps;
use ogm_corners::measure::pairs::TruePair;
use ogm_corners::merge::many::graph::Placement;
use ogm_corners::merge::many::prescreen::Signature;
use ogm_corners::merge::many::previous::Previous;
use ogm_corners::merge::many::{
    merge_maps_cached, run_cached, run_with, Cache, Engine, GlobalOptions, Local, PairRecord,
};
use ogm_corners::merge::pair::align::Prepared;
use ogm_corners::merge::Rigid;
use ogm_corners::OccupancyMap;
use serde_json::Value;

/// Every map's pose in its group, `None` when not placed.
fn poses(p: &Placement) -> Vec<Option<(usize, Rigid)>> {
    p.maps
        .iter()
        .map(|m| m.group.map(|g| (g, m.pose)))
        .collect()
}

/// Every two maps placed together: in one group, at most `rot` degrees and `px` pixels (at the truth's
/// check points) from the truth. Returns how many pairs were checked.
fn within_truth(names: &[String], p: &Placement, truths: &[TruePair], rot: f64, px: f64) -> usize {
    let at = |n: &str| names.iter().position(|x| x == n).unwrap();
    let placed = poses(p);
    let mut checked = 0;
    for t in truths {
        let (Some((gs, s)), Some((gd, d))) = (placed[at(&t.src)], placed[at(&t.dst)]) else {
            continue;
        };
        if gs != gd {
            continue;
        }
        let (r, e) = t.errors(&d.inverse().after(&s));
        assert!(
            r <= rot && e <= px,
            "{} -> {}: {r:.2} deg, {e:.2} px off the truth",
            t.src,
            t.dst
        );
        checked += 1;
    }
    checked
}

/// A set of six maps of one synthetic office, merged: names, maps, truth, the `--poses` document.
fn merged_set(seed: u64) -> (Vec<String>, Vec<OccupancyMap>, Vec<TruePair>, Value) {
    let (names, maps, truths) = synthetic_maps(6, seed).unwrap();
    let many = merge_maps_cached(
        maps.clone(),
        &names,
        &GlobalOptions::default(),
        &mut ReferenceBackend,
        &|_, _| {},
        &mut Cache::new(),
    )
    .unwrap();
    let doc = serde_json::to_value(&many.report).unwrap();
    (names, maps, truths, doc)
}

/// The set placed again from the document: `None` when the document is refused as a whole.
fn from_doc(doc: &Value, maps: &[OccupancyMap]) -> Option<(Placement, Cache)> {
    let options = GlobalOptions::default();
    let previous = Previous::parse(&doc.to_string(), "test").ok()?;
    let mut cache = previous.cache(&options);
    let run = run_cached(
        maps,
        &options,
        &mut ReferenceBackend,
        &|_, _| {},
        &mut cache,
    )
    .unwrap();
    Some((run.placement, cache))
}

/// One edit a careless or hostile hand may make to an alignment record (`x` a number in 0..1 that
/// sizes it); returns whether the record can no longer be the maps' own (it must then be refused).
fn edit(record: &mut Value, kind: usize, x: f64) -> bool {
    let r = record.as_object_mut().unwrap();
    let has_choice = r["edges"]
        .as_array()
        .unwrap()
        .first()
        .is_some_and(|e| e["rank"] == 0);
    let shift = |v: &mut Value, key: &str, by: f64| {
        let n = v[key].as_f64().unwrap();
        v[key] = Value::from(n + by);
    };
    match kind {
        // The choice moved: far, or by a few pixels.
        0 | 1 => {
            let by = if kind == 0 { 3000.0 } else { 4.0 + 8.0 * x };
            shift(&mut r["transform"], "tx", by);
            if has_choice {
                shift(&mut r["edges"][0]["transform"], "tx", by);
            }
            // Without a choice among its candidates the transform is the verdict's only.
            has_choice
        }
        // The choice turned.
        2 => {
            let by = 2.0 + 90.0 * x;
            shift(&mut r["transform"], "theta_deg", by);
            if has_choice {
                shift(&mut r["edges"][0]["transform"], "theta_deg", by);
            }
            has_choice
        }
        // Declined made accepted.
        3 => {
            let declined = r["accepted"] == false;
            r.insert("accepted".into(), Value::from(true));
            r.insert("reason".into(), Value::Null);
            declined
        }
        // Every candidate's rule value raised.
        4 => {
            let by = 20.0 + 40.0 * x;
            let edges = r["edges"].as_array_mut().unwrap();
            let any = !edges.is_empty();
            for e in edges {
                shift(e, "score", by);
            }
            if has_choice {
                r["score"] = r["edges"][0]["score"].clone();
            }
            any
        }
        // Every candidate's drift-tolerant conflict set to none.
        5 => {
            let edges = r["edges"].as_array_mut().unwrap();
            let any = edges.iter().any(|e| e["residual"].as_f64().unwrap() > 0.06);
            for e in edges {
                e["residual"] = Value::from(0.0);
            }
            any
        }
        // The candidates copied a hundred times.
        6 => {
            let edges = r["edges"].as_array().unwrap().clone();
            let any = !edges.is_empty();
            let many: Vec<Value> = (0..100).flat_map(|_| edges.clone()).collect();
            r.insert("edges".into(), Value::from(many));
            any
        }
        // Where the maps overlap moved.
        _ => {
            let edges = r["edges"].as_array_mut().unwrap();
            let any = !edges.is_empty();
            for e in edges {
                let at = e["at"].as_array_mut().unwrap();
                at[0] = Value::from(at[0].as_f64().unwrap() + 50.0 + 100.0 * x);
            }
            any
        }
    }
}

/// Random edits to a `--poses` file's alignments (moved, turned, made accepted, scores raised,
/// conflicts hidden, candidates copied, overlap moved; one record or several) never place a map
/// elsewhere than the maps themselves put it: a record that no longer holds is refused and its pair
/// aligned again, and every two maps placed together are where the truth has them.
#[test]
fn edits_to_a_poses_file_never_place_a_map_elsewhere_than_the_maps_put_it() {
    use proptest::prelude::*;
    let (names, maps, truths, doc) = merged_set(5);
    let pairs = doc["alignments"].as_array().unwrap().len();
    assert_eq!(pairs, 15);
    // Untouched, every record holds.
    let (placement, cache) = from_doc(&doc, &maps).unwrap();
    assert_eq!(cache.last_use().pairs_refused, 0, "{:?}", cache.refused());
    assert_eq!(cache.last_use().pairs_reused, 15);
    assert_eq!(within_truth(&names, &placement, &truths, 0.5, 1.0), 30);
    let config = ProptestConfig {
        cases: 16,
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    proptest!(config, |(edits in proptest::collection::vec((0usize..15, 0usize..8, 0.0f64..1.0), 1..4))| {
        let mut edited = doc.clone();
        let mut must_refuse = 0;
        for &(i, kind, x) in &edits {
            let record = &mut edited["alignments"][i]["alignment"];
            must_refuse += usize::from(edit(record, kind, x));
        }
        let Some((placement, cache)) = from_doc(&edited, &maps) else {
            return Ok(());
        };
        let used = cache.last_use();
        prop_assert!(
            must_refuse == 0 || used.pairs_refused >= 1,
            "{edits:?}: {used:?}"
        );
        // Every map placed with another lies where the truth has it; and as many as before.
        let checked = within_truth(&names, &placement, &truths, 1.0, 3.0);
        prop_assert_eq!(checked, 30, "{:?}: {:?}", edits, cache.refused());
    });
}

/// Two maps given one content id: their alignments with a third map would be taken for each other's.
#[test]
fn a_content_id_given_to_two_maps_is_refused() {
    let (_, _, _, mut doc) = merged_set(3);
    let first = doc["maps"][0]["content"].clone();
    doc["maps"][1]["content"] = first;
    let e = Previous::parse(&doc.to_string(), "f.json")
        .unwrap_err()
        .to_string();
    assert!(e.contains("content id given twice"), "{e}");
}

/// An engine that wraps the local one and spoils its answers.
struct Spoiled {
    how: usize,
}

impl Engine for Spoiled {
    fn prepare(
        &mut self,
        maps: &[(usize, &OccupancyMap)],
        signatures: bool,
    ) -> ogm_corners::Result<Vec<(Prepared, Option<Signature>)>> {
        Local.prepare(maps, signatures)
    }

    fn align(
        &mut self,
        maps: &[Prepared],
        pairs: &[(usize, usize)],
        options: &GlobalOptions,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> ogm_corners::Result<Vec<PairRecord>> {
        let mut records = Local.align(maps, pairs, options, progress)?;
        match self.how {
            // Every record's candidates three hundred times over.
            0 => {
                for r in &mut records {
                    let edges = r.edges.clone();
                    r.edges = (0..300).flat_map(|_| edges.clone()).collect();
                }
            }
            // The records in the other order than the pairs.
            1 => records.reverse(),
            // Each pair's record the other way round (A onto B).
            _ => {
                let flipped: Vec<(usize, usize)> = pairs.iter().map(|&(a, b)| (b, a)).collect();
                records = Local.align(maps, &flipped, options, progress)?;
            }
        }
        Ok(records)
    }
}

/// An executor's answers are checked as a file's are: swollen, shuffled or reversed records refuse the
/// run with a one-line error naming the pair, quickly, instead of running for minutes or placing nothing
/// in silence; honest answers place as the local threads do.
#[test]
fn an_engine_whose_records_do_not_hold_on_the_maps_is_refused() {
    let (_, maps, _) = synthetic_maps(4, 3).unwrap();
    let options = GlobalOptions::default();
    for how in 0..3 {
        let start = std::time::Instant::now();
        let e = run_with(
            &maps,
            &options,
            &mut ReferenceBackend,
            &|_, _| {},
            &mut Cache::new(),
            &mut Spoiled { how },
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("the engine's alignment of map") && e.contains("does not hold on the maps"),
            "{how}: {e}"
        );
        assert!(!e.contains('\n'), "{e}");
        assert!(
            start.elapsed().as_secs() < 60,
            "{how}: {:?}",
            start.elapsed()
        );
    }
}

/// The tool in `dir`, ended after `secs` seconds if it has not ended by then (a read that blocks).
fn tool_within(dir: &std::path::Path, args: &[&str], secs: u64) -> (Option<i32>, String) {
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_ogm-corners"))
        .arg("merge")
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed().as_secs() >= secs {
            child.kill().unwrap();
            child.wait().unwrap();
            return (None, format!("still running after {secs} s"));
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `merge --from` reads only a regular file, within the budget (a fifo used to block forever, /dev/zero
/// to be read to gigabytes), and takes up an edited record only once the maps bear it out: a choice
/// moved by 3000 px is aligned again, said so, and every map is placed where a fresh merge puts it.
#[test]
fn merge_from_reads_only_a_regular_file_and_aligns_an_edited_record_again() {
    let d = tempfile::tempdir().unwrap();
    let (names, maps, _) = synthetic_maps(4, 3).unwrap();
    for (n, m) in names.iter().zip(&maps) {
        m.image
            .write_pgm(&d.path().join(format!("{n}.pgm")))
            .unwrap();
        std::fs::write(
            d.path().join(format!("{n}.yaml")),
            format!("image: {n}.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n"),
        )
        .unwrap();
    }
    let yaml = |k: usize| format!("{}.yaml", names[k]);
    let all: Vec<String> = (0..4).map(yaml).collect();
    let mut args: Vec<&str> = all.iter().map(String::as_str).collect();
    args.extend(["--poses", "fresh.json"]);
    let (code, err) = tool_within(d.path(), &args, 300);
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = tool_within(
        d.path(),
        &[&yaml(0), &yaml(1), &yaml(2), "--poses", "fleet.json"],
        300,
    );
    assert_eq!(code, Some(0), "{err}");
    // Not regular files: refused at once.
    let fifo = d.path().join("fifo.json");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(made.success());
    for (from, kind) in [("fifo.json", "a fifo"), ("/dev/zero", "a device")] {
        let (code, err) = tool_within(
            d.path(),
            &["--from", from, &yaml(3), "--max-memory", "2G"],
            30,
        );
        assert_eq!(code, Some(2), "{from}: {err}");
        assert!(
            err.contains(&format!("not a regular file ({kind})")) && err.lines().count() == 1,
            "{err}"
        );
    }
    // A file larger than the budget allows is refused by its bytes read.
    let big = d.path().join("big.json");
    std::fs::write(&big, vec![b' '; 40 << 20]).unwrap();
    let (code, err) = tool_within(
        d.path(),
        &["--from", "big.json", &yaml(3), "--max-memory", "100M"],
        30,
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--from big.json"), "{err}");
    // The first accepted alignment's choice moved by 3000 px.
    let path = d.path().join("fleet.json");
    let mut doc: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let records = doc["alignments"].as_array_mut().unwrap();
    let r = records
        .iter_mut()
        .map(|a| &mut a["alignment"])
        .find(|r| r["accepted"] == true)
        .expect("an accepted pair");
    for at in ["/transform/tx", "/edges/0/transform/tx"] {
        let t = r.pointer_mut(at).unwrap();
        *t = Value::from(t.as_f64().unwrap() + 3000.0);
    }
    std::fs::write(&path, doc.to_string()).unwrap();
    let (code, err) = tool_within(
        d.path(),
        &["--from", "fleet.json", &yaml(3), "--poses", "added.json"],
        300,
    );
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("1 of its pairs' alignments do not hold on the maps"),
        "{err}"
    );
    let read = |f: &str| -> Value {
        serde_json::from_slice(&std::fs::read(d.path().join(f)).unwrap()).unwrap()
    };
    let (fresh, added) = (read("fresh.json"), read("added.json"));
    for (f, a) in fresh["maps"]
        .as_array()
        .unwrap()
        .iter()
        .zip(added["maps"].as_array().unwrap())
    {
        assert_eq!(f["map"], a["map"]);
        assert_eq!(a["placed"], true, "{a}");
        let (tf, ta) = (&f["transform"], &a["transform"]);
        let d = |k: &str| (tf[k].as_f64().unwrap() - ta[k].as_f64().unwrap()).abs();
        assert!(
            d("theta_deg") < 0.2 && d("tx") < 3.0 && d("ty") < 3.0,
            "{tf} vs {ta}"
        );
    }
}
