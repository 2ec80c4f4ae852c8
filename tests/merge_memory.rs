//! A many-map merge holds no more than it counts before it starts ([`footprint::many_bytes`], what
//! `merge --max-memory` and the Python `merge_many` check): the pairs aligned in parallel each with
//! their working memory, a map far larger than the others in several pairs at once, the cache of what
//! was aligned, the allocator's slack. Measured as the tool's peak resident memory under a budget of
//! its own estimate; and a map too large to align with any other spoils nothing.
//!
//! A binary of its own, not a module of `tests/merge/`: a child's peak resident memory as the kernel
//! reports it includes its parent's (the image it was started from, before `exec`), so a test binary running other
//! merges in its own threads at the same time would lend the tool their memory (measured: 845 MiB
//! against an estimate of 371 when it ran beside them).

use std::path::Path;

use ogm_corners::measure::merging::many::{synthetic_maps, synthetic_mixed};
use ogm_corners::{MapImage, OccupancyMap};

/// `merge` run in `dir` with `args`: its exit code, what it said (standard error, then output) and its
/// peak resident memory, bytes.
// Waited for by wait4 (for its resource usage), which std's `Child` does not offer.
#[allow(clippy::zombie_processes)]
fn merge_measured(dir: &Path, args: &[String]) -> (Option<i32>, String, u64) {
    use std::process::{Command, Stdio};
    let child = Command::new(env!("CARGO_BIN_EXE_ogm-corners"))
        .arg("merge")
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::from(
            std::fs::File::create(dir.join("stdout.txt")).unwrap(),
        ))
        .stderr(Stdio::from(
            std::fs::File::create(dir.join("stderr.txt")).unwrap(),
        ))
        .spawn()
        .unwrap();
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: plain libc calls on a child of this process that std has not waited for.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let waited = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(waited, pid);
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    let read = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
    let said = read("stderr.txt") + &read("stdout.txt");
    (code, said, usage.ru_maxrss as u64 * 1024)
}

/// `maps` written into `dir`; their file names.
fn written(dir: &Path, maps: &[OccupancyMap]) -> Vec<String> {
    maps.iter()
        .enumerate()
        .map(|(i, m)| {
            let name = format!("m{i:02}.pgm");
            m.image.write_pgm(&dir.join(&name)).unwrap();
            name
        })
        .collect()
}

/// The set merged under a budget of exactly its own estimate (each refusal's "needs about", from
/// 1 MiB up, until it runs): its peak resident memory stays within.
fn within_its_estimate(maps: &[OccupancyMap], what: &str) {
    let d = tempfile::tempdir().unwrap();
    let mut args = written(d.path(), maps);
    args.extend(["--max-memory".to_string(), "1048576".to_string()]);
    for _ in 0..40 {
        let limit: u64 = args.last().unwrap().parse().unwrap();
        let (code, err, peak) = merge_measured(d.path(), &args);
        let Some(need) = err.split("needs about ").nth(1) else {
            assert!(code.is_some(), "{what}: {err}");
            assert!(
                peak <= limit,
                "{what}: peak {} MiB over its estimate of {} MiB",
                peak >> 20,
                limit >> 20
            );
            return;
        };
        let mib: f64 = need
            .split(" MiB")
            .next()
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("{err}"));
        *args.last_mut().unwrap() = ((mib + 0.1) * 1048576.0).ceil().to_string();
    }
    panic!("{what}: still refused after forty estimates");
}

/// A strip `w` px long and 10 high: a corridor's two walls, free between them.
fn strip(w: u32) -> OccupancyMap {
    let px: Vec<u8> = (0..10u32)
        .flat_map(|y| {
            let v = match y {
                1 | 8 => 0,
                2..=7 => 254,
                _ => 205,
            };
            std::iter::repeat_n(v, w as usize)
        })
        .collect();
    OccupancyMap::from_image(MapImage::new(w, 10, px).unwrap())
}

#[test]
fn a_many_map_merge_stays_within_its_estimate_and_one_map_too_large_spoils_nothing() {
    // A fleet of 16 maps of two offices, screened.
    let (_, maps, _) = synthetic_mixed(16, 2, 5).unwrap();
    within_its_estimate(&maps, "16 maps");
    // Small maps and one 20000 px long: every pair with it runs at once with its large correlation.
    let (_, mut maps, _) = synthetic_maps(13, 3).unwrap();
    maps.push(strip(20000));
    within_its_estimate(&maps, "13 maps and a strip");
    // One 40000 px long, too large to correlate with any other: not placed, with the reason, and the
    // others merged.
    let (_, mut maps, _) = synthetic_maps(13, 3).unwrap();
    maps.push(strip(40000));
    let d = tempfile::tempdir().unwrap();
    let args = written(d.path(), &maps);
    let (code, err, _) = merge_measured(d.path(), &args);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains(
            "m13.pgm: not placed: none of its pairs could be aligned (too large to align)"
        ),
        "{err}"
    );
    assert!(!err.contains("m00.pgm: not placed"), "{err}");
}
