//! The merge surfaces against careless and hostile use: memory counted before a resampled map or a
//! preparation is allocated, outputs that never destroy the file standard output goes to, the user's
//! file size and address space limits met with one line and no leftovers, rosparam files that stay YAML,
//! names that cannot split records or reach the terminal raw, and plain messages. Each test fails on the
//! code before its fix.

use crate::common;
use std::fs;
use std::path::{Path, PathBuf};

use common::run::*;
use ogm_corners::map::synthetic::office_map;

/// An office map `w` x `h` written as `NAME.yaml` at `resolution` and `origin`, with its image beside it
/// (named after NAME with anything but letters and digits made `_`, so any NAME gives valid YAML).
fn office_yaml(dir: &Path, name: &str, w: u32, h: u32, resolution: f64, origin: &str) -> PathBuf {
    let image: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    office_map(w, h, 2)
        .unwrap()
        .write_pgm(&dir.join(format!("{image}.pgm")))
        .unwrap();
    let yaml = dir.join(format!("{name}.yaml"));
    fs::write(
        &yaml,
        format!(
            "image: {image}.pgm\nresolution: {resolution}\norigin: {origin}\nnegate: 0\n\
             occupied_thresh: 0.65\nfree_thresh: 0.196\n"
        ),
    )
    .unwrap();
    yaml
}

