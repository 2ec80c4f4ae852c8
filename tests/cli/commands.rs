//! The command-line tool: outputs, exit statuses and error messages.

use std::fs;
use std::path::PathBuf;
use std::process::{Command, Output};
pub(crate) fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ogm-corners"))
}

pub(crate) fn run(args: &[&str]) -> Output {
    bin().args(args).output().unwrap()
}

pub(crate) fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ogm-cli-{}-{name}", std::process::id()));
    fs::create_dir_all(&d).unwrap();
    d
}

pub(crate) fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).unwrap()
}

pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8(o.stderr.clone()).unwrap()
}

/// A 6x5 room with four inner corners, as a PGM.
pub(crate) fn room_pgm(dir: &std::path::Path) -> PathBuf {
    let rows = ["######", "#....#", "#....#", "#....#", "######"];
    let mut bytes = b"P5\n6 5\n255\n".to_vec();
    for r in rows {
        bytes.extend(r.bytes().map(|b| if b == b'#' { 0 } else { 254 }));
    }
    let p = dir.join("room.pgm");
    fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn detect_csv_to_stdout() {
    let d = tmpdir("csv");
    let o = run(&["detect", room_pgm(&d).to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "x,y,rule,code");
    assert_eq!(
        &lines[1..],
        &["1,1,5,199", "4,1,5,31", "1,3,5,241", "4,3,5,124"]
    );
}

#[test]
fn detect_json_with_yaml_has_world_coordinates() {
    let d = tmpdir("json");
    room_pgm(&d);
    let yaml = d.join("room.yaml");
    fs::write(&yaml, "image: room.pgm\nresolution: 0.5\norigin: [1.0, 2.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n").unwrap();
    let out = d.join("k.json");
    let o = run(&[
        "detect",
        yaml.to_str().unwrap(),
        "--format",
        "json",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stdout.is_empty());
    let v: serde_json::Value = serde_json::from_str(&fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(v["width"], 6);
    assert_eq!(v["height"], 5);
    assert_eq!(v["count"], 4);
    assert_eq!(v["rules"], "paper");
    let k0 = &v["keypoints"][0];
    assert_eq!(
        (k0["x"].as_u64(), k0["y"].as_u64(), k0["rule"].as_u64()),
        (Some(1), Some(1), Some(5))
    );
    // Pixel (1, 1) of a 5-row map is row 3 from the bottom: centre at (1 + 1.5 * 0.5, 2 + 3.5 * 0.5).
    assert_eq!(k0["world"][0].as_f64(), Some(1.75));
    assert_eq!(k0["world"][1].as_f64(), Some(3.75));
    // CSV of a yaml map carries world columns too.
    let o = run(&["detect", yaml.to_str().unwrap()]);
    let out = stdout(&o);
    assert_eq!(out.lines().next(), Some("x,y,rule,code,world_x,world_y"));
    assert_eq!(out.lines().nth(1), Some("1,1,5,199,1.750000,3.750000"));
}

#[test]
fn overlay_is_a_png_with_coloured_marks() {
    let d = tmpdir("overlay");
    let png = d.join("o.png");
    let o = run(&[
        "detect",
        room_pgm(&d).to_str().unwrap(),
        "--overlay",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&png).unwrap().to_rgb8();
    assert!(
        img.width() >= 6 * 8,
        "small maps are enlarged: {}",
        img.width()
    );
    let coloured = img
        .pixels()
        .filter(|p| !(p[0] == p[1] && p[1] == p[2]))
        .count();
    assert!(
        coloured > 4 * 8,
        "keypoints must be marked in colour ({coloured} px)"
    );
}

#[test]
fn rule_options_change_the_result() {
    let d = tmpdir("opts");
    // An L of unknown cells: a corner only with --unknown-as-occupied.
    let p = d.join("u.pgm");
    let mut bytes = b"P5\n3 3\n255\n".to_vec();
    bytes.extend([205, 205, 205, 205, 254, 254, 205, 254, 254]);
    fs::write(&p, bytes).unwrap();
    let plain = stdout(&run(&["detect", p.to_str().unwrap()]));
    let uao = stdout(&run(&[
        "detect",
        p.to_str().unwrap(),
        "--unknown-as-occupied",
    ]));
    assert_eq!(plain.lines().count(), 1);
    assert_eq!(uao.lines().count(), 2, "{uao}");
    let o = run(&[
        "detect",
        p.to_str().unwrap(),
        "--rules",
        "paper-mod2",
        "--backend",
        "cpu",
    ]);
    assert!(o.status.success());
}

#[test]
fn rules_command_csv_and_text() {
    let o = run(&["rules", "--format", "csv"]);
    assert!(o.status.success());
    let out = stdout(&o);
    let mut lines = out.lines();
    assert_eq!(lines.next(), Some("code,rule"));
    let rows: Vec<(u8, u8)> = lines
        .map(|l| {
            let (c, r) = l.split_once(',').unwrap();
            (c.parse().unwrap(), r.parse().unwrap())
        })
        .collect();
    assert_eq!(rows.len(), 44);
    let want: Vec<(u8, u8)> = ogm_corners::RuleTable::new(ogm_corners::RuleSet::Paper)
        .accepted()
        .collect();
    assert_eq!(rows, want);
    let o = run(&["rules", "--rules", "paper-mod2", "--format", "csv"]);
    assert_eq!(stdout(&o).lines().count(), 37);
    let text = stdout(&run(&["rules"]));
    assert!(
        text.contains("code 199 (0b11000111)  rule 5\n    # # #\n    # C .\n    # . ."),
        "{text}"
    );
}

#[test]
fn demo_merges_the_robots_maps_and_checks_them_against_the_truth() {
    // What a newcomer runs first: no arguments but the folder.
    let d = tmpdir("demo-merge");
    let o = run(&["demo", "-o", d.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("3 of 3 maps placed in one map"), "{out}");
    for f in [
        "robot-1.pgm",
        "robot-1.yaml",
        "robot-2.yaml",
        "robot-3.yaml",
        "merged.pgm",
        "merged.yaml",
        "poses.json",
        "corners.csv",
        "demo.png",
    ] {
        assert!(d.join(f).is_file(), "{f} missing: {out}");
    }
    let poses: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(d.join("poses.json")).unwrap()).unwrap();
    let robots = poses["robots"].as_array().unwrap();
    assert_eq!(robots.len(), 3);
    for r in robots {
        assert_eq!(r["group"], 0, "{r}");
        let (deg, px) = (
            r["error_deg"].as_f64().unwrap(),
            r["error_px"].as_f64().unwrap(),
        );
        assert!(deg < 0.5 && px < 1.5, "{r}");
    }
    // The merged map loads as a map, larger than any robot's; every robot's corners are listed, placed.
    let merged = ogm_corners::OccupancyMap::load(d.join("merged.yaml")).unwrap();
    let one = ogm_corners::OccupancyMap::load(d.join("robot-1.yaml")).unwrap();
    assert!(merged.image.len() > one.image.len());
    let csv = fs::read_to_string(d.join("corners.csv")).unwrap();
    for k in 1..=3 {
        let rows: Vec<&str> = csv
            .lines()
            .filter(|l| l.starts_with(&format!("robot-{k},")))
            .collect();
        assert!(rows.len() > 10, "robot-{k}: {} corners", rows.len());
        assert!(
            rows.iter().all(|l| !l.ends_with(",,")),
            "robot-{k} unplaced"
        );
    }
    // Run again with fewer robots into the same folder: robot-3's files are not this run's, and it says so.
    let o = run(&["demo", "-o", d.to_str().unwrap(), "--robots", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    for f in ["robot-3.pgm", "robot-3.yaml"] {
        assert!(
            err.contains(&format!("{f} is from an earlier run, not this one")),
            "{err}"
        );
    }
    assert!(!err.contains("robot-2.pgm is from"), "{err}");
    // Bad arguments are refused in one line, before anything is written.
    let bad = tmpdir("demo-merge-bad");
    let o = run(&["demo", "-o", bad.to_str().unwrap(), "--robots", "1"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = run(&["demo", "-o", bad.to_str().unwrap(), "--size", "100x100"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!bad.join("poses.json").exists());
}

#[test]
fn demo_writes_map_overlay_and_keypoints() {
    let d = tmpdir("demo");
    let o = run(&[
        "demo",
        "--detect-only",
        "-o",
        d.to_str().unwrap(),
        "--size",
        "300x200",
        "--seed",
        "3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        out.contains("corners in a 300x200 synthetic office map"),
        "{out}"
    );
    for f in [
        "demo-map.pgm",
        "demo-map.yaml",
        "overlay.png",
        "keypoints.csv",
        "keypoints.json",
    ] {
        assert!(d.join(f).is_file(), "{f} missing");
    }
    let n: usize = out.split_whitespace().next().unwrap().parse().unwrap();
    assert!(n > 10, "an office has corners: {n}");
    let csv = fs::read_to_string(d.join("keypoints.csv")).unwrap();
    assert_eq!(csv.lines().count(), n + 1);
    // The written map detects to the same keypoints through `detect`.
    let again = stdout(&run(&["detect", d.join("demo-map.yaml").to_str().unwrap()]));
    assert_eq!(again, csv);
}

#[test]
fn bad_input_exits_2_with_one_line_naming_the_file() {
    let d = tmpdir("bad");
    let trunc = d.join("trunc.pgm");
    fs::write(&trunc, b"P5\n10 10\n255\n\x00").unwrap();
    let yaml = d.join("broken.yaml");
    fs::write(&yaml, "image: [\n").unwrap();
    let missing = d.join("missing.pgm");
    for p in [&trunc, &yaml, &missing] {
        let o = run(&["detect", p.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{}", p.display());
        let err = stderr(&o);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.contains(p.file_name().unwrap().to_str().unwrap()),
            "{err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

#[test]
fn usage_errors_exit_2_and_help_exits_0() {
    assert_eq!(run(&["detect"]).status.code(), Some(2));
    assert_eq!(
        run(&["detect", "x.pgm", "--rules", "nope"]).status.code(),
        Some(2)
    );
    assert_eq!(run(&["frobnicate"]).status.code(), Some(2));
    assert_eq!(
        run(&["demo", "--detect-only", "--size", "0x5"])
            .status
            .code(),
        Some(2)
    );
    assert_eq!(
        run(&[
            "demo",
            "--detect-only",
            "--size",
            "10x10",
            "-o",
            tmpdir("tiny").to_str().unwrap()
        ])
        .status
        .code(),
        Some(2)
    );
    let h = run(&["--help"]);
    assert_eq!(h.status.code(), Some(0));
    assert!(stdout(&h).contains("detect"));
}

#[test]
fn unwritable_output_exits_1() {
    let d = tmpdir("unwritable");
    let o = run(&[
        "detect",
        room_pgm(&d).to_str().unwrap(),
        "-o",
        "/nonexistent-dir/k.csv",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("/nonexistent-dir/k.csv"));
}

pub(crate) fn gpu_available() -> bool {
    let ok = !ogm_corners::backend::gpu::list_adapters().is_empty();
    if !ok {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true"),
            "CI=true requires a GPU adapter"
        );
        eprintln!("SKIPPED: no GPU adapter; the GPU CLI checks did NOT run");
    }
    ok
}

#[test]
fn gpu_and_cpu_backends_write_the_same_csv() {
    if !gpu_available() {
        return;
    }
    let d = tmpdir("backends");
    let map = d.join("office");
    let o = run(&[
        "demo",
        "--detect-only",
        "-o",
        map.to_str().unwrap(),
        "--size",
        "200x150",
        "--backend",
        "cpu",
    ]);
    assert!(o.status.success());
    let yaml = map.join("demo-map.yaml");
    let cpu = run(&["detect", yaml.to_str().unwrap(), "--backend", "cpu"]);
    let gpu = run(&["detect", yaml.to_str().unwrap(), "--backend", "gpu"]);
    assert!(gpu.status.success(), "{}", stderr(&gpu));
    assert_eq!(stdout(&cpu), stdout(&gpu));
    assert!(stdout(&cpu).lines().count() > 5);
    // auto says on standard error which backend it picked.
    let auto = run(&["detect", yaml.to_str().unwrap()]);
    assert!(
        stderr(&auto).contains("ogm-corners: backend: "),
        "{}",
        stderr(&auto)
    );
    assert_eq!(stdout(&auto), stdout(&cpu));
}

#[test]
fn gpu_backend_without_adapter_fails_clearly() {
    let d = tmpdir("noadapter");
    let o = bin()
        .args(["detect", room_pgm(&d).to_str().unwrap(), "--backend", "gpu"])
        .env("WGPU_ADAPTER_NAME", "no-such-adapter-anywhere")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("WGPU_ADAPTER_NAME"), "{}", stderr(&o));
}

#[test]
fn info_lists_adapters() {
    let o = run(&["info", "--format", "json"]);
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let list = v.as_array().unwrap();
    if gpu_available() {
        assert!(!list.is_empty());
        assert!(list[0]["max_storage_buffer_binding_size"].as_u64().unwrap() > 0);
        let text = stdout(&run(&["info"]));
        assert!(
            text.contains("adapter 0:") && text.contains("max_storage_buffer_binding_size"),
            "{text}"
        );
    }
}

#[test]
fn every_detector_through_the_cli() {
    let d = tmpdir("detectors");
    let o = run(&[
        "demo",
        "--detect-only",
        "-o",
        d.to_str().unwrap(),
        "--size",
        "200x150",
        "--backend",
        "cpu",
    ]);
    assert!(o.status.success());
    let yaml = d.join("demo-map.yaml");
    for det in ["harris", "shi-tomasi", "trajkovic"] {
        let o = run(&[
            "detect",
            yaml.to_str().unwrap(),
            "--detector",
            det,
            "--backend",
            "cpu",
        ]);
        assert!(o.status.success(), "{det}: {}", stderr(&o));
        let out = stdout(&o);
        assert_eq!(
            out.lines().next(),
            Some("x,y,score,world_x,world_y"),
            "{det}"
        );
        assert!(out.lines().count() > 10, "{det} finds corners in an office");
        let j = run(&[
            "detect",
            yaml.to_str().unwrap(),
            "--detector",
            det,
            "--backend",
            "cpu",
            "--format",
            "json",
        ]);
        let v: serde_json::Value = serde_json::from_str(&stdout(&j)).unwrap();
        assert_eq!(v["detector"], det);
        assert!(v["keypoints"][0]["score"].as_i64().unwrap() > 0);
        assert!(v["keypoints"][0]["rule"].is_null());
    }
    // Options reach the detector: a cap on Shi-Tomasi's count, and bad values are usage errors.
    let o = run(&[
        "detect",
        yaml.to_str().unwrap(),
        "--detector",
        "shi-tomasi",
        "--max-corners",
        "5",
        "--backend",
        "cpu",
    ]);
    assert_eq!(stdout(&o).lines().count(), 6);
    let o = run(&[
        "detect",
        yaml.to_str().unwrap(),
        "--detector",
        "harris",
        "--harris-k",
        "0.0401",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("harris k"));
}

#[test]
fn overlay_of_a_map_wider_than_the_overlay_limit_is_shrunk() {
    let d = tmpdir("wide");
    // 20000 x 40: a wall along the top and a room corner at x = 19990.
    let (w, h) = (20_000u32, 40u32);
    let mut bytes = format!("P5\n{w} {h}\n255\n").into_bytes();
    for y in 0..h {
        for x in 0..w {
            bytes.push(if y == 5 || (x == 19_990 && y > 5) {
                0
            } else {
                254
            });
        }
    }
    let p = d.join("wide.pgm");
    fs::write(&p, bytes).unwrap();
    let png = d.join("wide.png");
    let o = run(&[
        "detect",
        p.to_str().unwrap(),
        "--backend",
        "cpu",
        "--overlay",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(
        (img.width(), img.height()),
        (20_000u32.div_ceil(3), 40u32.div_ceil(3))
    );
    // The wall survives the shrink and the corner is marked in colour.
    assert!(img.pixels().any(|p| p[0] == 0 && p[1] == 0 && p[2] == 0));
    assert!(img.pixels().any(|p| p[0] > 200 && p[1] < 60));
}

#[test]
fn eval_reports_every_detector_and_condition() {
    let d = tmpdir("eval");
    let o = run(&[
        "demo",
        "--detect-only",
        "-o",
        d.to_str().unwrap(),
        "--size",
        "160x120",
        "--backend",
        "cpu",
    ]);
    assert!(o.status.success());
    let yaml = d.join("demo-map.yaml");
    let o = run(&[
        "eval",
        yaml.to_str().unwrap(),
        "--trials",
        "1",
        "--backend",
        "cpu",
        "--format",
        "csv",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let mut lines = out.lines();
    assert_eq!(
        lines.next(),
        Some("map,detector,condition,level,repeatability,trials")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(
        rows.len(),
        5 * ogm_corners::measure::detection::conditions().len()
    );
    for r in rows
        .iter()
        .filter(|r| r[1] == "ogm" && ["rot90", "rot180", "rot270", "mirror"].contains(&r[2]))
    {
        assert_eq!(r[4], "1.0000", "{r:?}");
    }
    let plots = d.join("plots");
    let o = run(&[
        "eval",
        yaml.to_str().unwrap(),
        "--trials",
        "1",
        "--backend",
        "cpu",
        "--plot",
        plots.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in ["repeatability-noise.png", "repeatability-rotation.png"] {
        let img = image::open(plots.join(f)).unwrap().to_rgb8();
        assert_eq!((img.width(), img.height()), (900, 520));
        // A line per detector, in its colour: red (ogm) and blue (harris) are drawn.
        assert!(img.pixels().any(|p| p.0 == [220, 20, 20]), "{f}");
        assert!(img.pixels().any(|p| p.0 == [30, 90, 220]), "{f}");
    }
    assert_eq!(run(&["eval"]).status.code(), Some(2));
    assert_eq!(
        run(&["eval", yaml.to_str().unwrap(), "--tolerance", "-1"])
            .status
            .code(),
        Some(2)
    );
}

#[test]
fn compare_writes_the_table_and_a_contact_sheet_per_map() {
    let d = tmpdir("compare");
    let o = run(&[
        "demo",
        "--detect-only",
        "-o",
        d.to_str().unwrap(),
        "--size",
        "160x120",
        "--backend",
        "cpu",
    ]);
    assert!(o.status.success());
    let yaml = d.join("demo-map.yaml");
    let out = d.join("cmp");
    let o = run(&[
        "compare",
        yaml.to_str().unwrap(),
        "--repeat",
        "1",
        "--out",
        out.to_str().unwrap(),
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let rows = v.as_array().unwrap();
    let dets: Vec<&str> = rows
        .iter()
        .map(|r| r["detector"].as_str().unwrap())
        .collect();
    assert_eq!(
        dets,
        ["ogm", "ogm-robust", "harris", "shi-tomasi", "trajkovic"]
    );
    for r in rows {
        assert_eq!(r["map"], "demo-map");
        assert!(r["keypoints"].as_u64().unwrap() > 0);
        assert!(r["cpu_end_to_end_ms"].as_f64().unwrap() > 0.0);
        assert!(r["reference_kernel_ms"].as_f64().unwrap() > 0.0);
        assert!(r["reference_end_to_end_ms"].as_f64().unwrap() > 0.0);
        assert!(
            r["gpu_end_to_end_ms"].is_null(),
            "cpu and reference only by default"
        );
    }
    let md = fs::read_to_string(out.join("compare.md")).unwrap();
    assert!(md.starts_with(
        "| map | size | detector | keypoints | CPU end-to-end ms | reference kernel ms |"
    ));
    assert_eq!(md.lines().count(), 2 + 5);
    let sheet = image::open(out.join("demo-map-contact-sheet.png"))
        .unwrap()
        .to_rgb8();
    assert!(sheet.width() > 1000 && sheet.height() > 1000);
    assert!(
        sheet.pixels().any(|p| p.0 == [200, 0, 200]),
        "baseline keypoints drawn"
    );
    assert!(
        sheet.pixels().any(|p| p.0 == [230, 0, 0]),
        "OGM rule-5 keypoints drawn"
    );
    assert_eq!(run(&["compare"]).status.code(), Some(2));
}

#[test]
fn robust_detector_outputs_strength_scale_and_angle_and_checks_its_options() {
    let d = tmpdir("robust");
    let o = run(&[
        "demo",
        "--detect-only",
        "-o",
        d.to_str().unwrap(),
        "--size",
        "400x300",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let yaml = d.join("demo-map.yaml");
    let y = yaml.to_str().unwrap();
    let o = run(&["detect", "--detector", "ogm-robust", "--backend", "cpu", y]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = stdout(&o);
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("x,y,score,scale,convex,rule,code,world_x,world_y")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.len() > 10, "{csv}");
    for r in &rows {
        // Strength at least the default 12 px, a scale of the default ladder, rule 4-6.
        assert!(r[2].parse::<i64>().unwrap() >= 12, "{r:?}");
        assert!(
            [2, 3, 4, 6, 8, 12].contains(&r[3].parse::<u8>().unwrap()),
            "{r:?}"
        );
        assert!(["true", "false"].contains(&r[4]), "{r:?}");
        assert!((4..=6).contains(&r[5].parse::<u8>().unwrap()), "{r:?}");
    }
    let o = run(&[
        "detect",
        "--detector",
        "ogm-robust",
        "--backend",
        "cpu",
        "--format",
        "json",
        y,
    ]);
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["detector"], "ogm-robust");
    // The synthetic office is axis-aligned: the estimated wall direction is 0.
    assert!(
        v["angle_deg"].as_f64().unwrap().abs() < 0.01,
        "{}",
        v["angle_deg"]
    );
    assert_eq!(v["count"].as_u64().unwrap() as usize, rows.len());
    let k = &v["keypoints"][0];
    for f in [
        "x", "y", "score", "scale", "convex", "rule", "code", "world",
    ] {
        assert!(!k[f].is_null(), "{f} in {k}");
    }
    // --max-corners keeps the strongest.
    let o = run(&[
        "detect",
        "--detector",
        "ogm-robust",
        "--backend",
        "cpu",
        "--max-corners",
        "3",
        y,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 1 + 3);
    // Bad options: one line, exit 2.
    for args in [
        vec![
            "--detector",
            "ogm-robust",
            "--min-scale",
            "5",
            "--max-scale",
            "3",
        ],
        vec!["--detector", "ogm-robust", "--max-scale", "17"],
        vec!["--detector", "ogm-robust", "--angle", "nan"],
        vec!["--detector", "ogm", "--max-corners", "1"],
    ] {
        let mut all = vec!["detect", "--backend", "cpu"];
        all.extend(&args);
        all.push(y);
        let o = run(&all);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert_eq!(stderr(&o).lines().count(), 1, "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn eval_annotations_plot_draws_each_annotated_map() {
    let d = tmpdir("marked");
    let o = run(&[
        "demo",
        "--detect-only",
        "-o",
        d.to_str().unwrap(),
        "--size",
        "300x200",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let marks = d.join("marks.json");
    fs::write(&marks, r#"{"maps": {"demo-map": [[20, 20], [100, 60]]}}"#).unwrap();
    let plots = d.join("plots");
    let o = run(&[
        "eval",
        "--backend",
        "cpu",
        "--annotations",
        marks.to_str().unwrap(),
        "--plot",
        plots.to_str().unwrap(),
        d.join("demo-map.yaml").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let sheet = image::open(plots.join("demo-map-marked.png"))
        .unwrap()
        .to_rgb8();
    assert!(sheet.width() > 1000);
    assert!(
        sheet
            .pixels()
            .any(|p| p.0 == ogm_corners::measure::compare::MARK_COLOUR.0),
        "marked points ringed"
    );
}

/// The `data-rows` of table `id` on a report page, and the number of `<tr>` in its body.
fn report_rows(page: &str, id: &str) -> (usize, usize) {
    let start = page
        .find(&format!("<table class=\"report\" id=\"{id}\" data-rows=\""))
        .unwrap_or_else(|| panic!("no table {id}"));
    let table = &page[start..];
    let table = &table[..table.find("</table>").unwrap()];
    let n: usize = table
        .split("data-rows=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let body = &table[table.find("<tbody>").unwrap()..];
    (n, body.matches("<tr").count())
}

/// `--html` without a browser: the pages are written with their tables and pictures (the browser test,
/// tests/browser, checks them in Chromium), two maps given with `--html` are placed as many maps, and the
/// annotated `eval` page holds the recall rows and a picture per annotated map.
#[test]
fn html_reports_hold_their_tables_and_pictures() {
    let d = tmpdir("html");
    let office = d.join("office.pgm");
    let o = run(&[
        "bench",
        "--size",
        "300x200",
        "--seed",
        "5",
        "--write-map",
        office.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let room = room_pgm(&d);
    // Two maps with --html: the many-map page, one row per map.
    let html = d.join("merge-html");
    let o = run(&[
        "merge",
        office.to_str().unwrap(),
        room.to_str().unwrap(),
        "--html",
        html.to_str().unwrap(),
        "--format",
        "json",
    ]);
    // Nothing can be placed together here: exit 3 (declined), the page written all the same.
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(html.join("index.html").is_file(), "{}", stderr(&o));
    let page = fs::read_to_string(html.join("index.html")).unwrap();
    assert_eq!(report_rows(&page, "maps"), (2, 2));
    assert_eq!(report_rows(&page, "pairs"), (1, 1));
    for src in page
        .split("<img src=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap())
    {
        assert!(html.join(src).is_file(), "{src} missing");
    }
    // eval --annotations --html: a row per detector run on the map, then the pooled rows.
    let marks = d.join("marks.json");
    fs::write(&marks, r#"{"maps": {"office": [[20, 20], [100, 50]]}}"#).unwrap();
    let html = d.join("eval-html");
    let o = run(&[
        "eval",
        "--backend",
        "cpu",
        "--annotations",
        marks.to_str().unwrap(),
        office.to_str().unwrap(),
        "--format",
        "json",
        "--html",
        html.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let n = rows.as_array().unwrap().len();
    let page = fs::read_to_string(html.join("index.html")).unwrap();
    assert_eq!(report_rows(&page, "recall"), (n, n));
    assert!(html.join("000-office-marked.png").is_file());
    assert!(page.contains("<img src=\"000-office-marked.png\""));
    // A folder that is a file: a one-line error, exit 2.
    let o = run(&[
        "merge-eval",
        "--synthetic",
        "--html",
        office.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("is a file, not a folder"),
        "{}",
        stderr(&o)
    );
    fs::remove_dir_all(&d).unwrap();
}

/// The instruction-set cap: each valid value gives the same keypoints (the kernels are identical), and a
/// value that names no instruction set is a one-line error, exit 2, not a silent default.
#[test]
fn instruction_set_cap_is_checked_and_changes_nothing_but_speed() {
    let dir = tmpdir("isa");
    let map = room_pgm(&dir);
    let map = map.to_str().unwrap();
    let want = stdout(&run(&["detect", map, "--backend", "cpu"]));
    for isa in ["scalar", "avx2", "avx512"] {
        let o = bin()
            .args(["detect", map, "--backend", "cpu"])
            .env("OGM_CORNERS_ISA", isa)
            .output()
            .unwrap();
        assert!(o.status.success(), "{isa}: {}", stderr(&o));
        assert_eq!(stdout(&o), want, "{isa}");
    }
    let o = bin()
        .args(["detect", map])
        .env("OGM_CORNERS_ISA", "sse9")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("OGM_CORNERS_ISA=sse9") && err.trim().lines().count() == 1,
        "{err}"
    );
}
