//! The tool against careless and hostile use: outputs never half-written or destroyed, inputs never
//! overwritten, bounded memory and time on any input, clear one-line errors. One test (or more) per defect
//! of the reliability issue; each fails on the code before its fix.

use crate::common;
use common::run::*;

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use ogm_corners::map::synthetic::{office_map, FREE, OCCUPIED, UNKNOWN};

/// A map with many keypoints (a dense random three-state map), so keypoint files are large.
fn busy_pgm(dir: &Path, name: &str, w: u32, h: u32, seed: u64) -> PathBuf {
    let p = dir.join(name);
    common::random_map(w, h, seed).write_pgm(&p).unwrap();
    p
}

/// A small synthetic office map written as a PGM at `path`.
fn office_pgm(path: &Path, seed: u64) {
    office_map(64, 64, seed).unwrap().write_pgm(path).unwrap();
}

fn pgm_bytes(w: u32, h: u32, maxval: u32, samples: &[u8]) -> Vec<u8> {
    let mut b = format!("P5\n{w} {h}\n{maxval}\n").into_bytes();
    b.extend_from_slice(samples);
    b
}

fn room_samples() -> Vec<u8> {
    let rows = ["######", "#....#", "#....#", "#....#", "######"];
    rows.iter()
        .flat_map(|r| r.bytes().map(|b| if b == b'#' { 0 } else { 254 }))
        .collect()
}

// 1. Outputs are written whole or not at all.

#[test]
fn a_full_disk_leaves_the_previous_output_intact_and_no_partial_file() {
    let d = tmp();
    let map = busy_pgm(d.path(), "busy.pgm", 512, 512, 1);
    let out_dir = d.path().join("out");
    fs::create_dir(&out_dir).unwrap();
    for (ext, extra) in [("csv", ""), ("json", "--format json")] {
        let out = out_dir.join(format!("k.{ext}"));
        fs::write(&out, "previous good output\n").unwrap();
        // A file size limit makes writes past 16 KiB fail (EFBIG), as a full disk does (ENOSPC).
        let o = sh(&format!(
            "trap '' XFSZ; ulimit -f 32; exec \"$OGM\" detect --backend cpu {extra} {} -o {}",
            s(&map),
            s(&out)
        ));
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains("cannot write"), "{}", stderr(&o));
        assert_eq!(fs::read_to_string(&out).unwrap(), "previous good output\n");
    }
    // An overlay too, and no temporary file is left behind by any of them.
    let png = out_dir.join("o.png");
    let big = busy_pgm(d.path(), "big.pgm", 1100, 1100, 2);
    let o = sh(&format!(
        "trap '' XFSZ; ulimit -f 32; exec \"$OGM\" detect --backend cpu {} -o /dev/null --overlay {}",
        s(&big),
        s(&png)
    ));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!png.exists());
    assert_eq!(entries(&out_dir), ["k.csv", "k.json"]);
}

#[test]
fn an_interrupted_run_leaves_neither_a_partial_output_nor_a_temporary_file() {
    let d = tmp();
    // About a million keypoints: the JSON takes long enough to write to be caught in the middle.
    let map = busy_pgm(d.path(), "busy.pgm", 3000, 3000, 3);
    let out = d.path().join("k.json");
    let mut child = Command::new(BIN)
        .args([
            "detect",
            "--backend",
            "cpu",
            "--unknown-as-occupied",
            "--format",
            "json",
            s(&map),
            "-o",
            s(&out),
        ])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    let writing = loop {
        let temp = entries(d.path())
            .into_iter()
            .any(|n| n.starts_with(".k.json."));
        if temp || child.try_wait().unwrap().is_some() || Instant::now() > deadline {
            break temp;
        }
        std::thread::sleep(Duration::from_millis(1));
    };
    assert!(writing, "the temporary output never appeared");
    signal(child.id(), rustix::process::Signal::TERM);
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130));
    assert!(!out.exists(), "a partial output was left");
    assert_eq!(entries(d.path()), ["busy.pgm"]);
}

