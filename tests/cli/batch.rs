//! `detect` over many maps: folders and lists, one output per map identical to a single-map run, bad maps
//! reported without stopping the batch.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ogm_corners::map::synthetic::office_map;

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ogm-corners"))
        .args(args)
        .output()
        .unwrap()
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ogm-batch-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Three synthetic maps: two bare PGMs and one yaml with its PGM (which must not count twice).
fn maps(dir: &Path) {
    for (name, w, h) in [("a", 300, 200), ("b", 257, 129)] {
        office_map(w, h, w as u64)
            .unwrap()
            .write_pgm(&dir.join(format!("{name}.pgm")))
            .unwrap();
    }
    let sub = dir.join("site");
    fs::create_dir_all(&sub).unwrap();
    office_map(128, 96, 5)
        .unwrap()
        .write_pgm(&sub.join("map.pgm"))
        .unwrap();
    fs::write(
        sub.join("map.yaml"),
        "image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    )
    .unwrap();
}

#[test]
fn a_folder_gives_one_file_per_map_equal_to_single_runs() {
    let d = tmpdir("folder");
    let input = d.join("in");
    fs::create_dir_all(&input).unwrap();
    maps(&input);
    let out = d.join("out");
    for format in ["csv", "json"] {
        let o = run(&[
            "detect",
            s(&input),
            "-o",
            s(&out),
            "--format",
            format,
            "--backend",
            "cpu",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let summary = String::from_utf8(o.stdout).unwrap();
        assert_eq!(summary.lines().count(), 3, "{summary}");
        // The yaml map is named after its folder (ROS's usual map.yaml), and its PGM is not a second map.
        for (name, source) in [
            ("a", input.join("a.pgm")),
            ("b", input.join("b.pgm")),
            ("site", input.join("site/map.yaml")),
        ] {
            let single = run(&["detect", s(&source), "--format", format, "--backend", "cpu"]);
            assert!(single.status.success(), "{}", stderr(&single));
            let got = fs::read(out.join(format!("{name}.{format}"))).unwrap();
            assert_eq!(got, single.stdout, "{name}.{format}");
        }
    }
}

#[test]
fn a_bad_map_is_reported_and_the_rest_still_run() {
    let d = tmpdir("bad");
    maps(&d);
    fs::write(d.join("broken.pgm"), b"P5\n10 10\n255\nshort").unwrap();
    let out = d.join("out");
    let o = run(&[
        "detect",
        s(&d.join("a.pgm")),
        s(&d.join("broken.pgm")),
        s(&d.join("b.pgm")),
        "-o",
        s(&out),
        "--overlay",
        s(&d.join("png")),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("broken.pgm"), "{err}");
    assert!(
        err.contains("1 of 3 maps failed: 1 could not be read"),
        "{err}"
    );
    for name in ["a", "b"] {
        assert!(out.join(format!("{name}.csv")).is_file(), "{name}.csv");
        assert!(d.join(format!("png/{name}.png")).is_file(), "{name}.png");
    }
    assert!(!out.join("broken.csv").exists());
}

#[test]
fn same_names_get_suffixes() {
    let d = tmpdir("names");
    for sub in ["x", "y"] {
        fs::create_dir_all(d.join(sub)).unwrap();
        office_map(64, 64, 1)
            .unwrap()
            .write_pgm(&d.join(sub).join("floor.pgm"))
            .unwrap();
    }
    let out = d.join("out");
    let o = run(&[
        "detect",
        s(&d.join("x/floor.pgm")),
        s(&d.join("y/floor.pgm")),
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.join("floor.csv").is_file() && out.join("floor-2.csv").is_file());
}

#[test]
fn several_maps_need_an_output_folder_and_a_folder_needs_maps() {
    let d = tmpdir("usage");
    maps(&d);
    let o = run(&["detect", s(&d.join("a.pgm")), s(&d.join("b.pgm"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--output DIR"), "{}", stderr(&o));
    let empty = d.join("empty");
    fs::create_dir_all(&empty).unwrap();
    let o = run(&["detect", s(&empty), "-o", s(&d.join("out"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("no maps in this folder"),
        "{}",
        stderr(&o)
    );
}
