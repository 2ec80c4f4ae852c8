//! Folders, reruns and odd inputs, as a careless user meets them: a map yaml with a typo never leaves its
//! image to be used alone, the tool's own outputs (merged maps, report pictures, overlays) are not read
//! back as robots' maps, the round trips the docs promise work, and messages say what happened. Each test
//! fails on the code before its fix.

use crate::common;
use common::run::*;

use std::fs;
use std::path::Path;
use std::process::Command;

/// Four robots' maps of the demo (`robot-1.yaml` ... with their PGMs), and nothing else, in `dir`.
fn robots(dir: &Path) {
    let o = ogm(&["demo", "-o", s(dir), "--robots", "4", "--size", "512x384"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in entries(dir) {
        if !f.starts_with("robot-") {
            fs::remove_file(dir.join(&f)).unwrap();
        }
    }
    assert_eq!(entries(dir).len(), 8, "{:?}", entries(dir));
}

/// `merge DIR` with the poses written to `poses` (outside the folder): its JSON.
fn merge_poses(dir: &Path, extra: &[&str]) -> (std::process::Output, serde_json::Value) {
    let out = tmp();
    let poses = out.path().join("poses.json");
    let mut args = vec!["merge", s(dir), "--poses", s(&poses)];
    args.extend_from_slice(extra);
    let o = ogm(&args);
    let doc = fs::read_to_string(&poses)
        .ok()
        .map(|t| serde_json::from_str(&t).unwrap())
        .unwrap_or(serde_json::Value::Null);
    (o, doc)
}

fn map_names(doc: &serde_json::Value) -> Vec<String> {
    doc["maps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["map"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn a_broken_map_yaml_in_a_folder_is_an_error_and_its_image_is_never_used_alone() {
    let d = tmp();
    robots(d.path());
    let yaml = d.path().join("robot-3.yaml");
    let text = fs::read_to_string(&yaml).unwrap();
    // An unclosed bracket: the yaml does not parse at all.
    let broken = text.replacen(']', "", 1);
    assert_ne!(broken, text);
    fs::write(&yaml, &broken).unwrap();
    for cmd in [
        vec!["merge", s(d.path())],
        vec!["bench", s(d.path()), "--repeat", "1"],
    ] {
        let o = ogm(&cmd);
        refused(&o, "robot-3.yaml");
        assert!(!stderr(&o).contains("note: skipped"), "{}", stderr(&o));
    }
    // `detect DIR` does the other maps, says what it skipped, and fails; robot-3.pgm is not detected.
    let out = tmp();
    let o = ogm(&["detect", s(d.path()), "-o", s(out.path())]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("robot-3.yaml"), "{}", stderr(&o));
    let done = entries(out.path());
    assert!(done.iter().all(|f| !f.starts_with("robot-3")), "{done:?}");
    assert_eq!(done.len(), 3, "{done:?}");
    // A yaml that cannot be read at all (a fifo in its place) leaves its image of the same name unused.
    fs::remove_file(&yaml).unwrap();
    let made = Command::new("mkfifo").arg(&yaml).status().unwrap();
    assert!(made.success());
    let out = tmp();
    let o = ogm(&["detect", s(d.path()), "-o", s(out.path())]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("robot-3.yaml"), "{}", stderr(&o));
    let done = entries(out.path());
    assert!(done.iter().all(|f| !f.starts_with("robot-3")), "{done:?}");
    assert_eq!(done.len(), 3, "{done:?}");
}

#[test]
fn a_yaml_that_is_no_map_is_still_left_out_with_a_note() {
    let d = tmp();
    robots(d.path());
    // A ROS parameter file beside the maps, with a typo of its own: nothing to do with maps.
    fs::write(d.path().join("params.yaml"), "controller: {rate: [1, 2\n").unwrap();
    let (o, doc) = merge_poses(d.path(), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("params.yaml"), "{}", stderr(&o));
    assert_eq!(map_names(&doc).len(), 4);
}

#[test]
fn a_rerun_leaves_out_the_merged_map_and_report_pictures_it_wrote() {
    let d = tmp();
    robots(d.path());
    let (first, doc) = merge_poses(d.path(), &[]);
    assert!(first.status.success(), "{}", stderr(&first));
    let names = map_names(&doc);
    assert_eq!(names.len(), 4, "{names:?}");
    // The merged map, its picture and the HTML report written into the robots' own folder.
    let merged = d.path().join("merged.yaml");
    let html = d.path().join("report");
    let o = ogm(&[
        "merge",
        s(d.path()),
        "-o",
        s(&merged),
        "--overlay",
        s(&d.path().join("merged.png")),
        "--html",
        s(&html),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.path().join("merged.pgm").is_file());
    // Run again, the same way and with another output name: the same four maps, the same poses.
    let same_output = ["-o", s(&merged)];
    for again in [&same_output[..], &[]] {
        let (o, redo) = merge_poses(d.path(), again);
        assert!(o.status.success(), "{}", stderr(&o));
        assert_eq!(map_names(&redo), names, "{}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains("that ogm-corners wrote"), "{e}");
        for (a, b) in doc["maps"]
            .as_array()
            .unwrap()
            .iter()
            .zip(redo["maps"].as_array().unwrap())
        {
            assert_eq!(a["transform"], b["transform"], "{e}");
        }
    }
    // Named on the command line, a merged map is a map like any other.
    let o = ogm(&["detect", s(&merged)]);
    assert!(o.status.success(), "{}", stderr(&o));
    // `detect DIR` and `bench DIR` leave them out too.
    let out = tmp();
    let o = ogm(&["detect", s(d.path()), "-o", s(out.path())]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(entries(out.path()).len(), 4, "{:?}", entries(out.path()));
}

#[test]
fn an_overlay_of_detect_is_a_marked_picture_that_loads_as_any_png() {
    let d = tmp();
    robots(d.path());
    let png = d.path().join("overlay.png");
    let o = ogm(&[
        "detect",
        s(&d.path().join("robot-1.yaml")),
        "--overlay",
        s(&png),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        ogm_corners::support::marks::written_by_tool(&png),
        Some(ogm_corners::support::marks::Written::Picture)
    );
    // Other readers see an ordinary PNG.
    let img = image::open(&png).unwrap();
    assert!(img.width() > 0);
    let (o, doc) = merge_poses(d.path(), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(map_names(&doc).len(), 4);
}

#[test]
fn saved_synthetic_pairs_run_again_from_their_pair_file() {
    let d = tmp();
    robots(d.path());
    let sp = d.path().join("sp");
    let first = ogm_json(&[
        "merge-eval",
        "--synthetic",
        s(&d.path().join("robot-1.yaml")),
        "--per-map",
        "1",
        "--save-pairs",
        s(&sp),
        "--format",
        "json",
    ]);
    let again = ogm_json(&["merge-eval", s(&sp.join("pairs.json")), "--format", "json"]);
    let n = |v: &serde_json::Value| v.as_array().unwrap().len();
    assert_eq!(n(&first), n(&again));
    // A map the pair file names that is not there: every file looked for is named.
    let text = fs::read_to_string(sp.join("pairs.json")).unwrap();
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    let src = doc["pairs"][0]["src"].as_str().unwrap().to_string();
    for e in ["pgm", "png", "yaml"] {
        let _ = fs::remove_file(sp.join(format!("{src}.{e}")));
    }
    let o = ogm(&["merge-eval", s(&sp.join("pairs.json"))]);
    refused(&o, &format!("{src}.pgm"));
    assert!(
        stderr(&o).contains(&format!("{src}.yaml")),
        "{}",
        stderr(&o)
    );
    // A pair file with no pairs is refused, not a table of zeros.
    let empty = d.path().join("empty.json");
    fs::write(&empty, r#"{"pairs": [], "negatives": []}"#).unwrap();
    refused(&ogm(&["merge-eval", s(&empty)]), "no pairs");
}

#[test]
fn a_quoted_image_name_keeps_its_spaces_through_a_round_trip() {
    let d = tmp();
    robots(d.path());
    let out = d.path().join(" lead.yaml");
    let o = ogm(&[
        "merge",
        s(&d.path().join("robot-3.yaml")),
        s(&d.path().join("robot-4.yaml")),
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = fs::read_to_string(&out).unwrap();
    assert!(text.contains("' lead.pgm'"), "{text}");
    let merged = ogm_corners::OccupancyMap::load(&out).unwrap();
    assert_eq!(
        merged.image_path.as_deref(),
        Some(d.path().join(" lead.pgm").as_path())
    );
}

#[test]
fn a_cap_on_corners_to_standard_output_prints_nothing_when_it_refuses() {
    let d = tmp();
    robots(d.path());
    let map = d.path().join("robot-1.yaml");
    for format in ["json", "csv"] {
        let o = ogm(&["detect", s(&map), "--max-corners", "5", "--format", format]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(o.stdout.is_empty(), "{}", stdout(&o));
    }
    // Within the cap, the whole document, as without one.
    let plain = ogm(&["detect", s(&map), "--format", "json"]);
    let capped = ogm(&[
        "detect",
        s(&map),
        "--max-corners",
        "100000",
        "--format",
        "json",
    ]);
    assert!(capped.status.success(), "{}", stderr(&capped));
    let kp = |o: &std::process::Output| {
        let v: serde_json::Value = serde_json::from_str(&stdout(o)).unwrap();
        v["keypoints"].clone()
    };
    assert_eq!(kp(&plain), kp(&capped));
}

#[test]
fn annotations_off_the_map_or_named_twice_are_refused_and_an_unmarked_map_has_no_recall() {
    let d = tmp();
    robots(d.path());
    let map = d.path().join("robot-1.yaml");
    let marks = d.path().join("marks.json");
    let run = |text: &str| {
        fs::write(&marks, text).unwrap();
        ogm(&["eval", s(&map), "--annotations", s(&marks)])
    };
    refused(&run(r#"{"maps": {"robot-1": [[1e300, 5]]}}"#), "outside");
    refused(
        &run(r#"{"maps": {"robot-1": [[3, 5]], "robot-1": [[4, 5]]}}"#),
        "listed twice",
    );
    let o = run(r#"{"maps": {"robot-1": []}}"#);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = stdout(&o);
    assert!(table.contains("n/a") && !table.contains("0.0%"), "{table}");
}

#[test]
fn bench_of_an_empty_folder_says_there_are_no_maps() {
    let d = tmp();
    let o = ogm(&["bench", s(d.path())]);
    refused(&o, "no maps");
    assert!(!stderr(&o).contains("could not be read"), "{}", stderr(&o));
}

#[test]
fn a_gpu_probe_without_a_desktop_session_prints_no_wayland_error() {
    // `info` lists the adapters (the probe every GPU-choosing command makes).
    let o = within(
        {
            let mut c = Command::new(BIN);
            c.arg("info").env_remove("XDG_RUNTIME_DIR");
            c
        },
        120,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("XDG_RUNTIME_DIR"), "{}", stderr(&o));
}

#[test]
fn thousands_of_worker_threads_asked_for_are_capped_with_a_note() {
    let d = tmp();
    robots(d.path());
    let o = within(
        {
            let mut c = Command::new(BIN);
            c.args([
                "merge",
                s(&d.path().join("robot-3.yaml")),
                s(&d.path().join("robot-4.yaml")),
            ])
            .env("RAYON_NUM_THREADS", "4096");
            c
        },
        60,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("RAYON_NUM_THREADS=4096"),
        "{}",
        stderr(&o)
    );
}