/// No temporary output file (`.NAME.XXXX.tmp`) left in `dir`.
#[track_caller]
fn no_temporaries(dir: &Path) {
    let left: Vec<String> = entries(dir)
        .into_iter()
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn a_map_resampled_to_finer_cells_is_counted_before_it_is_allocated() {
    let d = tmp();
    let a = office_yaml(d.path(), "a", 400, 300, 0.05, "[0, 0, 0]");
    for (resolution, needle) in [
        // 20x finer: 8000 x 6000 pixels and their preparation, far over 100 MiB.
        ("1.0", "8000x6000 at A's cells"),
        // 5x: under a GiB, still over the limit (it once peaked at twice the limit, unchecked).
        ("0.25", "2000x1500 at A's cells"),
    ] {
        let b = office_yaml(
            d.path(),
            "b",
            400,
            300,
            resolution.parse().unwrap(),
            "[0, 0, 0]",
        );
        let o = ogm(&["--max-memory", "100M", "merge", s(&a), s(&b)]);
        refused(&o, needle);
        assert!(
            stderr(&o).contains("over the limit of 100.0 MiB"),
            "{}",
            stderr(&o)
        );
    }
    // Past the largest map a resampling can make: said in plain words, naming the map and both
    // resolutions (not a 300-digit number).
    let b = office_yaml(d.path(), "b", 400, 300, 1e6, "[0, 0, 0]");
    let o = ogm(&["merge", s(&a), s(&b)]);
    refused(&o, "b.yaml: its cells are 1.000e6 m");
    let e = stderr(&o);
    assert!(
        e.contains("0.05 m") && e.contains("8000000000 x 6000000000 pixels") && e.len() < 400,
        "{e}"
    );
    // The same in many-map mode.
    let o = ogm(&[
        "--max-memory",
        "200M",
        "merge",
        s(&a),
        s(&a),
        s(&office_yaml(d.path(), "c", 400, 300, 1.0, "[0, 0, 0]")),
    ]);
    refused(&o, "maps and their preparation");
}

#[test]
fn a_huge_canvas_holding_one_small_room_is_counted_by_its_explored_part() {
    let d = tmp();
    // 8000 x 8000 pixels, unknown but for a 300 px room: its preparation once needed 2.6 GiB by the
    // canvas; by the room, a few MiB.
    let (w, room) = (8000u32, 300u32);
    let mut px = vec![205u8; (w * w) as usize];
    for y in 4000..4000 + room {
        for x in 4000..4000 + room {
            let edge = y == 4000 || x == 4000 || y == 3999 + room || x == 3999 + room;
            let inner = x == 4100 && y < 4200;
            px[(y * w + x) as usize] = if edge || inner { 0 } else { 254 };
        }
    }
    let map = d.path().join("huge.pgm");
    ogm_corners::MapImage::new(w, w, px)
        .unwrap()
        .write_pgm(&map)
        .unwrap();
    let o = ogm(&["--max-memory", "1G", "merge", s(&map), s(&map)]);
    // Merged or declined, not refused for memory.
    assert!(matches!(o.status.code(), Some(0 | 3)), "{}", stderr(&o));
}

#[test]
fn standard_output_named_as_a_file_is_appended_to_not_replaced() {
    let d = tmp();
    let a = office_yaml(d.path(), "a", 300, 240, 0.05, "[0, 0, 0]");
    let log = d.path().join("log");
    for (name, cmd) in [
        (
            "/dev/stdout",
            format!("\"$OGM\" merge {a} {a} --poses /dev/stdout", a = s(&a)),
        ),
        (
            "/dev/fd/1",
            format!("\"$OGM\" detect {} -o /dev/fd/1 --format json", s(&a)),
        ),
        (
            "/proc/self/fd/1",
            format!("\"$OGM\" detect {} -o /proc/self/fd/1 --format json", s(&a)),
        ),
    ] {
        fs::write(&log, "earlier line\n").unwrap();
        let o = sh(&format!("{cmd} >> {}", s(&log)));
        assert_eq!(o.status.code(), Some(0), "{name}: {}", stderr(&o));
        let text = fs::read_to_string(&log).unwrap();
        assert!(text.starts_with("earlier line\n{"), "{name}: {text:.200}");
        // The JSON first (the text verdict may follow it).
        let json = serde_json::Deserializer::from_str(&text["earlier line\n".len()..])
            .into_iter::<serde_json::Value>()
            .next()
            .unwrap()
            .unwrap();
        assert!(json.is_object(), "{name}");
    }
    // A link to standard output, and the redirected file named itself: the same.
    let link = d.path().join("out.json");
    std::os::unix::fs::symlink("/dev/stdout", &link).unwrap();
    fs::write(&log, "earlier line\n").unwrap();
    let o = sh(&format!(
        "\"$OGM\" detect {} -o {} --format json >> {}",
        s(&a),
        s(&link),
        s(&log)
    ));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(fs::read_to_string(&log)
        .unwrap()
        .starts_with("earlier line\n{"));
    assert!(fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    no_temporaries(d.path());
}

#[test]
fn a_file_size_limit_is_an_error_with_nothing_left_behind() {
    let d = tmp();
    let a = office_yaml(d.path(), "a", 600, 400, 0.05, "[0, 0, 0]");
    // Many keypoints: a keypoint file far over the limit.
    let busy = d.path().join("busy.pgm");
    common::random_map(400, 400, 1).write_pgm(&busy).unwrap();
    let out = d.path().join("out");
    fs::create_dir(&out).unwrap();
    // No `trap '' XFSZ` here: the tool itself must not die of SIGXFSZ (exit 153).
    for cmd in [
        format!(
            "\"$OGM\" merge {a} {a} -o {}/m.yaml --overlay {}/m.png",
            s(&out),
            s(&out),
            a = s(&a)
        ),
        format!(
            "\"$OGM\" detect {} -o {}/k.json --format json --unknown-as-occupied",
            s(&busy),
            s(&out)
        ),
        format!("cd {} && \"$OGM\" demo", s(&out)),
    ] {
        let o = sh(&format!("ulimit -f 20; {cmd}"));
        // As a full disk: a write failure (exit 1), said in one line.
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        let line = e
            .lines()
            .find(|l| l.starts_with("ogm-corners: error: "))
            .unwrap();
        assert!(
            line.contains("cannot write: over this process's file size limit (ulimit -f"),
            "{e}"
        );
        no_temporaries(&out);
        assert!(!out.join("m.pgm").exists() && !out.join("m.yaml").exists());
    }
}

#[test]
fn an_address_space_limit_is_part_of_the_budget_and_a_failed_allocation_one_line() {
    let d = tmp();
    let a = office_yaml(d.path(), "a", 3000, 3000, 0.05, "[0, 0, 0]");
    // The default budget sees `ulimit -v`: refused up front with the estimate.
    let o = sh(&format!(
        "ulimit -v 150000; \"$OGM\" merge {a} {a}",
        a = s(&a)
    ));
    refused(&o, "this process's limits");
    // A limit given above what the process may have: the failed allocation is one line, exit 2, not
    // an abort with a backtrace.
    let o = sh(&format!(
        "ulimit -v 200000; \"$OGM\" --max-memory 100G merge {a} {a} -o {}/m.yaml",
        s(d.path()),
        a = s(&a)
    ));
    refused(&o, "out of memory");
    assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
    no_temporaries(d.path());
}

#[test]
fn init_poses_stay_yaml_for_any_file_name_and_refuse_infinite_poses() {
    let d = tmp();
    let odd = "robot\nsplit: 1 #x";
    let a = office_yaml(d.path(), odd, 300, 240, 0.05, "[0, 0, 0]");
    let b = office_yaml(d.path(), "true", 300, 240, 0.05, "[1, 2, 0]");
    let init = d.path().join("init.yaml");
    let o = ogm(&["merge", s(&a), s(&b), "--init-poses", s(&init)]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = fs::read_to_string(&init).unwrap();
    let y: serde_yaml::Value = serde_yaml::from_str(&text).unwrap();
    let m = y.as_mapping().unwrap();
    assert_eq!(m.len(), 2, "{text}");
    for key in [odd, "true"] {
        assert!(
            y[key]["map_merge"]["init_pose_x"].is_f64(),
            "{key:?}: {text}"
        );
    }
    // Origins whose difference overflows: refused with the map's name, nothing written.
    let c = office_yaml(d.path(), "c", 300, 240, 0.05, "[1.7e308, 1.7e308, 0]");
    let e = office_yaml(d.path(), "e", 300, 240, 0.05, "[-1.7e308, -1.7e308, 0]");
    let init2 = d.path().join("init2.yaml");
    let o = ogm(&["merge", s(&c), s(&e), "--init-poses", s(&init2)]);
    refused(&o, "not finite");
    assert!(!init2.exists());
}

#[test]
fn names_reach_standard_output_and_tables_escaped() {
    let d = tmp();
    let a = office_yaml(
        d.path(),
        "a\u{1b}[31mred\nfake: line",
        300,
        240,
        0.05,
        "[0, 0, 0]",
    );
    let o = ogm(&[
        "merge",
        s(&a),
        s(&a),
        "--poses",
        s(&d.path().join("p.json")),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(
        !out.contains('\u{1b}') && !out.contains("\nfake: line"),
        "{out}"
    );
    assert!(out.contains("\\u{1b}[31mred\\nfake: line"), "{out}");
    // merge-eval's Markdown table: the building's `|`, line breaks and escapes cannot break it.
    let maps = d.path().join("maps");
    fs::create_dir(&maps).unwrap();
    office_map(300, 240, 3)
        .unwrap()
        .write_pgm(&maps.join("m.pgm"))
        .unwrap();
    let pairs = d.path().join("pairs.json");
    fs::write(
        &pairs,
        r#"{"pairs": [{"src": "m", "dst": "m", "building": "x|y\u001b[2J\nz", "theta_deg": 0, "tx": 0, "ty": 0,
            "rms_limit_px": 5, "rot_limit_deg": 2, "src_points": [[10, 10]], "dst_points": [[10, 10]]}]}"#,
    )
    .unwrap();
    // Its maps and their preparation are counted before the first is read.
    refused(
        &ogm(&["--max-memory", "1M", "merge-eval", s(&pairs)]),
        "the pair file's maps held at once (1) and their preparation needs about",
    );
    let o = ogm(&["merge-eval", s(&pairs)]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(!out.contains('\u{1b}'), "{out}");
    assert!(out.contains("| x\\|y\\u{1b}[2J z |"), "{out}");
}

#[test]
fn merge_messages_and_checks_come_before_the_work() {
    let d = tmp();
    let a = office_yaml(d.path(), "a", 300, 240, 0.05, "[0, 0, nan]");
    // A NaN yaw is said, as detect says it.
    let o = ogm(&["merge", s(&a), s(&a)]);
    assert!(stderr(&o).contains("warning"), "{}", stderr(&o));
    // A missing folder for the merged map: refused before aligning (nothing said of a merge).
    let o = ogm(&[
        "merge",
        s(&a),
        s(&a),
        "-o",
        s(&d.path().join("nowhere/m.yaml")),
    ]);
    refused(&o, "its folder does not exist");
    assert!(!stdout(&o).contains("merged"), "{}", stdout(&o));
    // A read-only folder: the same (root writes anywhere, so the check is only meaningful for others).
    if is_root() {
        eprintln!("NOTE: running as root: the read-only folder case is checked by `access` only for others");
    } else {
        let ro = d.path().join("ro");
        fs::create_dir(&ro).unwrap();
        fs::set_permissions(&ro, std::os::unix::fs::PermissionsExt::from_mode(0o555)).unwrap();
        let o = ogm(&["merge", s(&a), s(&a), "-o", s(&ro.join("m.yaml"))]);
        refused(&o, "cannot be written");
    }
    // `.yml` as `.yaml`, whatever the case, as `.PGM` is.
    let o = ogm(&["merge", s(&a), s(&a), "-o", s(&d.path().join("m.YML"))]);
    assert!(matches!(o.status.code(), Some(0 | 3)), "{}", stderr(&o));
    if o.status.code() == Some(0) {
        assert!(d.path().join("m.YML").is_file() && d.path().join("m.pgm").is_file());
    }
    // A GPU backend wgpu does not know: said, not silently no GPU.
    refused(
        &sh(&format!(
            "WGPU_BACKEND=bogus \"$OGM\" detect {} -o /dev/null",
            s(&a)
        )),
        "WGPU_BACKEND=bogus: unknown backend bogus",
    );
    // merge-eval: maps too small to cut synthetic pairs from, a negative limit, a fifo as a map.
    let tiny = d.path().join("tiny.pgm");
    office_map(32, 32, 1).unwrap().write_pgm(&tiny).unwrap();
    let o = ogm(&["merge-eval", "--synthetic", s(&tiny)]);
    refused(&o, "no synthetic pair could be cut");
    let maps = d.path().join("maps");
    fs::create_dir(&maps).unwrap();
    let pair = |limit: &str| {
        format!(
            r#"{{"pairs": [{{"src": "p", "dst": "q", "building": "b", "theta_deg": 0, "tx": 0, "ty": 0,
            "rms_limit_px": {limit}, "rot_limit_deg": 2, "src_points": [[1, 1]], "dst_points": [[1, 1]]}}]}}"#
        )
    };
    let pairs = d.path().join("pairs.json");
    fs::write(&pairs, pair("-5")).unwrap();
    refused(&ogm(&["merge-eval", s(&pairs)]), "must be positive");
    fs::write(&pairs, pair("5")).unwrap();
    office_map(200, 200, 1)
        .unwrap()
        .write_pgm(&maps.join("q.pgm"))
        .unwrap();
    let fifo = maps.join("p.pgm");
    rustix::fs::mknodat(
        rustix::fs::CWD,
        &fifo,
        rustix::fs::FileType::Fifo,
        rustix::fs::Mode::from_raw_mode(0o644),
        0,
    )
    .unwrap();
    refused(&ogm(&["merge-eval", s(&pairs)]), "fifo");
}