#[test]
fn two_runs_writing_one_file_leave_one_complete_output() {
    let d = tmp();
    let a = busy_pgm(d.path(), "a.pgm", 700, 700, 4);
    let b = busy_pgm(d.path(), "b.pgm", 700, 700, 5);
    let expected: Vec<String> = [&a, &b]
        .iter()
        .map(|m| stdout(&ogm(&["detect", "--backend", "cpu", s(m)])))
        .collect();
    let out = d.path().join("k.csv");
    for round in 0..3 {
        let spawn = |m: &Path| {
            Command::new(BIN)
                .args(["detect", "--backend", "cpu", s(m), "-o", s(&out)])
                .spawn()
                .unwrap()
        };
        let (mut x, mut y) = (spawn(&a), spawn(&b));
        assert!(x.wait().unwrap().success() && y.wait().unwrap().success());
        let got = fs::read_to_string(&out).unwrap();
        assert!(
            expected.contains(&got),
            "round {round}: the output is neither run's ({} bytes)",
            got.len()
        );
    }
}

// 2. No output overwrites an input.

#[test]
fn outputs_naming_an_input_are_refused_and_the_input_kept() {
    let d = tmp();
    let img = d.path().join("room.pgm");
    fs::write(&img, pgm_bytes(6, 5, 255, &room_samples())).unwrap();
    let yaml = d.path().join("room.yaml");
    fs::write(
        &yaml,
        "image: room.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n",
    )
    .unwrap();
    let link = d.path().join("alias.pgm");
    std::os::unix::fs::symlink(&img, &link).unwrap();
    let (img_bytes, yaml_bytes) = (fs::read(&img).unwrap(), fs::read(&yaml).unwrap());
    let dotted = d.path().join(".").join("room.pgm");
    let cases: Vec<Vec<&str>> = vec![
        vec![s(&img), "-o", s(&img)],
        vec![s(&yaml), "-o", s(&yaml)],
        vec![s(&yaml), "-o", s(&img)],
        vec![s(&yaml), "--overlay", s(&img)],
        vec![s(&yaml), "--overlay", s(&link)],
        vec![s(&img), "-o", s(&dotted)],
    ];
    for args in cases {
        let mut full = vec!["detect"];
        full.extend(&args);
        let o = ogm(&full);
        refused(&o, "refusing to overwrite");
        assert_eq!(fs::read(&img).unwrap(), img_bytes, "{args:?}");
        assert_eq!(fs::read(&yaml).unwrap(), yaml_bytes, "{args:?}");
    }
    let out = d.path().join("same.csv");
    let o = ogm(&["detect", s(&img), "-o", s(&out), "--overlay", s(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn a_batch_overlay_folder_that_is_the_map_folder_is_refused() {
    let d = tmp();
    let maps = d.path().join("maps");
    fs::create_dir(&maps).unwrap();
    for (name, seed) in [("a", 1), ("b", 2)] {
        let img = office_map(64, 64, seed).unwrap();
        let mut png = Vec::new();
        image::GrayImage::from_raw(64, 64, img.pixels().to_vec())
            .unwrap()
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        fs::write(maps.join(format!("{name}.png")), png).unwrap();
    }
    let before: Vec<Vec<u8>> = ["a", "b"]
        .iter()
        .map(|n| fs::read(maps.join(format!("{n}.png"))).unwrap())
        .collect();
    let o = ogm(&[
        "detect",
        s(&maps),
        "-o",
        s(&d.path().join("out")),
        "--overlay",
        s(&maps),
    ]);
    refused(&o, "refusing to overwrite");
    for (n, b) in ["a", "b"].iter().zip(before) {
        assert_eq!(fs::read(maps.join(format!("{n}.png"))).unwrap(), b);
    }
}

// 3. Link loops in batch folders.

#[test]
fn link_loops_in_a_batch_folder_visit_each_map_once() {
    let d = tmp();
    let maps = d.path().join("maps");
    fs::create_dir_all(maps.join("sub")).unwrap();
    office_pgm(&maps.join("a.pgm"), 1);
    office_pgm(&maps.join("sub/b.pgm"), 2);
    std::os::unix::fs::symlink(".", maps.join("loop")).unwrap();
    std::os::unix::fs::symlink("..", maps.join("sub/up")).unwrap();
    let out = d.path().join("out");
    let o = ogm(&["detect", s(&maps), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 2, "{}", stdout(&o));
    assert_eq!(entries(&out), ["a.csv", "b.csv"]);
}

// 4. Headers first, non-regular files refused.

#[test]
fn a_device_or_fifo_as_image_is_refused_at_once() {
    let d = tmp();
    let yaml = d.path().join("zero.yaml");
    fs::write(
        &yaml,
        "image: /dev/zero\nresolution: 0.05\norigin: [0, 0, 0]\n",
    )
    .unwrap();
    let o = ogm(&["detect", s(&yaml)]);
    refused(&o, "not a regular file (a device)");
    let fifo = d.path().join("pipe.pgm");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let o = ogm(&["detect", s(&fifo)]);
    refused(&o, "not a regular file (a fifo)");
    // In a batch folder: skipped with an error, the other maps done, exit 2 at the end.
    office_pgm(&d.path().join("ok.pgm"), 1);
    let out = d.path().join("out");
    let o = ogm(&["detect", s(d.path()), "-o", s(&out)]);
    refused(&o, "pipe.pgm: not a regular file");
    assert!(out.join("ok.csv").is_file());
}

#[test]
fn data_after_the_raster_is_not_read() {
    let d = tmp();
    let p = d.path().join("tail.pgm");
    fs::write(&p, pgm_bytes(6, 5, 255, &room_samples())).unwrap();
    // 5 GB of (sparse) data after a valid map; with 1 GB of address space, reading it whole would fail.
    let f = fs::OpenOptions::new().write(true).open(&p).unwrap();
    f.set_len(5 << 30).unwrap();
    drop(f);
    let o = sh(&format!(
        "ulimit -v 1000000; RAYON_NUM_THREADS=1 MALLOC_ARENA_MAX=1 exec \"$OGM\" detect --backend cpu {}",
        s(&p)
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 5, "{}", stdout(&o));
    assert!(stderr(&o).contains("ignored"), "{}", stderr(&o));
}

// 5. Memory bounded up front.

#[test]
fn commands_that_would_exhaust_memory_are_refused_up_front() {
    let d = tmp();
    // Harris on a 200000000 x 1 map: the header alone says it needs far more than the limit.
    let p = d.path().join("line.pgm");
    let mut f = fs::File::create(&p).unwrap();
    f.write_all(b"P5\n200000000 1\n255\n").unwrap();
    f.set_len(200_000_000 + 19).unwrap();
    drop(f);
    let o = ogm(&[
        "detect",
        "--detector",
        "harris",
        "--max-memory",
        "4G",
        s(&p),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("needs about") && e.contains("limit of 4.0 GiB") && e.contains("--max-memory"),
        "{e}"
    );
    // A PNG bomb: 20000 x 20000 16-bit grey (800 MB of samples) in a few megabytes.
    let bomb = d.path().join("bomb.png");
    {
        let f = fs::File::create(&bomb).unwrap();
        let mut enc = png::Encoder::new(std::io::BufWriter::new(f), 20000, 20000);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        enc.set_compression(png::Compression::Fast);
        let mut w = enc.write_header().unwrap().into_stream_writer().unwrap();
        let row = vec![0u8; 40000];
        for _ in 0..20000 {
            w.write_all(&row).unwrap();
        }
        w.finish().unwrap();
    }
    assert!(fs::metadata(&bomb).unwrap().len() < 16 << 20);
    // The robust detector, which holds it whole or in tiles of tens of megabytes, is refused from the
    // header below what one tile needs.
    let o = ogm(&[
        "detect",
        "--detector",
        "ogm-robust",
        "--max-memory",
        "32M",
        s(&bomb),
    ]);
    refused(&o, "limit of 32.0 MiB");
    // Streamed (the other detectors), it is read row by row within the limit: all occupied, no corner.
    let o = ogm(&[
        "detect",
        "--backend",
        "cpu",
        "--max-memory",
        "256M",
        s(&bomb),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o), "x,y,rule,code\n");
    // The limit also comes from the environment.
    let mut c = Command::new(BIN);
    c.args(["detect", "--detector", "ogm-robust", s(&bomb)])
        .env("OGM_MAX_MEMORY", "40M");
    let o = within(c, 60);
    refused(&o, "limit of 40.0 MiB");
    // demo refuses before it makes its folder or its map.
    let demo_dir = d.path().join("demo");
    let o = ogm(&[
        "demo",
        "--detect-only",
        "--size",
        "1000000x4000",
        "--max-memory",
        "1G",
        "-o",
        s(&demo_dir),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!demo_dir.exists());
}

#[test]
fn compressed_metadata_is_not_inflated() {
    // tests/data/metadata-bomb.png: a 20 x 10 room whose colour profile (iCCP) and comment (zTXt) each
    // inflate to 256 MiB from 500 KB. The map needs none of it: with 200 MB of address space it loads.
    let bomb = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/metadata-bomb.png");
    let o = sh(&format!(
        "ulimit -v 200000; RAYON_NUM_THREADS=1 MALLOC_ARENA_MAX=1 exec \"$OGM\" detect --backend cpu {}",
        s(&bomb)
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 5, "{}", stdout(&o));
}

#[test]
fn absurd_option_values_are_refused() {
    let d = tmp();
    let map = d.path().join("m.pgm");
    office_pgm(&map, 1);
    for args in [
        vec!["eval", "--trials", "4294967295", s(&map)],
        vec!["eval", "--trials", "1001", s(&map)],
        vec!["compare", "--repeat", "100000", s(&map)],
        vec!["bench", "--repeat", "100000"],
        vec!["detect", "--max-memory", "lots", s(&map)],
    ] {
        let o = ogm(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).starts_with("ogm-corners: error: "),
            "{}",
            stderr(&o)
        );
    }
}

// 6. Yaml parsing is bounded.

#[test]
fn deeply_nested_or_huge_yaml_is_refused_quickly() {
    let d = tmp();
    let nested = d.path().join("nested.yaml");
    fs::write(&nested, "[".repeat(100_000)).unwrap();
    let t = Instant::now();
    let o = ogm(&["detect", s(&nested)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("too large") || stderr(&o).contains("nested"));
    let small_nested = d.path().join("small.yaml");
    fs::write(&small_nested, format!("image: {}", "[".repeat(5000))).unwrap();
    let o = ogm(&["detect", s(&small_nested)]);
    refused(&o, "nested 5000 levels deep");
    // Generous: the point is seconds, not the minute the parser took.
    assert!(t.elapsed() < Duration::from_secs(20));
}

// 7. One unreadable entry does not stop a batch.

#[test]
fn unreadable_entries_are_skipped_and_the_batch_fails_at_the_end() {
    let d = tmp();
    let maps = d.path().join("maps");
    fs::create_dir_all(maps.join("locked")).unwrap();
    office_pgm(&maps.join("a.pgm"), 1);
    office_pgm(&maps.join("locked/b.pgm"), 2);
    fs::write(maps.join("latin1.yaml"), b"# caf\xe9\nimage: a.pgm\n").unwrap();
    fs::write(maps.join("params.yaml"), "controller_frequency: 5.0\n").unwrap();
    // A map yaml with a bad value is an error, and its image is not detected as a bare image instead.
    office_pgm(&maps.join("c.pgm"), 3);
    fs::write(
        maps.join("c.yaml"),
        "image: c.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nfree_thresh: 1.5\n",
    )
    .unwrap();
    // Permissions bind root only through another user: run the tool as nobody when we are root.
    let out = d.path().join("out");
    fs::create_dir(&out).unwrap();
    for p in [d.path(), &maps, &out] {
        set_mode(p, 0o777);
    }
    set_mode(&maps.join("locked"), 0o000);
    let root = is_root();
    let mut c = if root {
        // A copy of the tool where the other user can reach it (the build folder may be under /root).
        let bin = d.path().join("ogm-corners");
        fs::copy(BIN, &bin).unwrap();
        set_mode(&bin, 0o755);
        let mut c = Command::new("setpriv");
        c.args(["--reuid=65534", "--regid=65534", "--clear-groups"])
            .arg(&bin);
        c
    } else {
        Command::new(BIN)
    };
    c.args(["detect", s(&maps), "-o", s(&out)]);
    let o = within(c, 60);
    set_mode(&maps.join("locked"), 0o755);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("latin1.yaml: not UTF-8"), "{e}");
    assert!(e.contains("locked: cannot list the folder"), "{e}");
    assert!(e.contains("params.yaml: not a map yaml"), "{e}");
    assert!(e.contains("c.yaml: free_thresh must lie in [0, 1]"), "{e}");
    assert!(e.contains("3 entries could not be read"), "{e}");
    assert_eq!(entries(&out), ["a.csv"]);
}

fn set_mode(p: &Path, mode: u32) {
    use std::os::unix::fs::PermissionsExt;
    fs::set_permissions(p, fs::Permissions::from_mode(mode)).unwrap();
}

// 8. Malformed image data is refused, CRLF headers read right.

#[test]
fn samples_above_maxval_and_palette_indices_past_the_palette_are_refused() {
    let d = tmp();
    let p = d.path().join("maxval.pgm");
    let mut samples = vec![100u8; 30];
    samples[7] = 205;
    fs::write(&p, pgm_bytes(6, 5, 100, &samples)).unwrap();
    let o = ogm(&["detect", s(&p)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("205") && stderr(&o).contains("100"),
        "{}",
        stderr(&o)
    );
    // A 4-entry palette, and one pixel with index 9.
    let png_path = d.path().join("palette.png");
    {
        let f = fs::File::create(&png_path).unwrap();
        let mut enc = png::Encoder::new(f, 4, 2);
        enc.set_color(png::ColorType::Indexed);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_palette(vec![0, 0, 0, 205, 205, 205, 254, 254, 254, 9, 9, 9]);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&[0, 1, 2, 3, 2, 9, 2, 2]).unwrap();
    }
    let o = ogm(&["detect", s(&png_path)]);
    refused(&o, "palette");
}

#[test]
fn a_crlf_pgm_header_gives_the_same_keypoints() {
    let d = tmp();
    let img = office_map(200, 160, 3).unwrap();
    let lf = d.path().join("lf.pgm");
    img.write_pgm(&lf).unwrap();
    let crlf = d.path().join("crlf.pgm");
    let mut b = b"P5\r\n# made on Windows\r\n200 160\r\n255\r\n".to_vec();
    b.extend_from_slice(img.pixels());
    fs::write(&crlf, b).unwrap();
    let a = ogm(&["detect", s(&lf)]);
    let b = ogm(&["detect", s(&crlf)]);
    assert!(a.status.success() && b.status.success(), "{}", stderr(&b));
    assert!(stdout(&a).lines().count() > 5);
    assert_eq!(stdout(&a), stdout(&b));
}

// 9. World coordinates stay finite.

#[test]
fn a_resolution_that_makes_world_coordinates_infinite_is_refused() {
    let d = tmp();
    fs::write(
        d.path().join("room.pgm"),
        pgm_bytes(6, 5, 255, &room_samples()),
    )
    .unwrap();
    for (res, origin) in [("1e308", "[0, 0, 0]"), ("1e307", "[1.79e308, 0, 0]")] {
        let yaml = d.path().join("room.yaml");
        fs::write(
            &yaml,
            format!("image: room.pgm\nresolution: {res}\norigin: {origin}\n"),
        )
        .unwrap();
        let o = ogm(&["detect", "--format", "json", s(&yaml)]);
        refused(&o, "non-finite world coordinates");
    }
}

// 10. The rest.

#[test]
fn a_closed_standard_output_is_an_error() {
    let d = tmp();
    let p = d.path().join("room.pgm");
    fs::write(&p, pgm_bytes(6, 5, 255, &room_samples())).unwrap();
    for cmd in [format!("detect {}", s(&p)), "rules".to_string()] {
        let o = sh(&format!("exec \"$OGM\" {cmd} >&-"));
        assert_eq!(o.status.code(), Some(1), "{cmd}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("standard output is closed"),
            "{}",
            stderr(&o)
        );
    }
    // With stdout closed, an output file must not take its place (fd 1) and receive stray text.
    let out = d.path().join("k.csv");
    let o = sh(&format!(
        "exec \"$OGM\" detect {} -o {} >&-",
        s(&p),
        s(&out)
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(fs::read_to_string(&out)
        .unwrap()
        .starts_with("x,y,rule,code\n"));
}

#[test]
fn a_yaml_with_a_byte_order_mark_loads() {
    let d = tmp();
    fs::write(
        d.path().join("room.pgm"),
        pgm_bytes(6, 5, 255, &room_samples()),
    )
    .unwrap();
    let yaml = d.path().join("room.yaml");
    fs::write(
        &yaml,
        "\u{feff}image: room.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n",
    )
    .unwrap();
    let o = ogm(&["detect", s(&yaml)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 5);
}

#[test]
fn a_batch_on_a_full_disk_says_what_failed() {
    let d = tmp();
    let maps = d.path().join("maps");
    fs::create_dir(&maps).unwrap();
    for i in 1..=3 {
        busy_pgm(&maps, &format!("m{i}.pgm"), 400, 400, i);
    }
    let out = d.path().join("out");
    let o = sh(&format!(
        "trap '' XFSZ; ulimit -f 16; exec \"$OGM\" detect --backend cpu {} -o {}",
        s(&maps),
        s(&out)
    ));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    let last = e.lines().last().unwrap();
    assert!(
        last.contains("3 of 3 maps failed: 3 could not be written (first:")
            && last.contains("File too large"),
        "{last}"
    );
    assert!(!e.contains("internal error"), "{e}");
    assert!(entries(&out).is_empty(), "{:?}", entries(&out));
}

#[test]
fn usage_errors_lead_with_one_line_and_refusals_come_before_output() {
    let o = ogm(&["detect"]);
    assert_eq!(o.status.code(), Some(2));
    let first = stderr(&o).lines().next().unwrap().to_string();
    assert!(
        first.starts_with("ogm-corners: error: ") && first.contains("<MAP>"),
        "{first}"
    );
    // bench refuses a size before it prints its header.
    let o = ogm(&["bench", "--size", "10x10"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(o.stdout.is_empty(), "{}", stdout(&o));
    // demo refuses a size before it makes its folder.
    let d = tmp();
    let dir = d.path().join("demo");
    let o = ogm(&["demo", "--detect-only", "--size", "10x10", "-o", s(&dir)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!dir.exists());
}

#[test]
fn values_in_a_map_are_read_as_they_are() {
    // Guard for the strict decoder: the three ROS values survive exactly.
    let d = tmp();
    let p = d.path().join("v.pgm");
    fs::write(&p, pgm_bytes(3, 1, 255, &[FREE, UNKNOWN, OCCUPIED])).unwrap();
    let m = ogm_corners::OccupancyMap::load(&p).unwrap();
    assert_eq!(m.image.pixels(), [FREE, UNKNOWN, OCCUPIED]);
}

#[test]
fn a_batch_piped_into_head_still_writes_every_map() {
    let d = tmp();
    let maps = d.path().join("maps");
    fs::create_dir(&maps).unwrap();
    for i in 0..6 {
        office_pgm(&maps.join(format!("m{i}.pgm")), i);
    }
    let out = d.path().join("out");
    let o = sh(&format!(
        "\"$OGM\" detect --backend cpu {} -o {} | head -1",
        s(&maps),
        s(&out)
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().count(), 1);
    assert_eq!(entries(&out).len(), 6, "{:?}", entries(&out));
    // And with standard output closed: the files are the results.
    let out2 = d.path().join("out2");
    let o = sh(&format!(
        "exec \"$OGM\" detect --backend cpu {} -o {} >&-",
        s(&maps),
        s(&out2)
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(entries(&out2).len(), 6);
}

#[test]
fn long_runs_check_every_map_before_they_start() {
    let d = tmp();
    let maps = d.path().join("maps");
    fs::create_dir(&maps).unwrap();
    office_pgm(&maps.join("good.pgm"), 1);
    let bad = d.path().join("trunc.pgm");
    fs::write(&bad, b"P5\n64 64\n255\n\x00\x00").unwrap();
    let out = d.path().join("cmp");
    let o = ogm(&[
        "compare",
        "--backend",
        "cpu",
        "--repeat",
        "1",
        "--out",
        s(&out),
        s(&maps),
        s(&bad),
    ]);
    refused(&o, "trunc.pgm: truncated PGM");
    assert!(!out.exists(), "compare wrote before checking its maps");
    // A folder is searched like detect's; an output folder that is a file is a usage error.
    let o = ogm(&["eval", "--backend", "cpu", "--trials", "1", s(&maps)]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Rows name the map by its first distinctive path component, not its path.
    assert!(stdout(&o).contains("| good |"), "{}", stdout(&o));
    let o = ogm(&["demo", "--detect-only", "--size", "64x64", "-o", s(&bad)]);
    refused(&o, "is a file, not a folder");
    let o = ogm(&[]);
    refused(&o, "no command given");
}

#[test]
fn standard_streams_given_as_dev_null_or_a_closed_pipe_are_no_errors() {
    // /dev/null opened read-write, as Python's subprocess.DEVNULL and daemons give it: an open stdout.
    let null = fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open("/dev/null")
        .unwrap();
    let o = Command::new(BIN)
        .arg("rules")
        .stdout(null)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    // A standard error nobody reads (`2>&1 | head`): the error is lost, the exit status is not, and no
    // panic replaces it.
    let (reader, writer) = rustix::pipe::pipe().unwrap();
    drop(reader);
    let st = Command::new(BIN)
        .args(["detect", "/nonexistent/map.pgm"])
        .stderr(std::fs::File::from(writer))
        .status()
        .unwrap();
    assert_eq!(st.code(), Some(2));
}

#[test]
fn a_folder_named_twice_is_searched_once_and_mixed_failures_say_so() {
    let d = tmp();
    let maps = d.path().join("maps");
    fs::create_dir_all(maps.join("sub")).unwrap();
    office_pgm(&maps.join("sub/a.pgm"), 1);
    let out = d.path().join("out");
    let o = ogm(&["detect", s(&maps), s(&maps.join("sub")), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("searched already"), "{}", stderr(&o));
    assert_eq!(entries(&out), ["a.csv"]);
    // One unreadable map and outputs that cannot be written: an output failure (1), not "internal".
    fs::write(maps.join("bad.pgm"), b"P5\n9 9\n255\n").unwrap();
    for i in 1..=2 {
        busy_pgm(&maps, &format!("m{i}.pgm"), 300, 300, i);
    }
    let o = sh(&format!(
        "trap '' XFSZ; ulimit -f 16; exec \"$OGM\" detect --backend cpu {} -o {}",
        s(&maps),
        s(&d.path().join("out2"))
    ));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("1 could not be read") && e.contains("could not be written"),
        "{e}"
    );
    assert!(!e.contains("internal error"), "{e}");
}
