//! Sets `OGM_GIT_COMMIT` (the short commit, or "unknown" without git) for `ogm-corners bench` records, and
//! `OGM_MEASURE_ID` (a hash of the code that measures an alignment) for the `merge-eval` cache.

use std::path::Path;
use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".to_string());
    println!("cargo:rustc-env=OGM_GIT_COMMIT={commit}");
    measure_id();
    // Rerun only when HEAD moves (a checkout, or a commit on the current branch), not on every source edit.
    // Only existing paths: Cargo reruns on every build for a path that does not exist.
    println!("cargo:rerun-if-changed=build.rs");
    let head = Path::new(".git/HEAD");
    if head.is_file() {
        println!("cargo:rerun-if-changed=.git/HEAD");
        if let Some(r) = std::fs::read_to_string(head)
            .ok()
            .and_then(|s| s.strip_prefix("ref: ").map(|r| r.trim().to_string()))
        {
            let loose = Path::new(".git").join(r);
            if loose.is_file() {
                println!("cargo:rerun-if-changed={}", loose.display());
            }
        }
    }
}

/// Sets `OGM_MEASURE_ID`: a hash of the code that measures an alignment (every source under `src/` but the
/// command line and the evaluation harness, the shaders, the locked dependencies), so that the results
/// `merge-eval` caches on disk are found again only by a build that would measure them the same way.
fn measure_id() {
    use std::hash::Hasher;
    let mut files = Vec::new();
    for dir in ["src", "shaders"] {
        collect(Path::new(dir), &mut files);
        println!("cargo:rerun-if-changed={dir}");
    }
    files.push(Path::new("Cargo.lock").to_path_buf());
    println!("cargo:rerun-if-changed=Cargo.lock");
    files.retain(|p| !(p.starts_with("src/cli") || p.starts_with("src/merge/eval")));
    files.sort();
    // SipHash with fixed keys: stable within a toolchain, which is all a cache key needs.
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for f in &files {
        h.write(f.to_string_lossy().as_bytes());
        h.write(&std::fs::read(f).unwrap_or_default());
    }
    println!(
        "cargo:rustc-env=OGM_MEASURE_ID={}-{:016x}",
        std::env::var("CARGO_PKG_VERSION").unwrap_or_default(),
        h.finish()
    );
}

/// Every file under `dir`.
fn collect(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            collect(&p, out);
        } else {
            out.push(p);
        }
    }
}