/// A pair file of `n` pairs of the office map `m` with itself (each drawn in an HTML report).
fn self_pairs(dir: &Path, n: usize) -> PathBuf {
    let maps = dir.join("maps");
    fs::create_dir_all(&maps).unwrap();
    office_map(300, 240, 3)
        .unwrap()
        .write_pgm(&maps.join("m.pgm"))
        .unwrap();
    let pair = r#"{"src": "m", "dst": "m", "building": "b", "theta_deg": 0, "tx": 0, "ty": 0,
        "rms_limit_px": 5, "rot_limit_deg": 2, "src_points": [[10, 10]], "dst_points": [[10, 10]]}"#;
    let path = dir.join(format!("pairs{n}.json"));
    fs::write(
        &path,
        format!(r#"{{"pairs": [{}]}}"#, vec![pair; n].join(",")),
    )
    .unwrap();
    path
}

#[test]
fn a_report_folder_holds_one_whole_report_and_a_stopped_run_leaves_the_previous_one() {
    let d = tmp();
    let html = d.path().join("report");
    let pngs = |dir: &Path| -> Vec<String> {
        entries(dir)
            .into_iter()
            .filter(|n| n.ends_with(".png"))
            .collect()
    };
    // A larger report, then a smaller one: the first one's extra pictures go with it; a file of the
    // user's in the folder stays.
    let o = ogm(&[
        "merge-eval",
        s(&self_pairs(d.path(), 3)),
        "--html",
        s(&html),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let first = pngs(&html);
    assert!(first.len() >= 3, "{first:?}");
    fs::write(html.join("notes.txt"), "mine").unwrap();
    let o = ogm(&[
        "merge-eval",
        s(&self_pairs(d.path(), 1)),
        "--html",
        s(&html),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let page = fs::read_to_string(html.join("index.html")).unwrap();
    let second = pngs(&html);
    assert!(second.len() < first.len(), "{second:?}");
    for p in &second {
        assert!(
            page.contains(&format!("src=\"{p}\"")),
            "{p} is not on the page"
        );
    }
    assert_eq!(fs::read_to_string(html.join("notes.txt")).unwrap(), "mine");
    // Stopped in the middle of a long report: the folder is as it was, no staging folder left.
    let before: Vec<(String, Vec<u8>)> = entries(&html)
        .into_iter()
        .map(|n| (n.clone(), fs::read(html.join(&n)).unwrap()))
        .collect();
    let mut child = std::process::Command::new(BIN)
        .args([
            "merge-eval",
            "--synthetic",
            "--family",
            "office",
            "--html",
            s(&html),
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    let staging_has_pictures = || {
        entries(&html)
            .iter()
            .filter(|n| n.starts_with(".staging."))
            .any(|n| !pngs(&html.join(n)).is_empty())
    };
    while !staging_has_pictures() && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(staging_has_pictures(), "no picture was staged");
    signal(child.id(), rustix::process::Signal::TERM);
    assert_eq!(child.wait().unwrap().code(), Some(130));
    let after: Vec<(String, Vec<u8>)> = entries(&html)
        .into_iter()
        .map(|n| (n.clone(), fs::read(html.join(&n)).unwrap()))
        .collect();
    assert!(after == before, "{:?}", entries(&html));
}

/// The pre-screen aligns a bounded number of pairs a map whatever the set: maps of noise share no
/// corner-pair term with each other, and each used to be aligned with every map (780 pairs of 40 maps);
/// now its partners are its neighbours in order and in size, and the whole screen (first round, cycles,
/// joins) stays within `partners + rounds x (per_round / 2 + 1)` pairs a map.
#[test]
fn the_pre_screen_aligns_a_bounded_number_of_pairs_a_map_for_maps_that_share_nothing() {
    use ogm_corners::backend::reference::ReferenceBackend;
    use ogm_corners::merge::many::prescreen::Prescreen;
    use ogm_corners::merge::many::{run, GlobalOptions};
    use ogm_corners::{MapImage, OccupancyMap};
    let maps: Vec<OccupancyMap> = (0..40u64)
        .map(|seed| {
            let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
            let px: Vec<u8> = (0..64 * 64)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    [0u8, 254, 205][(state % 3) as usize]
                })
                .collect();
            OccupancyMap::from_image(MapImage::new(64, 64, px).unwrap())
        })
        .collect();
    let r = run(
        &maps,
        &GlobalOptions::default(),
        &mut ReferenceBackend,
        &|_, _| {},
    )
    .unwrap();
    let p = Prescreen::default();
    let most = maps.len() * (p.partners + p.rounds * (p.per_round / 2 + 1));
    let aligned = r.pairwise.pairs.len();
    assert!(aligned <= most, "{aligned} pairs aligned, over {most}");
    assert!(aligned < 780 / 4, "{aligned} pairs aligned");
}
