//! `bench`: its records for every detector and backend, sizes, maps and folders, the GPU's stages, the
//! machine and build it names, the maps it saves, its usage errors and the bandwidth shares.

use super::commands::{gpu_available, room_pgm, run, stderr, stdout, tmpdir};
use std::fs;

/// `bench ARGS --format json`, parsed; panics with its standard error when it fails.
fn bench_json(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["bench"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--format", "json"]);
    let o = run(&all);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_str(&stdout(&o)).unwrap()
}

#[test]
fn bench_json_covers_every_detector_and_cpu_backend() {
    let v = bench_json(&[
        "--size",
        "64x48",
        "--repeat",
        "1",
        "--backend",
        "cpu,reference",
        "--detector",
        "all",
    ]);
    for k in ["version", "commit", "cpu", "os", "arch"] {
        assert!(v[k].as_str().is_some_and(|s| !s.is_empty()), "{k} in {v}");
    }
    assert!(v["threads"].as_u64().unwrap() >= 1);
    assert!(v["gpu"].is_null(), "no GPU asked for");
    let recs = v["records"].as_array().unwrap();
    let rows: Vec<(&str, &str, &str)> = recs
        .iter()
        .map(|r| {
            (
                r["detector"].as_str().unwrap(),
                r["backend"].as_str().unwrap(),
                r["stage"].as_str().unwrap(),
            )
        })
        .collect();
    let mut want = Vec::new();
    for d in ["ogm", "ogm-robust", "harris", "shi-tomasi", "trajkovic"] {
        want.push((d, "cpu", "end_to_end"));
        want.push((d, "reference", "end_to_end"));
        want.push((d, "reference", "kernel"));
    }
    assert_eq!(rows, want);
    for r in recs {
        for k in [
            "map",
            "adapter",
            "width",
            "height",
            "median_ms",
            "mpx_per_s",
            "keypoints",
        ] {
            assert!(!r[k].is_null(), "{k} missing in {r}");
        }
        assert_eq!(r["map"], "synthetic");
        assert!(r["source"].is_null() && r["image"].is_null(), "{r}");
        assert_eq!(
            (r["width"].as_u64(), r["height"].as_u64()),
            (Some(64), Some(48))
        );
        assert!(r["mpx_per_s"].as_f64().unwrap() > 0.0);
        if cfg!(target_os = "linux") {
            let peak = r["peak_rss_mb"].as_f64().expect("peak memory on Linux");
            assert!(
                peak > 0.0 && r["rss_before_mb"].as_f64().unwrap() <= peak,
                "{r}"
            );
            let ratio = r["peak_rss_ratio"].as_f64().unwrap();
            assert!((ratio - peak * 1e6 / (64.0 * 48.0)).abs() < 1e-6 * ratio);
        }
    }
    // Both backends found the same keypoints (bench fails otherwise); every record carries the count.
    for d in ["ogm", "harris", "shi-tomasi", "trajkovic"] {
        let n: Vec<u64> = recs
            .iter()
            .filter(|r| r["detector"] == d)
            .map(|r| r["keypoints"].as_u64().unwrap())
            .collect();
        assert!(n[0] > 0 && n.iter().all(|&c| c == n[0]), "{d}: {n:?}");
    }
}

#[test]
fn bench_sizes_and_maps_in_one_run_and_the_gpu_rows() {
    let d = tmpdir("bench-maps");
    let room = room_pgm(&d);
    let v = bench_json(&[
        "--size",
        "64x64",
        "--size",
        "40x32",
        room.to_str().unwrap(),
        "--repeat",
        "1",
        "--backend",
        "cpu",
    ]);
    let maps: Vec<(String, u64, u64)> = v["records"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r["map"].as_str().unwrap().to_string(),
                r["width"].as_u64().unwrap(),
                r["height"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        maps,
        [
            ("synthetic".to_string(), 64, 64),
            ("synthetic".to_string(), 40, 32),
            ("room".to_string(), 6, 5)
        ]
    );
    let r = &v["records"][2];
    assert_eq!(r["keypoints"], 4);
    assert_eq!(r["source"].as_str(), room.to_str());
    if gpu_available() {
        let v = bench_json(&[
            "--size",
            "64x64",
            "--repeat",
            "1",
            "--detector",
            "ogm,harris",
        ]);
        assert!(v["gpu"].is_string());
        let recs = v["records"].as_array().unwrap();
        for d in ["ogm", "harris"] {
            for (b, s) in [
                ("cpu", "end_to_end"),
                ("reference", "end_to_end"),
                ("gpu", "end_to_end"),
                ("gpu", "kernel_resident"),
                ("gpu", "upload"),
                ("gpu", "upload_ref"),
                ("gpu", "transfer_floor"),
            ] {
                assert!(
                    recs.iter()
                        .any(|r| r["detector"] == d && r["backend"] == b && r["stage"] == s),
                    "{d} {b} {s} missing"
                );
            }
        }
        assert!(recs
            .iter()
            .filter(|r| r["backend"] == "gpu")
            .all(|r| r["peak_rss_mb"].is_null() && r["gb_per_s"].as_f64().unwrap() > 0.0));
        // The OGM detector on the map already in a device buffer, alone of the detectors.
        let resident: Vec<_> = recs.iter().filter(|r| r["stage"] == "device_map").collect();
        assert_eq!(resident.len(), 1, "{resident:?}");
        assert!(resident[0]["detector"] == "ogm" && resident[0]["backend"] == "gpu");
        // One write pass a map (its list fits the buffer the warm-up grew), and what it dispatched: the
        // OGM detector's 64 x 64 map is one tile of four kernels, in memory or on the device.
        for r in recs.iter().filter(|r| {
            r["backend"] == "gpu"
                && ["end_to_end", "kernel_resident", "device_map"]
                    .contains(&r["stage"].as_str().unwrap())
        }) {
            assert_eq!(r["write_passes"], 1, "{r}");
            let d = r["dispatches"].as_u64().unwrap();
            assert!(
                if r["detector"] == "ogm" {
                    d == 4
                } else {
                    d > 4
                },
                "{r}"
            );
        }
        // End to end is reported against the transfer floor.
        assert!(recs
            .iter()
            .filter(|r| r["backend"] == "gpu" && r["stage"] == "end_to_end")
            .all(|r| r["vs_upload_ref"].as_f64().unwrap() > 0.0
                && r["vs_transfer_floor"].as_f64().unwrap() > 0.0));
    }
}

#[test]
fn bench_text_names_the_machine_and_the_build() {
    let o = run(&[
        "bench",
        "--size",
        "64x64",
        "--repeat",
        "1",
        "--backend",
        "cpu",
        "--detector",
        "trajkovic",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert!(
        lines[0].starts_with("# ogm-corners ")
            && lines[0].contains("threads")
            && lines[0].contains("(git "),
        "{out}"
    );
    let head = lines.iter().position(|l| l.starts_with("map ")).unwrap();
    assert!(
        lines[head].contains("Mpx/s") && lines[head].contains("peak MB"),
        "{out}"
    );
    assert_eq!(lines.len(), head + 2, "one row: {out}");
    assert!(lines[head + 1].starts_with("synthetic") && lines[head + 1].contains("trajkovic"));
}

#[test]
fn bench_save_map_writes_the_pixels_it_measured() {
    let d = tmpdir("bench-save");
    let file = d.join("one.pgm");
    let v = bench_json(&[
        "--size",
        "64x48",
        "--seed",
        "3",
        "--repeat",
        "1",
        "--backend",
        "cpu",
        "--save-map",
        file.to_str().unwrap(),
    ]);
    assert_eq!(v["records"][0]["image"].as_str(), file.to_str());
    let saved = ogm_corners::map::load_image(&file).unwrap();
    assert_eq!(
        saved.pixels(),
        ogm_corners::map::synthetic::office_map(64, 48, 3)
            .unwrap()
            .pixels()
    );
    // The saved map, measured as a file, gives the same keypoints.
    let again = bench_json(&[file.to_str().unwrap(), "--repeat", "1", "--backend", "cpu"]);
    assert_eq!(
        again["records"][0]["keypoints"],
        v["records"][0]["keypoints"]
    );
    // A folder takes several sizes.
    let folder = d.join("maps");
    bench_json(&[
        "--size",
        "64x48",
        "--size",
        "32x32",
        "--repeat",
        "1",
        "--backend",
        "cpu",
        "--save-map",
        folder.to_str().unwrap(),
    ]);
    for f in ["synthetic-64x48-seed1.pgm", "synthetic-32x32-seed1.pgm"] {
        assert!(folder.join(f).is_file(), "{f}");
    }
    // One file for two sizes, or nothing synthetic to save: usage errors.
    let two = run(&[
        "bench",
        "--size",
        "64x48",
        "--size",
        "32x32",
        "--save-map",
        file.to_str().unwrap(),
    ]);
    assert_eq!(two.status.code(), Some(2), "{}", stderr(&two));
    let none = run(&[
        "bench",
        file.to_str().unwrap(),
        "--save-map",
        folder.to_str().unwrap(),
    ]);
    assert_eq!(none.status.code(), Some(2), "{}", stderr(&none));
}

#[test]
fn bench_folder_means_its_yaml_maps_and_unnamed_images() {
    let d = tmpdir("bench-folder");
    let maps = d.join("maps");
    let sub = maps.join("sub");
    fs::create_dir_all(&sub).unwrap();
    room_pgm(&sub);
    fs::write(
        sub.join("map.yaml"),
        "image: room.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n",
    )
    .unwrap();
    let lone = room_pgm(&d);
    fs::rename(&lone, maps.join("lone.pgm")).unwrap();
    fs::write(maps.join("params.yaml"), "speed: 3\n").unwrap();
    let o = run(&[
        "bench",
        maps.to_str().unwrap(),
        "--repeat",
        "1",
        "--backend",
        "cpu,reference",
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("params.yaml"),
        "the non-map yaml is named"
    );
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let mut labels: Vec<&str> = v["records"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["backend"] == "cpu")
        .map(|r| r["map"].as_str().unwrap())
        .collect();
    labels.sort();
    // sub/room.pgm is named by sub/map.yaml, so it is measured once, as the yaml map "sub".
    assert_eq!(labels, ["lone", "sub"]);
    let empty = d.join("empty");
    fs::create_dir_all(&empty).unwrap();
    assert_eq!(
        run(&["bench", empty.to_str().unwrap()]).status.code(),
        Some(2)
    );
    assert_eq!(
        run(&["bench", d.join("missing.pgm").to_str().unwrap()])
            .status
            .code(),
        Some(2)
    );
}

#[test]
fn bench_usage_errors() {
    assert_eq!(run(&["bench", "--repeat", "0"]).status.code(), Some(2));
    assert_eq!(run(&["bench", "--detector", "fast"]).status.code(), Some(2));
    assert_eq!(run(&["bench", "--backend", "tpu"]).status.code(), Some(2));
    assert_eq!(run(&["bench", "--size", "0x5"]).status.code(), Some(2));
    for rows in ["0", "17", "four"] {
        assert_eq!(
            run(&["bench", "--gpu-strip-rows", rows]).status.code(),
            Some(2)
        );
    }
}

/// The GPU's tuning choices: the records carry them in the adapter's label, and the keypoints still agree
/// with the CPU's (bench fails when they differ): strips of 4 rows, bands copied.
#[test]
fn bench_gpu_tuning_is_named_and_keeps_the_keypoints() {
    if !gpu_available() {
        return;
    }
    let plain = bench_json(&["--size", "300x200", "--repeat", "1", "--backend", "cpu,gpu"]);
    let v = bench_json(&[
        "--size",
        "300x200",
        "--repeat",
        "1",
        "--backend",
        "cpu,gpu",
        "--gpu-strip-rows",
        "4",
        "--gpu-copy-bands",
    ]);
    let label = v["gpu"].as_str().unwrap();
    assert!(
        label.ends_with("; strips of 4 rows, bands copied to device buffers"),
        "{label}"
    );
    assert!(!plain["gpu"].as_str().unwrap().contains("strips of"));
    let gpu = |v: &serde_json::Value| -> Vec<u64> {
        v["records"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|r| r["backend"] == "gpu")
            .map(|r| r["keypoints"].as_u64().unwrap())
            .collect()
    };
    assert!(!gpu(&v).is_empty());
    assert_eq!(gpu(&v), gpu(&plain));
}

/// `bench --bandwidth`: one `read` record per map (its GB/s), and every CPU record's share of it, which is
/// its own pixels a second over the read's bytes a second; the reference's share is far below the fast
/// path's. Without the option, neither.
#[test]
fn bench_bandwidth_reports_each_cpu_record_as_a_share_of_a_plain_read() {
    let args = [
        "bench",
        "--size",
        "512x512",
        "--detector",
        "ogm,harris",
        "--backend",
        "cpu,reference",
        "--repeat",
        "3",
        "--format",
        "json",
    ];
    let o = run(&[&args[..], &["--bandwidth"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let records = v["records"].as_array().unwrap();
    let read: Vec<_> = records.iter().filter(|r| r["detector"] == "read").collect();
    assert_eq!(read.len(), 1);
    let gbs = read[0]["gb_per_s"].as_f64().unwrap();
    assert!(gbs > 0.0 && read[0]["stage"] == "read");
    let share = |det: &str, backend: &str| {
        let r = records
            .iter()
            .find(|r| r["detector"] == det && r["backend"] == backend && r["stage"] == "end_to_end")
            .unwrap();
        let pct = r["read_percent"].as_f64().unwrap();
        let want = 100.0 * r["mpx_per_s"].as_f64().unwrap() / 1e3 / gbs;
        assert!(
            (pct - want).abs() < 1e-6 * want.max(1.0),
            "{det} {backend}: {pct} vs {want}"
        );
        pct
    };
    assert!(share("ogm", "cpu") > share("ogm", "reference"));
    share("harris", "cpu");
    assert!(!v["isa"].as_str().unwrap().is_empty());
    let plain = run(&args);
    let v: serde_json::Value = serde_json::from_str(&stdout(&plain)).unwrap();
    for r in v["records"].as_array().unwrap() {
        assert!(r["detector"] != "read" && r["read_percent"].is_null());
    }
}
